"""ctypes binding to the abbe C library (``libabbe.so``).

The shared object is looked up in ``$ABBE_LIB`` first, then in the installed
package (a wheel carries it), then in the checkout's ``build/lib/`` (built by
CMake); see :mod:`abbe.paths`. The structs below mirror
``lib/include/abbe/*.h`` field by field; keep them in step with the headers.

Units as in the C API: the ``_f32`` variant takes mm / deg C and returns um
(urad for angular terms); the ``_q`` variant takes nm / Q30 / m°C and returns
nm (pm / prad for single terms).
"""

from __future__ import annotations

import ctypes as C
import platform
import struct
from pathlib import Path
from typing import Any

import numpy as np

from abbe import paths
from abbe.model.table import AXES, TERMS, TableError

ABBE_AXES = 3
ABBE_TERMS = 6
ABBE_BLOCKS = 2
# abbe_model_t has the x86-64-v3 phase lanes on x86-64 only (model.h, ABBE_MODEL_X86_64_LANES)
_X86_64 = platform.machine().lower() in ("x86_64", "amd64") and C.sizeof(C.c_void_p) == 8

STATUS_NAMES: dict[int, str] = {
    0: "ABBE_OK", -1: "ABBE_E_ARG", -2: "ABBE_E_TRUNCATED", -3: "ABBE_E_MAGIC",
    -4: "ABBE_E_VERSION_MAJOR", -5: "ABBE_E_VERSION_MINOR", -6: "ABBE_E_SIZE",
    -7: "ABBE_E_CRC", -8: "ABBE_E_FLAGS", -9: "ABBE_E_COUNT", -10: "ABBE_E_OFFSET",
    -11: "ABBE_E_NONFINITE", -12: "ABBE_E_PERIOD", -13: "ABBE_E_TRAVEL",
    -14: "ABBE_E_RANGE", -15: "ABBE_E_INPUT", -16: "ABBE_E_NO_MODEL", -17: "ABBE_E_MISMATCH",
    -18: "ABBE_E_ALIGN",
}

FLAG_OUT_OF_TRAVEL = 0x0001
FLAG_SATURATED = 0x0002
FLAG_INPUT_INVALID = 0x0200
DIR_Q30_ONE = 1 << 30


class LibraryNotFound(RuntimeError):
    """The shared library is not built or not where expected.

    ``what`` is the finding alone (no advice), for a caller that gives its own advice
    (``abbe fit``: the build command or ``--no-clib-check``) and must say it once."""

    def __init__(self, what: str, advice: str = "") -> None:
        super().__init__(what + (f": {advice}" if advice else ""))
        self.what = what


# --------------------------------------------------------------------------- structs


class AxisModel(C.Structure):
    """abbe_axis_model_t (private fields, mirrored for the size and layout)."""
    _fields_ = [
        ("coef_q", C.c_void_p),
        ("coef_f32", C.c_void_p),
        ("freq", C.c_uint64 * ABBE_BLOCKS),
        ("phase_min", C.c_uint64 * ABBE_BLOCKS),
        ("takeup_rate_q46", C.c_uint64),
        ("travel_min_nm", C.c_int32),
        ("travel_max_nm", C.c_int32),
        ("span_nm", C.c_uint32),
        ("cheb_mul", C.c_uint32),
        ("backlash_reversal_q8", C.c_int32),
        ("backlash_takeup_nm", C.c_int32),
        ("thermal_expansion_q50", C.c_int32),
        ("thermal_offset_q16", C.c_int32),
        ("thermal_tref_mdegc", C.c_int32),
        ("cheb_shift", C.c_uint8),
        ("term_mask", C.c_uint8),
        ("n_terms", C.c_uint8),
        ("trend_rows", C.c_uint8),
        ("harmonics", C.c_uint8 * ABBE_BLOCKS),
        ("n_basis", C.c_uint8),
        ("column", C.c_uint8 * ABBE_TERMS),
        ("reversal_rows", C.c_uint8),
    ]


