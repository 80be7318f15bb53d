"""Fit report: one PNG per term and an HTML index with the metrics tables.

Each PNG shows, for one term, the run scatter (``+`` and ``-`` approaches), the
bidirectional mean, the stored fit and the paper's two models (top) and the
residuals of the mean against the stored fit, in-sample and held-out (bottom).
The index page links them and holds a table per term in the style of the
paper's Table 4 (emax, R^2, SSE, RMSE), in-sample and held-out, for the chosen
model and both paper models. No timestamps: the same input gives the same files.
Units: mm, um, urad.
"""

from __future__ import annotations

import html
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from abbe.analysis.fit.options import COMPARED
from abbe.analysis.certificate import band, page_head, test_date
from abbe.model.table import OWN_TERM

if TYPE_CHECKING:
    from abbe.analysis.fit.results import AxisResult, FitResult, TermResult

LABELS = {"chosen": "chosen (auto)", "paper_fourier3": "paper 3rd-order Fourier",
          "paper_poly7": "paper 7th-order polynomial"}


def _model_label(res: "FitResult", tr: "TermResult") -> str:
    d, h = tr.order
    ar = res.axes[tr.axis]
    blk = ar.table.blocks[0]
    s = f"Chebyshev degree {d}"
    if h and blk is not None:
        s += f" + {h} harmonic{'s' if h > 1 else ''} of P = {blk.period_mm:.2f} mm"
    return s


class _Plotter:
    """One reusable figure: artists are created once and updated per term (fast)."""

    def __init__(self) -> None:
        import matplotlib
        matplotlib.use("Agg")
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        self.fig = Figure(figsize=(7.5, 5.0), dpi=72)
        FigureCanvasAgg(self.fig)
        self.top = self.fig.add_axes((0.10, 0.38, 0.86, 0.54))
        self.bot = self.fig.add_axes((0.10, 0.09, 0.86, 0.22), sharex=self.top)
        t, b = self.top, self.bot
        self.up, = t.plot([], [], ".", ms=3, color="0.55", label="runs, + approach")
        self.dn, = t.plot([], [], "x", ms=3, color="0.75", label="runs, - approach")
        self.mean, = t.plot([], [], "o", ms=3.5, color="k", label="bidirectional mean")
        self.fit, = t.plot([], [], "-", lw=1.6, color="tab:blue", label="chosen fit (stored)")
        self.f3, = t.plot([], [], "--", lw=0.9, color="tab:orange", label="paper Fourier 3")
        self.p7, = t.plot([], [], ":", lw=1.1, color="tab:green", label="paper poly 7")
        self.rin, = b.plot([], [], "o", ms=3, color="tab:blue", label="in-sample")
        self.rho, = b.plot([], [], "x", ms=4, color="tab:red", label="held-out")
        b.axhline(0.0, color="k", lw=0.5)
        # Labels as figure texts at fixed places: cheaper than axis labels, whose
        # positions matplotlib recomputes from the tick labels on every draw.
        self.title = self.fig.text(0.53, 0.955, "", ha="center", va="center", fontsize=11)
        self.ylab = self.fig.text(0.015, 0.65, "", rotation=90, ha="left", va="center")
        self.rlab = self.fig.text(0.015, 0.20, "", rotation=90, ha="left", va="center")
        self.fig.text(0.53, 0.015, "position (mm)", ha="center", va="bottom")
        t.tick_params(labelbottom=False)
        t.grid(True, lw=0.3)
        b.grid(True, lw=0.3)
        from matplotlib.ticker import MaxNLocator
        for ax in (t, b):
            ax.yaxis.set_major_locator(MaxNLocator(nbins=5 if ax is t else 3))
        b.xaxis.set_major_locator(MaxNLocator(nbins=8))

    def render(self, pd: dict[str, Any], path: Path) -> None:
        """Draw one term from its precomputed plot data (see :func:`plot_data`)."""
        self.up.set_data(pd["pp"], pd["up"])
        self.dn.set_data(pd["pp"], pd["dn"])
        self.mean.set_data(pd["p"], pd["mean"])
        self.fit.set_data(pd["x"], pd["fit"])
        for line, key in ((self.f3, "f3"), (self.p7, "p7")):
            if pd[key] is None:
                line.set_data([], [])
            else:
                line.set_data(pd["x"], pd[key])
        self.rin.set_data(pd["p"], pd["res_in"])
        self.rho.set_data(pd["p"], pd["res_ho"])
        for ax in (self.top, self.bot):
            ax.relim()
            ax.autoscale_view()
        self.title.set_text(pd["title"])
        self.ylab.set_text(pd["ylabel"])
        self.rlab.set_text(pd["rlabel"])
        self.fig.savefig(path, pil_kwargs={"compress_level": 1}, metadata={"Software": None})


