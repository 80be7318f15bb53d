"""The thermal report: plots a person reads first (model vs measured vs compensated on the
held-out hours), numbers after (the per-channel table, the terms and their intervals, the
selection, the ISO 230-3 drift figures). Static HTML + PNG (matplotlib, Agg)."""

from __future__ import annotations

import html
from pathlib import Path

import numpy as np

from abbe.analysis.thermal.pipeline import TARGET_RATIO, FitResult


def _esc(x: object) -> str:
    return html.escape(str(x))


def _fig(w: float, h: float):
    import matplotlib
    matplotlib.use("Agg")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(w, h), dpi=100)
    FigureCanvasAgg(fig)
    return fig


def _windows(ax, res: FitResult) -> None:
    a, b = res.spec.identify_hours
    c, d = res.spec.validate_hours
    ax.axvspan(a, b, color="tab:blue", alpha=0.06)
    ax.axvspan(c, d, color="tab:orange", alpha=0.08)


def plot_signals(res: FitResult, path: Path) -> None:
    sigs = res.channels + [s for s in res.outputs if s.unit == "urad"]
    h = res.record.hours
    fig = _fig(11, 2.3 * len(sigs) + 0.6)
    for k, s in enumerate(sigs):
        ax = fig.add_subplot(len(sigs), 1, k + 1)
        _windows(ax, res)
        ax.plot(h, s.measured, color="0.25", lw=1.0, label="measured")
        ax.plot(h, s.predicted, color="tab:blue", lw=1.0, label="model")
        ax.plot(h, s.measured - s.predicted, color="tab:green", lw=1.0, label="compensated")
        ax.plot(h, s.measured - s.mlr, color="tab:red", lw=0.7, alpha=0.6,
                label="compensated by MLR (16 T)")
        ax.set_ylabel(f"{s.name} ({s.unit})")
        ax.set_title(f"{s.name}: held-out RMS {s.rms_uncomp:.1f} -> model {s.rms_comp:.1f} "
                     f"({100 * s.ratio:.0f} %), MLR {s.rms_mlr:.1f} {s.unit}", fontsize=9, loc="left")
        ax.grid(alpha=0.3)
        if k == 0:
            ax.legend(fontsize=7, ncol=4, loc="upper left")
    ax.set_xlabel("time (h); blue band: identification hours, orange: held-out hours")
    fig.tight_layout()
    fig.savefig(path)


def plot_inputs(res: FitResult, path: Path) -> None:
    rec = res.record
    h = rec.hours
    fig = _fig(11, 4.2)
    ax = fig.add_subplot(2, 1, 1)
    _windows(ax, res)
    if rec.speed_rpm is not None:
        ax.plot(h, rec.speed_rpm, color="k", lw=1)
    ax.set_ylabel("spindle (rpm)")
    ax.grid(alpha=0.3)
    ax2 = fig.add_subplot(2, 1, 2, sharex=ax)
    _windows(ax2, res)
    for k, n in enumerate(rec.temp_names):
        ax2.plot(h, rec.temps_c[:, k] - rec.temps_c[0, k], lw=0.8, label=n)
    ax2.set_ylabel("temperature rise (K)")
    ax2.set_xlabel("time (h)")
    ax2.legend(fontsize=6, ncol=8, loc="upper left")
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)


def plot_bars(res: FitResult, path: Path) -> None:
    sigs = res.channels
    fig = _fig(8, 3.2)
    ax = fig.add_subplot(111)
    x = np.arange(len(sigs))
    ax.bar(x - 0.27, [s.rms_uncomp for s in sigs], 0.27, color="0.6", label="uncompensated")
    ax.bar(x, [s.rms_mlr for s in sigs], 0.27, color="tab:red", label="MLR on 16 T")
    ax.bar(x + 0.27, [s.rms_comp for s in sigs], 0.27, color="tab:green", label="model")
    ax.scatter(x, [TARGET_RATIO * s.rms_uncomp for s in sigs], marker="_", s=900, color="k",
               label=f"target ({100 * TARGET_RATIO:.0f} % of uncompensated)", zorder=5)
    ax.set_xticks(x, [s.name for s in sigs])
    ax.set_ylabel("RMS on held-out hours (um)")
    ax.legend(fontsize=7)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)