class Model(C.Structure):
    """abbe_model_t."""
    _fields_ = [
        ("blob", C.c_void_p),
        ("size", C.c_uint32),
        ("crc", C.c_uint32),
        ("features", C.c_uint32),
        ("version_major", C.c_uint16),
        ("version_minor", C.c_uint16),
        ("reference_nm", C.c_int32 * ABBE_AXES),
        ("tool_offset_nm", C.c_int32 * ABBE_AXES),
        ("squareness_q36", C.c_int32 * 3),
        ("square_const_q36", C.c_int64 * 2),
        ("ref_half_nm", C.c_int32 * 4),
        ("lane_min_nm", C.c_int32 * 4),
        ("lane_max_nm", C.c_int32 * 4),
        ("lane_span_nm", C.c_uint32 * 4),
        ("lane_cheb_shift", C.c_uint32 * 4),
        ("lane_cheb_mul", C.c_uint32 * 4),
        ("tool_half_nm", C.c_float * 4),
        ("squareness_f", C.c_float * 3),
        ("square_dx_dy", C.c_float * 4),
        ("square_dx_f", C.c_float * 4),
        *([("lane_freq", (C.c_uint64 * 4) * ABBE_BLOCKS), ("lane_phase_min", (C.c_uint64 * 4) * ABBE_BLOCKS)]
          if _X86_64 else []),
        ("any_block1", C.c_uint8),
        ("simd", C.c_uint8),
        ("axis", AxisModel * ABBE_AXES),
    ]


class InputF32(C.Structure):
    _fields_ = [("pos_mm", C.c_float * ABBE_AXES), ("dir_state", C.c_float * ABBE_AXES),
                ("temp_c", C.c_float * ABBE_AXES)]


class ErrorF32(C.Structure):
    _fields_ = [("error_um", C.c_float * ABBE_AXES), ("flags", C.c_uint32)]


class InputQ(C.Structure):
    _fields_ = [("pos_nm", C.c_int32 * ABBE_AXES), ("dir_state_q30", C.c_int32 * ABBE_AXES),
                ("temp_mdegc", C.c_int32 * ABBE_AXES)]


class ErrorQ(C.Structure):
    _fields_ = [("error_nm", C.c_int32 * ABBE_AXES), ("flags", C.c_uint32)]


class CompConfig(C.Structure):
    _fields_ = [
        ("warn_nm", C.c_int32 * ABBE_AXES),
        ("limit_nm", C.c_int32 * ABBE_AXES),
        ("rate_nm_per_cycle", C.c_int32 * ABBE_AXES),
        ("fade_cycles", C.c_uint16),
        ("stale_cycles", C.c_uint16),
        ("axis_sign", C.c_int8 * ABBE_AXES),
    ]


class CompInputF32(C.Structure):
    _fields_ = [("pos_mm", C.c_float * ABBE_AXES), ("temp_c", C.c_float * ABBE_AXES),
                ("dir", C.c_int8 * ABBE_AXES), ("fresh", C.c_uint8),
                ("axis_fault_mask", C.c_uint8)]


class CompInputQ(C.Structure):
    _fields_ = [("pos_nm", C.c_int32 * ABBE_AXES), ("temp_mdegc", C.c_int32 * ABBE_AXES),
                ("dir", C.c_int8 * ABBE_AXES), ("fresh", C.c_uint8),
                ("axis_fault_mask", C.c_uint8)]


class CompOutput(C.Structure):
    _fields_ = [("corr_nm", C.c_int32 * ABBE_AXES), ("target_nm", C.c_int32 * ABBE_AXES),
                ("flags", C.c_uint32), ("state", C.c_int)]


class CompStats(C.Structure):
    _fields_ = [("cycles", C.c_uint32), ("invalid_inputs", C.c_uint32),
                ("stale_events", C.c_uint32), ("limit_trips", C.c_uint32),
                ("rate_limited", C.c_uint32), ("model_swaps", C.c_uint32)]