def plot_data(res: "FitResult", ar: "AxisResult", tr: "TermResult") -> dict[str, Any]:
    """Everything one term's PNG shows, as arrays (um / urad over mm)."""
    from abbe.analysis.fit.results import role_of
    from abbe.model.reference import term_values

    p = ar.targets_mm
    n = tr.runs.shape[0]
    x = np.linspace(p[0], p[-1], 600)
    i = list(ar.terms).index(tr.term)
    f3, p7 = ar.fit.paper_f3[i], ar.fit.paper_p7[i]
    pred = tr.predictions["chosen"]
    u = tr.unit
    return {
        "p": p, "pp": np.tile(p, n), "up": tr.runs[:, 0, :].ravel(),
        "dn": tr.runs[:, 1, :].ravel(), "mean": tr.stats.mean, "x": x,
        "fit": term_values(res.table, ar.axis, tr.term, x),
        "f3": None if f3 is None else f3.predict(x)[:, 0] - tr.post_shift,
        "p7": None if p7 is None else p7.predict(x)[:, 0] - tr.post_shift,
        "res_in": tr.stats.mean - pred["in_sample"], "res_ho": tr.stats.mean - pred["held_out"],
        "title": f"{ar.axis} axis, {tr.term} ({role_of(ar.axis, tr.term)}): "
                 f"{_model_label(res, tr)}",
        "ylabel": f"{tr.term} ({u})", "rlabel": f"residual ({u})",
    }


def png_name(axis: str, term: str) -> str:
    return f"{axis}_{term}.png"