def _tau(tau: float, u95: float | None) -> str:
    """A time constant and its interval; "not bounded" when the data do not pin it (an
    interval wider than five times the value)."""
    if tau == 0.0:
        return "static"
    if u95 is None or u95 > 5.0 * tau:
        return f"{tau:.0f} (not bounded by the data)"
    return f"{tau:.0f} &plusmn; {u95:.0f}"


def _f(v: float | None, nd: int = 2) -> str:
    return "-" if v is None or not np.isfinite(v) else f"{v:.{nd}f}"


def _fU(U: float | None) -> str:
    """An expanded uncertainty: two significant digits below 0.1 (0.004 printed as 0.00
    would read as none), two decimals above."""
    if U is None or not np.isfinite(U):
        return "-"
    return f"{U:.2f}" if U >= 0.1 else f"{U:.2g}"


def _record_date(path: str) -> str:
    from abbe.analysis.certificate import test_date
    return test_date(path)


def write_report(res: FitResult, iso: dict, out: Path, diagnosis: dict | None = None,
                 machine: str | None = None, uncertainty: dict | None = None) -> None:
    """``out/index.html`` and its figures: machine, test, date and the verdict band (does
    the model meet its target on every held-out signal) first, with the bar chart; the
    signals, terms, selection and ISO 230-3 figures after, folded."""
    from abbe.analysis.certificate import band, page_head
    plot_signals(res, out / "signals.png")
    plot_bars(res, out / "rms.png")
    plot_inputs(res, out / "inputs.png")
    rec = res.record
    sigs = res.channels + [s for s in res.outputs if s.unit == "urad"]
    unc = {u["name"]: u for u in (uncertainty or {}).get("signals", [])}
    rows = []
    for s in sigs:
        ok = "yes" if s.meets else "no"
        rms_u = unc.get(s.name, {}).get("heldout_rms")
        rows.append(f"<tr><td class='l'>{_esc(s.name)}</td><td>{s.unit}</td><td>{_f(s.rms_uncomp)}</td>"
                    f"<td>{_f(s.rms_mlr)} ({100 * s.rms_mlr / s.rms_uncomp:.0f} %)</td>"
                    f"<td>{_f(s.rms_comp)}"
                    + (f" &plusmn; {_fU(rms_u['U_stated'])}" if rms_u else "")
                    + f" ({100 * s.ratio:.0f} %)</td>"
                    f"<td>{_f(s.rms_comp_ident)}</td><td class='l {'pass' if s.meets else 'fail'}'>"
                    f"{ok}</td></tr>")
    terms = []
    for s in sigs:
        for t in s.fit.terms:
            terms.append(f"<tr><td class='l'>{_esc(s.name)}</td><td class='l'>{_esc(res.input_names[t.input])}</td>"
                         f"<td>{_tau(t.tau_s, t.tau_u95_s)}</td>"
                         f"<td>{_f(t.gain, 3)} &plusmn; {_f(t.gain_u95, 3)}</td></tr>")
    sel = []
    for s in res.channels:
        own = s.direct if s.direct is not None else s.fit  # a composed channel: its own run
        for st in own.steps:
            inputs = {"heated": "heated inputs",
                      "heated+room": "heated inputs, then a room sensor"}.get(
                          own.input_set, "all inputs")
            if s.composed:
                inputs += (f"; not used: {s.composed[0]} + {s.composed[2]:g} x "
                           f"{s.composed[1]} won")
            sel.append(f"<tr><td class='l'>{_esc(s.name)} ({inputs})</td><td class='l'>{_esc(st[0])}</td><td>{st[1]:.0f}</td>"
                       f"<td>{st[2]:.2f}</td><td>{st[3]:.1f}</td>"
                       f"<td class='l'>{_esc(', '.join(st[4]) or '-')}</td></tr>")
    drift = _drift_rows(iso)
    diag = ""
    if diagnosis:
        diag = ("<h2>Diagnosis: the thermal effect the static model misses</h2><pre>"
                + _esc(diagnosis.get("text", "")) + "</pre>")
    notes = "".join(f"<li>{_esc(n)}</li>" for n in res.notes)
    missed = [s.name for s in sigs if not s.meets]
    status = "fail" if missed else "pass"
    va, vb = res.spec.validate_hours
    headline = (f"The model meets its target on all {len(sigs)} signals of the held-out hours "
                f"{va:g}-{vb:g} h" if not missed else
                f"The model misses its target on {', '.join(_esc(m) for m in missed)} "
                f"({len(sigs) - len(missed)} of {len(sigs)} signals met, held-out hours "
                f"{va:g}-{vb:g} h)")
    body = ("<table><tr><th class='l'>signal</th><th>unit</th><th>uncompensated</th>"
            "<th>MLR</th><th>model</th><th>model, identification hours</th>"
            f"<th class='l'>meets target</th></tr>{''.join(rows)}</table>"
            f"<p class='small'>RMS of the displacement from its start (uncompensated), of what "
            f"is left after the static multi-linear regression on all {len(rec.temp_names)} "
            f"temperatures (MLR, trained on the same identification hours) and after the "
            f"dynamic model. Target: model &le; {100 * TARGET_RATIO:.0f} % of uncompensated "
            f"and below MLR."
            + (" The model's figure &plusmn; U (k = 2: the identification's residuals and "
               "the sensors' calibration, docs/uncertainty.md)." if unc else "")
            + "</p>")
    head = page_head(f"Thermal model: {Path(rec.file).name}", [
        ("Machine", machine or "not named"),
        ("Test", f"ISO 230-3 thermal record, {iso['duration_h']:.1f} h, {iso['samples']} "
                 f"samples, {len(rec.temp_names)} temperatures, {len(rec.channel_names)} "
                 "displacement channels"),
        ("Date", _record_date(rec.file)),
        ("Model", f"dynamic (first-order lags), identified on {res.spec.identify_hours[0]:g}-"
                  f"{res.spec.identify_hours[1]:g} h, judged on {va:g}-{vb:g} h")])
    page = "\n".join(head) + f"""
{band(status, headline, body)}
<div class="plots"><img src="rms.png" alt="rms"></div>
<ul>{notes}</ul>
<h2>Details</h2>
<details><summary>Measured, model and compensated per signal (held-out hours in orange)</summary>
<img class="wide" src="signals.png" alt="signals"></details>
<details><summary>Terms (95 % intervals from the Jacobian, serial correlation accounted)</summary>
<table><tr><th class='l'>signal</th><th class='l'>input</th><th>tau (s)</th><th>gain (um or urad per K / krpm)</th></tr>
{''.join(terms)}</table></details>
{_budget_fold(unc)}
<details><summary>Selection (forward, leave-one-cycle-out CV inside the identification hours; per channel on all inputs or on the speed and the sensors the spindle heats, whichever cross-validates better)</summary>
<table><tr><th class='l'>channel</th><th class='l'>added</th><th>tau, refined (s)</th><th>CV RMS (um)</th>
<th>max VIF</th><th class='l'>rivals within 10 % (not decided by the data)</th></tr>
{''.join(sel)}</table></details>
{diag}
<details><summary>ISO 230-3 evaluation of the whole record</summary>
<table><tr><th class='l'>signal</th><th>unit</th><th>range</th><th>U, k = 2</th><th>max</th><th>min</th><th>end</th></tr>
{drift}</table>
<p>Envelope: {_esc(iso['envelope']['channel'])}, {iso['envelope']['range_um']:.1f} um.</p></details>
<details><summary>Inputs (spindle speed, temperature rises)</summary>
<img class="wide" src="inputs.png" alt="inputs"></details>
</body></html>"""
    (out / "index.html").write_text(page, encoding="utf-8")


