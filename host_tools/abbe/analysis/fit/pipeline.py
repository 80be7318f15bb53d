"""The ``abbe fit`` pipeline: machine file + 6D laser lines -> table, metrics, provenance.

Per measured axis (docs/formats.md, "abbe fit"):

1. read the laser CSV and convert instrument channels to model terms (map signs);
2. ISO 230-2 evaluation of the axis' own positioning term;
3. run averaging (bidirectional mean, reversal per target, run-to-run noise);
4. least-squares straightness detrending (paper Eq. 1) of the two straightness
   terms; squareness is unobservable and stays zero;
5. values relative to the reference point;
6. model selection and fitting (:mod:`abbe.analysis.fit.select`), with the paper's models for
   comparison; the stored term is shifted so it is exactly 0 at the reference;
7. quantisation into the table format, worst-case quantisation error per term.

Backlash: the mean reversal of the own positioning term goes into the table
(``AxisTable.backlash_um``) only when it is significant against the run-to-run
noise; it is always reported. A reversal that changes along the travel
significantly (:func:`abbe.analysis.fit.prep.assess_reversal`) goes in as its
Chebyshev series: the level in ``backlash_um``, T1..Td in the axis' reversal block
(``AxisTable.reversal_cheb_um``, table format 1.1).

Units: mm, um (linear terms), urad (angular terms).
"""

from __future__ import annotations

import os
import platform
from pathlib import Path
from typing import Any

import numpy as np

from abbe import __version__
from abbe.analysis.fit.options import COMPARED, FitOptions
from abbe.analysis.fit.prep import (
    SQUARENESS_NOTE,
    RunStats,
    assess_reversal,
    average_runs,
    bin_targets,
    estimate_thermal,
    detrend_line,
    relative_to_reference,
)
from abbe.analysis.fit.select import fit_axis
from abbe.analysis.fit.uncertainty import fit_uncertainty
from abbe.analysis.fit.uncertainty import to_json as uncertainty_json
from abbe.analysis.iso230_2 import evaluate
from abbe.errors import AbbeInputError
from abbe.formats.blob import coef_sum_cap, quantization_error, read_blob, write_blob
from abbe.formats.deviations import PositioningData
from abbe.formats.laser_csv import to_terms
from abbe.formats.laser_file import read_laser_line
from abbe.formats.limits import FIT_MAX_TARGETS
from abbe.formats.machine import Machine
from abbe.formats.table_json import table_to_json
from abbe.model.table import AXES, LINEAR_TERMS, OWN_TERM, TERMS, AxisTable, Table, basis_matrix

from abbe.analysis.fit.results import (  # noqa: E402,F401  (re-exported)
    JSON_FORMAT, TERM_NAMES, AxisResult, FitResult, TermResult, role_of, unit_of)


def options_from_machine(machine: Machine, **overrides: Any) -> FitOptions:
    """FitOptions from the machine file's [fit] section, then non-None overrides."""
    opts = FitOptions()
    fit = machine.extra.get("fit", {})
    if fit:
        opts.max_degree = fit["max_trend_degree"]
        opts.max_harmonics = fit["max_harmonics"]
        opts.folds = fit["folds"]
    for k, v in overrides.items():
        if v is not None:
            setattr(opts, k, v)
    return opts


def backlash_sigma(machine: Machine) -> float:
    """Significance threshold (in standard errors) for a backlash term."""
    return float(machine.extra.get("fit", {}).get("backlash_sigma", 3.0))


def assess_backlash(stats: RunStats, sigma: float) -> dict[str, Any]:
    """Mean reversal of the own positioning term and its significance.

    reversal B = mean over targets of (mean + approach - mean - approach), um.
    Its standard error from the run-to-run noise s: a single target's reversal
    has SE s * sqrt(2 / n); the mean over T targets is not credited with 1/sqrt(T)
    because run-to-run errors (drift) are correlated along the line. Significant
    when |B| > sigma * s * sqrt(2 / n).
    """
    n = stats.n_runs
    B = float(np.mean(stats.reversal))
    se = float(stats.noise * np.sqrt(2.0 / n)) if n > 1 else float("nan")
    sig = bool(n > 1 and np.isfinite(se) and abs(B) > sigma * se)
    return {"mean_reversal_um": B, "max_abs_reversal_um": float(np.max(np.abs(stats.reversal))),
            "reversal_std_um": float(np.std(stats.reversal, ddof=1)) if stats.reversal.size > 1
            else 0.0, "noise_um": float(stats.noise), "se_um": se, "threshold_sigma": sigma,
            "significant": sig}