def render_pngs(res: "FitResult", out_dir: Path) -> list[Path]:
    """Write one PNG per fitted term into ``out_dir``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    pl = _Plotter()
    paths = []
    for a, ar in res.axes.items():
        for t, tr in ar.terms.items():
            path = out_dir / png_name(a, t)
            pl.render(plot_data(res, ar, tr), path)
            paths.append(path)
    return paths


def _fmt(v: Any, nd: int = 4) -> str:
    if v is None or (isinstance(v, float) and not np.isfinite(v)):
        return "-"
    if isinstance(v, float):
        return f"{v:.{nd}g}"
    return html.escape(str(v))


def index_html(res: "FitResult") -> str:
    """The report's index page (links the PNGs, metrics tables per term)."""
    mj = res.model_json
    m = res.machine
    e = html.escape
    out = page_head(f"abbe fit: {m.name}", [
        ("Machine", f"{m.name} (three-axis, machine file {m.path.name})"),
        ("Test", "laser lines of " + ", ".join(res.axes) + ": the 18 error terms of Eq. 3 "
                 "fitted and written as a compensation table (ISO 230-1 / ISO 230-2)"),
        ("Date", test_date(str(m.path))),
        ("Table", "model.bin" + (f" (CRC32 {mj['table']['crc32']})"
                                 if isinstance(mj.get("table"), dict) and mj["table"].get("crc32")
                                 else ""))])
    out += ["<style>table{border-collapse:collapse;margin:6px 0}td,th{border:1px solid #bbb;"
            "padding:2px 6px;text-align:right}th{background:#eee}td.l,th.l{text-align:left}"
            "img{max-width:100%}.best{font-weight:bold}</style>", _headline_band(res)]
    out += [
           f"<p>abbe {e(mj['provenance']['version'])}; machine file {e(m.path.name)} "
           f"(sha256 {e(m.sha256[:16])}...). Units: positions mm, linear terms um, "
           "angular terms urad; SSE in unit&sup2;.</p>",
           f"<p>{e(mj['metrics_note'])}</p>",
           f"<p><b>Squareness:</b> {e(mj['squareness']['note'])}</p>",
           "<p><b>Plots</b> (top): grey dots / light crosses = runs, + / - approach; black "
           "dots = bidirectional mean; blue line = chosen fit (the stored table term); orange "
           "dashes = paper 3rd-order Fourier; green dots = paper 7th-order polynomial. "
           "(bottom): residual of the mean against the chosen fit, blue dots in-sample, red "
           "crosses held-out.</p>"]
    for a, ar in res.axes.items():
        aj = mj["axes"][a]
        blk = aj["block0"]
        out.append(f"<h2>{a} axis</h2>")
        out.append(f"<p>Laser file {e(aj['laser_file'])}: {aj['n_targets']} targets x "
                   f"{aj['n_runs']} bidirectional runs. Shared structure: Chebyshev trend degree "
                   f"{aj['trend_degree']}, Fourier block 0 "
                   + ("unused" if blk is None else
                      f"period {blk['period_mm']:.3f} mm, origin {blk['origin_mm']:.3f} mm, "
                      f"{blk['harmonics']} harmonics")
                   + f"; block 1 {e(aj['block1_note'])}.</p>")
        for w in aj.get("warnings", []):
            out.append(f"<p><b>Warning:</b> {e(w)}</p>")
        bl = ar.backlash
        if "mean_reversal_um" in bl and "se_um" in bl:
            out.append(f"<p>Backlash: mean reversal {bl['mean_reversal_um']:.3f} um, run-to-run "
                       f"noise {bl['noise_um']:.3f} um (SE of one reversal {bl['se_um']:.3f} um): "
                       + ("significant, in the table" if bl["significant"] else
                          "not significant, not in the table") + ".</p>")
            rv = bl.get("reversal") or {}
            if rv.get("position_dependent"):
                pv = rv["p_value"]
                p_txt = "p &lt; 1e-16" if pv < 1e-16 else f"p = {pv:.2g}"
                out.append(f"<p>Reversal: changes along the travel (Chebyshev degree "
                           f"{rv['degree']}, {p_txt}; per target "
                           f"{min(rv['per_target_um']):.2f} .. {max(rv['per_target_um']):.2f} um): "
                           f"{e(rv.get('note', ''))}.</p>")
        if aj["iso230_2"]:
            iso = aj["iso230_2"]
            out.append("<p>ISO 230-2 (own positioning term, U with k = 2): " + ", ".join(
                f"{k[0]} = {iso[k]:.2f}"
                + (f" &plusmn; {iso[k[0] + '_U_um']:.2f}" if iso.get(k[0] + "_U_um") is not None
                   else "") + " um" for k in ("B_um", "R_um", "E_um", "A_um", "M_um"))
                + "</p>")
        out += _uncertainty_table(mj, a)
        n20 = aj.get("normalisation_20c")
        if n20:
            nde = n20["nominal_differential_expansion_um"]
            out.append(f"<p>20 deg C: {e(n20['status'])}"
                       + ("" if nde is None else f", nominal differential expansion {nde:+.3f} um "
                          f"over {n20['span_mm']:g} mm") + f" ({e(n20['reason'])}).</p>")
        for t, tr in ar.terms.items():
            u = tr.unit
            tj = aj["terms"][t]
            out.append(f"<h3 id='{a}_{t}'>{a} {t} ({e(tj['role'])}, {u}): "
                       f"{e(_model_label(res, tr))}</h3>")
            extra = [f"channel {e(tr.channel)} (sign {tr.sign:+d})",
                     f"noise {_fmt(tj[f'noise_{u}'])} {u}",
                     f"quantisation error {_fmt(tj[f'quantization_error_{u}'])} {u}"]
            if tr.detrend:
                extra.append(f"detrended slope {tr.detrend['slope_urad']:.2f} urad")
            if tj["paper_fourier3_period_mm"]:
                extra.append(f"paper Fourier period {tj['paper_fourier3_period_mm']:.2f} mm")
            out.append("<p>" + "; ".join(extra) + "</p>")
            out.append("<table><tr><th class='l' rowspan='2'>model</th>"
                       "<th colspan='4'>in-sample</th><th colspan='4'>held-out</th></tr><tr>"
                       + "".join(f"<th>{h}</th>" for h in
                                 (f"emax ({u})", "R&sup2;", "SSE", f"RMSE ({u})") * 2)
                       + "</tr>")
            ho = {k: tr.metrics[k]["held_out"]["emax"] for k in COMPARED}
            best = min(ho, key=lambda k: ho[k] if np.isfinite(ho[k]) else np.inf)
            for k in COMPARED:
                mm = tr.metrics[k]
                cls = " class='l best'" if k == best else " class='l'"
                out.append(f"<tr><td{cls}>{e(LABELS[k])}</td>" + "".join(
                    f"<td>{_fmt(mm[kind][q])}</td>" for kind in ("in_sample", "held_out")
                    for q in ("emax", "r2", "sse", "rmse")) + "</tr>")
            out.append("</table>")
            out.append(f"<p><a href='{png_name(a, t)}'><img src='{png_name(a, t)}' "
                       f"alt='{a} {t}'></a></p>")
    out.append("</body></html>")
    return "\n".join(out) + "\n"


