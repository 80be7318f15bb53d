"""The thermal discrepancy workflow (docs/thermal.md, "Diagnosis"; linked from
``abbe diagnose``): on a thermal record, today's one-coefficient thermal term leaves a gap;
name the missing thermal effect (which channel, which input: a temperature or the spindle
speed, its lag), add it, and show the gap shrink on hours it never saw.

Today's term (the table's per-axis expansion from one temperature) is, per channel, one
static gain on one temperature's rise: the best single sensor on the identification hours.
For every channel the diagnosis searches one added lagged term (every input x the time
constant grid) by leave-one-cycle-out cross-validation inside the identification hours
(:func:`abbe.analysis.thermal.identify.select_terms` with the static term given), refines
it by nonlinear least squares with its 95 % intervals, and scores both models on the
held-out hours. An effect is named when the cross-validated RMS drops by at least
:data:`MIN_DROP` (a fraction); the held-out hours only report, they never choose.

Never imports :mod:`abbe.sim` (the import contract).
"""

from __future__ import annotations

import numpy as np

from abbe.analysis.thermal.identify import (candidates_of, cycles_of, refine, select_terms,
                                            TAU_GRID_S)
from abbe.formats.thermal_machine import ThermalSpec
from abbe.formats.thermal_record import ThermalRecord
from abbe.model.thermal import lag_states

#: A named effect must lower the cross-validated RMS by at least this fraction.
MIN_DROP = 0.15


def _rms(v: np.ndarray) -> float:
    return float(np.sqrt(np.mean(v ** 2)))


def diagnose_thermal(rec: ThermalRecord, spec: ThermalSpec) -> dict:
    """The diagnosis as plain data (``text``: what is said; ``channels``: the figures)."""
    h = rec.hours
    t = rec.time_s
    ident = (h >= spec.identify_hours[0]) & (h < spec.identify_hours[1])
    valid = (h >= spec.validate_hours[0]) & (h <= spec.validate_hours[1])
    cands = candidates_of(rec.temps_c, list(rec.temp_names), rec.speed_rpm)
    cyc = cycles_of(t, ident, spec.cycle_hours * 3600.0)
    n_temp = len(rec.temp_names)
    out = []
    series: dict[str, dict[str, np.ndarray]] = {}
    lines = [f"abbe thermal diagnose: {rec.file}", f"  today's term: one static gain on one "
             f"temperature per channel; identification hours {spec.identify_hours[0]:g}-"
             f"{spec.identify_hours[1]:g}, held-out hours {spec.validate_hours[0]:g}-"
             f"{spec.validate_hours[1]:g}"]
    for k, name in enumerate(rec.channel_names):
        y = rec.disp_um[:, k] - rec.disp_um[0, k]
        # today's term: the best single temperature, static (and the sensor's zero), least
        # squares on the identification hours
        best = None
        for i in range(n_temp):
            a = np.column_stack([np.ones(int(ident.sum())), cands[i].rise[ident]])
            g = np.linalg.lstsq(a, y[ident], rcond=None)[0]
            r = _rms(y[ident] - a @ g)
            if best is None or r < best[1]:
                best = (i, r)
        base = [(best[0], 0.0)]
        chosen, trace = select_terms(t, y, cands, cyc, max_terms=2, start=base,
                                     min_gain=MIN_DROP, grid=TAU_GRID_S)
        terms_b, _, _, _, off_b = refine(t, y, cands, base, ident)
        pred_b = off_b + terms_b[0].gain * cands[base[0][0]].rise
        series[name] = {"measured": y, "before": y - pred_b}
        row = {"channel": name, "baseline_input": cands[base[0][0]].name,
               "baseline_gain": terms_b[0].gain,
               "gap_ident_um": _rms((y - pred_b)[ident]), "gap_heldout_um": _rms((y - pred_b)[valid]),
               "uncompensated_heldout_um": _rms(y[valid]), "named": None}
        if len(chosen) == 2:
            terms, _, _, _, off = refine(t, y, cands, chosen, ident)
            pred = off + sum(tt.gain * lag_states(cands[tt.input].rise, t, tt.tau_s) for tt in terms)
            add = terms[1]
            row["named"] = {"input": cands[add.input].name, "kind": cands[add.input].kind,
                            "tau_s": add.tau_s, "tau_u95_s": add.tau_u95_s, "gain": add.gain,
                            "gain_u95": add.gain_u95, "cv_rms_before_um": None,
                            "cv_rms_after_um": trace[-1][2]}
            series[name]["after"] = y - pred
            row["after_ident_um"] = _rms((y - pred)[ident])
            row["after_heldout_um"] = _rms((y - pred)[valid])
        out.append(row)
        if row["named"]:
            n = row["named"]
            unit = "um/krpm" if n["kind"] == "speed" else "um/K"
            tau_u = f" +/- {n['tau_u95_s'] / 60:.1f}" if n["tau_u95_s"] is not None else ""
            lines.append(
                f"  {name}: missing thermal effect: {n['input']} through a lag of "
                f"{n['tau_s'] / 60:.1f}{tau_u} min, gain {n['gain']:.3f} +/- "
                f"{(n['gain_u95'] or float('nan')):.3f} {unit} (today's term: "
                f"{row['baseline_input']} static); held-out gap {row['gap_heldout_um']:.2f} -> "
                f"{row['after_heldout_um']:.2f} um (uncompensated "
                f"{row['uncompensated_heldout_um']:.2f})")
        else:
            lines.append(f"  {name}: no lagged effect lowers the cross-validated gap by "
                         f"{100 * MIN_DROP:.0f} %; held-out gap {row['gap_heldout_um']:.2f} um "
                         f"(today's term on {row['baseline_input']})")
    return {"record": rec.file, "identify_hours": list(spec.identify_hours),
            "validate_hours": list(spec.validate_hours), "channels": out,
            "text": "\n".join(lines), "_series": series}