def _check_reference(machine: Machine, axis: str, targets: np.ndarray) -> float:
    j = AXES.index(axis)
    r = machine.reference_mm[j]
    lo, hi = float(targets[0]), float(targets[-1])
    if not lo - 1e-6 <= r <= hi + 1e-6:
        raise AbbeInputError(
            f"the reference point's {axis.lower()} = {r} mm lies outside the measured targets "
            f"[{lo}, {hi}] mm of laser line {axis}: terms cannot be taken relative to it",
            file=str(machine.path), line=machine.line_of("reference.point_mm"),
            field="reference.point_mm")
    return r


def fit_line(machine: Machine, axis: str, opts: FitOptions) -> AxisResult:
    """Steps 1-6 for one laser line."""
    line = machine.laser[axis]
    j = AXES.index(axis)
    spec = machine.axes[axis]
    data = read_laser_line(line, channels=tuple(line.map), travel_mm=spec.travel_mm,
                           span_mm=(line.start_mm[j], line.end_mm[j]))
    terms = to_terms(data, line)
    p = data.targets_mm
    n_measured = int(p.size)
    if p.size < 5:
        raise AbbeInputError(f"{p.size} targets: the fit needs at least 5", file=str(data.file),
                             field="target_mm")
    ref = _check_reference(machine, axis, p)
    present = [t for t in TERMS if t in terms]

    own = OWN_TERM[axis]
    # Thermal (with temp_c): offset and expansion per kelvin of the own positioning term,
    # from the run-to-run variation; the readings are corrected to the line's first
    # temperature (the table's T_ref), so every fitted term holds at T_ref.
    thermal: dict[str, Any] = {"significant": False, "note": "no temp_c column"}
    if own in terms and data.temp_c is not None:
        first = np.unravel_index(int(np.argmin(data.line_no)), data.line_no.shape)
        thermal = estimate_thermal(terms[own], data.temp_c, p, ref, float(data.temp_c[first]),
                                   backlash_sigma(machine))
        terms[own] = terms[own] - thermal.pop("correction_um")
        thermal["in_table"] = bool(thermal["significant"])
    iso = None
    if own in terms and data.n_runs >= 2:
        iso = evaluate(PositioningData(str(data.file), p, terms[own][:, 0, :],
                                       terms[own][:, 1, :]))
    if p.size > FIT_MAX_TARGETS:  # a dense capture: fit bin means (time and memory bounded)
        p, terms = bin_targets(p, terms, FIT_MAX_TARGETS)

    runs_pre: dict[str, np.ndarray] = {}
    detr: dict[str, dict[str, float] | None] = {}
    shift: dict[str, float] = {}
    for t in present:
        r = terms[t].astype(float)
        st = average_runs(r)
        d = None
        if t in LINEAR_TERMS and t != own:  # straightness: paper Eq. 1
            _, k, b = detrend_line(p, st.mean)
            r = r - (k * p + b)
            d = {"slope_urad": k * 1000.0, "intercept_um": b}
        _, v = relative_to_reference(p, average_runs(r).mean, ref)
        runs_pre[t] = r - v
        detr[t] = d
        shift[t] = v

    Y = np.column_stack([average_runs(runs_pre[t]).mean for t in present])
    af = fit_axis(p, Y, opts, caps=[coef_sum_cap(t) for t in present])
    tab = af.model.table
    # Exact reference adaptation: shift so every stored term is 0 at the reference.
    bref = basis_matrix(tab, np.array([ref]))[0]
    coefs: dict[str, np.ndarray] = {}
    results: dict[str, TermResult] = {}
    for i, t in enumerate(present):
        c = af.model.coef[i].copy()
        v2 = float(bref @ c)
        c[0] -= v2  # row T_0 == 1 everywhere: every candidate has a trend block
        coefs[t] = c
        runs = runs_pre[t] - v2
        preds = {k: {"in_sample": af.in_sample[k][:, i] - v2, "held_out": af.held_out[k][:, i] - v2}
                 for k in COMPARED}
        f3 = af.paper_f3[i]
        cm = line.term_channel(t)
        results[t] = TermResult(
            axis=axis, term=t, channel=cm.channel, sign=cm.sign, runs=runs,
            stats=average_runs(runs), detrend=detr[t], ref_shift=shift[t] + v2,
            order=af.model.orders[i], coef=c, predictions=preds, metrics=af.metrics[i],
            paper_f3_period_mm=None if f3 is None else f3.period_mm, post_shift=v2)

    bl = {"mean_reversal_um": 0.0, "significant": False, "note": "no positioning term measured"}
    backlash_um, takeup = 0.0, 0.0
    reversal_block: tuple[float, ...] | None = None
    if own in terms:
        bl = assess_backlash(average_runs(terms[own]), backlash_sigma(machine))
        bl["takeup_mm"] = spec.backlash_takeup_mm
        if bl["significant"]:
            backlash_um, takeup = bl["mean_reversal_um"], spec.backlash_takeup_mm
        bl["in_table"] = bool(bl["significant"])
        bl["reversal"] = assess_reversal(average_runs(terms[own]), p, tab.travel_mm,
                                         backlash_sigma(machine))
        rev = bl["reversal"]
        rev["in_table"] = bool(rev["position_dependent"])
        if rev["position_dependent"]:
            # format 1.1 reversal block: R(p) = backlash_um + sum_k r_k T_k(u) with the
            # series' level in backlash_um and T1..Td in the block (r_0 = 0), so a
            # controller that drops the block keeps the mean reversal
            cheb = [float(v) for v in rev["chebyshev_um"]]
            backlash_um, takeup = cheb[0], spec.backlash_takeup_mm
            reversal_block = (0.0, *cheb[1:])
            rev["note"] = (f"in the table: backlash {cheb[0]:.3f} um plus a degree {rev['degree']} "
                           "reversal block (table format 1.1)")
            bl["in_table"] = True
    axt = AxisTable(travel_mm=tab.travel_mm, trend_degree=tab.trend_degree, blocks=tab.blocks,
                    coef=coefs, backlash_um=backlash_um, backlash_takeup_mm=takeup,
                    reversal_cheb_um=reversal_block)
    if thermal.get("in_table"):
        axt.thermal_offset_um_per_k = thermal["offset_um_per_k"]
        axt.thermal_expansion_ppm_per_k = thermal["expansion_ppm_per_k"]
        axt.thermal_tref_c = thermal["tref_c"]
    return AxisResult(axis=axis, line=line, data=data, targets_mm=p, fit=af, terms=results,
                      backlash=bl, iso=iso, table=axt, n_measured=n_measured,
                      thermal=thermal, ref_mm=float(ref))


