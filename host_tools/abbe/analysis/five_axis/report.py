"""The five-axis identification report, ISO 230-7 style: JSON, text and HTML with polar plots.

Sections: the location of each axis average line (position and orientation,
value and 95 % interval, or "not observable" with the confounded group and the
test that would see it), the error motions (radial / axial / tilt / angular,
Fourier coefficients and their peak-to-valley over a turn), the angular
positioning of an indexed axis (ISO 230-2 statistics, urad), the sphere-centre
dispersion before / after and held out, the observability table (rank,
condition number, what the plan fixes by convention), the strongest
correlations and the rotary ballbar tests (ISO 10791-6 style: the bar's length
deviation over the turning axis' angle, measured and left by the identified
model, as polar plots). Units: um, urad, degrees.
"""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any

import numpy as np

from abbe.analysis.five_axis.data import PlanData
from abbe.analysis.five_axis.identify import SEEN_BY, FitResult
from abbe.analysis.five_axis.problem import Block, residual_block
from abbe.analysis.five_axis.uncertainty import budget as uncertainty_budget
from abbe.analysis.five_axis.uncertainty import type_b
from abbe.analysis.iso230_2 import evaluate
from abbe.formats.deviations import PositioningData
from abbe.formats.five_axis import FiveAxisSpec, IndexerRuns
from abbe.model.five_axis import MOTION_COMPONENTS, fourier_rows, motion_name

#: |correlation| above this is reported.
STRONG_CORRELATION = 0.9


def _f(v: float) -> float | None:
    return None if not np.isfinite(v) else float(v)


def _group_of(res: FitResult, name: str) -> list[str]:
    for g in res.obs.groups:
        if name in g:
            return [n for n in g if n != name]
    return []


def _seen_key(name: str, kind: str) -> str:
    """The SEEN_BY key: an angular zero (EC0C, EA0A, EB0B) has its own."""
    return "zero" if kind == "location" and name[1] == name[3] else kind


def param_rows(res: FitResult, type_b: dict[str, Any] | None = None) -> list[dict[str, Any]]:
    """One row per parameter: value and 95 % interval, or why it has no number;
    ``type_b`` (``uncertainty.type_b``) adds each instrument's calibration to u."""
    rows = []
    uB2 = np.zeros(len(res.params))
    for ux, _what in (type_b or {}).values():
        uB2 += np.asarray(ux) ** 2
    for i, p in enumerate(res.params):
        row: dict[str, Any] = {"name": p.name, "kind": p.kind, "unit": p.unit}
        if res.obs.observable[i]:
            # U (k = 2) is the certificate's figure (docs/uncertainty.md); ci95 (1.96 u) kept
            u = float(np.sqrt(res.sd[i] ** 2 + uB2[i]))
            row.update(observable=True, value=_f(res.x[i]), ci95=_f(1.96 * u),
                       u=_f(u), U=_f(2.0 * u), u_typeA=_f(res.sd[i]))
            if p.kind != "setup" and res.x_table is not None:
                # what model_five.bin holds: the fit's value, moved (within its interval)
                # by the prior on the errors the plan sees only in the convention
                row["value_in_table"] = _f(res.x_table[i])
        else:
            # value_in_convention: what the table holds (0 for the fixed ones): only its
            # combination with the fixed errors is seen (identify.py, cli/fit_five_axis.py)
            conv = None if res.x_table is None else _f(res.x_table[i])
            sdc = None if res.sd_convention is None or i in res.obs.fixed \
                else _f(1.96 * res.sd_convention[i])
            row.update(observable=False, value=None, ci95=None, u=None, U=None,
                       value_in_convention=None if p.kind == "setup" else conv,
                       ci95_in_convention=None if p.kind == "setup" else sdc,
                       U_in_convention=None if p.kind == "setup" or sdc is None
                       else _f(2.0 * res.sd_convention[i]),
                       fixed_by_convention=i in res.obs.fixed,
                       confounded_with=_group_of(res, p.name),
                       seen_by=SEEN_BY[_seen_key(p.name, p.kind)])
        rows.append(row)
    return rows


