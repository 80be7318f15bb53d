"""The fitted table's own uncertainty along a named effect (docs/effects.md §3, "The model's
own uncertainty"; docs/uncertainty.md, "Diagnosis").

A diagnosed effect is relative to the table the checks are compared with: the table's own
fit error (the commissioning lines' repeatability and lack of fit, carried to its
coefficients by ``abbe fit``: ``model.json`` ``uncertainty.axes.<A>.terms.<t>.covariance_*``,
C = G S G^T, docs/uncertainty.md "Fitted table") moves every prediction by J dc (J the
predictions' derivative by the coefficients), hence the effect's value by -s . J dc (s the
value's sensitivity to the readings, the final fit's linear operator). Its standard
uncertainty is sqrt(s J C J^T s^T). A term whose order the fit's selection chose below the axis'
full structure gets the selection's bias added to C (:func:`post_selection_covariance`:
model.json states the selected order's covariance only). The table's instrument scale (a laser's ppm on the own
positioning term) is left out: the check lines' own instrument inputs carry that figure in
the budget already, and the table was measured with the same instrument class.
"""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from abbe.model.table import AXES, Table, basis_matrix

#: the own positioning term of each axis (the one the instrument's scale acts on)
_OWN = {"X": "dx", "Y": "dy", "Z": "dz"}


def model_json_of(model: Any) -> Path | None:
    """The ``model.json`` of ``abbe fit`` that belongs to ``model`` (the file itself, or the
    one beside a ``model.bin``), or None."""
    if model is None or isinstance(model, Table):
        return None
    p = Path(model)
    cand = p if p.suffix == ".json" else p.with_name("model.json")
    return cand if cand.is_file() else None


def _scale_coefficients(ax: Any, ref_mm: float) -> np.ndarray:
    """Coefficients (table row order) of the linear function (p - ref) * 1e-3 um per ppm:
    a scale error of 1 ppm of the distance from the reference point."""
    lo, hi = ax.travel_mm
    p = np.linspace(lo, hi, 201)
    B = basis_matrix(ax, p)
    c, *_ = np.linalg.lstsq(B, (p - ref_mm) * 1e-3, rcond=None)
    return np.asarray(c, dtype=np.float64)


def _fit_scale_image(doc: dict[str, Any], table: Table, a: str, term: str) -> np.ndarray | None:
    """g = G (p x 1e-3): the coefficients ``abbe fit`` gave a scale of 1 ppm of its own line
    (``G`` the fit's operator, abbe.analysis.fit.uncertainty.fit_operator, on the line's
    targets ``axes.<A>.targets_mm`` with the term's ``trend_degree`` and ``harmonics``):
    the direction of the instrument-scale part it put into C (su² g g^T). It is the exact
    linear function only where the term's basis reproduces a line on those targets; with
    harmonics or targets over part of the travel it is aliased. None when model.json does
    not state the targets or the term's order."""
    from abbe.analysis.fit.uncertainty import fit_operator
    try:
        ad = doc["axes"][a]
        td = ad["terms"][term]
        p = np.asarray(ad["targets_mm"], dtype=np.float64)
        order = (int(td["trend_degree"]), int(td.get("harmonics") or 0))
        G = fit_operator(p, float(table.reference_mm[AXES.index(a)]), table.axes[a], order,
                         detrend=False)
    except (KeyError, TypeError, ValueError, IndexError):
        return None
    return np.asarray(G @ (p * 1e-3), dtype=np.float64)


def full_order(ax: Any) -> tuple[int, int]:
    """The axis' full structure (trend degree, block-0 harmonics): every column of the
    table's basis a term's order may select (abbe.analysis.fit.select.columns)."""
    blk = ax.blocks[0]
    return ax.n_trend() - 1, int(blk.harmonics) if blk is not None else 0