class Comp(C.Structure):
    """abbe_comp_t."""
    _fields_ = [
        ("cfg", CompConfig),
        ("model", C.c_void_p),
        ("pending", C.c_void_p),
        ("gain_step_q16", C.c_uint32),
        ("gain_q16", C.c_uint32 * ABBE_AXES),
        ("out_nm", C.c_int32 * ABBE_AXES),
        ("target_nm", C.c_int32 * ABBE_AXES),
        ("fault_from_nm", C.c_int32 * ABBE_AXES),
        ("last_pos_nm", C.c_int32 * ABBE_AXES),
        ("dir_state_q30", C.c_int32 * ABBE_AXES),
        ("eval_flags", C.c_uint32),
        ("stale_count", C.c_uint16),
        ("have_pos", C.c_uint8),
        ("enabled", C.c_uint8),
        ("fault", C.c_uint8),
        ("stale", C.c_uint8),
        ("stats", CompStats),
        ("scratch", C.c_int32 * (ABBE_AXES * ABBE_TERMS + ABBE_AXES)),
    ]


COMP_STATES = {0: "OFF", 1: "ON", 2: "FAULT"}

# numpy views of abbe_error_f32_t / abbe_error_q_t rows for the batch calls
_ERROR_F32_DTYPE = np.dtype([("error_um", np.float32, (ABBE_AXES,)), ("flags", np.uint32)])
_ERROR_Q_DTYPE = np.dtype([("error_nm", np.int32, (ABBE_AXES,)), ("flags", np.uint32)])
assert _ERROR_F32_DTYPE.itemsize == C.sizeof(ErrorF32) and _ERROR_Q_DTYPE.itemsize == C.sizeof(ErrorQ)

# --------------------------------------------------------------------------- loading

_LIB: C.CDLL | None = None


def library_path() -> Path:
    """Where the shared library is expected (:func:`abbe.paths.library_path`)."""
    return paths.library_path()


def load_library() -> C.CDLL:
    """Load (once) and type the C library; LibraryNotFound if it is missing."""
    global _LIB
    if _LIB is not None:
        return _LIB
    path = library_path()
    if not path.is_file():
        raise LibraryNotFound(
            f"abbe C library not found at {path}",
            "build it with 'cmake -S . -B build && cmake --build build' or set ABBE_LIB")
    try:
        lib = C.CDLL(str(path))
    except OSError as exc:
        raise LibraryNotFound(f"cannot load {path}: {exc}") from exc
    P = C.POINTER
    sigs: dict[str, tuple[Any, list[Any]]] = {
        "abbe_strerror": (C.c_char_p, [C.c_int]),
        "abbe_model_load": (C.c_int, [P(Model), C.c_void_p, C.c_size_t]),
        "abbe_model_crc": (C.c_uint32, [P(Model)]),
        "abbe_model_features": (C.c_uint32, [P(Model)]),
        "abbe_model_size": (C.c_uint32, [P(Model)]),
        "abbe_crc32": (C.c_uint32, [C.c_uint32, C.c_void_p, C.c_size_t]),
        "abbe_error_eval_f32": (C.c_int, [P(Model), P(InputF32), P(ErrorF32)]),
        "abbe_error_eval_q": (C.c_int, [P(Model), P(InputQ), P(ErrorQ)]),
        "abbe_error_eval_batch_f32": (C.c_int, [P(Model), C.c_size_t, P(InputF32), P(ErrorF32)]),
        "abbe_error_eval_batch_q": (C.c_int, [P(Model), C.c_size_t, P(InputQ), P(ErrorQ)]),
        "abbe_term_eval_f32": (C.c_int, [P(Model), C.c_uint, C.c_uint, C.c_float,
                                         P(C.c_float)]),
        "abbe_term_eval_q": (C.c_int, [P(Model), C.c_uint, C.c_uint, C.c_int32,
                                       P(C.c_int32)]),
        "abbe_reversal_eval_f32": (C.c_int, [P(Model), C.c_uint, C.c_float, P(C.c_float)]),
        "abbe_reversal_eval_q": (C.c_int, [P(Model), C.c_uint, C.c_int32, P(C.c_int32)]),
        "abbe_comp_init": (C.c_int, [P(Comp), P(CompConfig), P(Model)]),
        "abbe_comp_enable": (C.c_int, [P(Comp)]),
        "abbe_comp_disable": (C.c_int, [P(Comp)]),
        "abbe_comp_reset": (C.c_int, [P(Comp)]),
        "abbe_comp_swap_model": (C.c_int, [P(Comp), P(Model)]),
        "abbe_comp_load_model": (C.c_int, [P(Comp), P(Model), C.c_void_p, C.c_size_t]),
        "abbe_comp_model": (C.c_void_p, [P(Comp)]),
        "abbe_comp_step_f32": (C.c_int, [P(Comp), P(CompInputF32), P(CompOutput)]),
        "abbe_comp_step_q": (C.c_int, [P(Comp), P(CompInputQ), P(CompOutput)]),
        "abbe_comp_stats": (CompStats, [P(Comp)]),
        "abbe_model_sizeof": (C.c_size_t, []),
        "abbe_comp_sizeof": (C.c_size_t, []),
    }
    for name, (res, args) in sigs.items():
        try:
            fn = getattr(lib, name)
        except AttributeError as exc:
            raise LibraryNotFound(f"{path} does not export {name}: rebuild it from this checkout") from exc
        fn.restype = res
        fn.argtypes = args
    # The binding allocates abbe_model_t / abbe_comp_t itself: a layout that
    # differs from the library's would corrupt memory silently, so refuse it.
    for mirror, fn in ((Model, lib.abbe_model_sizeof), (Comp, lib.abbe_comp_sizeof)):
        if C.sizeof(mirror) != fn():
            raise LibraryNotFound(
                f"{path}: sizeof({mirror.__name__}) is {fn()} in the library but {C.sizeof(mirror)} "
                "in abbe/clib.py: the binding and the library are from different versions")
    _LIB = lib
    return lib