def fit_machine(machine: Machine, opts: FitOptions) -> FitResult:
    """Fit every laser line of ``machine`` and build the (float) table and its blob."""
    if not machine.laser:
        raise AbbeInputError("no [laser.X/Y/Z] sections: nothing to fit", file=str(machine.path),
                             field="laser")
    axes: dict[str, AxisResult] = {}
    for a in AXES:
        if a in machine.laser:
            axes[a] = fit_line(machine, a, opts)
    tables = {}
    for a in AXES:
        if a in axes:
            tables[a] = axes[a].table
        else:
            tr = machine.axes[a].travel_mm if a in machine.axes else (0.0, 1.0)
            tables[a] = AxisTable(travel_mm=tr)
    table = Table(axes=tables, reference_mm=machine.reference_mm,
                  tool_offset_mm=machine.tool_offset_mm, squareness_urad=(0.0, 0.0, 0.0))
    blob = write_blob(table)
    qerr = quantization_error(table)
    for (a, t), e in qerr.items():
        axes[a].terms[t].quant_error = float(e)
    res = FitResult(machine=machine, options=opts, table=table, blob=blob, axes=axes)
    res.uncertainty = fit_uncertainty(res)
    res.model_json = model_json(res)
    return res


def _r(x: float, nd: int = 6) -> float | None:
    """Round for the JSON (stable text across platforms); None for NaN."""
    x = float(x)
    if not np.isfinite(x):
        return None
    return float(f"{x:.{nd}g}") if nd else x


MODEL_LABELS = {"chosen": "the chosen model", "paper_fourier3": "the paper's 3rd-order Fourier",
                "paper_poly7": "the paper's 7th-order polynomial"}


def _unavailable_why(name: str, kind: str, y: np.ndarray, yhat: np.ndarray) -> str | None:
    """Why a metric of ``name`` / ``kind`` is undefined (None: every one is defined).

    A prediction is missing where the model cannot be fitted: the paper's Fourier needs a
    period at which the targets (of the line, or of a held-out fold's other targets)
    resolve 3 harmonics, 7 coefficients and the period; on an 11-target line a fold of 8
    or 9 targets does not. R^2 is undefined for a term constant at the targets."""
    miss = int(np.count_nonzero(~np.isfinite(yhat)))
    what = MODEL_LABELS.get(name, name)
    if miss and kind == "in_sample":
        return (f"{what} could not be fitted on the line's {y.size} targets (no period at "
                "which they resolve its harmonics)")
    if miss:
        return (f"{miss} of {y.size} targets have no held-out prediction: {what} could not be "
                "fitted on the other targets of their fold (no period at which they resolve "
                "its harmonics)")
    if not float(np.sum((y - y.mean()) ** 2)) > 0.0:
        return "R^2 is undefined: the term is constant at the targets (SST = 0)"
    return None


