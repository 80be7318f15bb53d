"""The one model comparison of ``abbe diagnose``: an evidence ratio from the estimated noise.

Every candidate effect, declared quantity or not, is judged by the same number
(docs/effects.md §3, "Selection"): the log evidence ratio (natural log) of "the
model plus this effect" against "the model as it is", computed from

* the whitened residual, i.e. the noise model the diagnosis estimates (each
  channel's sigma, its autocorrelation inflation, and s^2 = max(1, the residual
  variance in noise units) when the model does not reach the noise);
* the **prior** the catalogue already states: an absent effect is exactly zero, a
  present one is uniform within its plausible range (``ParamSpec.limit``; the tool
  offset within +/- ``tool_offset_max_mm``). A quantity the machine file declares (the
  tool offset) is a measurement: "right" is a Gaussian of its declared uncertainty
  about the declared value, "wrong" a blunder of prior probability
  ``declared_blunder_prob`` anywhere in the range;
* the **model's own uncertainty** along the signature: a tool offset multiplies the
  model's angular terms, whose error (``model_angle_sigma_urad`` x the lever) gives
  the same signature, so its amplitude's variance is sigma_w^2 + sigma_m^2, not the
  white-noise sigma_w^2 alone; what stays below it is lack of fit / model error (an
  assumed figure: where ``model.json`` states the table's error, the next item replaces
  it, candidate_eval._evidence);
* the **fitted table's own error** (``model.json``'s coefficient covariance C_t, the
  checks' derivative J by the coefficients: abbe.diagnose.table_uncertainty): the
  readings' covariance J C J^T carried to the candidate's fitted amplitude (the same
  whitening and set-up projection as its columns) is added to the amplitude's
  covariance; without ``model.json`` none (the behaviour before);
* the **look-elsewhere** of a searched shape (period, take-up, time constant, degree):
  a uniform prior over the searched grid's independent points, i.e. - log(points).

Laplace's approximation (exact for the linear, Gaussian part):

    log K = - log N(theta; mu0, Sigma0 + C) - sum_i log(2 L_i) + log odds - log(points)

theta the fitted change, C its covariance (white noise, inflated by the model's
uncertainty), mu0 / Sigma0 the "unchanged" hypothesis (zero; the declared value and
its uncertainty), L_i the half-widths of the prior range. With Sigma0 = 0 this is the
familiar D / 2 + log(sqrt(det 2 pi C) / prod 2 L_i) + ..., D the RSS decrease in
noise units.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np


def log_evidence(theta: np.ndarray, cov_white: np.ndarray, drss: float, contrib_um: float,
                 half_width: np.ndarray, sigma_model_um: float = 0.0,
                 prior_log_odds: float = 0.0, declared_cov: np.ndarray | None = None,
                 n_scan: int = 1, typical: np.ndarray | None = None,
                 cov_table: np.ndarray | None = None) -> dict[str, float]:
    """Log evidence ratio of a change ``theta`` (parameter units) against no change.

    ``cov_white``: its covariance from the whitened fit (s^2 (Z'Z)^-1); ``drss``: the
    RSS decrease it gives, in s^2 units; ``contrib_um``: its fitted contribution (RMS,
    um); ``half_width``: the prior range +/- L_i of each parameter (a value beyond it
    has no prior mass: -inf); ``sigma_model_um``: the RMS of the same signature the
    model's own uncertainty gives; ``prior_log_odds``: log P(present) / P(absent);
    ``declared_cov``: the covariance of a declared value's uncertainty (None = 0);
    ``n_scan``: independent grid points searched for a shape value; ``typical``: the
    catalogue's typical magnitude of each parameter: ``log_evidence_typical`` is then the
    same ratio under a Gaussian prior of that standard deviation (an effect of typical
    size expected), log N(theta; 0, T + C) - log N(theta; 0, C) + log odds - log(points):
    the prior-sensitivity of the decision (docs/effects.md §3, "Undecided");
    ``cov_table``: the covariance of ``theta`` the fitted table's own coefficient error
    gives (candidate_eval.table_cov_of; None = no ``model.json``: none), added to the
    white one (docs/effects.md §3, "The model's own uncertainty")."""
    theta = np.atleast_1d(np.asarray(theta, dtype=float))
    k = theta.size
    L = np.broadcast_to(np.asarray(half_width, dtype=float), (k,))
    out = {"log_evidence": -math.inf, "log_lr": 0.0, "sigma_model_um": float(sigma_model_um),
           "inflation": 1.0}
    if k == 0 or not drss > 0 or not np.all(np.isfinite(theta)):
        return out
    if np.any(np.abs(theta) > L):
        out["reason"] = "outside the plausible range"  # type: ignore[assignment]
        return out
    # the model's uncertainty along the signature: the amplitude's variance is the white
    # part (c^2 / D) plus sigma_m^2, so every variance is inflated by f^2
    f2 = 1.0
    if sigma_model_um > 0 and contrib_um > 0:
        f2 = 1.0 + sigma_model_um ** 2 * drss / contrib_um ** 2
    C = np.asarray(cov_white, dtype=float).reshape(k, k) * f2
    if cov_table is not None:
        T = np.asarray(cov_table, dtype=float).reshape(k, k)
        C = C + T
        # the RMS of the same signature the table's error gives (beside sigma_model_um)
        tt = float(theta @ T @ theta)
        th2 = float(theta @ theta)
        if tt > 0 and th2 > 0:
            s_tab = contrib_um * math.sqrt(tt) / th2
            out["sigma_table_um"] = float(s_tab)
            out["sigma_model_um"] = float(math.hypot(sigma_model_um, s_tab))
    # the change's own standard uncertainty (white, inflated, the table's error): its
    # interval where it is reported but not named (tested.possibly_present)
    theta_sd = np.sqrt(np.clip(np.diag(C), 0.0, None))
    if declared_cov is not None:
        C = C + np.asarray(declared_cov, dtype=float).reshape(k, k)
    # the covariance must be a proper (positive definite) one: a parameter the data do
    # not identify has none, and no evidence (never a solve on a singular matrix)
    C = 0.5 * (C + C.T)
    if not np.all(np.isfinite(C)):
        return out
    lam = np.linalg.eigvalsh(C)
    if not lam[0] > 1e-12 * max(float(lam[-1]), 0.0):
        return out
    sign, logdet = np.linalg.slogdet(2.0 * math.pi * C)
    if sign <= 0:
        return out
    quad = float(theta @ np.linalg.solve(C, theta))
    log_n0 = -0.5 * logdet - 0.5 * quad        # log N(theta; 0, Sigma0 + C)
    logk = -log_n0 - float(np.sum(np.log(2.0 * L))) + prior_log_odds - math.log(max(n_scan, 1))
    if typical is not None and declared_cov is None:
        T = np.diag(np.broadcast_to(np.asarray(typical, dtype=float), (k,)) ** 2)
        s_t, logdet_t = np.linalg.slogdet(2.0 * math.pi * (T + C))
        if s_t > 0:
            quad_t = float(theta @ np.linalg.solve(T + C, theta))
            out["log_evidence_typical"] = float(-0.5 * logdet_t - 0.5 * quad_t - log_n0
                                                + prior_log_odds - math.log(max(n_scan, 1)))
    out["theta_sd"] = [float(x) for x in theta_sd]
    out.update({"log_evidence": float(logk), "log_lr": float(drss / (2.0 * f2)),
                "inflation": float(math.sqrt(f2))})
    return out


def tool_is_declared(declared_mm: Any, opts: Any) -> bool:
    """Whether the tool offset is a declared quantity (docs/effects.md, "Declared
    quantities"): the model's tool (mm) is not zero, or the machine file states the tool's
    uncertainty (``[tool] offset_sigma_mm``: a zero tool stated so is a declaration)."""
    return (float(np.linalg.norm(np.asarray(declared_mm, dtype=float))) > 0
            or bool(getattr(opts, "declared_tool_stated", False)))


def candidate_prior(spec: Any, param_idx: list[int], declared_mm: np.ndarray,
                    lever_mm: float, opts: Any) -> dict[str, Any]:
    """The prior of a candidate (docs/effects.md §3): its parameters' plausible half-widths,
    the model's uncertainty along its signature (um, per unit of its contribution's
    lever), the prior log odds and, for a declared quantity, the declared covariance."""
    L = np.array([spec.params[i].limit for i in param_idx] if spec.kind != "tool_offset"
                 else [opts.tool_offset_max_mm] * len(param_idx), dtype=float)
    prior: dict[str, Any] = {"half_width": L, "sigma_model_um": 0.0,
                             "prior_log_odds": opts.prior_log_odds, "declared_cov": None,
                             "declared": False}
    if spec.kind == "tool_offset":
        # the tool offset multiplies the model's angular terms: their uncertainty times the
        # lever gives the same signature; the range is the physically plausible tool
        prior["half_width"] = np.full(len(param_idx), opts.tool_offset_max_mm)
        prior["sigma_model_um"] = lever_mm * opts.model_angle_sigma_urad * 1e-3
        if tool_is_declared(declared_mm, opts):
            p = opts.declared_blunder_prob
            prior.update({"prior_log_odds": math.log(p / (1.0 - p)), "declared": True,
                          "declared_cov": np.eye(len(param_idx)) * opts.declared_tool_sigma_mm ** 2})
    return prior


def declared_tool_log_evidence(drss: float, coef: np.ndarray, contrib_um: float,
                               declared_mm: np.ndarray, lever_mm: float,
                               opts: Any) -> dict[str, float]:
    """Log evidence ratio of "the declared tool offset is wrong by ``coef``" (mm) against
    "it is right within its declared uncertainty" (docs/effects.md, "Declared
    quantities"), with the covariance of ``coef`` taken as diagonal from the amplitude's
    signal-to-noise (``drss`` = c^2 / sigma_w^2): the special case of
    :func:`log_evidence` a reader can check by hand."""
    coef = np.atleast_1d(np.asarray(coef, dtype=float))
    if drss <= 0 or contrib_um <= 0:
        return {"log_evidence": -math.inf, "sigma_model_um": float("nan"), "log_lr": 0.0}
    cov_w = np.diag((np.abs(coef) / math.sqrt(drss)) ** 2 + 1e-24)
    spec = type("S", (), {"kind": "tool_offset", "params": ()})()
    pr = candidate_prior(spec, list(range(coef.size)), np.asarray(declared_mm, dtype=float),
                         lever_mm, opts)
    if not pr["declared"]:
        pr["prior_log_odds"] = math.log(opts.declared_blunder_prob / (1 - opts.declared_blunder_prob))
        pr["declared_cov"] = np.eye(coef.size) * opts.declared_tool_sigma_mm ** 2
    return log_evidence(coef, cov_w, drss, contrib_um, pr["half_width"], pr["sigma_model_um"],
                        pr["prior_log_odds"], pr["declared_cov"])