def _headline_band(res: "FitResult") -> str:
    """The verdict band of the fit report: what the written table leaves of each axis' own
    positioning error at the measured targets (max |r| and RMS with U, k = 2), beside the
    axis' ISO 230-2 E before compensation. A fit has no tolerance: the band is 'info'."""
    mj = res.model_json
    unc = mj.get("uncertainty") or {}
    rows, parts = [], []
    for a in res.axes:
        own = OWN_TERM[a]
        d = (unc.get("axes") or {}).get(a, {}).get("terms", {}).get(own)
        iso = mj["axes"][a].get("iso230_2") or {}
        e_before = "-" if iso.get("E_um") is None else (
            f"{iso['E_um']:.2f}" + (f" &plusmn; {iso['E_U_um']:.2f}"
                                    if iso.get("E_U_um") is not None else ""))
        if d is None:
            rows.append(f"<tr><td class='l'>{a} ({own})</td><td>{e_before}</td>"
                        "<td>-</td><td>-</td></tr>")
            continue
        c = d["compensated_residual_um"]
        parts.append(f"{a} {c['max_abs']:.2f} &plusmn; {c['max_abs_U']:.2f} um")
        rows.append(f"<tr><td class='l'>{a} ({own})</td><td>{e_before}</td>"
                    f"<td>{_fmt(c['max_abs'], 3)} &plusmn; {_fmt(c['max_abs_U'], 3)}</td>"
                    f"<td>{_fmt(c['rms'], 3)} &plusmn; {_fmt(c['rms_U'], 3)}</td></tr>")
    headline = ("Table written for " + ", ".join(res.axes) + "; left at the targets (max |r| "
                "&plusmn; U, k = 2): " + ("; ".join(parts) if parts else "no uncertainty block"))
    body = ("<table><tr><th class='l'>axis (own positioning term)</th><th>ISO 230-2 E before "
            "&plusmn; U (um)</th><th>compensated max |r| &plusmn; U (um)</th><th>compensated RMS &plusmn; U "
            "(um)</th></tr>" + "".join(rows) + "</table><p class='small'>No tolerance applies to a "
            "fit: the verdicts are those of `abbe iso230-2` and `abbe ballbar` on the compensated "
            "machine. Every term, its model choice and its held-out figures follow.</p>")
    return band("info", headline, body)


