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


def write_report(res: FitResult, iso: dict, out: Path, diagnosis: dict | None = None) -> None:
    """``out/index.html`` and its figures."""
    plot_signals(res, out / "signals.png")
    plot_bars(res, out / "rms.png")
    plot_inputs(res, out / "inputs.png")
    rec = res.record
    rows = []
    for s in res.channels + [s for s in res.outputs if s.unit == "urad"]:
        ok = "yes" if s.meets else "no"
        rows.append(f"<tr><td>{_esc(s.name)}</td><td>{s.unit}</td><td>{_f(s.rms_uncomp)}</td>"
                    f"<td>{_f(s.rms_mlr)} ({100 * s.rms_mlr / s.rms_uncomp:.0f} %)</td>"
                    f"<td>{_f(s.rms_comp)} ({100 * s.ratio:.0f} %)</td>"
                    f"<td>{_f(s.rms_comp_ident)}</td><td>{ok}</td></tr>")
    terms = []
    for s in res.channels + [o for o in res.outputs if o.unit == "urad"]:
        for t in s.fit.terms:
            terms.append(f"<tr><td>{_esc(s.name)}</td><td>{_esc(res.input_names[t.input])}</td>"
                         f"<td>{_tau(t.tau_s, t.tau_u95_s)}</td>"
                         f"<td>{_f(t.gain, 3)} &plusmn; {_f(t.gain_u95, 3)}</td></tr>")
    sel = []
    for s in res.channels:
        for st in s.fit.steps:
            sel.append(f"<tr><td>{_esc(s.name)}</td><td>{_esc(st[0])}</td><td>{st[1]:.0f}</td>"
                       f"<td>{st[2]:.2f}</td><td>{st[3]:.1f}</td>"
                       f"<td>{_esc(', '.join(st[4]) or '-')}</td></tr>")
    drift = "".join(f"<tr><td>{_esc(d['name'])}</td><td>{d['unit']}</td><td>{d['range']:.1f}</td>"
                    f"<td>{d['max']:.1f} @ {d['max_h']:.1f} h</td>"
                    f"<td>{d['min']:.1f} @ {d['min_h']:.1f} h</td><td>{d['final']:.1f}</td></tr>"
                    for d in iso["channels"] + iso["tilts"])
    diag = ""
    if diagnosis:
        diag = ("<h2>Diagnosis: the thermal effect the static model misses</h2><pre>"
                + _esc(diagnosis.get("text", "")) + "</pre>")
    notes = "".join(f"<li>{_esc(n)}</li>" for n in res.notes)
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>abbe thermal</title>
<style>body{{font-family:sans-serif;max-width:1150px;margin:1em auto}}
table{{border-collapse:collapse;font-size:13px}}td,th{{border:1px solid #ccc;padding:2px 6px;
text-align:right}}td:first-child{{text-align:left}}img{{max-width:100%}}</style></head><body>
<h1>Thermal model of {_esc(Path(rec.file).name)}</h1>
<ul>{notes}</ul>
<h2>Measured, model and compensated (held-out hours in orange)</h2>
<img src="signals.png" alt="signals">
<h2>RMS on the held-out hours</h2><img src="rms.png" alt="rms">
<h2>Numbers: held-out hours {res.spec.validate_hours[0]:g}-{res.spec.validate_hours[1]:g}</h2>
<p>RMS of the displacement from its start (uncompensated), of what is left after the static
multi-linear regression on all {len(rec.temp_names)} temperatures (MLR, trained on the same
identification hours) and after the dynamic model. Target: model &le; {100 * TARGET_RATIO:.0f} %
of uncompensated and below MLR.</p>
<table><tr><th>signal</th><th>unit</th><th>uncompensated</th><th>MLR</th><th>model</th>
<th>model, identification hours</th><th>meets target</th></tr>{''.join(rows)}</table>
<h2>Terms (95 % intervals from the Jacobian, serial correlation accounted)</h2>
<table><tr><th>signal</th><th>input</th><th>tau (s)</th><th>gain (um or urad per K / krpm)</th></tr>
{''.join(terms)}</table>
<h2>Selection (forward, leave-one-cycle-out CV inside the identification hours)</h2>
<table><tr><th>channel</th><th>added</th><th>tau, refined (s)</th><th>CV RMS (um)</th>
<th>max VIF</th><th>rivals within 10 % (not decided by the data)</th></tr>
{''.join(sel)}</table>
{diag}
<h2>ISO 230-3 evaluation of the whole record</h2>
<table><tr><th>signal</th><th>unit</th><th>range</th><th>max</th><th>min</th><th>end</th></tr>
{drift}</table>
<p>Envelope: {_esc(iso['envelope']['channel'])}, {iso['envelope']['range_um']:.1f} um.</p>
<h2>Inputs</h2><img src="inputs.png" alt="inputs">
</body></html>"""
    (out / "index.html").write_text(page, encoding="utf-8")
