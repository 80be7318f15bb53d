"""``abbe history report``: one machine's life as an HTML page with trend plots.

OUT/index.html: the current alerts, the alert history (the campaign where each
alert was first raised), one plot per quantity that matters (a series with a
tolerance, or any series that raised an alert; from the first campaign on: values with their 95 % intervals,
the band, the tolerance, the trend line carried over the horizon, the campaigns
with an alert ringed), a table of every series and the list of campaigns.
OUT/trend_NN.png: the plots. Written through :class:`abbe.formats.output.Outputs`
(all files or none; an older report stays whole until the new one is complete).
"""

from __future__ import annotations

import datetime as dt
import html
from pathlib import Path
from typing import Any

from abbe.history.limits import Settings
from abbe.history.trends import Alert, Analysis
from abbe.history.zones import show, to_site, zone_name

#: At most this many plots (the quantities with an alert first, then those with a limit).
MAX_PLOTS = 60


def _esc(x: Any) -> str:
    return html.escape(str(x))


def _day(t: dt.datetime, zone: Any) -> str:
    return to_site(t, zone).strftime("%Y-%m-%d")


def _plot(an: Analysis, s: Settings, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    pts = an.series.points
    unit = an.series.unit
    x = [p.measured_at for p in pts]
    y = [p.value for p in pts]
    fig = Figure(figsize=(7.5, 3.2), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(111)
    if an.band is not None:
        ax.axhspan(an.band[0], an.band[1], color="tab:green", alpha=0.12,
                   label=f"band (first {s.baseline_campaigns} campaigns)")
    # the bar is U (k = 2) where the producer stated it, else its 95 % interval
    lo = [p.U if p.U is not None else p.value - p.ci_low if p.ci_low is not None else 0.0
          for p in pts]
    hi = [p.U if p.U is not None else p.ci_high - p.value if p.ci_high is not None else 0.0
          for p in pts]
    if any(lo) or any(hi):
        what = ("U, k = 2" if all(p.U is not None for p in pts) else
                "95 % interval" if all(p.U is None for p in pts) else
                "U (k = 2), else the 95 % interval")
        ax.errorbar(x, y, yerr=[lo, hi], fmt="o-", ms=4, lw=1, capsize=2, color="tab:blue",
                    label=f"value ({what})")
    else:
        ax.plot(x, y, "o-", ms=4, lw=1, color="tab:blue", label="value")
    if an.limit is not None:
        ax.axhline(an.limit, color="tab:red", ls="--", lw=1, label=f"limit {an.limit:g} {unit}")
        if min(y) < 0:
            ax.axhline(-an.limit, color="tab:red", ls="--", lw=1)
    if an.trend is not None:
        slope, now = an.trend
        t_end = x[-1] + dt.timedelta(days=s.horizon_days)
        ax.plot([x[-1], t_end], [now, now + slope * s.horizon_days], ":", color="tab:orange",
                lw=1.5, label=f"trend, next {s.horizon_days:g} days")
    flagged = {a.campaign_id for a in an.alerts}
    fx = [p.measured_at for p in pts if p.campaign_id in flagged]
    fy = [p.value for p in pts if p.campaign_id in flagged]
    if fx:
        ax.plot(fx, fy, "o", ms=10, mfc="none", mec="tab:red", mew=1.5, label="alert")
    ax.set_title(f"{an.series.key} ({unit})", fontsize=10)
    ax.set_ylabel(unit)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    fig.autofmt_xdate()
    fig.tight_layout()
    fig.savefig(path)


def _first_of_runs(alerts: list[Alert], order: dict[int, int]) -> list[tuple[Alert, int, int]]:
    """Alerts grouped into runs of consecutive campaigns: (first alert, its length, last index)."""
    out: list[tuple[Alert, int, int]] = []
    last: dict[tuple[str, str], tuple[int, int]] = {}  # (series, kind) -> (index in out, pos)
    for a in sorted(alerts, key=lambda a: (order[a.campaign_id], a.series, a.kind)):
        pos = order[a.campaign_id]
        k = (a.series, a.kind)
        if k in last and last[k][1] == pos - 1:
            i = last[k][0]
            out[i] = (out[i][0], out[i][1] + 1, pos)
            last[k] = (i, pos)
        else:
            out.append((a, 1, pos))
            last[k] = (len(out) - 1, pos)
    return out


def render(out: Path, machine: str, campaigns: list[dict[str, Any]],
           analyses: list[Analysis], details: dict[int, dict[str, Any]], s: Settings,
           db_shown: str, zone: Any = None) -> dict[str, Any]:
    """Write index.html and the plots into the (staging) folder ``out``; a summary."""
    order = {c["id"]: i for i, c in enumerate(campaigns)}
    number = {c["id"]: i + 1 for i, c in enumerate(campaigns)}
    alerts = [a for an in analyses for a in an.alerts]
    last_id = campaigns[-1]["id"] if campaigns else None
    current = [a for a in alerts if a.campaign_id == last_id]
    ranked = sorted(analyses, key=lambda an: (not an.alerts, an.limit is None, an.series.key))
    # every quantity that matters gets its plot, from the first campaign on (one point,
    # its interval, the limit: no trend line before there are enough campaigns)
    plotted = [an for an in ranked if an.alerts or an.limit is not None][:MAX_PLOTS]
    h: list[str] = [
        "<!DOCTYPE html>", "<html><head><meta charset='utf-8'>",
        f"<title>abbe history: {_esc(machine)}</title>",
        "<style>body{font-family:sans-serif;max-width:1100px;margin:auto;padding:0 1em}"
        "table{border-collapse:collapse;font-size:13px}td,th{border:1px solid #ccc;"
        "padding:2px 6px;text-align:right;white-space:nowrap}td.l,th.l{text-align:left}"
        "td.m{text-align:left;white-space:normal}"
        ".alert{color:#b00000;font-weight:bold}.ok{color:#006000}"
        "img{max-width:100%}</style></head><body>",
        f"<h1>abbe history: {_esc(machine)}</h1>",
        f"<p>{len(campaigns)} campaigns from {_day(campaigns[0]['measured_at'], zone)} to "
        f"{_day(campaigns[-1]['measured_at'], zone)} (dates in {_esc(zone_name(zone))}); "
        f"database {_esc(db_shown)}. Band: the first "
        f"{s.baseline_campaigns} campaigns +- {s.band_sigma:g} s (never narrower than the "
        f"measurement's interval); trend: the last {s.trend_campaigns} campaigns, alert when it "
        f"reaches the limit within {s.horizon_days:g} days (docs/history.md).</p>",
    ]
    if current:
        h.append(f"<h2 class='alert'>Current alerts (campaign {number[last_id]}, "
                 f"{_day(campaigns[-1]['measured_at'], zone)}): {len(current)}</h2><ul>")
        h += [f"<li class='alert'>{_esc(a.series)} [{a.kind}]: {_esc(a.message)}</li>"
              for a in current]
        h.append("</ul>")
    else:
        h.append("<h2 class='ok'>No alert at the last campaign</h2>")
    h.append("<h2>Alert history (where each alert was first raised)</h2>")
    runs = _first_of_runs(alerts, order)
    if runs:
        h.append("<table><tr><th>campaign</th><th class='l'>date</th><th class='l'>series</th>"
                 "<th class='l'>kind</th><th>campaigns in a row</th><th class='l'>message</th></tr>")
        for a, n, last in runs:
            h.append(f"<tr><td>{number[a.campaign_id]}</td><td class='l'>"
                     f"{_day(a.measured_at, zone)}"
                     f"</td><td class='l'>{_esc(a.series)}</td><td class='l'>{a.kind}</td>"
                     f"<td>{n} (to {last + 1})</td><td class='m'>{_esc(a.message)}</td></tr>")
        h.append("</table>")
    else:
        h.append("<p>none</p>")
    h.append("<h2>Trends</h2>")
    written = []
    for i, an in enumerate(plotted):
        name = f"trend_{i + 1:02d}.png"
        _plot(an, s, out / name)
        written.append(name)
        h.append(f"<h3 id='s{i + 1}'>{_esc(an.series.key)}</h3><img src='{name}' "
                 f"alt='trend of {_esc(an.series.key)}'>")
    h.append("<h2>Every series</h2><table><tr><th class='l'>series</th><th>unit</th>"
             "<th>n</th><th>first</th><th>last</th><th>U of the last (k = 2)</th>"
             "<th>band</th><th>limit</th>"
             "<th>trend / month</th><th class='l'>reaches the limit</th><th>alerts now</th></tr>")
    for an in sorted(analyses, key=lambda a: a.series.key):
        p = an.series.points
        band = f"{an.band[0]:.4g} .. {an.band[1]:.4g}" if an.band else "-"
        if an.out_of_band():
            band += " (last value out)"
        trend = f"{an.trend[0] * 30.44:+.3g}" if an.trend else "-"
        cross = "-"
        if an.crossing is not None:  # a date decades away says only "not soon"
            far = an.crossing - p[-1].measured_at > dt.timedelta(days=10 * s.horizon_days)
            cross = f"not within {10 * s.horizon_days:g} days" if far else \
                f"{an.crossing:%Y-%m-%d}"
        now = ", ".join(a.kind for a in an.current())
        h.append(f"<tr><td class='l'>{_esc(an.series.key)}</td><td>{_esc(an.series.unit)}</td>"
                 f"<td>{len(p)}</td><td>{p[0].value:.4g}</td><td>{p[-1].value:.4g}</td>"
                 f"<td>{'-' if p[-1].U is None else f'{p[-1].U:.3g}'}</td>"
                 f"<td>{band}</td><td>{'-' if an.limit is None else f'{an.limit:g}'}</td>"
                 f"<td>{trend}</td><td class='l'>{cross}</td>"
                 f"<td class='{'alert' if now else ''}'>{now or '-'}</td></tr>")
    h.append("</table><h2>Campaigns</h2><table><tr><th>#</th><th>id</th><th class='l'>date "
             f"({_esc(zone_name(zone))})</th><th class='l'>operator</th><th class='l'>outputs</th>"
             "<th class='l'>instruments</th><th class='l'>temperatures (deg C)</th>"
             "<th class='l'>note</th></tr>")
    for c in campaigns:
        d = details.get(c["id"], {})
        temps = ", ".join(f"{v:.2f}" for _s, v in d.get("temperatures", []))
        h.append(f"<tr><td>{number[c['id']]}</td><td>{c['id']}</td><td class='l'>"
                 f"{_esc(show(c['measured_at'], zone))}</td><td class='l'>"
                 f"{_esc(c['operator'] or '')}"
                 f"</td><td class='l'>{_esc(c['kinds'])}</td><td class='l'>"
                 f"{_esc(', '.join(d.get('instruments', [])))}</td><td class='l'>{temps}</td>"
                 f"<td class='m'>{_esc(c.get('note') or '')}</td></tr>")
    h.append("</table></body></html>")
    (out / "index.html").write_text("\n".join(h) + "\n", encoding="utf-8")
    return {"plots": written, "alerts_now": len(current), "alerts": len(alerts)}
