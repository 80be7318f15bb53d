"""Outputs of ``abbe diagnose``: text report, diagnose JSON, residual plots, updated tables.

:func:`write_outputs` writes OUT/ (built in a temporary folder beside OUT and swapped in
by one rename, so a failure leaves no partial output and keeps the old result):

* ``model.bin``, ``abbe_model.c`` / ``abbe_model.h``, ``model.json``: the updated
  table (the effects the C library evaluates added);
* ``diagnose.json`` (docs/formats.md, "diagnose JSON"), also to ``--json FILE``;
* ``report.txt``: the text report;
* ``plots/residual_<check>.png``: residual before and after the update (polar for
  a ballbar, along the travel for a laser line), and
  ``plots/effect_<key>.png``: the residual before and after adding that effect on
  the check where it shows most.

No timestamps: the same input gives the same bytes (plots: PNG without metadata).
Units: um, urad, mm, ms, ppm.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from abbe.diagnose.checks import BallbarCheck, Check, LaserCheck
from abbe.diagnose.results import DiagnoseResult, EffectResult


def _fmt(v: float, nd: int = 3) -> str:
    return f"{v:.{nd}f}" if math.isfinite(v) else str(v)


def format_text(res: DiagnoseResult, model_path: str | None = None) -> str:
    """Human-readable report."""
    L: list[str] = []
    L.append(f"abbe diagnose: {len(res.checks)} check(s), predictions through the "
             f"{'C library' if res.backend == 'c' else 'float64 reference'}")
    for c in res.checks:
        L.append(f"  {c.kind:8s} {c.name}: {c.n} samples ({c.source})")
    L.append("noise (1 sigma; laser: repeated runs; ballbar: scatter about a saturated smooth "
             "fit, cross-checked on the CW/CCW pair):")
    for g, v in res.noise.items():
        pair = f", CW/CCW pair {v['pair_sigma']:.3f}" if "pair_sigma" in v else ""
        rej = (f", {v['rejected_readings']} wild reading(s) left out"
               if v.get("rejected_readings") else "")
        L.append(f"  {g}: {v['sigma']:.3f} {v['unit']} (dof {v['dof']}, "
                 f"autocorrelation inflation {v['inflation']:.2f}{pair}{rej})")
    outl = getattr(res, "outliers", [])
    if outl:
        L.append("outlier runs (excluded from the check; the rest is diagnosed):")
        for o in outl:
            L.append(f"  - {o.message()}")
    L.append("")
    if not res.effects and not res.tentative and res.possible:
        L.append("RESULT: nothing named; the data cannot decide whether "
                 + " / ".join(p["key"] for p in res.possible) + " is present (see below).")
    elif not res.effects and not res.tentative:
        L.append("RESULT: nothing is missing.")
    elif not res.effects:
        L.append("RESULT: nothing in the catalogue explains the residual (see the notes).")
    elif res.tentative:
        L.append(f"RESULT (TENTATIVE, the residual stays at {res.lack_of_fit:.1f} x the noise): "
                 f"{len(res.effects)} effect(s) would reduce it:")
    else:
        L.append(f"RESULT: {len(res.effects)} missing effect(s) named:")
    for e in res.effects:
        L.append("")
        where = f" [{e.axis or e.plane}]" if (e.axis or e.plane) and e.id in (
            "thermal_drift", "servo_mismatch", "straightness") else ""
        key = f" ({e.key})" if e.key != e.id else ""
        uu = e.uncertainty or {}
        L.append(f"* {e.id}{where}{key}: {_fmt(e.value)} {e.unit}"
                 + (f" +- {_fmt(uu['U'])} (U, k = 2, the budget below)" if uu.get("U") is not None
                    else "")
                 + f", 95 % interval [{_fmt(e.ci95[0])}, {_fmt(e.ci95[1])}]"
                 + (" (the coverage interval to state: the same budget, Student t on the "
                    "fit's part" + ("; the warm-up time constants the data allow: asymmetric"
                                    if e.evidence.get("tau_alternatives") else "") + ")"
                    if uu.get("U") is not None else "")
                 + ("  [TENTATIVE]" if e.tentative else ""))
        if uu.get("budget_u"):
            L.append("    budget (u): " + "; ".join(f"{k} {_fmt(v, 4)}"
                                                  for k, v in uu["budget_u"].items()
                                                  if v is not None and v >= 1e-4 * uu["u"])
                     + (f"; Monte Carlo U {_fmt(uu['U_mc'])} ({100 * uu['mc_agreement']:+.1f} %), "
                        f"stated: {uu['U_from']}" if uu.get("U_mc") is not None
                        and uu.get("mc_agreement") is not None else ""))
        for p in e.params:
            L.append(f"    {p['name']} = {p['value']:.4f} {p['unit']} "
                     f"[{p['ci95'][0]:.4f}, {p['ci95'][1]:.4f}]")
        if len(e.components) > 1:
            L.append(f"    {len(e.components)} components (one effect, one time constant):")
            for c in e.components:
                L.append(f"      {c['key']} [{c['axis']}]: {_fmt(c['value'])} {c['unit']}, 95 % "
                         f"interval [{_fmt(c['ci95'][0])}, {_fmt(c['ci95'][1])}]; "
                         + ", ".join(f"{p['name']} = {p['value']:.4f} {p['unit']}"
                                     for p in c["parameters"]))
        if e.scan:
            for k, v in e.scan.items():
                txt = "linear (no saturation)" if not math.isfinite(v) else f"{v:.4g}"
                ci = (e.scan_ci95 or {}).get(k)
                if k == "per_target":
                    L.append(f"    form: per target ({int(v)} targets; chosen against the smooth "
                             "degrees by BIC)")
                elif k == "degree" and e.id.startswith("reversal"):
                    L.append(f"    form: smooth, degree {int(v)} over the travel (chosen by BIC "
                             "among the degrees and the per-target form)")
                elif k == "takeup_mm" and "takeup_plus_mm" in e.scan:
                    L.append(f"    {k} = {txt} (the table's one take-up: the mean of the take-ups "
                             "after a reversal to + and to - motion below, which the table and the "
                             "compensator cannot hold apart; the residual after is the pair's)")
                elif ci is None:
                    L.append(f"    {k} = {txt} (searched on a grid)")
                else:
                    lo = "<" if ci[0] is None else f"{ci[0]:.4g}"
                    hi = ">" if ci[1] is None else f"{ci[1]:.4g}"
                    L.append(f"    {k} = {txt}, 95 % interval [{lo}, {hi}] (profile; < / > = "
                             "not resolved beyond the searched range)")
        for line in (e.shape_notes or []):
            L.append(f"    {line}")
        L.append(f"    physics: {e.physics}")
        ev = e.evidence
        if ev.get("residual_before") and ev.get("residual_after"):
            L.append(f"    residual RMS {ev['residual_before']['rms_um']:.3f} -> "
                     f"{ev['residual_after']['rms_um']:.3f} um, max "
                     f"{ev['residual_before']['max_um']:.3f} -> {ev['residual_after']['max_um']:.3f} um")
        L.append(f"    log evidence ratio {ev.get('log_evidence', float('nan')):.1f} (BIC change "
                 f"{ev['delta_bic']:.1f}, F = {ev['F']:.2f}, p = {ev['p_value']:.3g}); "
                 f"held-out ({ev['heldout_split']}): RSS change {ev['heldout_change_percent']:.1f} %")
        L.append(f"    compensated by: {e.where}; remedy: {e.remedy}")
        if e.undecided:
            L.append("    UNDECIDED: " + e.undecided["statement"])
            for alt in e.undecided["alternatives"]:
                L.append(f"      {alt['key']}: {alt['value']} {alt['unit']}")
            L.append("      constrained by the checks: " + e.undecided["constrained"])
            if e.undecided.get("table_holds"):
                L.append("      the table holds: " + ", ".join(
                    f"{k} {v}" for k, v in e.undecided["table_holds"].items()))
            if e.undecided.get("unknown"):
                L.append("      unknown: " + e.undecided["unknown"])
        for a in e.ambiguous_with:
            how = (f"reproduces {100 * a['r2']:.0f} % of the signature" if a.get("r2") is not None
                   else "same signature at one height")
            L.append(f"    AMBIGUOUS with {a['key']} ({how}); to separate them run: "
                     f"{a['separating_test']}")
    for p in res.possible:
        L.append("")
        ci = (f" [{_fmt(p['ci95'][0])}, {_fmt(p['ci95'][1])}]" if p.get("ci95") else "")
        L.append(f"POSSIBLY PRESENT (not named, not in the table): {p['key']}, "
                 f"{_fmt(p['contribution_rms_um'])} um RMS on the checks (its first parameter "
                 f"{_fmt(p['value'])}{ci} {p['unit']}, 95 % interval)")
        L.append("    " + p["statement"])
        L.append("    to decide: " + p["test"])
    L.append("")
    L.append("gap (residual after nuisance removal, um-valued samples):")
    if res.heldout_split:
        L.append(f"  (held out: {res.heldout_split})")
    for k in ("before", "after", "held_out_before", "held_out_after"):
        g = res.gap.get(k)
        if g is not None:
            gu = (res.gap_uncertainty or {}).get(k)
            if gu and gu["rms_um"]["U"] is not None and gu["max_um"]["U"] is not None:
                L.append(f"  {k:16s} RMS {g.rms_um:8.3f} +- {gu['rms_um']['U']:.3f} um   max "
                         f"{g.max_um:8.3f} +- {gu['max_um']['U']:.3f} um   (n = {g.n}; U, k = 2)")
            else:
                L.append(f"  {k:16s} RMS {g.rms_um:8.3f} um   max {g.max_um:8.3f} um   (n = {g.n})")
        else:
            L.append(f"  {k:16s} not available")
    b, a = res.gap.get("before"), res.gap.get("after")
    if b is not None and a is not None and b.rms_um > 0:
        L.append(f"  RMS shrink {100 * (1 - a.rms_um / b.rms_um):.1f} % on the data used")
    hb, ha = res.gap.get("held_out_before"), res.gap.get("held_out_after")
    if hb is not None and ha is not None and hb.rms_um > 0:
        L.append(f"  RMS shrink {100 * (1 - ha.rms_um / hb.rms_um):.1f} % on held-out data")
    if res.notes:
        L.append("")
        L.append("notes:")
        for n in res.notes:
            L.append(f"  - {n}")
    if res.drift_ties:
        L.append("")
        L.append("drift and the campaign's temperature (docs/thermal.md):")
        for t in res.drift_ties:
            L.append(f"  - {t.sentence()}")
    if res.not_observable:
        L.append("")
        L.append("not observable with these checks:")
        by_reason: dict[str, list[str]] = {}
        for n in res.not_observable:
            k, _, why = n.partition(": ")
            by_reason.setdefault(why, []).append(k)
        for why, keys in by_reason.items():
            L.append(f"  - {', '.join(keys)}: {why}")
    if model_path:
        L.append("")
        L.append(f"updated model: {model_path}")
    return "\n".join(L) + "\n"


# --------------------------------------------------------------------------- plots


def _polar(ax: Any, c: BallbarCheck, r: np.ndarray, style: dict[str, Any], half: float,
           label: str) -> None:
    for d, ls in (("ccw", "-"), ("cw", "--")):
        m = c.direction == d
        a = c.x[m]
        o = np.argsort(a)
        a2 = np.append(a[o], a[o][0] + 360.0)
        r2 = np.append(r[m][o], r[m][o][0])
        ax.plot(np.radians(a2), np.clip(r2, -half, half), ls=ls, lw=1.0,
                label=f"{label} {d.upper()}", **style)


def _plot_check(path: Path, c: Check, before: np.ndarray, after: np.ndarray, title: str,
                labels: tuple[str, str] = ("before", "after")) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fin = np.isfinite(before) & np.isfinite(after)
    if isinstance(c, BallbarCheck):
        span = max(float(np.max(np.abs(before[fin]))) if fin.any() else 1.0, 1e-3) * 1.1
        fig = plt.figure(figsize=(6.4, 6.4), dpi=100)
        ax = fig.add_subplot(projection="polar")
        ax.set_rorigin(-3.0 * span)
        ax.set_rlim(-span, span)
        th = np.radians(np.linspace(0, 360, 361))
        ax.plot(th, np.zeros_like(th), color="black", lw=1.4)
        _polar(ax, c, before, {"color": "tab:gray"}, span, labels[0])
        _polar(ax, c, after, {"color": "tab:blue"}, span, labels[1])
        ax.set_title(f"{title}\nradial residual (um), centre/radius removed", fontsize=9)
        ax.tick_params(axis="y", labelsize=7)
        ax.legend(loc="upper right", bbox_to_anchor=(1.15, 1.12), fontsize=7)
    else:
        assert isinstance(c, LaserCheck)
        chans = c.group_names
        fig, axs = plt.subplots(len(chans), 1, figsize=(7.0, 2.2 * len(chans) + 0.6), dpi=100,
                                squeeze=False)
        for g, name in enumerate(chans):
            ax = axs[g, 0]
            m = c.group == g
            unit = c.group_units[g]
            for d, mk in (("+", "^"), ("-", "v")):
                mm = m & (c.direction == d)
                ax.plot(c.x[mm], before[mm], mk, ms=3, color="tab:gray", alpha=0.7,
                        label=f"{labels[0]} {d}")
                ax.plot(c.x[mm], after[mm], mk, ms=3, color="tab:blue", alpha=0.8,
                        label=f"{labels[1]} {d}")
            ax.axhline(0.0, color="black", lw=0.8)
            ax.set_ylabel(f"{name.split(':')[-1]} ({unit})", fontsize=8)
            ax.tick_params(labelsize=7)
            if g == 0:
                ax.set_title(f"{title}: residual along the travel (zeros removed)", fontsize=9)
                ax.legend(fontsize=6, ncol=4)
        axs[-1, 0].set_xlabel(f"{c.meta.get('axis', '')} target (mm)", fontsize=8)
        fig.tight_layout()
    fig.savefig(str(path), format="png", metadata={"Software": None})
    plt.close(fig)


def write_plots(res: DiagnoseResult, out_dir: Path) -> list[Path]:
    """Residual plots per check (before/after the update) and per named effect."""
    out_dir.mkdir(parents=True, exist_ok=True)
    paths: list[Path] = []
    for i, c in enumerate(res.checks):
        p = out_dir / f"residual_{_safe(c.name)}.png"
        _plot_check(p, c, res.residual_before[i], res.residual_after[i],
                    f"{c.name}: before -> after the update")
        paths.append(p)
    for e in res.effects:
        if not e.stage_before:
            continue
        contrib = e.evidence.get("checks", {})
        best = max(range(len(res.checks)), key=lambda k: contrib.get(res.checks[k].name, 0.0))
        c = res.checks[best]
        p = out_dir / f"effect_{_safe(e.key)}.png"
        _plot_check(p, c, e.stage_before[best], e.stage_after[best],
                    f"{e.key} = {e.value:.3g} {e.unit} on {c.name}",
                    labels=(f"without {e.id}", f"with {e.id}"))
        paths.append(p)
    return paths


def _safe(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in name)


# --------------------------------------------------------------------------- writing


def write_outputs(res: DiagnoseResult, out_dir: str | Path, json_path: str | Path | None = None,
                  plots: bool = True, extra_json: dict[str, Any] | None = None) -> dict[str, Path]:
    """Write the updated table (blob, C, JSON), diagnose.json, report.txt and plots into
    ``out_dir``, and ``json_path`` if given: all or nothing (abbe.formats.output.Outputs:
    OUT is swapped in by one rename, the old result stays intact on any failure, no
    empty folder is left). Returns name -> final path."""
    from abbe.formats.output import Outputs

    with Outputs() as outs:
        tmp = outs.directory(out_dir, option="--out")
        jtmp = outs.file(json_path, option="--json") if json_path is not None else None
        return _write_into(res, Path(out_dir), tmp, jtmp, json_path, plots, extra_json)


def _write_into(res: DiagnoseResult, out: Path, tmp: Path, jtmp: Path | None,
                json_path: str | Path | None, plots: bool,
                extra_json: dict[str, Any] | None) -> dict[str, Path]:
    from abbe.formats.blob import write_blob
    from abbe.formats.c_source import write_c
    from abbe.formats.table_json import table_to_json
    from abbe.model.table import TableError
    try:
        blob = write_blob(res.table)
    except TableError as exc:  # the updated table does not fit the table format
        raise exc.located(file=str(out / "model.bin")) from None
    (tmp / "model.bin").write_bytes(blob)
    write_c(blob, tmp)
    (tmp / "model.json").write_text(json.dumps(table_to_json(res.table), indent=1) + "\n",
                                    encoding="utf-8")
    model_path = str(out / "model.bin")
    d = res.to_json(model_path)
    if extra_json:
        d.update(extra_json)
    text = json.dumps(clean_json(d), indent=1, default=_json_default, allow_nan=False) + "\n"
    (tmp / "diagnose.json").write_text(text, encoding="utf-8")
    (tmp / "report.txt").write_text(format_text(res, model_path), encoding="utf-8")
    if plots:
        write_plots(res, tmp / "plots")
    if jtmp is not None:
        jtmp.write_text(text, encoding="utf-8")
    # plots/ is replaced as a whole: plots of an earlier run that this run did not
    # write would mislead
    written = {str(src.relative_to(tmp)): out / src.relative_to(tmp)
               for src in sorted(tmp.rglob("*")) if not src.is_dir()}
    if json_path is not None:
        written["json"] = Path(json_path)
    return written


def clean_json(o: Any) -> Any:
    """Non-finite floats -> None (strict JSON), numpy scalars -> Python."""
    if isinstance(o, dict):
        return {k: clean_json(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [clean_json(v) for v in o]
    if isinstance(o, (np.floating, float)):
        f = float(o)
        return f if math.isfinite(f) else None
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.ndarray):
        return clean_json(o.tolist())
    return o


def _json_default(o: Any) -> Any:
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def effect_summary(e: EffectResult) -> str:
    """One line: id, value, interval, unit."""
    return f"{e.key}: {e.value:.3f} {e.unit} [{e.ci95[0]:.3f}, {e.ci95[1]:.3f}]"