def _budget_fold(unc: dict) -> str:
    """The uncertainty budget of each signal's largest predicted drift and held-out RMS."""
    if not unc:
        return ""
    rows = []
    for name, u in unc.items():
        for key, what in (("drift", "largest predicted drift"), ("heldout_rms", "held-out RMS")):
            d = u.get(key)
            if not d:
                continue
            parts = "; ".join(f"{_esc(c['name'])} {c['u']:.3f}" for c in d.get("budget", []))
            mc = (f"{d['U_mc']:.2f}" if "U_mc" in d else "&ndash;")
            rows.append(f"<tr><td class='l'>{_esc(name)}</td><td class='l'>{what}</td>"
                        f"<td>{d['value']:.2f}</td><td>{d.get('U_first_order', d['U']):.2f}</td>"
                        f"<td>{d['U']:.2f}</td><td>{mc}</td>"
                        f"<td>{d['U_stated']:.2f}</td><td class='l'>{parts}</td></tr>")
    return ("<details><summary>Uncertainty budget (U, k = 2; first order, cubature and Monte "
            "Carlo)"
            "</summary><table><tr><th class='l'>signal</th><th class='l'>figure</th>"
            "<th>value</th><th>U first order</th><th>U cubature</th><th>U Monte Carlo</th>"
            "<th>U stated</th>"
            "<th class='l'>standard uncertainties u (um or urad)</th></tr>"
            + "".join(rows) + "</table><p class='small'>The analytic U is the degree-5 "
            "cubature of the parameters' distribution (deterministic sigma points; the budget "
            "lines are first order). Where it and the Monte Carlo differ by more than 10 % the "
            "Monte Carlo's U is stated (GUM S1): a held-out RMS near its minimum in the "
            "parameters is not near a quadratic over their interval.</p></details>")