def correlations(res: FitResult) -> list[dict[str, Any]]:
    """Pairs of observable parameters with |correlation| > STRONG_CORRELATION."""
    out = []
    P = len(res.params)
    for i in range(P):
        for j in range(i + 1, P):
            c = res.corr[i, j]
            if res.obs.observable[i] and res.obs.observable[j] and np.isfinite(c) \
                    and abs(c) > STRONG_CORRELATION:
                out.append({"a": res.params[i].name, "b": res.params[j].name, "r": float(c)})
    return out


def motion_curves(res: FitResult, axis: str, n: int = 360) -> dict[str, np.ndarray]:
    """Identified error motions of ``axis`` over a turn (only components with a number)."""
    t = np.linspace(0.0, 360.0, n, endpoint=False)
    out: dict[str, np.ndarray] = {}
    for comp in MOTION_COMPONENTS:
        idx = [i for i, p in enumerate(res.params) if p.kind == "motion" and p.axis == axis
               and p.comp == comp and res.obs.observable[i]]
        if not idx:
            continue
        coef = np.zeros(2 * res.harmonics)
        for i in idx:
            p = res.params[i]
            coef[2 * (p.harmonic - 1) + (0 if p.trig == "sin" else 1)] = res.x[i]
        out[motion_name(axis, comp)] = fourier_rows(t, res.harmonics) @ coef
    return out


def rotary_positioning(runs: IndexerRuns) -> dict[str, Any] | None:
    """ISO 230-2 statistics of a rotary axis from indexer runs (urad), or None when the runs
    are not complete (every run visits every target from both sides)."""
    tg = np.unique(runs.target_deg)
    nr = int(runs.run.max())
    up = np.full((nr, tg.size), np.nan)
    down = np.full((nr, tg.size), np.nan)
    for r, d, t, v in zip(runs.run, runs.direction, runs.target_deg, runs.deviation_urad):
        (up if d > 0 else down)[int(r) - 1, int(np.searchsorted(tg, t))] = v
    if np.isnan(up).any() or np.isnan(down).any() or nr < 2:
        return None
    res = evaluate(PositioningData("indexer", tg, up, down))
    return {"standard": "ISO 230-2 applied to a rotary axis (values in urad, targets in deg)",
            "n_runs": nr, "n_targets": int(tg.size), "B_urad": res.B_um, "R_urad": res.R_um,
            "E_urad": res.E_um, "A_urad": res.A_um, "M_urad": res.M_um}


def turning_axis(b: Block, tilt: str) -> tuple[str, np.ndarray]:
    """The axis that turns in a rotary ballbar test (the one with the larger range) and its
    angles (deg)."""
    k = int(np.argmax(np.ptp(b.angles_deg, axis=0)))
    return (tilt if k == 0 else "C"), b.angles_deg[:, k]


def ballbar_curves(res: FitResult, spec: FiveAxisSpec) -> dict[str, dict[str, Any]]:
    """Per rotary ballbar test: the turning axis, its angles (deg), the measured length
    deviation (um, less its mean: the bar's zero is a set-up unknown) and what the
    identified model leaves of it (um)."""
    out: dict[str, dict[str, Any]] = {}
    x = res.x_solution if res.x_solution is not None else np.nan_to_num(res.x)
    for b in res.blocks:
        if b.kind != "ballbar":
            continue
        axis, ang = turning_axis(b, spec.geometry.tilt)
        left = residual_block(spec.geometry, res.params, x, res.harmonics, b)
        out[b.name] = {"axis": axis, "angle_deg": ang, "measured_um": b.obs - np.mean(b.obs),
                       "left_um": left - np.mean(left),
                       "length_mm": float(np.linalg.norm(b.tool_mm - b.sphere_mm))}  # type: ignore[operator]
    return out


