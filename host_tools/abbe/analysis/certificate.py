"""Small HTML reports of `abbe iso230-2 -o` and `abbe ballbar -o`, read verdict-first:
machine, test, date, the verdicts, then the results with U, the budget (folded) and the
Monte Carlo check. Built from the JSON document the command writes beside it, so the
two cannot disagree. Printable through the browser (no scripts, no external files
other than the plots beside it).

The page frame every abbe report shares (:func:`page_head`, :func:`band`, :data:`CSS`):
a title, the machine / test / date rows, then one full-width band coloured by the
verdict (pass, fail, inconclusive; "info" where no tolerance applies) that carries the
headline figures. Long explanations go below, folded in ``<details>`` (unfolded in
print)."""

from __future__ import annotations

import datetime as _dt
import html
import os
from typing import Any

RULE = ("Decision rule (ISO 14253-1): pass when result + U &le; limit, fail when result "
        "&minus; U &gt; limit, inconclusive when the result lies within U of the limit.")

_CSS = """
body{font-family:sans-serif;max-width:60em;margin:1.5em auto;color:#222}
h1{font-size:1.4em;margin-bottom:.2em} h2{font-size:1.1em;margin-top:1.4em}
table{border-collapse:collapse;margin:.4em 0} td,th{border:1px solid #bbb;padding:.25em .6em;
text-align:right} th{background:#eee} td.l,th.l{text-align:left}
.pass{background:#c8efc8} .fail{background:#f6c3c3} .inconclusive{background:#fbe7a6}
.info{background:#d6e6f5}
.band{padding:.5em .8em;margin:.6em 0;font-size:1.1em;-webkit-print-color-adjust:exact;
print-color-adjust:exact} .band p{margin:.2em 0}
.band table{font-size:.8em} .band table td,.band table th{border-color:#889;
background:transparent} .band table td{white-space:nowrap}
.plots img{max-width:48%;vertical-align:top} .plots img.wide{max-width:100%}
.head td{border:none;text-align:left;padding:.1em .8em .1em 0} .small{font-size:.85em;color:#555}
details{margin:.5em 0} summary{cursor:pointer;font-weight:bold}
@media print{details{display:block} summary{display:none}
details::details-content{content-visibility:visible;display:block} body{max-width:none;margin:0}
a{color:inherit;text-decoration:none} h2{break-after:avoid} img,table{break-inside:avoid}}
"""

#: The band colours (RGB) a report's verdict band may have (tests look for them).
BAND_RGB = {"pass": (0xc8, 0xef, 0xc8), "fail": (0xf6, 0xc3, 0xc3),
            "inconclusive": (0xfb, 0xe7, 0xa6), "info": (0xd6, 0xe6, 0xf5)}
CSS = _CSS


def page_head(title: str, rows: list[tuple[str, str]]) -> list[str]:
    """The top of a report: title, then machine / test / date rows (plain text, escaped)."""
    return _head(title, rows)


def band(status: str, headline: str, body: str = "") -> str:
    """The verdict band: ``status`` pass | fail | inconclusive | info; ``headline`` and
    ``body`` are HTML (the caller escapes)."""
    assert status in BAND_RGB, status
    return (f"<div class='band {status}' id='verdict'><p><b>{headline}</b></p>{body}</div>")


def overall(verdicts: list[str]) -> str:
    """The overall verdict of several (fail beats inconclusive beats pass)."""
    return ("fail" if "fail" in verdicts else "inconclusive" if "inconclusive" in verdicts
            else "pass")


def test_date(path: str) -> str:
    """The measurement file's date (its modification time, UTC), YYYY-MM-DD."""
    try:
        t = os.stat(path).st_mtime
    except OSError:
        return "unknown"
    return _dt.datetime.fromtimestamp(t, tz=_dt.timezone.utc).strftime("%Y-%m-%d")


def _e(x: Any) -> str:
    return html.escape(str(x))


def _f(x: Any, nd: int = 2) -> str:
    return "&ndash;" if x is None else f"{float(x):.{nd}f}"


def _head(title: str, rows: list[tuple[str, str]]) -> list[str]:
    out = ["<!DOCTYPE html>", "<html><head><meta charset='utf-8'>",
           f"<title>{_e(title)}</title><style>{_CSS}</style></head><body>",
           f"<h1>{_e(title)}</h1>", "<table class='head'>"]
    out += [f"<tr><td><b>{_e(k)}</b></td><td>{_e(v)}</td></tr>" for k, v in rows]
    out.append("</table>")
    return out