def _U_cell(d: dict) -> str:
    """A range's U (k = 2), or a dash where none was evaluated."""
    return f"<td>{_fU(d['U'])}</td>" if d.get("U") is not None else "<td>&ndash;</td>"


def _drift_rows(iso: dict) -> str:
    return "".join(f"<tr><td class='l'>{_esc(d['name'])}</td><td>{d['unit']}</td><td>{d['range']:.1f}</td>"
                   + _U_cell(d) +
                   f"<td>{d['max']:.1f} @ {d['max_h']:.1f} h</td>"
                   f"<td>{d['min']:.1f} @ {d['min_h']:.1f} h</td><td>{d['final']:.1f}</td></tr>"
                   for d in iso["channels"] + iso["tilts"])


def _range_budget(doc: dict) -> str:
    """The ranges' budget, folded: each sensor's calibration and noise, and per range its
    standard uncertainty lines, first-order and Monte Carlo U."""
    unc = doc.get("uncertainty")
    if not unc:
        return ""
    sens = "".join(f"<tr><td class='l'>{_esc(n)}</td><td class='l'>{_esc(v['sensitivity'])}</td>"
                   f"<td>{v['noise_sd']:.4f} {v['unit']}</td></tr>"
                   for n, v in unc["sensors"].items())
    rows = "".join(
        f"<tr><td class='l'>{_esc(d['name'])}</td><td class='l'>"
        + ", ".join(f"{_esc(k)} {v:.3g}" for k, v in d["budget_u"].items())
        + f"</td><td>{d['U_first_order']:.3g}</td><td>"
        + (f"{d['U_mc']:.3g}" if d.get("U_mc") is not None else "&ndash;")
        + f"</td><td class='l'>{_esc(d['U_from'])}</td></tr>"
        for d in doc["channels"] + doc["tilts"] + doc["temperatures"])
    return ("<details><summary>Uncertainty budget (GUM; the sensors, then each range's "
            "standard uncertainty lines)</summary>"
            "<table><tr><th class='l'>sensor</th><th class='l'>sensitivity</th>"
            f"<th>reading noise (1 sd)</th></tr>{sens}</table>"
            "<table><tr><th class='l'>range</th><th class='l'>u per input</th><th>U first order"
            f"</th><th>U Monte Carlo</th><th class='l'>stated</th></tr>{rows}</table>"
            f"<p class='small'>{_esc(unc['method'])}. Not included: "
            f"{_esc(unc['not_included'])}.</p></details>")