def to_json(res: FitResult, spec: FiveAxisSpec, plan: PlanData) -> dict[str, Any]:
    """The identification as JSON (five_axis.json)."""
    g = spec.geometry
    tb = type_b(spec, plan.blocks, res.params, res)
    loc = {p.name: (_f(res.x[i]) if res.obs.observable[i] else None)
           for i, p in enumerate(res.params) if p.kind == "location"}
    motions: dict[str, Any] = {}
    for i, p in enumerate(res.params):
        if p.kind == "motion":
            m = motions.setdefault(motion_name(p.axis, p.comp),
                                   {"unit": p.unit, "period_deg": 360.0, "coef": {}})
            m["coef"][f"{p.trig}{p.harmonic}"] = _f(res.x[i]) if res.obs.observable[i] else None
    return {
        "format": "abbe-five-axis 1.0",
        "kinematics": g.kind,
        "geometry": {"rot_point_mm": list(g.rot_point_mm), "offset_mm": list(g.offset_mm),
                     "tool_length_mm": g.tool_length_mm,
                     "travel_deg": {k: list(v) for k, v in g.travel_deg.items()}},
        "table": {"location": loc, "location_units": {p.name: p.unit for p in res.params
                                                      if p.kind == "location"},
                  "squareness_urad": {p.name: (_f(res.x[i]) if res.obs.observable[i] else None)
                                      for i, p in enumerate(res.params) if p.kind == "squareness"},
                  "motions": motions,
                  "note": "null = not observable with this plan (never 0): see observability"},
        "parameters": param_rows(res, tb),
        "observability": {"rank": res.obs.rank, "n_params": res.obs.n_params,
                          "condition_number": _f(res.obs.condition),
                          "fixed_by_convention": [res.params[i].name for i in res.obs.fixed],
                          "confounded_groups": res.obs.groups},
        "correlations": correlations(res),
        "dispersion_um": {"before": _f(res.dispersion_before_um),
                          "after": _f(res.dispersion_after_um),
                          "heldout_before": _f(res.heldout_before_um),
                          "heldout_after": _f(res.heldout_after_um), "folds": spec.fit.folds},
        "block_sigma": {b.key: np.atleast_1d(b.sigma).astype(float).tolist() for b in res.blocks},
        "uncertainty": uncertainty_budget(res),
        "rejected_positions": [{"probing": n, "position": p, "radius_mm": r, "expected_mm": e}
                               for n, p, r, e in plan.rejected],
        "rotary_positioning": {ax: rotary_positioning(r) for ax, r in plan.indexer_raw.items()},
        "rotary_ballbar": {n: {"turning_axis": c["axis"], "length_mm": c["length_mm"],
                               "readings": int(c["angle_deg"].size),
                               "measured_pv_um": float(np.ptp(c["measured_um"])),
                               "left_pv_um": float(np.ptp(c["left_um"])),
                               "left_rms_um": float(np.sqrt(np.mean(c["left_um"] ** 2))),
                               "angle_deg": [float(v) for v in c["angle_deg"]],
                               "measured_um": [round(float(v), 4) for v in c["measured_um"]],
                               "left_um": [round(float(v), 4) for v in c["left_um"]]}
                           for n, c in ballbar_curves(res, spec).items()},
    }