def post_selection_covariance(doc: dict[str, Any], table: Table, a: str,
                              term: str) -> np.ndarray | None:
    """The covariance (unit²) of the shape ``abbe fit``'s order selection left out of a
    term, from the lack of fit model.json states beside it (docs/effects.md §3, "The
    model's own uncertainty"); None when there is none to add.

    model.json's ``covariance_*`` is u_y² G_S G_S^T with G_S the *selected* order's
    operator: the selected estimator's variance, the order held fixed. Its error is that
    plus the bias of what the selection dropped (mean squared error = variance + bias
    bias^T); a coefficient set to zero by selection has no variance there, so a shape the
    selection left out is taken for exact. The bias is the fit of the left-out shape f
    minus f itself: D z with f = W z, W the functions the axis' full structure (the table's
    own basis, abbe.analysis.fit.select.columns) adds beyond the selected columns (and the
    line, for a detrended term), orthonormal over the travel, and D = G_S B_t W - W_t (B_t
    the basis at the line's targets, W_t the same functions as the table states them:
    detrended on the targets, zero at the reference). Nothing tells the direction of z:
    z ~ N(0, tau² I), the same mean square per direction over the travel (so a wiggle the
    targets do not see gets no more than any other shape). tau² is set by the fit's own
    figures: the selected order's residual sum of squares exceeds its noise share by
    E[SSE_S] - (T - p) u_rep² = |(I - H_S) f_t|², measured as
    e² = (T - p)(u_lack_of_fit² - u_repeatability²), so tau² = e² / ||(I - H_S) B_t W||²_F.
    C_b = tau² D D^T. Zero when the lack of fit is within the repeatability (e² <= 0), the
    term is at the full structure, or the run-to-run spread is not known (one run)."""
    from abbe.analysis.fit.select import columns
    from abbe.analysis.fit.uncertainty import fit_operator
    from abbe.model.table import LINEAR_TERMS
    try:
        ax = table.axes[a]
        ad = doc["axes"][a]
        td = ad["terms"][term]
        p = np.asarray(ad["targets_mm"], dtype=np.float64)
        d, h = int(td["trend_degree"]), int(td.get("harmonics") or 0)
        unit = "um" if term in LINEAR_TERMS else "urad"
        ud = doc["uncertainty"]["axes"][a]["terms"][term]
        u_rep = float(ud[f"u_repeatability_{unit}"])
        u_fit = float(ud[f"u_lack_of_fit_{unit}"])
    except (KeyError, TypeError, ValueError, IndexError, AttributeError):
        return None
    if (p.ndim != 1 or ax.trend_degree is None or not math.isfinite(u_rep)
            or not math.isfinite(u_fit) or u_fit <= u_rep):
        return None
    hh = h if ax.blocks[0] is not None else 0
    n_p = d + 1 + 2 * hh + (1 if hh else 0)     # the fit's own count (the period counted)
    e2 = (p.size - n_p) * (u_fit * u_fit - u_rep * u_rep)
    detrend = term in LINEAR_TERMS and term != _OWN[a]
    sel = sorted(set(columns(ax, d, hh)) | ({0, 1} if detrend else set()))
    full = [c for c in columns(ax, *full_order(ax)) if c not in sel]
    if e2 <= 0.0 or not full:
        return None
    # functions of the full structure orthogonal (over the travel) to the selected ones
    x = np.linspace(float(ax.travel_mm[0]), float(ax.travel_mm[1]), 401)
    Bx = basis_matrix(ax, x)
    Qs, _ = np.linalg.qr(Bx[:, sel])
    R = Bx[:, full] - Qs @ (Qs.T @ Bx[:, full])
    U, sv, Vt = np.linalg.svd(R / math.sqrt(x.size), full_matrices=False)
    keep = sv > 1e-8 * max(float(sv[0]), 1e-300)
    if not np.any(keep):
        return None
    # coefficient vectors: R v / s = Bx[:, full] v / s - (selected columns' part)
    Cs, *_ = np.linalg.lstsq(Bx[:, sel], Bx[:, full], rcond=None)
    nb = ax.n_basis()
    W = np.zeros((nb, int(keep.sum())))
    Vk = Vt[keep].T / sv[keep]
    W[full] = Vk
    W[sel] = -Cs @ Vk
    ref = float(table.reference_mm[AXES.index(a)])
    Bt = basis_matrix(ax, p)
    Ft = Bt @ W                                   # the functions at the targets
    Wt = W.copy()                                 # as the table states them
    if detrend:
        Wt -= fit_operator(p, ref, ax, (1, 0), detrend=False) @ Ft
    Wt[0] -= basis_matrix(ax, np.array([ref]))[0] @ Wt
    G = fit_operator(p, ref, ax, (d, hh), detrend=detrend)
    D = G @ Ft - Wt
    St = Bt[:, sel]
    Qt, _ = np.linalg.qr(St)
    Rt = Ft - Qt @ (Qt.T @ Ft)
    den = float(np.sum(Rt * Rt))
    if den <= 0.0:
        return None
    return np.asarray((e2 / den) * (D @ D.T), dtype=np.float64)


