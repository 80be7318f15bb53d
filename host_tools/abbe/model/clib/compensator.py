"""The C compensator (``abbe_comp_*``) for tests and simulation: :class:`CCompensator`."""

from __future__ import annotations

import ctypes as C
from typing import Any

import numpy as np

from abbe.model.clib.library import _check, load_library
from abbe.model.clib.structs import (COMP_STATES, Comp, CompConfig, CompInputF32, CompInputQ,
                                     CompOutput, CompStats, Model)
from abbe.model.clib.three_axis import CModel

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