def _metrics_json(tr: TermResult, unit: str) -> dict[str, Any]:
    """paper Eqs. 6-8 per model and kind; a metric that is undefined is null and its
    block says why (docs/formats.md, model.json)."""
    out: dict[str, Any] = {}
    for name, d in tr.metrics.items():
        out[name] = {}
        for kind, v in d.items():
            block: dict[str, Any] = {f"emax_{unit}": _r(v["emax"]), "r2": _r(v["r2"]),
                                     f"sse_{unit}2": _r(v["sse"]), f"rmse_{unit}": _r(v["rmse"])}
            if any(x is None for x in block.values()):
                yhat = tr.predictions[name][kind] + tr.post_shift  # as fitted (before the shift)
                block["why_null"] = _unavailable_why(name, kind, tr.stats.mean + tr.post_shift,
                                                     yhat) or "not finite"
            out[name][kind] = block
    return out


def axis_warnings(ar: AxisResult, opts: FitOptions) -> list[str]:
    """Caveats about one line's data that the metrics cannot show."""
    out = []
    dp = np.diff(ar.targets_mm)
    if dp.size and float(dp.max()) <= 1.05 * float(dp.min()):
        s = float(np.median(dp))
        out.append(
            f"targets evenly spaced ({s:g} mm): a cyclic error with a period below {2 * s:g} mm "
            "(e.g. a ball-screw lead) aliases into an apparent longer wave that fits the targets "
            "and the held-out targets alike but is wrong between them; ISO 230-2 advises "
            "unevenly spaced targets")
    if ar.data.n_runs < 5:
        out.append(f"{ar.data.n_runs} runs: ISO 230-2 asks for 5 bidirectional runs")
    return out


def _rel(path: Path, base: Path) -> str:
    try:
        return os.path.relpath(path, base)
    except ValueError:
        return str(path)