def table_covariance(model: Any, table: Table) -> dict[tuple[str, str], np.ndarray]:
    """Per (axis, term) the covariance (um² / urad²) of the table's coefficients that its
    own fit leaves: ``model.json``'s (read by the fit's own reader,
    abbe.analysis.fit.uncertainty.terms_from_json), the instrument scale removed from the
    own positioning term (``scale_u_ppm``, standard, along the fit's own image of a scale,
    :func:`_fit_scale_image`; without the targets in model.json, the linear function of
    the distance from the reference point); {} when there is no ``model.json`` with an
    ``uncertainty`` section beside the model (an imported or hand-made table, or diagnose's
    own output: no line). A model.json that is there but unreadable, not JSON, not a JSON
    object, whose ``uncertainty`` is not an object, or whose covariances do not fit
    ``table`` raises AbbeInputError (file, line, field)."""
    from abbe.analysis.fit.uncertainty import terms_from_json
    from abbe.errors import AbbeInputError
    from abbe.formats.structured import JsonLocator
    path = model_json_of(model)
    if path is None:
        return {}
    # a model.json beside the table is input: unreadable, not JSON or a covariance that does
    # not fit the table is an error (exit 2), never a budget line silently left out
    try:
        text = path.read_text()
        doc = json.loads(text)
    except OSError as exc:
        raise AbbeInputError(f"cannot read the table's model.json: {exc.strerror}",
                             file=str(path)) from None
    except ValueError as exc:
        raise AbbeInputError(f"expected JSON (the model.json of `abbe fit`): {exc}",
                             file=str(path), line=getattr(exc, "lineno", None)) from None
    # only a missing ``uncertainty`` section means "no line" (a table fitted without one);
    # any other shape is a spoiled file (issue 36: a list, a number or a string was taken
    # for "no line" silently)
    if not isinstance(doc, dict):
        raise AbbeInputError("expected a JSON object (the model.json of `abbe fit`), got "
                             f"{_json_kind(doc)}", file=str(path), line=1, field="(top level)")
    if "uncertainty" not in doc:
        return {}
    loc = JsonLocator(text)
    unc = doc["uncertainty"]
    if not isinstance(unc, dict):
        raise AbbeInputError("expected an object (the fitted table's uncertainty block of "
                             f"`abbe fit`, with its axes), got {_json_kind(unc)}",
                             file=str(path), line=loc.line("uncertainty"), field="uncertainty")
    try:
        terms = terms_from_json(unc, table, str(path))
    except AbbeInputError as exc:
        raise exc.located(line=loc.line(exc.field)) from None
    out: dict[tuple[str, str], np.ndarray] = {}
    for a, per in terms.items():
        ax = table.axes[a]
        for t, tu in per.items():
            C = np.asarray(tu.cov, dtype=np.float64)
            su = tu.inputs.get("scale_u_ppm", 0.0)      # checked by terms_from_json
            if t == _OWN[a] and su > 0:
                g = _fit_scale_image(doc, table, a, t)
                if g is None or g.size != C.shape[0]:
                    g = _scale_coefficients(ax, float(table.reference_mm[AXES.index(a)]))
                w, V = np.linalg.eigh(C - su * su * np.outer(g, g))
                C = (V * np.clip(w, 0.0, None)) @ V.T
            Cb = post_selection_covariance(doc, table, a, t)
            out[(a, t)] = C if Cb is None or Cb.shape != C.shape else C + Cb
    return out