def _verdict_block(verdicts: dict[str, Any], unc: dict[str, Any] | None = None,
                   names: dict[str, str] | None = None) -> list[str]:
    out = ["<h2>Verdicts</h2>"]
    if not verdicts:
        figures = ""
        if unc:
            figures = ", ".join(
                f"{_e((names or {}).get(q, q).split(' ')[0] if q in 'EABRM' else q)} "
                f"{_f(r['value_um'])} &plusmn; {_f(r['U_um'])}"
                for q, r in unc["results"].items()) + " um (U, k = 2)"
        out.append(band("info", "No tolerances stated: no verdict", f"<p>{figures}</p>"
                        "<p class='small'>Add a <code>[tolerances]</code> section to the "
                        "machine file for pass / fail / inconclusive.</p>"))
        return out
    ov = overall([v["verdict"] for v in verdicts.values()])
    out.append(band(ov, f"Overall: {ov.upper()}"))
    out.append("<table><tr><th class='l'>result</th><th>value (um)</th><th>U, k = 2 (um)</th>"
               "<th>limit (um)</th><th class='l'>verdict</th></tr>")
    for key, v in verdicts.items():
        out.append(f"<tr><td class='l'>{_e(key[:-3])}</td><td>{_f(v['value_um'])}</td>"
                   f"<td>{_f(v['U_um'])}</td><td>{_f(v['limit_um'])}</td>"
                   f"<td class='l {v['verdict']}'><b>{v['verdict'].upper()}</b></td></tr>")
    out.append("</table>")
    out.append(f"<p class='small'>{RULE}</p>")
    return out


def _results_table(unc: dict[str, Any], names: dict[str, str]) -> list[str]:
    mc = unc.get("monte_carlo")
    out = ["<table><tr><th class='l'>result</th><th>value (um)</th><th>u<sub>c</sub> (um)</th>"
           "<th>U, k = 2 (um)</th>" + ("<th>Monte Carlo U (um)</th>" if mc else "") + "</tr>"]
    for q, r in unc["results"].items():
        row = (f"<tr><td class='l'>{_e(names.get(q, q))}</td><td>{_f(r['value_um'])}</td>"
               f"<td>{_f(r['u_um'], 3)}</td><td><b>{_f(r['U_um'])}</b></td>")
        if mc:
            m = mc["results"].get(q)
            row += f"<td>{_f(m['U_um']) if m else '&ndash;'}</td>"
        out.append(row + "</tr>")
    out.append("</table>")
    return out


def _budget_tables(unc: dict[str, Any], names: dict[str, str]) -> list[str]:
    b = unc["budget_inputs"]
    out = ["<details><summary>Budget per result (each input acting alone)</summary>",
           f"<p class='small'>Instrument class <b>{_e(b['instrument'])}</b>, figures from "
           f"{_e(b['source'])}; declared in the machine file: "
           f"{_e(', '.join(b['declared']) or 'none')}.</p>"]
    for q, r in unc["results"].items():
        out.append(f"<p><b>{_e(names.get(q, q))}</b>: u<sub>c</sub> = {_f(r['u_um'], 3)} um "
                   f"(quadrature sum of the lines {_f(r['quadrature_u_um'], 3)} um)</p>")
        out.append("<table><tr><th class='l'>input</th><th class='l'>what</th>"
                   "<th>u(input)</th><th class='l'>unit</th><th>sensitivity</th>"
                   "<th>u (um)</th></tr>")
        for c in r["budget"]:
            out.append(f"<tr><td class='l'>{_e(c['name'])}</td><td class='l'>{_e(c['what'])}"
                       f"</td><td>{c['u_input']:.4g}</td><td class='l'>{_e(c['unit'])}</td>"
                       f"<td>{c['sensitivity']:.4g}</td><td>{_f(c['u_um'], 3)}</td></tr>")
        out.append("</table>")
    out.append("</details>")
    return out