def _uncertainty_table(mj: dict[str, Any], a: str) -> list[str]:
    """One compact table per axis: each term's largest U (k = 2) along the travel and the
    compensated residual at the targets with its U (model.json's uncertainty block)."""
    unc = mj.get("uncertainty")
    if not unc or a not in unc["axes"]:
        return []
    b = unc["budget_inputs"]
    rows = [f"<p><b>Uncertainty</b> (k = 2; budget: {html.escape(b['instrument'])}, "
            f"{html.escape(b['source'])}; docs/uncertainty.md). The table's U is 0 at the "
            "reference point, where every term is 0 by definition; the compensated residual "
            "is the measured mean minus the stored table at the targets.</p>",
            "<table><tr><th class='l'>term</th><th>U max along the travel</th>"
            "<th>compensated max |r| &plusmn; U</th><th>compensated RMS &plusmn; U</th></tr>"]
    for t, d in unc["axes"][a]["terms"].items():
        u = d["unit"]
        c = d[f"compensated_residual_{u}"]
        rows.append(f"<tr><td class='l'>{t} ({u})</td><td>{_fmt(d[f'U_max_{u}'], 3)}</td>"
                    f"<td>{_fmt(c['max_abs'], 3)} &plusmn; {_fmt(c['max_abs_U'], 3)}</td>"
                    f"<td>{_fmt(c['rms'], 3)} &plusmn; {_fmt(c['rms_U'], 3)}</td></tr>")
    rows.append("</table>")
    return rows


SHORT = {"chosen": "chosen", "paper_fourier3": "paper Fourier 3", "paper_poly7": "paper poly 7"}


def metrics_text(res: "FitResult") -> str:
    """Per term, the paper's Table 4 layout (emax, R^2, SSE, RMSE) for the chosen
    model and both paper models, in-sample and held-out. um or urad (SSE squared)."""
    head = (f"{'term':<12} {'model':<34} {'emax':>8} {'R2':>8} {'SSE':>10} {'RMSE':>8}   "
            f"{'emax':>8} {'R2':>8} {'SSE':>10} {'RMSE':>8}")
    out = [f"{'':<47}{'in-sample':^37}   {'held-out':^37}", head]
    for a, ar in res.axes.items():
        for t, tr in ar.terms.items():
            for k in COMPARED:
                if k == "chosen":
                    d, h = tr.order
                    blk = ar.table.blocks[0]
                    name = f"chosen: degree {d}" + (f" + {h}h P={blk.period_mm:.1f}" if h and blk
                                                    else "")
                elif k == "paper_fourier3" and tr.paper_f3_period_mm:
                    name = f"paper Fourier 3, P={tr.paper_f3_period_mm:.1f}"
                else:
                    name = SHORT[k]
                m = tr.metrics[k]
                cells = "   ".join(" ".join(f"{_num(m[kind][q], w)}" for q, w in
                                            (("emax", 8), ("r2", 8), ("sse", 10), ("rmse", 8)))
                                   for kind in ("in_sample", "held_out"))
                label = f"{a} {t} ({tr.unit})" if k == "chosen" else ""
                out.append(f"{label:<12} {name:<34} {cells}")
    return "\n".join(out)


def _num(v: float, w: int) -> str:
    if v is None or not np.isfinite(v):
        return "-".rjust(w)
    return f"{v:{w}.4g}"


def write_report(res: "FitResult", out_dir: Path) -> Path:
    """PNGs + index.html into ``out_dir``; returns the index path."""
    render_pngs(res, out_dir)
    idx = out_dir / "index.html"
    idx.write_text(index_html(res), encoding="utf-8")
    return idx
