"""The scale-like instrument inputs of a diagnosis' budget, through the selection they
would have produced (docs/uncertainty.md, "Diagnosis").

A laser line's scale inputs (instrument scale, air temperature / pressure / humidity,
temperature not normalised, cosine misalignment) perturb its readings by a ramp along the
line's axis. Had the readings carried that ramp, the diagnosis would have named (or held
free) the axis' scale rather than moved another effect; so, unless a scale of the axis is
named (then its column is in the fit already), each named effect's line of such an input
is its sensitivity with the axis' scale column free in the final fit (a nuisance,
projected out with the set-up's), with the scales :func:`freed_with` adds; the line is
the smaller of that and the selection held fixed (freeing a scale can make an effect
more sensitive through the scale's other signature, a circle's ellipse: gen2's tool
offsets 14 -> 722 mm, where the diagnosis rerun on a ramped line moves less; which
scales the diagnosis names under a ramp is a change of the selection no first order
holds). A scale named on the axis carries the line as before (a scale measured at an
unknown temperature is uncertain by alpha dT).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from abbe.diagnose.candidates import apply_selection
from abbe.diagnose.problem import project_out, qr_basis
from abbe.diagnose.results import FitState


def free_scale_axes(inp: Any, st: FitState) -> list[str]:
    """The axes whose laser lines have scale-like inputs (ramps along the axis) and of
    which no scale is named: their instrument inputs are propagated with the axis' scale
    free in the fit (a ramp in the readings would have named, or held free, that scale
    rather than moved another effect: docs/uncertainty.md, "Diagnosis")."""
    named = {s.cand.spec.axis for s in st.selected if s.cand.spec.kind == "scale"}
    return sorted({x.ramp_axis for x in inp.systematic
                   if x.ramp_axis is not None and x.ramp_axis not in named})


def scale_columns(st: FitState, axes: list[str]) -> np.ndarray:
    """(N, len(axes)) d prediction / d ppm of each axis' scale (the catalogue's ``scale_*``
    candidate, its linear parameter) at the final solution."""
    from abbe.diagnose.effects import by_key
    eng = st.eng
    if not axes:
        return np.zeros((eng.prob.N, 0))
    t, p = apply_selection(eng, st.selected, st.values)
    y = eng.prob.predict(eng.ev, t, p)
    specs = by_key()
    return np.column_stack([eng.sensitivity(specs[f"scale_{a.lower()}"], None, t, p, y, [0])[:, 0]
                            for a in axes])


def freed_with(inp: Any, st: FitState, axis: str) -> list[str]:
    """The scales held free for a ramp along ``axis``: its own, and those of the axes no
    laser line measures that the checks see only in a ballbar circle's plane with it (a
    circle sees only the difference of its two axes' scales, its radius taking a common
    one: a ramp on one line is then a common scale of the plane, as the whole diagnosis
    names it), none named already (their columns are in the fit). An axis also seen in
    a plane without ``axis`` is held (the diagnosis rerun on a ramped line names the
    line's scale alone there)."""
    named = {s.cand.spec.axis for s in st.selected if s.cand.spec.kind == "scale"}
    lined = {x.ramp_axis for x in inp.systematic if x.ramp_axis is not None}
    planes = [str(getattr(c, "plane", "")).upper() for c in st.eng.prob.checks]
    planes = [pl for pl in planes if len(pl) == 2]
    partners = {b for pl in planes if axis in pl for b in pl
                if all(axis in q for q in planes if b in q)}
    return [a for a in ("X", "Y", "Z") if a not in named
            and (a == axis or (a in partners and a not in lined))]


def freed_columns(st: FitState, axes: list[str]) -> np.ndarray:
    """:func:`scale_columns` of ``axes``, those the checks do not move left out."""
    xs = scale_columns(st, axes)
    return xs[:, np.any(xs != 0.0, axis=0)]


def free_scale_L(st: FitState, X: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """(p, N) d theta / d y of the final fit with the columns ``xs`` free beside the
    selection (nuisances, projected out with the set-up's); theta's rows only."""
    prob = st.eng.prob
    Q = qr_basis(prob.nuis * st.W[:, None])
    Xe = project_out(Q, np.hstack([X, xs]) * st.W[:, None])
    return (np.linalg.pinv(Xe) * st.W[None, :])[:X.shape[1]]


def absorbed(st: FitState, X: np.ndarray, xs: np.ndarray, pattern: np.ndarray) -> np.ndarray:
    """(N,) the part of a reading change ``pattern`` the free scales ``xs`` take in the
    weighted fit beside the set-up nuisance and the selection ``X``: the rest, fitted with
    the selection alone, moves the effects as :func:`free_scale_L` says (the rest is
    orthogonal to every column of the larger fit). The Monte Carlo draws the rest."""
    if xs.shape[1] == 0:
        return np.zeros_like(pattern)
    W = st.W
    A = np.hstack([st.eng.prob.nuis, X, xs]) * W[:, None]
    coef = np.linalg.lstsq(A, pattern * W, rcond=None)[0]
    return xs @ coef[-xs.shape[1]:]
