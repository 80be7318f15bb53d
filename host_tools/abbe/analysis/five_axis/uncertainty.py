"""Five-axis identification results with their expanded uncertainty U (k = 2) and the
budget they come from; the Monte Carlo check (GUM Supplement 1) of the analytic U.

The identification's covariance is s^2 (J^T W J)^-1 (``identify``, step 3): a Type A
evaluation whose inputs are each data block's standard deviation (``block_sigma``: a
probing's sphere centres per machine axis, an R-test's displacements, an indexer's
readings, a rotary ballbar's lengths; each estimated from the block's own residuals) and
the weighted residual variance s^2. U = 2 u (k = 2), u the parameter's standard
deviation; the 95 % interval the report gave (1.96 u) is the same figure with k = 1.96.

The check draws new observations (each residual row: normal with its block's standard
deviation x s), solves the exact nonlinear model again (``least_squares`` on the model's
own residuals from the solution; the Jacobian only steers the iterations) and takes
2 x the standard deviation of each parameter over the draws. Units: um, urad (as each
parameter's ``unit``)."""

from __future__ import annotations

from typing import Any

import numpy as np
from scipy.optimize import least_squares

from abbe.analysis.five_axis.identify import FitResult, _Problem
from abbe.analysis.five_axis.problem import Block, Param, residual_block
from abbe.formats.five_axis import FiveAxisSpec

K = 2.0
METHOD = ("ISO/TR 230-9 / GUM, Type A: covariance s^2 (J^T W J)^-1 of the identification, "
          "W from each block's standard deviation (its own residuals); U = k u, k = 2")


def _dof_s2(pb: _Problem, x: np.ndarray, free: list[int]) -> tuple[int, float]:
    r = pb.raw(x) * pb.weights()
    dof = max(r.size - len(free), 1)
    return dof, float(r @ r) / dof


def budget(res: FitResult) -> dict[str, Any]:
    """The inputs of the five-axis U: each block's standard deviation and what it is."""
    what = {"probe": "sphere centres from the probing (x, y, z), um",
            "rtest": "R-test displacements (x, y, z), um",
            "indexer": "rotary indexer readings, urad",
            "ballbar": "rotary ballbar lengths, um",
            "datum": "a datum sphere's declared place (x, y, z), um"}
    inputs = [{"block": b.key, "what": what.get(b.kind, b.kind),
               "u": [float(v) for v in np.atleast_1d(b.sigma)],
               "evaluation": "Type B: declared in the machine file (datum_u_um)"
               if b.kind == "datum" else "Type A: the block's residuals after the fit"}
              for b in res.blocks]
    for b in res.blocks:
        if b.calibration is not None:
            kind, U, src = b.calibration
            inputs.append({"block": b.key, "what": (
                f"{b.kind} sensors' sensitivity, % (U = {U:g} at k = 2)" if kind == "scale"
                else f"{b.kind} length calibration, um (U = {U:g} at k = 2)"),
                "u": [U / K], "evaluation": f"Type B: {src} (rtest calibration_U_pct, "
                "rotary_ballbar calibration_U_um; docs/uncertainty.md)"})
    return {"method": METHOD, "k": K, "inputs": inputs,
            "not_included": ("the probe's own calibration (a sphere's centre does not move "
                             "with the stylus radius; the probing's scale is the machine's, "
                             "which the model holds), the indexer's reference (no figure "
                             "declared), the kinematic model's own adequacy beyond its "
                             "residuals")}


def _at_solution(spec: FiveAxisSpec, blocks: list[Block], params: list[Param],
                 res: FitResult) -> tuple[_Problem, np.ndarray, list[int]]:
    """The identification's problem with its Jacobian at the solution (not at zero), the
    solution and the free parameters."""
    pb = _Problem.__new__(_Problem)
    pb.spec, pb.params, pb.blocks = spec, params, blocks
    pb.scale = np.array([p.scale for p in params])
    sizes = [residual_block(spec.geometry, params, res.x_solution, spec.fit.harmonics, b).size
             for b in blocks]
    pb.offsets = np.r_[0, np.cumsum(sizes)]
    x0 = np.asarray(res.x_solution, dtype=float)
    pb.J = pb.jacobian(x0)
    free = [i for i in range(len(params)) if i not in res.obs.fixed]
    return pb, x0, free


def _calibration_rows(blocks: list[Block], offsets: np.ndarray
                      ) -> list[tuple[Block, float, np.ndarray]]:
    """Each calibrated block: (block, standard uncertainty of its calibration error e, the
    change of the raw residuals per unit e): a sensitivity error scales the block's
    observations (e relative), a length offset shifts each reading (e in um)."""
    out = []
    for k, b in enumerate(blocks):
        if b.calibration is None:
            continue
        kind, U, _src = b.calibration
        dr = np.zeros(int(offsets[-1]))
        seg = slice(int(offsets[k]), int(offsets[k + 1]))
        if kind == "scale":
            dr[seg] = np.asarray(b.obs, dtype=float).ravel()
            u = U / 100.0 / K
        else:
            dr[seg] = 1.0
            u = U / K
        if u > 0:
            out.append((b, u, dr))
    return out