def _json_kind(v: Any) -> str:
    """A parsed JSON value for a message: ``null``, else :func:`abbe.errors.numbers.show_value`."""
    from abbe.errors.numbers import show_value
    return "null" if v is None else show_value(v)


#: singular values of a term's basis over its travel below this share of the largest are
#: directions the table can show only through coefficients 1e6 times larger
#: (:func:`visible_part`)
VISIBLE_RCOND = 1e-6


def visible_part(C: np.ndarray, ax: Any, n_grid: int = 200) -> np.ndarray:
    """The part of a term's coefficient covariance ``C`` its values over the travel show:
    P C P with P the projector on the basis' row space over the travel, its singular
    directions below ``VISIBLE_RCOND`` of the largest left out.

    A full structure of trend and harmonics on a short travel is nearly dependent
    (Z of degree 7 and 4 harmonics of 508 mm over 391 mm: singular values down to 2e-6 of
    the largest), and the order selection's left-out shapes (:func:`post_selection_covariance`)
    can give C eigenvalues of 6e12 um² along such a direction: cancelled over the travel
    (the term's value u stays 0.18 um), but a derivative J that is not exactly the basis
    (a circle's set-up projected out, the servo lag moving the positions) does not cancel
    it, and 1e-6 of it came back as 1.5 um on a circle (docs/effects.md §3, "What the
    table shows"). Dropping those directions changes the value u over the travel by at
    most 0.03 um on that term."""
    lo, hi = ax.travel_mm
    B = basis_matrix(ax, np.linspace(float(lo), float(hi), n_grid))
    if B.shape[1] != C.shape[0]:
        return C
    _, sv, Vt = np.linalg.svd(B, full_matrices=False)
    keep = sv > VISIBLE_RCOND * float(sv[0]) if sv.size else np.zeros(0, dtype=bool)
    P = Vt[keep].T @ Vt[keep]
    return P @ C @ P


def table_factor(eng: Any, table: Table, pp: Any,
                 cov: dict[tuple[str, str], np.ndarray]) -> np.ndarray | None:
    """A factor M (N, r) of the predictions' covariance the table's coefficient covariance
    ``cov`` gives, M M^T = sum over terms of J_t C_t J_t^T (um²; J_t the predictions'
    derivative by the term's coefficients, one unit of each, the model being linear in its
    coefficients; C_t = V diag(w) V^T, M_t = J_t V sqrt(w)); the terms' fits are
    independent lines or independent channels of one. None when ``cov`` is empty (no
    ``model.json``: no line)."""
    if not cov:
        return None
    prob = eng.prob
    y0 = prob.predict(eng.ev, table, pp)
    t = copy.deepcopy(table)
    blocks: list[np.ndarray] = []
    for (a, term), C in cov.items():
        co = t.axes[a].coef.get(term)
        if co is None or co.size != C.shape[0]:
            continue
        J = np.zeros((y0.size, co.size))
        for k in range(co.size):
            if C[k, k] <= 0.0:
                continue
            old = co[k]
            co[k] = old + 1.0     # one um / urad
            J[:, k] = prob.predict(eng.ev, t, pp) - y0
            co[k] = old
        C = visible_part(C, t.axes[a])
        w, V = np.linalg.eigh(0.5 * (C + C.T))
        keep = w > 0.0
        if np.any(keep):
            blocks.append(J @ (V[:, keep] * np.sqrt(w[keep])))
    return np.hstack(blocks) if blocks else np.zeros((y0.size, 0))


def table_u(M: np.ndarray | None, sens: np.ndarray) -> float:
    """Standard uncertainty of a figure whose change is ``sens`` . dy (dy the readings'
    change, ``sens`` (N,)) due to the table's coefficient covariance: sqrt(|sens M|²), ``M``
    the factor :func:`table_factor` gives (sqrt(g C g^T) per term, g the term's derivative
    through ``sens``, summed in quadrature); 0 without one. One factor serves every figure
    of a diagnosis (it depends on the table and the prediction parameters only)."""
    if M is None:
        return 0.0
    g = np.asarray(sens, dtype=np.float64) @ M
    return math.sqrt(float(g @ g))
