"""The 3-axis model through the C library: :class:`CModel` (``abbe_model_load``, the
``_f32`` / ``_q`` evaluations of whole rows, single terms and reversals) and
:func:`crc32`.

Units as in the C API: the ``_f32`` variant takes mm / deg C and returns um
(urad for angular terms); the ``_q`` variant takes nm / Q30 / m°C and returns
nm (pm / prad for single terms).
"""

from __future__ import annotations

import ctypes as C
import struct
from typing import Any

import numpy as np

from abbe.model.clib.library import FLAG_INPUT_INVALID, _check, _f32_rows, _i32_rows, load_library
from abbe.model.clib.structs import (_ERROR_F32_DTYPE, _ERROR_Q_DTYPE, ErrorF32, ErrorQ, InputF32,
                                     InputQ, Model)
from abbe.model.table import AXES, TERMS

def _axis_term(axis: str | int, term: str | int) -> tuple[int, int]:
    ai = AXES.index(axis) if isinstance(axis, str) else int(axis)
    ti = TERMS.index(term) if isinstance(term, str) else int(term)
    return ai, ti


class CModel:
    """A table loaded and validated by the C library (``abbe_model_load``).

    The C model points into the blob, so this object keeps its own copy of the
    bytes alive as long as it lives.
    """

    def __init__(self, blob: bytes, source: str = "<blob>") -> None:
        self._lib = load_library()
        self._buf = C.create_string_buffer(bytes(blob), len(blob))
        self._size = len(blob)
        self._model = Model()
        _check(self._lib.abbe_model_load(C.byref(self._model), self._buf, self._size),
               "abbe_model_load", source)

    @property
    def ptr(self) -> Any:
        """ctypes pointer to the abbe_model_t."""
        return C.byref(self._model)

    @property
    def crc(self) -> int:
        """CRC-32 of the table (abbe_model_crc)."""
        return int(self._lib.abbe_model_crc(C.byref(self._model)))

    @property
    def features(self) -> int:
        """Feature bits (abbe_model_features)."""
        return int(self._lib.abbe_model_features(C.byref(self._model)))

    @property
    def size(self) -> int:
        """total_size of the table (abbe_model_size)."""
        return int(self._lib.abbe_model_size(C.byref(self._model)))

    def tref_mdegc(self) -> np.ndarray:
        """Per-axis thermal reference temperature (m°C) of the loaded table: the
        default temperature input (no thermal contribution)."""
        raw = self._buf.raw
        return np.array([struct.unpack_from("<i", raw, 64 + 64 * j + 44)[0] for j in range(3)],
                        dtype=np.int64)

    def tref_c(self) -> np.ndarray:
        """Per-axis thermal reference temperature, deg C."""
        return self.tref_mdegc() / 1000.0

    def error_f32(self, pos_mm: Any, dir_state: Any = None,
                  temp_c: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """abbe_error_eval_f32 for each row: ((N,3) um float64 of the float32 result,
        (N,) flags). ``temp_c`` None = each axis at its reference temperature.
        Raises TableError(ABBE_E_INPUT ...) for a non-finite input."""
        pos = _f32_rows(pos_mm)
        n = pos.shape[0]
        ds = _f32_rows(dir_state, n)
        tc = (np.tile(self.tref_c(), (n, 1)).astype(np.float32) if temp_c is None
              else _f32_rows(temp_c))
        if ds.shape[0] != n or tc.shape[0] != n:
            raise ValueError("dir_state / temp_c must have the same rows as pos_mm")
        # one call for all rows (abbe_error_eval_batch_f32): rows of
        # abbe_input_f32_t (9 floats) in, abbe_error_f32_t (3 floats, flags) out
        inp = np.ascontiguousarray(np.hstack([pos, ds, tc]), dtype=np.float32)
        out = np.zeros(n, dtype=_ERROR_F32_DTYPE)
        status = self._lib.abbe_error_eval_batch_f32(
            C.byref(self._model), n, inp.ctypes.data_as(C.POINTER(InputF32)),
            out.ctypes.data_as(C.POINTER(ErrorF32)))
        if status != 0:
            bad = np.flatnonzero(out["flags"] & FLAG_INPUT_INVALID)
            where = f" (row {int(bad[0])})" if bad.size else ""
            _check(status, f"abbe_error_eval_f32{where}")
        return out["error_um"].astype(np.float64), out["flags"].copy()

    def error_q(self, pos_nm: Any, dir_q30: Any = None,
                temp_mdegc: Any = None) -> tuple[np.ndarray, np.ndarray]:
        """abbe_error_eval_q for each row: ((N,3) int64 nm, (N,) flags)."""
        pos = _i32_rows(pos_nm)
        n = pos.shape[0]
        ds = _i32_rows(dir_q30, n)
        tc = (np.tile(self.tref_mdegc(), (n, 1)) if temp_mdegc is None
              else _i32_rows(temp_mdegc))
        if ds.shape[0] != n or tc.shape[0] != n:
            raise ValueError("dir_q30 / temp_mdegc must have the same rows as pos_nm")
        # one call for all rows (abbe_error_eval_batch_q)
        inp = np.ascontiguousarray(np.hstack([pos, ds, tc]), dtype=np.int32)
        out = np.zeros(n, dtype=_ERROR_Q_DTYPE)
        _check(self._lib.abbe_error_eval_batch_q(
            C.byref(self._model), n, inp.ctypes.data_as(C.POINTER(InputQ)),
            out.ctypes.data_as(C.POINTER(ErrorQ))), "abbe_error_eval_q")
        return out["error_nm"].astype(np.int64), out["flags"].copy()

    def term_f32(self, axis: str | int, term: str | int, pos_mm: Any) -> np.ndarray:
        """abbe_term_eval_f32 at each position: um (linear) / urad (angular)."""
        ai, ti = _axis_term(axis, term)
        p = np.asarray(pos_mm, dtype=np.float32).reshape(-1)
        out = np.zeros(p.size)
        v = C.c_float()
        for i, x in enumerate(p):
            _check(self._lib.abbe_term_eval_f32(C.byref(self._model), ai, ti, float(x),
                                                C.byref(v)), "abbe_term_eval_f32")
            out[i] = v.value
        return out

    def term_q(self, axis: str | int, term: str | int, pos_nm: Any) -> np.ndarray:
        """abbe_term_eval_q at each position (int nm): pm (linear) / prad (angular)."""
        ai, ti = _axis_term(axis, term)
        p = np.asarray(pos_nm).astype(np.int64).reshape(-1)
        out = np.zeros(p.size, dtype=np.int64)
        v = C.c_int32()
        for i, x in enumerate(p):
            _check(self._lib.abbe_term_eval_q(C.byref(self._model), ai, ti, int(x),
                                              C.byref(v)), "abbe_term_eval_q")
            out[i] = v.value
        return out


    def reversal_f32(self, axis: str | int, pos_mm: Any) -> np.ndarray:
        """abbe_reversal_eval_f32 at each position: the axis' total reversal
        B + R(p), um (abbe.model.reference.reversal_values)."""
        ai, _ = _axis_term(axis, 0)
        p = np.asarray(pos_mm, dtype=np.float32).reshape(-1)
        out = np.zeros(p.size)
        v = C.c_float()
        for i, x in enumerate(p):
            _check(self._lib.abbe_reversal_eval_f32(C.byref(self._model), ai, float(x), C.byref(v)),
                   "abbe_reversal_eval_f32")
            out[i] = v.value
        return out

    def reversal_q(self, axis: str | int, pos_nm: Any) -> np.ndarray:
        """abbe_reversal_eval_q at each position (int nm): the total reversal, pm."""
        ai, _ = _axis_term(axis, 0)
        p = np.asarray(pos_nm).astype(np.int64).reshape(-1)
        out = np.zeros(p.size, dtype=np.int64)
        v = C.c_int32()
        for i, x in enumerate(p):
            _check(self._lib.abbe_reversal_eval_q(C.byref(self._model), ai, int(x), C.byref(v)),
                   "abbe_reversal_eval_q")
            out[i] = v.value
        return out


def crc32(data: bytes, crc: int = 0) -> int:
    """abbe_crc32 (zlib CRC-32, continuing from ``crc``)."""
    lib = load_library()
    buf = C.create_string_buffer(bytes(data), len(data))
    return int(lib.abbe_crc32(crc, buf, len(data)))