def available() -> bool:
    """True if the shared library can be loaded."""
    try:
        load_library()
        return True
    except LibraryNotFound:
        return False


def status_name(status: int) -> str:
    """C status code -> its name (``ABBE_E_CRC``)."""
    return STATUS_NAMES.get(int(status), f"status {int(status)}")


def _check(status: int, what: str, source: str | None = None) -> None:
    if status != 0:
        lib = load_library()
        text = lib.abbe_strerror(status)
        msg = f"{what}: {text.decode() if text else 'unknown status'}"
        raise TableError(msg, status=status_name(status), file=source)


def _f32_rows(a: Any, n: int | None = None, default: float = 0.0) -> np.ndarray:
    if a is None:
        return np.full((n or 0, 3), default, dtype=np.float32)
    return np.asarray(a, dtype=np.float32).reshape(-1, 3)


def _i32_rows(a: Any, n: int | None = None, default: int = 0) -> np.ndarray:
    if a is None:
        return np.full((n or 0, 3), default, dtype=np.int64)
    arr = np.asarray(a)
    if arr.dtype.kind == "f":
        if not np.all(arr == np.rint(arr)):
            raise ValueError("integer input expected")
    arr = arr.astype(np.int64).reshape(-1, 3)
    if np.any(arr < -(1 << 31)) or np.any(arr >= (1 << 31)):
        raise ValueError("value outside int32")
    return arr


def _axis_term(axis: str | int, term: str | int) -> tuple[int, int]:
    ai = AXES.index(axis) if isinstance(axis, str) else int(axis)
    ti = TERMS.index(term) if isinstance(term, str) else int(term)
    return ai, ti


# --------------------------------------------------------------------------- model


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


class FiveInputF32(C.Structure):
    """abbe_five_input_f32_t."""
    _fields_ = [("pos_mm", C.c_float * 3), ("angle_deg", C.c_float * 2),
                ("dir_state", C.c_float * 3), ("temp_c", C.c_float * 3)]


class FiveErrorF32(C.Structure):
    """abbe_five_error_f32_t."""
    _fields_ = [("error_um", C.c_float * 3), ("orient_urad", C.c_float * 3), ("flags", C.c_uint32)]


def _load_five(lib: C.CDLL) -> dict[str, Any]:
    """The five-axis entry points, typed as function objects of their own (the shared
    ``lib`` attributes stay untouched: other callers type them their way); LibraryNotFound
    when the library has none (a build without format 1.1 / 1.2 reading,
    ABBE_WITH_REVERSAL=OFF)."""
    P = C.POINTER
    out: dict[str, Any] = {}
    for name, res, args in (
            ("abbe_five_model_load", C.c_int, [C.c_void_p, C.c_void_p, C.c_size_t]),
            ("abbe_five_model_sizeof", C.c_size_t, []),
            ("abbe_five_model_kind", C.c_uint32, [C.c_void_p]),
            ("abbe_five_error_eval_f32", C.c_int, [C.c_void_p, P(FiveInputF32), P(FiveErrorF32)])):
        if not hasattr(lib, name):
            raise LibraryNotFound(f"the C library does not export {name}: a build without "
                                  "five-axis tables, or older than this checkout")
        out[name] = C.CFUNCTYPE(res, *args)((name, lib))
    return out


