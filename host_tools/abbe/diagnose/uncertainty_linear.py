"""The linear propagation of ``abbe diagnose``'s uncertainty (moved from
:mod:`abbe.diagnose.uncertainty`): the selection held fixed, the final fit is linear in the
readings (theta = theta0 + L dy): the final fit's design X and operator L at the solution,
a named effect's headline and its gradient by the parameters, and each instrument input's
standard uncertainty of a figure whose change is s . dy (a laser's scale-like ramp with
the axis' scale free: :mod:`abbe.diagnose.scale_free`).
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from abbe.diagnose.candidates import Engine, Selected, apply_selection
from abbe.diagnose.problem import project_out, qr_basis
from abbe.diagnose.results import FitState
from abbe.diagnose.uncertainty_inputs import SQRT3, Inputs


def _line_u(s: np.ndarray, inp: Inputs,
            s_free: dict[str, np.ndarray] | None = None) -> dict[str, float]:
    """Each input's standard uncertainty of a figure whose change is s . dy; a ramp along
    a: the smaller with ``s_free[a]`` (:mod:`abbe.diagnose.scale_free`)."""
    out: dict[str, float] = {}
    for x in inp.systematic:
        v = abs(float(s @ x.pattern)) * x.sd
        if x.ramp_axis in (s_free or {}):
            v = min(v, abs(float(s_free[x.ramp_axis] @ x.pattern)) * x.sd)  # type: ignore[index]
        out[f"{x.check}: {x.name}"] = out.get(f"{x.check}: {x.name}", 0.0) + v
    for g in inp.grouped:
        m = g.labels >= 0
        if not np.any(m):
            continue
        sums = np.bincount(g.labels[m], weights=s[m])
        out[f"{g.check}: {g.name}"] = float(np.sqrt(np.sum(sums ** 2))) * g.half_um / SQRT3
    for r in inp.per_reading:
        out[f"{r.check}: {r.name}"] = float(np.sqrt(np.sum((s * r.half_um) ** 2))) / SQRT3
    return {k: v for k, v in out.items()}


def _headline_fn(eng: Engine, s: Selected, C: np.ndarray) -> Callable[[np.ndarray], float]:
    from abbe.diagnose.describe import _headline
    spec, idx = s.cand.spec, s.cand.param_idx
    return lambda v: float(_headline(spec, idx, v, C, 1.96, eng)[0])


def _grad(fn: Callable[[np.ndarray], float], v: np.ndarray, C: np.ndarray) -> np.ndarray:
    """Central differences, each step 1e-3 of the parameter's standard deviation."""
    g = np.zeros(v.size)
    for j in range(v.size):
        h = max(1e-3 * math.sqrt(max(C[j, j], 0.0)), 1e-9 * max(abs(v[j]), 1.0))
        e = np.zeros(v.size)
        e[j] = h
        g[j] = (fn(v + e) - fn(v - e)) / (2 * h)
    return g


def _final_design(st: FitState) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(X (N, p) unweighted sensitivities at the solution, L (p, N) = d theta / d y,
    y_fit (N,) the prediction at the solution)."""
    eng, prob = st.eng, st.eng.prob
    t, p = apply_selection(eng, st.selected, st.values)
    y = prob.predict(eng.ev, t, p)
    cols = [eng.sensitivity(s.cand.spec, s.cand.scan_value, t, p, y, s.cand.param_idx)[:, s.cand.param_idx]
            for s in st.selected]
    X = np.hstack(cols)
    Q = qr_basis(prob.nuis * st.W[:, None])
    Xe = project_out(Q, X * st.W[:, None])
    L = np.linalg.pinv(Xe) * st.W[None, :]
    return X, L, y
