"""The thermal runtime through the C library (abbe/thermal.h): :class:`CThermal`
(``abbe_thermal_load``, then ``abbe_thermal_update_*`` / ``abbe_thermal_apply_*`` over a
record) and :func:`thermal_load_status`."""

from __future__ import annotations

import ctypes as C
from typing import Any

import numpy as np

from abbe.model.clib.library import LibraryNotFound, _check, load_library, status_name
from abbe.model.clib.structs import Model

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