class CFiveModel:
    """A five-axis (format 1.2) or 3-axis table loaded by ``abbe_five_model_load``.

    The model is allocated as ``abbe_five_model_sizeof()`` bytes (8-aligned), so the
    binding need not mirror its private layout; it keeps its own copy of the blob.
    """

    def __init__(self, blob: bytes, source: str = "<blob>") -> None:
        self._fn = _load_five(load_library())
        self._buf = C.create_string_buffer(bytes(blob), len(blob))
        n = int(self._fn["abbe_five_model_sizeof"]())
        self._model = (C.c_uint64 * ((n + 7) // 8))()
        _check(self._fn["abbe_five_model_load"](self._model, self._buf, len(blob)),
               "abbe_five_model_load", source)

    @property
    def kind(self) -> int:
        """ABBE_KIN_*: 0 none (a 3-axis table), 1 xyzac-trt, 2 xyzbc-trt; format 1.4: 3 xyzbc-hh,
        4 xyzbc-ht, 5 xyzab-tdr."""
        return int(self._fn["abbe_five_model_kind"](self._model))

    def tref_c(self) -> np.ndarray:
        """The linear axes' thermal reference temperatures, deg C (the default input)."""
        raw = self._buf.raw
        return np.array([struct.unpack_from("<i", raw, 64 + 64 * j + 44)[0] for j in range(3)],
                        dtype=np.float64) / 1000.0

    def error_f32(self, pos_mm: Any, angles_deg: Any, dir_state: Any = None,
                  temp_c: Any = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """abbe_five_error_eval_f32 at joint positions X, Y, Z (N, 3) mm and tilt, C (N, 2)
        deg: (tool tip position error (N, 3) um, orientation error (N, 3) urad, flags (N,)).
        TableError(ABBE_E_INPUT) for a non-finite input (its row named)."""
        pos = _f32_rows(pos_mm)
        n = pos.shape[0]
        ang = np.asarray(angles_deg, dtype=np.float32).reshape(-1, 2)
        ds = _f32_rows(dir_state, n)
        tc = (np.tile(self.tref_c(), (n, 1)).astype(np.float32) if temp_c is None
              else _f32_rows(temp_c))
        if ang.shape[0] != n or ds.shape[0] != n or tc.shape[0] != n:
            raise ValueError("angles_deg / dir_state / temp_c must have the same rows as pos_mm")
        err, rot, flags = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros(n, dtype=np.uint32)
        inp, out = FiveInputF32(), FiveErrorF32()
        fn = self._fn["abbe_five_error_eval_f32"]
        for i in range(n):
            inp.pos_mm[:] = pos[i].tolist()
            inp.angle_deg[:] = ang[i].tolist()
            inp.dir_state[:] = ds[i].tolist()
            inp.temp_c[:] = tc[i].tolist()
            _check(fn(self._model, C.byref(inp), C.byref(out)), f"abbe_five_error_eval_f32 (row {i})")
            err[i] = out.error_um[:]
            rot[i] = out.orient_urad[:]
            flags[i] = out.flags
        return err, rot, flags


def crc32(data: bytes, crc: int = 0) -> int:
    """abbe_crc32 (zlib CRC-32, continuing from ``crc``)."""
    lib = load_library()
    buf = C.create_string_buffer(bytes(data), len(data))
    return int(lib.abbe_crc32(crc, buf, len(data)))


# --------------------------------------------------------------------------- compensator


def _vec3(cfg: dict, key: str, default: Any = None) -> list[int]:
    v = cfg.get(key, default)
    if v is None:
        raise ValueError(f"compensator config needs '{key}'")
    if np.isscalar(v):
        v = [v] * 3
    v = list(v)
    if len(v) != 3:
        raise ValueError(f"'{key}' needs 3 values (X, Y, Z)")
    return [int(x) for x in v]


class CCompensator:
    """The C compensator (abbe_comp_*), for tests and simulation.

    ``config`` keys (per-axis values as 3-lists or one scalar): ``warn_nm``,
    ``limit_nm``, ``rate_nm_per_cycle``, ``fade_cycles``, ``stale_cycles``,
    ``axis_sign`` (default +1). ``model`` is an optional initial :class:`CModel`.
    Every model handed to the C side is kept referenced here while the
    compensator lives.
    """

    def __init__(self, config: dict, model: CModel | None = None) -> None:
        self._lib = load_library()
        cfg = CompConfig()
        cfg.warn_nm[:] = _vec3(config, "warn_nm")
        cfg.limit_nm[:] = _vec3(config, "limit_nm")
        cfg.rate_nm_per_cycle[:] = _vec3(config, "rate_nm_per_cycle")
        cfg.fade_cycles = int(config.get("fade_cycles", 1))
        cfg.stale_cycles = int(config.get("stale_cycles", 1))
        cfg.axis_sign[:] = _vec3(config, "axis_sign", [1, 1, 1])
        self._cfg = cfg
        self._comp = Comp()
        self._keep: list[Any] = []  # models (and blobs) the C side may point at
        if model is not None:
            self._keep.append(model)
        _check(self._lib.abbe_comp_init(C.byref(self._comp), C.byref(cfg),
                                        model.ptr if model is not None else None),
               "abbe_comp_init")

    def enable(self) -> None:
        _check(self._lib.abbe_comp_enable(C.byref(self._comp)), "abbe_comp_enable")

    def disable(self) -> None:
        _check(self._lib.abbe_comp_disable(C.byref(self._comp)), "abbe_comp_disable")

    def reset(self) -> None:
        _check(self._lib.abbe_comp_reset(C.byref(self._comp)), "abbe_comp_reset")

    def swap_model(self, model: CModel) -> None:
        """Queue an already loaded model (takes effect at the next step)."""
        self._keep.append(model)
        _check(self._lib.abbe_comp_swap_model(C.byref(self._comp), model.ptr),
               "abbe_comp_swap_model")

    def load_model(self, blob: bytes) -> None:
        """abbe_comp_load_model into a fresh slot; TableError if the blob is refused
        (the running model goes on)."""
        buf = C.create_string_buffer(bytes(blob), len(blob))
        slot = Model()
        status = self._lib.abbe_comp_load_model(C.byref(self._comp), C.byref(slot), buf,
                                                len(blob))
        _check(status, "abbe_comp_load_model")
        self._keep.append((slot, buf))

    def has_model(self) -> bool:
        """True if a model is in use."""
        return bool(self._lib.abbe_comp_model(C.byref(self._comp)))

    @staticmethod
    def _result(out: CompOutput) -> dict:
        return {"corr_nm": np.array(list(out.corr_nm), dtype=np.int64),
                "target_nm": np.array(list(out.target_nm), dtype=np.int64),
                "flags": int(out.flags), "state": COMP_STATES.get(out.state, out.state)}

    def step_f32(self, pos_mm: Any, temp_c: Any = (20.0, 20.0, 20.0), dir: Any = (0, 0, 0),
                 fresh: bool = True, axis_fault_mask: int = 0) -> dict:
        """One cycle, float input (mm, deg C, dir in {-1, 0, 1}). Returns a dict with
        corr_nm, target_nm (int arrays), flags, state ('OFF'/'ON'/'FAULT')."""
        inp, out = CompInputF32(), CompOutput()
        inp.pos_mm[:] = [float(v) for v in pos_mm]
        inp.temp_c[:] = [float(v) for v in temp_c]
        inp.dir[:] = [int(v) for v in dir]
        inp.fresh = 1 if fresh else 0
        inp.axis_fault_mask = int(axis_fault_mask)
        _check(self._lib.abbe_comp_step_f32(C.byref(self._comp), C.byref(inp), C.byref(out)),
               "abbe_comp_step_f32")
        return self._result(out)

    def step_q(self, pos_nm: Any, temp_mdegc: Any = (20000, 20000, 20000),
               dir: Any = (0, 0, 0), fresh: bool = True, axis_fault_mask: int = 0) -> dict:
        """One cycle, integer input (nm, m°C, dir in {-1, 0, 1})."""
        inp, out = CompInputQ(), CompOutput()
        inp.pos_nm[:] = [int(v) for v in pos_nm]
        inp.temp_mdegc[:] = [int(v) for v in temp_mdegc]
        inp.dir[:] = [int(v) for v in dir]
        inp.fresh = 1 if fresh else 0
        inp.axis_fault_mask = int(axis_fault_mask)
        _check(self._lib.abbe_comp_step_q(C.byref(self._comp), C.byref(inp), C.byref(out)),
               "abbe_comp_step_q")
        return self._result(out)

    def stats(self) -> dict[str, int]:
        """Counters since init (abbe_comp_stats)."""
        s = self._lib.abbe_comp_stats(C.byref(self._comp))
        return {name: int(getattr(s, name)) for name, _ in CompStats._fields_}


# --------------------------------------------------------------------------- thermal


def _thermal_lib() -> C.CDLL:
    """The library with the thermal runtime's functions typed (abbe/thermal.h)."""
    lib = load_library()
    if getattr(lib, "_abbe_thermal_typed", False):
        return lib
    P, V = C.POINTER, C.c_void_p
    sigs: dict[str, tuple[Any, list[Any]]] = {
        "abbe_thermal_load": (C.c_int, [P(Model), V, V, C.c_size_t]),
        "abbe_thermal_init_f32": (C.c_int, [V, V, C.c_float]),
        "abbe_thermal_init_q": (C.c_int, [V, V, C.c_uint32]),
        "abbe_thermal_update_f32": (C.c_int, [V, P(C.c_float), C.c_uint32, C.c_float]),
        "abbe_thermal_update_q": (C.c_int, [V, P(C.c_int32), C.c_uint32, C.c_uint32]),
        "abbe_thermal_apply_f32": (None, [V, P(C.c_float)]),
        "abbe_thermal_apply_q": (None, [V, P(C.c_int32)]),
        "abbe_thermal_channels_f32": (C.c_uint, [V, P(C.c_float)]),
        "abbe_thermal_channels_q": (C.c_uint, [V, P(C.c_int32)]),
        "abbe_thermal_flags": (C.c_uint32, [V]),
        "abbe_thermal_input_faults": (C.c_uint32, [V]),
        "abbe_thermal_n_inputs": (C.c_uint, [V]),
        "abbe_thermal_n_channels": (C.c_uint, [V]),
        "abbe_thermal_model_sizeof": (C.c_size_t, []),
        "abbe_thermal_state_sizeof": (C.c_size_t, []),
    }
    for name, (res, args) in sigs.items():
        try:
            fn = getattr(lib, name)
        except AttributeError as exc:
            raise LibraryNotFound(f"the library does not export {name}: rebuild it from this "
                                  "checkout") from exc
        fn.restype = res
        fn.argtypes = args
    lib._abbe_thermal_typed = True  # type: ignore[attr-defined]
    return lib


def _opaque(size: int) -> Any:
    """An 8-byte aligned buffer of ``size`` bytes for a caller-owned C struct."""
    return (C.c_uint64 * ((size + 7) // 8))()


class CThermal:
    """A format 1.0 / 1.1 / 1.3 table loaded by ``abbe_thermal_load`` and its thermal
    runtime (abbe/thermal.h), run over a record.

    ``run_f32`` / ``run_q`` feed the samples one by one (``abbe_thermal_update_*``)
    with ``applies`` evaluations (``abbe_thermal_apply_*``) of ``period_s`` each after
    every sample; they return the channel values after each sample (um / urad), the
    tool tip error after its evaluations (um) and the flags.
    """

    def __init__(self, blob: bytes, source: str = "<blob>") -> None:
        self._lib = _thermal_lib()
        self._buf = C.create_string_buffer(bytes(blob), len(blob))
        self._model = Model()
        self._thermal = _opaque(self._lib.abbe_thermal_model_sizeof())
        _check(self._lib.abbe_thermal_load(C.byref(self._model), self._thermal, self._buf, len(blob)),
               "abbe_thermal_load", source)

    @property
    def n_inputs(self) -> int:
        return int(self._lib.abbe_thermal_n_inputs(self._thermal))

    @property
    def n_channels(self) -> int:
        return int(self._lib.abbe_thermal_n_channels(self._thermal))

    def _run(self, q: bool, dt: Any, x: Any, valid: Any, period_s: float,
             applies: int) -> dict[str, np.ndarray]:
        lib = self._lib
        x = np.asarray(x)
        n = x.shape[0]
        if x.ndim != 2 or x.shape[1] != self.n_inputs:
            raise ValueError(f"inputs of shape {x.shape}: expected (n, {self.n_inputs})")
        dt = np.asarray(dt)
        valid_mask = (np.full(n, (1 << self.n_inputs) - 1, dtype=np.int64) if valid is None
                      else np.asarray(valid, dtype=np.int64))
        st = _opaque(lib.abbe_thermal_state_sizeof())
        if q:
            _check(lib.abbe_thermal_init_q(st, self._thermal, int(round(period_s * 1e6))),
                   "abbe_thermal_init_q")
        else:
            _check(lib.abbe_thermal_init_f32(st, self._thermal, period_s), "abbe_thermal_init_f32")
        ch = np.zeros((n, self.n_channels))
        tip = np.zeros((n, 3))
        flags = np.zeros(n, dtype=np.int64)
        ybuf_f, ybuf_q = (C.c_float * 5)(), (C.c_int32 * 5)()
        for i in range(n):
            if q:
                xi = (C.c_int32 * self.n_inputs)(*(int(v) for v in x[i]))
                _check(lib.abbe_thermal_update_q(st, xi, int(valid_mask[i]), int(dt[i])),
                       "abbe_thermal_update_q")
                e = (C.c_int32 * 3)()
                for _ in range(applies):
                    e = (C.c_int32 * 3)()
                    lib.abbe_thermal_apply_q(st, e)
                lib.abbe_thermal_channels_q(st, ybuf_q)
                ch[i] = np.array(ybuf_q[:self.n_channels], dtype=float) / 1000.0
                tip[i] = np.array(e[:], dtype=float) / 1000.0
            else:
                xi = (C.c_float * self.n_inputs)(*(float(v) for v in x[i]))
                _check(lib.abbe_thermal_update_f32(st, xi, int(valid_mask[i]), float(dt[i])),
                       "abbe_thermal_update_f32")
                ef = (C.c_float * 3)()
                for _ in range(applies):
                    ef = (C.c_float * 3)()
                    lib.abbe_thermal_apply_f32(st, ef)
                lib.abbe_thermal_channels_f32(st, ybuf_f)
                ch[i] = np.array(ybuf_f[:self.n_channels], dtype=float)
                tip[i] = np.array(ef[:], dtype=float)
            flags[i] = lib.abbe_thermal_flags(st)
        return {"channels": ch, "tip": tip, "flags": flags}

    def run_f32(self, dt_s: Any, x: Any, valid: Any = None, period_s: float = 1.0,
                applies: int = 1) -> dict[str, np.ndarray]:
        """``dt_s``: seconds since the previous sample (first ignored); ``x``: (n, inputs)
        in degC / rpm; ``valid``: per-sample valid masks (default all)."""
        return self._run(False, dt_s, x, valid, period_s, applies)

    def run_q(self, dt_ms: Any, x_milli: Any, valid: Any = None, period_s: float = 1.0,
              applies: int = 1) -> dict[str, np.ndarray]:
        """As :meth:`run_f32` with integers: ms, m degC / rpm."""
        return self._run(True, dt_ms, x_milli, valid, period_s, applies)


def thermal_load_status(blob: bytes) -> str:
    """The status name ``abbe_thermal_load`` gives ``blob`` (``"ABBE_OK"`` if valid)."""
    lib = _thermal_lib()
    buf = C.create_string_buffer(bytes(blob), max(len(blob), 1))
    model = Model()
    th = _opaque(lib.abbe_thermal_model_sizeof())
    st = lib.abbe_thermal_load(C.byref(model), th, buf, len(blob))
    return "ABBE_OK" if st == 0 else status_name(st)