def text_report(doc: dict[str, Any]) -> str:
    """The text report of a five_axis.json document."""
    out = [f"Five-axis identification ({doc['kinematics']}), ISO 230-7 notation",
           "", "Location errors and parameters (value +- U, k = 2; the budget: each data "
           "block's standard deviation, block_sigma):"]
    for r in doc["parameters"]:
        if r["observable"]:
            out.append(f"  {r['name']:<26} {r['value']:>11.3f} {r['unit']:<4} +- {r['U']:.3f}")
        else:
            conv = r.get("value_in_convention")
            ci = r.get("U_in_convention")
            how = (f"{conv:.3f} {r['unit']} in the convention"
                   + (f" +- {ci:.3f}" if ci is not None else "") if conv else
                   "fixed at 0 by convention" if r["fixed_by_convention"] else "no number")
            conf = ", ".join(r["confounded_with"]) or "-"
            out.append(f"  {r['name']:<26} NOT OBSERVABLE ({how}); confounded with {conf}; "
                       f"seen by: {r['seen_by']}")
    o = doc["observability"]
    out += ["", f"Observability: rank {o['rank']} of {o['n_params']}, condition number "
            f"{o['condition_number']:.3g}; fixed by convention: "
            f"{', '.join(o['fixed_by_convention']) or 'none'}"]
    if doc["correlations"]:
        out.append("Strong correlations: " + ", ".join(
            f"{c['a']} ~ {c['b']} ({c['r']:+.3f})" for c in doc["correlations"]))
    d = doc["dispersion_um"]
    if d["before"] is not None:
        out += ["", "Sphere-centre dispersion (RMS, um): before {:.3f}, after {:.3f}; held out "
                "({} folds): before {:.3f}, after {:.3f}".format(
                    d["before"], d["after"], d["folds"], d["heldout_before"] or float("nan"),
                    d["heldout_after"] or float("nan"))]
    blob = doc.get("blob") or {}
    if blob.get("convention"):
        cv = blob["convention"]
        out += ["", f"Table {blob['file']} (format {blob['format']}): {cv['statement']}.",
                f"  Workpiece datum: {cv['workpiece_datum']}."]
        rp = blob.get("repredicted")
        if rp:
            out.append(f"  The table re-predicts the probed centres ({rp['positions']} positions, "
                       f"{rp['evaluated_by']}): dispersion before {rp['before']:.3f} um, after "
                       f"{rp['after']:.3f} um (the fit's after: "
                       f"{d['after'] if d['after'] is not None else float('nan'):.3f} um)")
    for ax, rp in doc["rotary_positioning"].items():
        if rp:
            out.append(f"Angular positioning of {ax} (ISO 230-2, urad): A {rp['A_urad']:.2f}, "
                       f"E {rp['E_urad']:.2f}, R {rp['R_urad']:.2f}, B {rp['B_urad']:.2f}, "
                       f"M {rp['M_urad']:.2f}")
    for n, bb in doc.get("rotary_ballbar", {}).items():
        out.append(f"Rotary ballbar {n} ({bb['turning_axis']} turning, {bb['length_mm']:.1f} mm "
                   f"bar, {bb['readings']} readings): deviation {bb['measured_pv_um']:.2f} um "
                   f"peak-to-valley, {bb['left_pv_um']:.2f} um left by the identified model "
                   f"(RMS {bb['left_rms_um']:.2f} um)")
    for rj in doc["rejected_positions"]:
        out.append(f"Rejected probing {rj['probing']} position {rj['position']}: radius "
                   f"{rj['radius_mm']:.4f} mm, expected {rj['expected_mm']:.4f} mm")
    return "\n".join(out) + "\n"