def model_json(res: FitResult) -> dict[str, Any]:
    """model.json: coefficients with units, fit metrics and provenance. No timestamps."""
    m = res.machine
    base = m.path.resolve().parent
    qt = read_blob(res.blob)
    axes: dict[str, Any] = {}
    for a, ar in res.axes.items():
        tab = ar.table
        blk = tab.blocks[0]
        spacing = float(np.median(np.diff(ar.targets_mm)))
        terms: dict[str, Any] = {}
        for t, tr in ar.terms.items():
            u = tr.unit
            d, h = tr.order
            terms[t] = {
                "name": f"{TERM_NAMES[t]}({a.lower()})",
                "role": role_of(a, t),
                "unit": u,
                "channel": tr.channel, "sign": tr.sign,
                "family": "polynomial" if h == 0 else "trend+fourier",
                "trend_degree": d, "harmonics": h, "n_parameters": d + 1 + 2 * h,
                f"coef_{u}": [float(v) for v in tr.coef],
                f"coef_quantized_{u}": [float(v) for v in qt.axes[a].coef[t]],
                f"quantization_error_{u}": _r(tr.quant_error),
                "detrend": None if tr.detrend is None else
                {"slope_urad": _r(tr.detrend["slope_urad"]),
                 "intercept_um": _r(tr.detrend["intercept_um"])},
                f"reference_shift_{u}": _r(tr.ref_shift),
                f"noise_{u}": _r(tr.stats.noise),
                f"max_abs_reversal_{u}": _r(float(np.max(np.abs(tr.stats.reversal)))),
                "paper_fourier3_period_mm": _r(tr.paper_f3_period_mm) if tr.paper_f3_period_mm
                else None,
                "metrics": _metrics_json(tr, u),
            }
        axes[a] = {
            "laser_file": _rel(ar.line.file, base),
            "n_targets": int(ar.targets_mm.size), "n_runs": ar.data.n_runs,
            **({"n_targets_measured": ar.n_measured,
                "binning": f"{ar.n_measured} targets fitted as {ar.targets_mm.size} bins of "
                           "consecutive targets (bin means; docs/formats.md, \"Limits\")"}
               if ar.n_measured > ar.targets_mm.size else {}),
            "targets_mm": [float(v) for v in ar.targets_mm],
            "travel_mm": [float(v) for v in tab.travel_mm],
            "trend_degree": tab.trend_degree,
            "block0": None if blk is None else {"period_mm": blk.period_mm,
                                                "origin_mm": blk.origin_mm,
                                                "harmonics": blk.harmonics},
            "block1": None,
            "block1_note": ("unused: cyclic errors with periods below "
                            f"{_r(res.options.samples_per_wavelength * spacing, 4)} mm "
                            f"({res.options.samples_per_wavelength} target spacings) are not "
                            "resolved by these data"),
            "selection_score": _r(ar.fit.model.score),
            "warnings": axis_warnings(ar, res.options),
            "backlash": {k: (_r(v) if isinstance(v, float) else v) for k, v in ar.backlash.items()},
            "thermal": {k: (_r(v) if isinstance(v, float) else v) for k, v in ar.thermal.items()},
            "iso230_2": None if ar.iso is None else _iso_with_U(ar.iso, res.machine),
            "normalisation_20c": (None if ar.data.normalisation is None else
                                  {k: (_r(v) if isinstance(v, float) else v)
                                   for k, v in ar.data.normalisation.to_json().items()}),
            "terms": terms,
        }
    o = res.options
    return {
        "format": JSON_FORMAT,
        "units": {"position": "mm", "linear": "um", "angular": "urad",
                  "sse": "unit^2 (um^2 or urad^2)"},
        "provenance": {
            "tool": "abbe", "version": __version__,
            "python": platform.python_version(), "numpy": np.__version__,
            "inputs": {"machine": {"file": m.path.name, "sha256": m.sha256},
                       **{f"laser.{a}": {"file": _rel(ar.data.file, base),
                                         "sha256": ar.data.sha256}
                          for a, ar in res.axes.items()}},
        },
        "options": {"model": o.model, "max_trend_degree": o.max_degree,
                    "max_harmonics": o.max_harmonics, "folds": o.folds,
                    "samples_per_wavelength": o.samples_per_wavelength,
                    "max_wave_trend_degree": o.max_wave_degree,
                    "column_independence_tol": o.col_tol, "one_standard_error_rule": o.one_se,
                    "backlash_sigma": backlash_sigma(m)},
        "machine": {"name": m.name, "reference_mm": list(m.reference_mm),
                    "tool_offset_mm": list(m.tool_offset_mm)},
        "squareness": {"S_xy_urad": 0.0, "S_xz_urad": 0.0, "S_yz_urad": 0.0,
                       "observable": False, "note": SQUARENESS_NOTE},
        "metrics_note": ("emax, R^2, SSE, RMSE per paper Eqs. 6-8 on the bidirectional mean at "
                         "the targets; in_sample: fitted on all targets; held_out: each target "
                         "predicted by an outer K-fold (target i in fold i mod K) that repeats "
                         "the whole selection on the other targets. paper_fourier3: a_0 + 3 "
                         "harmonics, period fitted per term by least squares; paper_poly7: "
                         "degree-7 polynomial. A metric that is undefined (the model cannot be "
                         "fitted on the targets, or on a fold's; R^2 of a constant term) is null, "
                         "and its block's why_null says why."),
        "table": {"crc32": f"0x{int.from_bytes(res.blob[-4:], 'little'):08X}",
                  "size_bytes": len(res.blob), **table_to_json(qt)},
        "axes": axes,
        **({"uncertainty": uncertainty_json(res, res.uncertainty)}
           if res.uncertainty is not None else {}),
    }


def _iso_with_U(iso: Any, machine: Machine) -> dict[str, Any]:
    """The axis' ISO 230-2 results (um) with their U (k = 2) from the machine file's laser
    budget (else the laser_interferometer class defaults), as `abbe iso230-2` gives them
    (docs/uncertainty.md, "ISO 230-2")."""
    from abbe.analysis.fit.uncertainty import laser_budget
    from abbe.analysis.uncertainty import iso230_2_uncertainty
    budget = laser_budget(machine)
    unc = iso230_2_uncertainty(iso, budget)
    out: dict[str, Any] = {}
    for q in ("B", "R", "E", "A", "M"):
        out[f"{q}_um"] = _r(getattr(iso, f"{q}_um"))
        out[f"{q}_U_um"] = _r(unc.results[q].U_um)
    out["U_k"] = 2
    out["U_budget"] = getattr(budget, "source", "")
    return out
