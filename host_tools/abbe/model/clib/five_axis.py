"""The five-axis model through the C library: :class:`CFiveModel`
(``abbe_five_model_load``, ``abbe_five_error_eval_f32``). The model's layout is the
library's own (allocated by ``abbe_five_model_sizeof``), not mirrored here.
"""

from __future__ import annotations

import ctypes as C
import struct
from typing import Any

import numpy as np

from abbe.model.clib.library import LibraryNotFound, _check, _f32_rows, load_library
from abbe.model.clib.structs import FiveErrorF32, FiveInputF32

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