def _polar(out: Path, png: str, title: str, curves: list[tuple[np.ndarray, np.ndarray, str]],
           size: float) -> str:
    """One polar plot of deviations (um / urad) about a base circle twice their largest
    magnitude: ``curves`` are (angle rad, value, label); writes ``out/png``."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(size, size))
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(projection="polar")
    scale = max(max(float(np.max(np.abs(v))) for _t, v, _l in curves), 1e-3)
    for t, v, label in curves:
        ax.plot(t, v + 2.0 * scale, ".-" if len(t) < 200 else "-", ms=2, label=label)
    ax.plot(np.linspace(0, 2 * np.pi, 181), np.full(181, 2.0 * scale), "k:", lw=0.6)
    ax.set_title(f"{title} (about a base circle of {2 * scale:.2g})", fontsize=8)
    ax.set_yticklabels([])
    ax.legend(fontsize=7, loc="lower left", bbox_to_anchor=(-0.15, -0.15))
    fig.savefig(out / png, dpi=90)
    return png


#: The one measurement that would see an error of each SEEN_BY kind (the report's short
#: table; the full alternatives are SEEN_BY's, in the folded parameter table).
ONE_MEASUREMENT = {
    "zero": "probe a datum feature at a known angle on the table (a workpiece datum)",
    "location": "probe the sphere at a second height on the table",
    "motion": "an R-test with spheres at two heights",
    "squareness": "a laser diagonal or ballbar circles of the linear axes (abbe fit)",
    "setup": "the sphere's position measured in a known frame",
}


def _seen_kind(r: dict[str, Any]) -> str:
    return _seen_key(r["name"], r["kind"]) if r["kind"] in ("location", "motion",
                                                            "squareness") else r["kind"]


def _motion_terms(names: list[str]) -> str:
    """'EXC(C) sin2', 'EXC(C) cos2', 'EZC(C) sin1' -> 'EXC(C) 2nd harmonic, EZC(C) 1st'."""
    by: dict[str, set[int]] = {}
    for n in names:
        base, _, term = n.partition(" ")
        digits = "".join(ch for ch in term if ch.isdigit())
        by.setdefault(base, set()).add(int(digits or 0))
    nth = {1: "1st", 2: "2nd", 3: "3rd"}
    return ", ".join(f"{b} {'/'.join(nth.get(h, f'{h}th') for h in sorted(hs))} harmonic"
                     for b, hs in by.items())


def unseen_rows(doc: dict[str, Any]) -> list[dict[str, Any]]:
    """What the plan could not see, one row per measurement that would see it: the
    machine errors (set-up unknowns apart), how model_five.bin holds them, the one
    measurement."""
    rows: dict[str, dict[str, Any]] = {}
    for r in doc["parameters"]:
        if r["observable"] or r["kind"] == "setup":
            continue
        k = _seen_kind(r)
        row = rows.setdefault(k, {"kind": k, "names": [], "fixed": [], "convention": [],
                                  "measurement": ONE_MEASUREMENT.get(k, r["seen_by"]),
                                  "alternatives": r["seen_by"]})
        row["names"].append(r["name"])
        (row["fixed"] if r["fixed_by_convention"] else row["convention"]).append(r["name"])
    return list(rows.values())


def _what(row: dict[str, Any]) -> str:
    names = row["names"]
    return (_motion_terms(names) if row["kind"] == "motion" else ", ".join(names))


def _held(row: dict[str, Any]) -> str:
    parts = []
    if row["fixed"]:
        parts.append(("0 by convention: " if row["convention"] else "0 by convention")
                     + (", ".join(row["fixed"]) if row["convention"] else ""))
    if row["convention"]:
        parts.append("their combination with the fixed ones" if row["fixed"] else
                     "their combination with the errors fixed by convention")
    return "; ".join(parts)


def _plan_text(doc: dict[str, Any]) -> str:
    kinds = {"probe": "sphere probing", "rtest": "R-test", "indexer": "rotary indexer",
             "ballbar": "rotary ballbar"}
    names = [k.split(".", 1) for k in doc.get("block_sigma", {})]
    return ", ".join(f"{kinds.get(a, a)} {b}" for a, b in names) or "-"


def write_html(res: FitResult, doc: dict[str, Any], out: Path) -> None:
    """report/index.html, verdict first: machine, plan, date; a band with the location
    errors identified (value and 95 % interval) and the sphere-centre dispersion; the
    error-motion polar plots; one short table of what the plan could not see with the
    one measurement that would see it; every parameter, the observability and the text
    report folded below."""
    import matplotlib
    matplotlib.use("Agg")

    from abbe.analysis.certificate import band, page_head, test_date

    out.mkdir(parents=True, exist_ok=True)
    imgs = []
    t = np.deg2rad(np.linspace(0.0, 360.0, 361))
    for axis in ("A", "B", "C"):
        curves = motion_curves(res, axis)
        if curves:
            imgs.append(_polar(out, f"motions_{axis}.png", f"Error motions of {axis}, um / urad",
                               [(t, np.r_[v, v[:1]], n) for n, v in curves.items()], 6.0))
    bb_imgs = [_polar(out, f"ballbar_{name}.png", f"Rotary ballbar {name}: "
                      f"{c['turning_axis']} turning, length deviation um",
                      [(np.deg2rad(c["angle_deg"]), np.asarray(c["measured_um"]), "measured"),
                       (np.deg2rad(c["angle_deg"]), np.asarray(c["left_um"]),
                        "left by the model")], 5.0)
               for name, c in doc.get("rotary_ballbar", {}).items()]
    e = html.escape
    loc = [r for r in doc["parameters"] if r["kind"] == "location"]
    seen = [r for r in loc if r["observable"]]
    unseen = unseen_rows(doc)
    n_unseen_loc = len(loc) - len(seen)
    status = "pass" if n_unseen_loc == 0 else "inconclusive"
    headline = (f"All {len(loc)} location errors identified" if n_unseen_loc == 0 else
                f"{len(seen)} of {len(loc)} location errors identified; {n_unseen_loc} not "
                "seen by this plan (the table below names the measurement that would see them)")
    lrows = "".join(
        f"<tr><td class='l'>{e(r['name'])}</td><td>{r['value']:.3f}</td>"
        f"<td>&plusmn; {r['U']:.3f}</td><td class='l'>{e(r['unit'])}</td></tr>" for r in seen)
    o, d = doc["observability"], doc["dispersion_um"]
    disp = "" if d["before"] is None else (
        f"<p>Sphere-centre dispersion (RMS): {d['before']:.2f} &rarr; {d['after']:.2f} um "
        f"fitted, {d['heldout_before']:.2f} &rarr; {d['heldout_after']:.2f} um held out "
        f"({d['folds']} folds).</p>")
    body = ("<table><tr><th class='l'>location error</th><th>value</th>"
            "<th>U (k = 2)</th><th class='l'>unit</th></tr>" + lrows + "</table>" + disp)
    prov = doc.get("provenance") or {}
    head = page_head(f"Five-axis identification: {doc.get('machine') or doc['kinematics']}", [
        ("Machine", f"{doc.get('machine') or 'not named'} ({doc['kinematics']}, "
                    "table-table five-axis)"),
        ("Test", f"{_plan_text(doc)} (ISO 230-7 / ISO 10791-6 notation)"),
        ("Date", test_date(prov["machine_file"]) if prov.get("machine_file") else "unknown"),
        ("Table", f"model_five.bin" + (f" (CRC {doc['blob']['crc32']})"
                                       if doc.get("blob") and doc["blob"].get("crc32") else ""))])
    urows = "".join(
        f"<tr><td class='l'>{e(_what(r))}</td><td class='l'>{e(_held(r))}</td>"
        f"<td class='l'><b>{e(r['measurement'])}</b></td></tr>" for r in unseen)
    unseen_html = ("<h2>What this plan could not see</h2><table><tr><th class='l'>errors not "
                   "seen</th><th class='l'>held in model_five.bin as</th><th class='l'>the "
                   "measurement that would see them</th></tr>" + urows + "</table>"
                   "<p class='small'>Set-up unknowns the plan cannot place (sphere positions "
                   "across the axis) are not machine errors: they are in the folded table."
                   "</p>") if unseen else "<p>The plan sees every error it models.</p>"
    prow = []
    for r in doc["parameters"]:
        if r["observable"]:
            cell = f"{r['value']:.3f} &plusmn; {r['U']:.3f} {e(r['unit'])} (U, k = 2)"
            why = ""
        else:
            cell = "not observable" + (" (0 by convention)" if r["fixed_by_convention"] else "")
            why = (f"confounded with {e(', '.join(r['confounded_with']) or '-')}; seen by: "
                   f"{e(r['seen_by'])}")
        prow.append(f"<tr><td class='l'>{e(r['name'])}</td><td class='l'>{e(r['kind'])}</td>"
                    f"<td class='l'>{cell}</td><td class='l small'>{why}</td></tr>")
    page = "\n".join(head) + "\n" + band(status, headline, body) + (
        "<div class='plots'>" + "".join(f"<img src='{p}' alt='{p}'>" for p in imgs + bb_imgs)
        + "</div>" if imgs or bb_imgs else
        "<p>No error motion identified by this plan ([rotary.fit] harmonics = 0 or "
        "not observable).</p>") + unseen_html + (
        "<h2>Details</h2>"
        f"<details><summary>Every parameter ({len(doc['parameters'])}), with what it is "
        "confounded with</summary><table><tr><th class='l'>parameter</th><th class='l'>kind"
        "</th><th class='l'>value value (95 %)plusmn; U (k = 2)</th><th class='l'>why no number</th></tr>"
        + "".join(prow) + "</table></details>"
        f"<details><summary>Observability</summary><p>rank {o['rank']} of {o['n_params']}, "
        f"condition number {o['condition_number']:.3g}; fixed by convention: "
        f"{e(', '.join(o['fixed_by_convention']) or 'none')}</p></details>"
        f"<details><summary>Text report</summary><pre>{e(text_report(doc))}</pre></details>"
        "</body></html>\n")
    (out / "index.html").write_text(page, encoding="utf-8")