def plot_record(rec, path: Path) -> None:
    """The record at a glance: displacement channels from their start (um) over time, the
    spindle speed above."""
    h = rec.hours
    fig = _fig(11, 4.6)
    ax0 = fig.add_subplot(3, 1, 1)
    if rec.speed_rpm is not None:
        ax0.plot(h, rec.speed_rpm, color="k", lw=1)
    ax0.set_ylabel("spindle (rpm)")
    ax0.grid(alpha=0.3)
    ax = fig.add_subplot(3, 1, (2, 3), sharex=ax0)
    for k, n in enumerate(rec.channel_names):
        ax.plot(h, rec.disp_um[:, k] - rec.disp_um[0, k], lw=1.0, label=n)
    ax.set_ylabel("displacement from start (um)")
    ax.set_xlabel("time (h)")
    ax.legend(fontsize=7, ncol=8, loc="upper left")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)


def write_record_report(doc: dict, rec, out: Path) -> None:
    """``out/report.html`` (+ ``drift.png``) of ``abbe thermal evaluate -o``: machine, test,
    date, the headline figures (envelope, largest drift and tilt) in the band, the record
    plot, then the ISO 230-3 table. No tolerance applies (the band says so)."""
    from abbe.analysis.certificate import band, page_head
    plot_record(rec, out / "drift.png")
    env = doc["envelope"]
    tilts = sorted(doc["tilts"], key=lambda d: -d["range"])
    pm = (lambda d: f" &plusmn; {_fU(d['U'])}" if d.get("U") is not None else "")
    env_U = f" &plusmn; {_fU(env['U_um'])}" if env.get("U_um") is not None else ""
    headline = (f"Thermal drift envelope {env['range_um']:.1f}{env_U} um "
                f"({_esc(env['channel'])}) over {doc['duration_h']:.1f} h"
                + (" (U, k = 2)" if env_U else ""))
    unc = doc.get("uncertainty") or {}
    mc = unc.get("monte_carlo") or {}
    body = ("<p>" + ", ".join(f"{_esc(d['name'])} {d['range']:.1f}{pm(d)} {d['unit']}"
                              for d in doc["channels"])
            + (f"; the largest tilt: {_esc(tilts[0]['name'])} {tilts[0]['range']:.1f}"
               f"{pm(tilts[0])} urad" if tilts else "")
            + "</p><p class='small'>Range of each channel from its start (ISO 230-3). "
            + ("U (k = 2): each sensor's calibration and reading noise"
               + (f", checked by a {mc['draws']}-draw Monte Carlo ({mc['agree']} of {mc['of']} "
                  "within 10 %)" if mc.get("draws") else "") + "; budget below. " if unc else "")
            + "No tolerance stated: no verdict.</p>")
    head = page_head(f"ISO 230-3 thermal test: {Path(rec.file).name}", [
        ("Machine", doc.get("machine") or "not named"),
        ("Test", f"ISO 230-3 thermal drift record, {doc['duration_h']:.1f} h, {doc['samples']} "
                 f"samples, {len(rec.temp_names)} temperatures, {len(rec.channel_names)} "
                 "displacement channels"),
        ("Date", _record_date(rec.file)), ("File", Path(rec.file).name)])
    temps = "".join(f"<tr><td class='l'>{_esc(d['name'])}</td><td>{d['range']:.2f}</td>"
                    f"<td>{d['max']:.2f} @ {d['max_h']:.1f} h</td><td>{d['final']:.2f}</td></tr>"
                    for d in doc["temperatures"])
    page = "\n".join(head) + f"""
{band("info", headline, body)}
<div class="plots"><img class="wide" src="drift.png" alt="drift"></div>
<h2>Drift per channel and tilt</h2>
<table><tr><th class='l'>signal</th><th>unit</th><th>range</th><th>U, k = 2</th><th>max</th><th>min</th><th>end</th></tr>
{_drift_rows(doc)}</table>
{_range_budget(doc)}
<details><summary>Temperature rises (K)</summary>
<table><tr><th class='l'>sensor</th><th>range</th><th>max</th><th>end</th></tr>{temps}</table>
</details>
<p class='small'>abbe thermal evaluate; docs/thermal.md.</p>
</body></html>"""
    (out / "report.html").write_text(page, encoding="utf-8")