def write_thermal_report(diag: dict, rec: ThermalRecord, spec: ThermalSpec, out,
                         machine: str | None = None) -> None:
    """``out/index.html`` (+ ``gaps.png``), verdict first: machine, record, date, then a
    band with one row per channel (today's term, the named effect, the held-out gap before
    and after), the gap plot, the full text folded."""
    import html

    import matplotlib
    matplotlib.use("Agg")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    series = diag["_series"]
    h = rec.hours
    fig = Figure(figsize=(11, 2.2 * len(series) + 0.6), dpi=100)
    FigureCanvasAgg(fig)
    for k, (name, s) in enumerate(series.items()):
        ax = fig.add_subplot(len(series), 1, k + 1)
        ax.axvspan(*spec.validate_hours, color="tab:orange", alpha=0.08)
        ax.plot(h, s["measured"], color="0.6", lw=0.8, label="measured drift")
        ax.plot(h, s["before"], color="tab:red", lw=1.0, label="gap: today's static term")
        if "after" in s:
            ax.plot(h, s["after"], color="tab:green", lw=1.0, label="gap: with the named effect")
        ax.set_ylabel(f"{name} (um)")
        ax.grid(alpha=0.3)
    from matplotlib.lines import Line2D
    fig.legend([Line2D([], [], color=c) for c in ("0.6", "tab:red", "tab:green")],
               ["measured drift", "gap: today's static term", "gap: with the named effect"],
               loc="upper center", ncol=3, fontsize=8)
    ax.set_xlabel("time (h); orange: held-out hours")
    fig.tight_layout(rect=(0, 0, 1, 0.97))
    fig.savefig(out / "gaps.png")
    from pathlib import Path

    from abbe.analysis.certificate import band, page_head, test_date
    e = html.escape
    rows = []
    for ch in diag["channels"]:
        n = ch.get("named")
        what = ("nothing named" if not n else
                f"{e(str(n['input']))} through a lag of {n['tau_s'] / 60:.0f} "
                f"&plusmn; {(n.get('tau_u95_s') or float('nan')) / 60:.0f} min")
        after = ch.get("after_heldout_um")
        rows.append(f"<tr><td class='l'>{e(ch['channel'])}</td>"
                    f"<td class='l'>{e(str(ch['baseline_input']))} static</td>"
                    f"<td class='l'>{what}</td><td>{ch['gap_heldout_um']:.2f}</td>"
                    f"<td>{'&ndash;' if after is None else f'{after:.2f}'}</td>"
                    f"<td>{ch['uncompensated_heldout_um']:.2f}</td></tr>")
    named = sum(1 for ch in diag["channels"] if ch.get("named"))
    head = page_head(f"Thermal diagnosis: {Path(rec.file).name}", [
        ("Machine", machine or "not named"),
        ("Test", f"ISO 230-3 thermal record, identified on {spec.identify_hours[0]:g}-"
                 f"{spec.identify_hours[1]:g} h, judged on {spec.validate_hours[0]:g}-"
                 f"{spec.validate_hours[1]:g} h"),
        ("Date", test_date(rec.file))])
    body = ("<table><tr><th class='l'>channel</th><th class='l'>today's term</th>"
            "<th class='l'>missing effect named</th><th>held-out gap before (um)</th>"
            "<th>after (um)</th><th>uncompensated (um)</th></tr>" + "".join(rows)
            + "</table>")
    page = ("\n".join(head)
            + band("info", f"A missing thermal effect named on {named} of "
                   f"{len(diag['channels'])} channels", body)
            + "<div class='plots'><img class='wide' src='gaps.png' alt='gaps'></div>"
            "<details><summary>The diagnosis in words (intervals, what was tried)</summary>"
            "<pre style='white-space:pre-wrap'>" + e(diag["text"]) + "</pre></details>"
            "</body></html>")
    (out / "index.html").write_text(page, encoding="utf-8")