def type_b(spec: FiveAxisSpec, blocks: list[Block], params: list[Param],
           res: FitResult) -> dict[str, Any]:
    """Every free parameter's standard uncertainty from each instrument's calibration:
    the identification is least squares, so a calibration error e moves the solution by
    (J^T W J)^-1 J^T W dr e to first order (the identification's J); {block key: (u per
    parameter (P,), what)}."""
    if res.jacobian is None or res.weights is None or res.row_offsets is None:
        pb, _x0, free = _at_solution(spec, blocks, params, res)
        J, w, offsets = pb.J, pb.weights(), pb.offsets
    else:  # the identification's own (the covariance's): no second Jacobian
        J, w, offsets = res.jacobian, res.weights, res.row_offsets
        free = [i for i in range(len(params)) if i not in res.obs.fixed]
    Jw = J[:, free] * w[:, None]
    sc = np.array([p.scale for p in params])[free]
    out: dict[str, Any] = {}
    for b, u, dr in _calibration_rows(blocks, offsets):
        dz = np.linalg.lstsq(Jw, w * dr, rcond=None)[0]
        ux = np.zeros(len(params))
        ux[free] = np.abs(dz * sc) * u
        kind, U, src = b.calibration  # type: ignore[misc]
        what = (f"{b.kind} sensors' sensitivity, U = {U:g} % (k = 2, {src})" if kind == "scale"
                else f"{b.kind} length calibration, U = {U:g} um (k = 2, {src})")
        out[b.key] = (ux, what)
    return out


def monte_carlo(spec: FiveAxisSpec, blocks: list[Block], params: list[Param], res: FitResult,
                draws: int = 100, seed: int = 1) -> dict[str, Any]:
    """GUM S1 check of the observable parameters' U (module docstring). Returns
    name -> {value, U, U_mc}."""
    rng = np.random.default_rng(seed)
    pb, x0, free = _at_solution(spec, blocks, params, res)
    P = len(params)
    w = pb.weights()
    _, s2 = _dof_s2(pb, x0, free)
    sd_row = np.sqrt(s2) / w
    sc = pb.scale[free]
    Jw = pb.J[:, free] * w[:, None]
    method = "lm" if Jw.shape[0] >= Jw.shape[1] else "trf"
    calib = _calibration_rows(blocks, pb.offsets)
    xs = np.zeros((draws, P))
    for k in range(draws):
        e = rng.normal(0.0, sd_row)
        for _b, u, dr in calib:  # each instrument's calibration error, one per draw
            e = e + rng.normal(0.0, u) * dr

        def fun(z: np.ndarray) -> np.ndarray:
            x = x0.copy()
            x[free] = z * sc
            return (pb.raw(x) + e) * w

        sol = least_squares(fun, x0[free] / sc, jac=lambda z: Jw, method=method,
                            xtol=1e-10, ftol=1e-10)
        xs[k] = x0
        xs[k, free] = sol.x * sc
    U_mc = K * xs.std(axis=0, ddof=1)
    out = {}
    for i, p in enumerate(params):
        if res.obs.observable[i]:
            out[p.name] = {"kind": p.kind, "unit": p.unit, "value": float(res.x[i]),
                           "U": K * float(res.sd[i]), "U_mc": float(U_mc[i])}
    return {"draws": draws, "seed": seed, "parameters": out}



#: First order and Monte Carlo further apart than this: the first order is not adequate
#: (GUM S1's validation) and the Monte Carlo's U is the one stated (as for thermal results).
AGREEMENT = 0.10


def state_monte_carlo(doc: dict[str, Any], mc: dict[str, Any]) -> None:
    """Put the Monte Carlo check into ``doc`` (five_axis.json): every observable parameter
    gets ``U_first_order``, ``U_mc`` and ``U_from``; where the two part by more than 10 %
    ``U`` (and u, ci95) become the Monte Carlo's, the figure every report then states."""
    agree = n = 0
    for row in doc["parameters"]:
        m = mc["parameters"].get(row["name"])
        if not row.get("observable") or m is None:
            continue
        n += 1
        U1, Umc = float(row["U"]), float(m["U_mc"])
        ok = U1 > 0 and abs(Umc / U1 - 1.0) <= AGREEMENT
        agree += ok
        row.update(U_first_order=U1, U_mc=round(Umc, 6),
                   U_from="first order (the Monte Carlo agrees within 10 %)" if ok else
                   "Monte Carlo (the first order is more than 10 % off: the model is not "
                   "linear over this parameter's interval)")
        if not ok:
            row.update(U=round(Umc, 6), u=round(Umc / K, 6), ci95=round(1.96 * Umc / K, 6))
    doc["uncertainty"]["monte_carlo"] = {
        "draws": mc["draws"], "seed": mc["seed"], "agree": agree, "of": n,
        "method": "GUM S1: new observations drawn from each block's standard deviation, "
                  "the exact model solved again per draw; U_mc = 2 x the spread"}