def _mc_block(unc: dict[str, Any]) -> list[str]:
    mc = unc.get("monte_carlo")
    if not mc:
        return ["<p class='small'>Monte Carlo check not run (--mc 0).</p>"]
    ag = mc.get("agreement", {})
    worst = max((abs(v) for v in ag.values()), default=0.0)
    return [f"<p class='small'>Independent check (GUM Supplement 1, {mc['draws']} draws, seed "
            f"{mc['seed']}): U<sub>MC</sub> / U &minus; 1 within {100 * worst:.1f} % for every "
            f"result. {_e(mc['method'])}.</p>"]


def _instrument(unc: dict[str, Any]) -> str:
    b = unc["budget_inputs"]
    return f"{b['instrument']} (budget: {b['source']})"


def iso230_2_html(d: dict[str, Any], date: str) -> str:
    """The report of one `abbe iso230-2 -o` run (``d``: its JSON document)."""
    unc = d["uncertainty"]
    names = {"E": "E systematic deviation", "A": "A accuracy", "B": "B reversal",
             "R": "R repeatability", "M": "M mean bidirectional deviation"}
    norm = d.get("normalisation_20c")
    rows = [("Machine", d.get("machine") or "not named (no --machine)"),
            ("Axis", d.get("axis") or "not named (no --axis)"),
            ("Test", f"ISO 230-2 bidirectional positioning, {d['n_runs']} runs, "
                     f"{d['n_targets']} targets"),
            ("Date", date), ("File", os.path.basename(str(d["file"]))),
            ("Instrument", _instrument(unc)),
            ("20 deg C", norm["status"] + ": " + norm["reason"] if norm else
             "the file carries no material temperature (results as measured)")]
    out = _head("ISO 230-2 positioning test", rows)
    out += _verdict_block(d.get("verdicts") or {}, unc, names)
    out.append("<h2>Results with their expanded uncertainty</h2>")
    out += _results_table(unc, names)
    out += _mc_block(unc)
    out += _budget_tables(unc, names)
    out.append("<details><summary>Per target (um)</summary><table><tr><th>target (mm)</th>"
               "<th>x up</th><th>U</th><th>x down</th><th>U</th><th>B<sub>i</sub></th>"
               "<th>R<sub>i</sub></th></tr>")
    for t, u in zip(d["targets"], unc["per_target"]):
        out.append(f"<tr><td>{t['target_mm']:g}</td><td>{_f(t['mean_up_um'])}</td>"
                   f"<td>{_f(u['U_mean_up_um'])}</td><td>{_f(t['mean_down_um'])}</td>"
                   f"<td>{_f(u['U_mean_down_um'])}</td><td>{_f(t['reversal_um'])}</td>"
                   f"<td>{_f(t['repeatability_um'])}</td></tr>")
    out.append("</table></details>")
    out.append("<p class='small'>abbe; method: docs/uncertainty.md.</p></body></html>")
    return "\n".join(out) + "\n"


def ballbar_html(d: dict[str, Any], date: str, plot: str | None) -> str:
    """The report of one `abbe ballbar -o` run (``d``: its JSON document)."""
    unc = d["uncertainty"]
    names = {"G_ccw": "G circular deviation, CCW", "G_cw": "G circular deviation, CW",
             "G_bidirectional": "G circular deviation, bidirectional",
             "H": "H circular hysteresis", "radius_dev": "radius deviation"}
    rows = [("Machine", d.get("machine_name") or d.get("machine", "")),
            ("Test", f"ISO 230-4 circular test {d['name']}: plane {d['plane']}, "
                     f"R {d['radius_mm']:g} mm, F {d['feed_mm_min']:g} mm/min"),
            ("Date", date), ("File", os.path.basename(str(d["file"]))),
            ("Instrument", _instrument(unc))]
    out = _head("ISO 230-4 circular test (ballbar)", rows)
    out += _verdict_block(d.get("verdicts") or {}, unc, names)
    if plot:
        out.append(f"<p><img src='{_e(plot)}' alt='polar plot' style='max-width:26em'></p>")
    out.append("<h2>Results with their expanded uncertainty</h2>")
    out += _results_table(unc, names)
    out += _mc_block(unc)
    out += _budget_tables(unc, names)
    out.append("<p class='small'>The ballbar's own repeatability (a second run) is not in the "
               "budget: one test cannot show it. abbe; method: docs/uncertainty.md.</p>")
    out.append("</body></html>")
    return "\n".join(out) + "\n"
