"""The Monte Carlo check (GUM Supplement 1) of a kinematic chain's identification
(:mod:`abbe.analysis.five_axis.chain_fit`): every identified location error and error
motion coefficient identified again from observations drawn with each set-up's sigma, and
the first-order U replaced by the Monte Carlo's where the two differ by more than 10 %
(docs/uncertainty.md). Units as in chain_fit: um, urad; probe observations mm."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from abbe.analysis.five_axis.chain_fit import (ChainFit, ChainSetup, _jacobian, _residual,
                                               _unknowns, observability)
from abbe.analysis.uncertainty import K
from abbe.model.chain import KinematicChain


def monte_carlo_chain(chain: KinematicChain, setups: list[ChainSetup], fit: ChainFit,
                      draws: int = 100, seed: int = 1, iterations: int = 6) -> dict:
    """GUM S1 check of every identified error's U: each draw adds normal noise with each
    set-up's sigma x s to its observations (new observations) and solves the exact
    nonlinear model again (the chain's own prediction, :func:`predict`); as in the
    trunnion's check (abbe.analysis.five_axis.uncertainty.monte_carlo) the Jacobian at the
    solution only steers the Gauss-Newton iterations (``iterations``, from the fit's
    solution). Returns {draws, seed, parameters: name -> {value, U, U_mc}}."""
    rng = np.random.default_rng(seed)
    s = float(np.sqrt(fit.s2))
    h = fit.harmonics
    unk = _unknowns(chain, setups, h)
    names = [u[0] for u in unk]
    scale = np.array([u[1] for u in unk])
    _unobs, fixed, _null, _rank = observability(chain, setups, h)
    free = [j for j in range(len(unk)) if j not in fixed]
    held = {**fit.values, **fit.motion_values, **fit.setup}
    x0 = np.array([held.get(n, 0.0) for n in names])
    Jpinv = np.linalg.pinv(_jacobian(chain, setups, x0, scale, harmonics=h)[:, free])
    rows = [r for r in fit.rows + fit.motion_rows if r.value is not None]
    idx = [names.index(r.name) for r in rows]
    xs = np.empty((draws, len(rows)))
    for k in range(draws):
        new = []
        for st in setups:
            sd = st.sigma_um * s * (1e-3 if st.kind == "probe" else 1.0)  # probe obs in mm
            obs = np.asarray(st.obs, dtype=np.float64)
            new.append(replace(st, obs=obs + rng.normal(0.0, sd, size=obs.shape)))
        x = x0.copy()
        for _ in range(iterations):
            x[free] += (Jpinv @ _residual(chain, new, x, h)) * scale[free]
        xs[k] = x[idx]
    U_mc = K * xs.std(axis=0, ddof=1)
    return {"draws": draws, "seed": seed,
            "parameters": {r.name: {"unit": r.unit, "value": r.value, "U": r.U,
                                    "U_mc": float(U_mc[i])} for i, r in enumerate(rows)}}


def state_monte_carlo_chain(doc: dict, mc: dict) -> dict[str, float]:
    """Put the Monte Carlo check into ``doc`` (chain_fit.json), as the trunnion fit does
    (abbe.analysis.five_axis.uncertainty.state_monte_carlo): every identified error gets
    ``U_first_order``, ``U_mc``, ``U_from``; beyond 10 % ``U`` (u, u95) become the Monte
    Carlo's. Returns name -> the U stated where it is the Monte Carlo's."""
    from abbe.analysis.five_axis.uncertainty import AGREEMENT
    agree = n = 0
    stated: dict[str, float] = {}
    for row in doc["location"] + doc["motions"]:
        m = mc["parameters"].get(row["name"])
        if row["value"] is None or m is None:
            continue
        n += 1
        U1, Umc = float(row["U"]), float(m["U_mc"])
        ok = U1 > 0 and abs(Umc / U1 - 1.0) <= AGREEMENT
        agree += ok
        row.update(U_first_order=U1, U_mc=Umc,
                   U_from="first order (the Monte Carlo agrees within 10 %)" if ok else
                   "Monte Carlo (the first order is more than 10 % off)")
        if not ok:
            row.update(U=Umc, u=Umc / K, u95=1.96 * Umc / K)
            stated[row["name"]] = Umc
    doc["uncertainty"]["monte_carlo"] = {
        "draws": mc["draws"], "seed": mc["seed"], "agree": agree, "of": n,
        "method": "GUM S1: new observations drawn from each set-up's sigma x s, the "
                  "identification run again per draw; U_mc = 2 x the spread"}
    return stated
