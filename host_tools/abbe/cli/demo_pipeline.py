"""The demo pipeline on a bundled example machine (README's main job).

fit -> tables -> build check -> predict -> diagnose -> predict again ->
compensate in the loop, with an HTML report and the paper's §3-4 figures side
by side with ours. Every step uses the same code a user runs (the CLI's fit,
the C library through its binding, the simulator as the machine).
"""

from __future__ import annotations

import html
import json
import shutil
import subprocess
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from abbe import paths
from abbe.analysis.iso230_4 import BallbarResult, evaluate_ballbar, plot_polar
from abbe.analysis.predict import Prediction, plot_prediction, predict, residual_uncertainty
from abbe.analysis.uncertainty import ballbar_budget, ballbar_uncertainty
from abbe.errors import AbbeInputError
from abbe.formats.machine import load_machine
from abbe.model import clib
from abbe.sim.compensation import campaign_test, compensated_circle

# The paper's §3-4 figures (Zhang & Chen 2021), for comparison in the report.
PAPER = {"prediction_max_residual_um": 4.5, "roundness_before_um": 19.9, "roundness_after_um": 8.2,
         "improvement_pct": 58.79, "ideal_roundness_um": 7.1, "ideal_improvement_pct": 64.32,
         "table4": {"fourier3": {"emax_um": 1.69, "r2": 0.8815}, "poly7": {"emax_um": 1.99, "r2": 0.8666}}}


@dataclass
class DemoResult:
    """Everything the demo measured (um, %, s)."""

    summary: dict[str, Any] = field(default_factory=dict)
    timings_s: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def _build_check(fit_dir: Path) -> dict[str, Any]:
    """The generated C compiles against the library headers and its CRC macro
    matches the CRC the C library computes for model.bin."""
    blob = (fit_dir / "model.bin").read_bytes()
    crc = clib.CModel(blob).crc
    header = (fit_dir / "abbe_model.h").read_text()
    macro = [ln for ln in header.splitlines() if "ABBE_MODEL_BLOB_CRC32" in ln and "#define" in ln]
    macro_crc = int(macro[0].split()[2].rstrip("uU"), 16) if macro else None
    result: dict[str, Any] = {"model_crc": f"0x{crc:08X}", "header_crc_matches": macro_crc == crc}
    include = paths.include_dir()
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc and include is not None:
        r = subprocess.run([cc, "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-fsyntax-only",
                            f"-I{include}", f"-I{fit_dir}", str(fit_dir / "abbe_model.c")],
                           capture_output=True, text=True)
        result["generated_c_compiles"] = r.returncode == 0
        if r.returncode != 0:
            raise AbbeInputError(f"generated C does not compile: {r.stderr.strip()}",
                                 file=str(fit_dir / "abbe_model.c"))
    else:
        result["generated_c_compiles"] = None  # no compiler or no source tree: not checked
    if not result["header_crc_matches"]:
        raise AbbeInputError("ABBE_MODEL_BLOB_CRC32 in the generated header does not match model.bin",
                             file=str(fit_dir / "abbe_model.h"))
    return result


def _table4(fit_dir: Path) -> dict[str, Any]:
    """The paper's Table 4 for our fit: held-out metrics of the chosen model and
    both paper models, for the Y positioning error (the paper's example) and
    summarised over all 18 terms."""
    model = json.loads((fit_dir / "model.json").read_text())
    rows = []
    for axis, ax in model["axes"].items():
        for term, t in ax["terms"].items():
            met = t["metrics"]
            row: dict[str, Any] = {"axis": axis, "term": term, "name": t["name"], "unit": t["unit"],
                                   "family": t["family"]}
            for k in ("chosen", "paper_fourier3", "paper_poly7"):
                held = met.get(k, {}).get("held_out", {})
                emax = next((v for name, v in held.items() if name.startswith("emax")), None)
                row[f"{k}_emax"] = emax          # in the term's unit (um or urad)
                row[f"{k}_r2"] = held.get("r2")
            rows.append(row)
    beats = sum(1 for r in rows if r["chosen_emax"] is not None
                and r["chosen_emax"] <= min(r["paper_fourier3_emax"] or np.inf, r["paper_poly7_emax"] or np.inf))
    y_pos = next((r for r in rows if r["axis"] == "Y" and r["term"] == "dy"), None)
    return {"rows": rows, "chosen_best_count": beats, "n_terms": len(rows), "y_positioning": y_pos}


def _roundness(res: BallbarResult) -> dict[str, float]:
    na, nb = res.axis_names()
    return {"G_um": res.both.G_um, "G_ccw_um": res.per_direction["ccw"].G_um,
            "G_cw_um": res.per_direction["cw"].G_um,
            f"center_{na.lower()}_um": res.both.center_um[0], f"center_{nb.lower()}_um": res.both.center_um[1],
            "H_um": res.H_um}


#: the Monte Carlo check of the diagnosis's U (about 5 s on the demo; docs/uncertainty.md)
DIAGNOSE_MC_DRAWS = 200


def _diagnose_step(machine_file: Path, model_path: Path, ballbar: str,
                   out_dir: Path) -> tuple[Path, dict, Any]:
    """Run the discrepancy workflow as ``abbe diagnose`` runs it (its parser, its defaults,
    its outputs and printout); returns the updated model, its JSON summary and the
    DiagnoseResult (its residuals give the diagnosed model's U)."""
    from abbe.cli import conventions
    from abbe.cli.diagnose import diagnose_three_axis
    from abbe.cli.entry import build_parser
    from abbe.diagnose.report import format_text

    json_path = out_dir / "diagnose.json"
    argv = ["diagnose", str(machine_file), "--model", str(model_path), "--ballbar", ballbar,
            "--json", str(json_path), "-o", str(out_dir / "diagnose"),
            "--mc", str(DIAGNOSE_MC_DRAWS)]
    args = conventions.clean(build_parser().parse_args(argv))
    res, written = diagnose_three_axis(args)
    print(format_text(res, str(written["model.bin"])), end="")
    print(f"wrote {len(written)} files to {args.out} and {json_path}")
    d = json.loads(json_path.read_text())
    return Path(d["model"]), d, res


def diagnosed_residual_uncertainty(res: Any, p: Prediction, budget: Any, draws: int = 200,
                                   seed: int = 20233) -> dict[str, Any]:
    """The diagnosed model's (table + servo) residual on the ballbar circle ``p`` (max |r|,
    RMS, um) with U (k = 2) from the ballbar budget, as :func:`residual_uncertainty` gives
    the table's: the diagnosis's own residual of that check (its set-up nuisance, centre and
    radius, removed by least squares) is linear in the readings once the model is held
    fixed, r(y') = r + P (y' - y) with P the nuisance removal; the same inputs (scale, drift
    ramp, resolution) act on the readings, and a Monte Carlo of ``draws`` checks it."""
    from abbe.analysis.predict import trace_residual_uncertainty
    i = next(k for k, c in enumerate(res.checks) if c.kind == "ballbar" and c.name == p.name)
    check = res.checks[i]
    r_after = np.asarray(res.residual_after[i], dtype=np.float64)
    m = p.trace.data_mask()
    y = np.asarray(p.trace.radial_um, dtype=np.float64)[m]
    if y.shape != r_after.shape or not np.allclose(y, check.y):
        raise AbbeInputError(f"the diagnosis's ballbar check {p.name!r} does not hold the "
                             "trace's readings", field=f"ballbar.{p.name}")
    A = check.nuisance[:, np.any(check.nuisance != 0, axis=0)]

    def residual_of(rr: np.ndarray) -> np.ndarray:
        dy = rr[m] - y
        coef, *_ = np.linalg.lstsq(A, dy, rcond=None)
        return r_after + dy - A @ coef

    return trace_residual_uncertainty(
        p.trace, float(p.test.radius_mm), residual_of, budget, draws=draws, seed=seed,
        note="measurement of the circle only; the diagnosed model (table and the "
             "prediction-only effects) is held fixed")


def run_demo(example_dir: Path, out_dir: Path, *, diagnose: bool = True,
             log: Callable[[str], None] = print) -> DemoResult:
    """Run the whole pipeline on ``example_dir`` (machine.toml, laser/, ballbar/,
    truth/) and write the report into ``out_dir``."""
    from abbe.cli.entry import COMMANDS
    from abbe.cli.entry import main as cli_main

    t_start = time.perf_counter()
    res = DemoResult()
    machine_file = example_dir / "machine.toml"
    truth_file = example_dir / "truth" / "truth.json"
    if not machine_file.is_file() or not truth_file.is_file():
        raise AbbeInputError("an example machine needs machine.toml and truth/truth.json "
                             "(written by abbe simulate)", file=str(example_dir))
    out_dir.mkdir(parents=True, exist_ok=True)
    machine = load_machine(machine_file)
    if not machine.ballbar:
        raise AbbeInputError("the example machine has no ballbar test", file=str(machine_file))
    ballbar = sorted(machine.ballbar)[0]

    def lap(name: str, t0: float) -> None:
        res.timings_s[name] = round(time.perf_counter() - t0, 2)

    # 1. fit -> tables (blob, C, JSON, report); the fit itself checks C vs reference
    t0 = time.perf_counter()
    fit_dir = out_dir / "fit"
    log(f"[1/6] fit {machine_file} -> {fit_dir}")
    if cli_main(["fit", str(machine_file), "-o", str(fit_dir)]) != 0:
        raise AbbeInputError("abbe fit failed", file=str(machine_file))
    table4 = _table4(fit_dir)
    clib_check = json.loads((fit_dir / "model.json").read_text()).get("clib_check", {})
    lap("fit", t0)

    # 2. build check: the generated C compiles; its CRC is the blob's
    t0 = time.perf_counter()
    build = _build_check(fit_dir)
    log(f"[2/6] build check: generated C compiles={build['generated_c_compiles']}, "
        f"CRC {build['model_crc']} matches={build['header_crc_matches']}; C vs reference "
        f"f32 {clib_check.get('max_diff_f32_nm')} nm, q {clib_check.get('max_diff_q_nm')} nm")
    lap("build_check", t0)

    # 3. predict the ballbar test with the laser-only model (C library)
    t0 = time.perf_counter()
    p_laser = predict(machine, fit_dir / "model.bin", ballbar)
    plot_prediction(p_laser, out_dir / "predict_laser_only.png",
                    title=f"{ballbar}: prediction of the laser-only model vs measurement")
    log(f"[3/6] predict ({ballbar}, laser-only model): residual max {p_laser.max_residual_um:.2f} um, "
        f"RMS {p_laser.rms_residual_um:.2f} um")
    lap("predict_laser_only", t0)

    # 4. diagnose: what is the model missing? add it, predict again
    t0 = time.perf_counter()
    final_model = fit_dir / "model.bin"
    p_final: Prediction = p_laser
    diag: dict[str, Any] | None = None
    diag_res: Any = None
    if diagnose and "abbe.cli.diagnose" in COMMANDS:
        final_model, diag, diag_res = _diagnose_step(machine_file, fit_dir / "model.bin",
                                                     ballbar, out_dir)
        p_final = predict(machine, final_model, ballbar)
        plot_prediction(p_final, out_dir / "predict_updated.png",
                        title=f"{ballbar}: prediction of the updated model vs measurement")
        names = ", ".join(f"{e['id']} = {e['value']:.3g} {e['unit']}" for e in diag["effects"]) or "none"
        log(f"[4/6] diagnose: effects {names}; prediction residual max "
            f"{p_laser.max_residual_um:.2f} -> {p_final.max_residual_um:.2f} um")
    else:
        res.notes.append("diagnose step not available: the laser-only model is compensated")
        log("[4/6] diagnose: not available, compensating with the laser-only model")
    lap("diagnose", t0)

    # 5. compensate in the loop: the virtual machine runs the circle again with the
    # C compensator correcting the commanded positions every 1 ms
    t0 = time.perf_counter()
    test, end_s, gap_s, noise_um = campaign_test(truth_file, ballbar)
    before = p_final.before
    after_trace, stats = compensated_circle(truth_file, test, final_model.read_bytes(), end_s + gap_s,
                                            noise_um, seed=1)
    after = evaluate_ballbar(after_trace, test)
    plot_polar(before, out_dir / "ballbar_before.png", title=f"{ballbar} before compensation")
    plot_polar(after, out_dir / "ballbar_after.png", title=f"{ballbar} with the C compensator")
    g0, g1 = before.both.G_um, after.both.G_um
    # G with its expanded uncertainty (ISO 230-4 budget of the machine file, else the
    # ballbar class defaults), as `abbe ballbar` states it
    budget, _limits = ballbar_budget(machine)
    U0 = ballbar_uncertainty(p_final.trace, p_final.test, before, budget).results[
        "G_bidirectional"].U_um
    U1 = ballbar_uncertainty(after_trace, test, after, budget).results["G_bidirectional"].U_um
    # the prediction residual's U from the same budget (the measured circle's inputs; the
    # table as written is exact), checked by a Monte Carlo of the same inputs
    res_u = residual_uncertainty(p_final, budget, draws=200)
    # the diagnosed model's residual on the same circle, with U from the same budget
    diag_u = (diagnosed_residual_uncertainty(diag_res, p_final, budget, draws=200)
              if diag_res is not None else None)
    improvement = 100.0 * (1.0 - g1 / g0)
    log(f"[5/6] compensate in the loop: roundness {g0:.2f} -> {g1:.2f} um ({improvement:.1f} % better; "
        f"model-ideal {p_final.ideal_improvement_pct:.1f} %)")
    lap("compensate", t0)

    res.summary = {
        "machine": machine.name, "ballbar": ballbar,
        "prediction_max_residual_um": round(p_final.max_residual_um, 3),
        "prediction_rms_residual_um": round(p_final.rms_residual_um, 3),
        "prediction_max_residual_U_um": round(res_u["max_abs"]["U_stated_um"], 4),
        "prediction_rms_residual_U_um": round(res_u["rms"]["U_stated_um"], 4),
        "prediction_residual_uncertainty": res_u,
        "prediction_max_residual_laser_only_um": round(p_laser.max_residual_um, 3),
        # with the effects the table cannot hold (servo lag) in the prediction too (diagnose's
        # model), on the same circle: its residual there, with U (k = 2)
        "prediction_max_residual_with_prediction_effects_um":
            round(diag_u["max_abs"]["value_um"], 3) if diag_u else None,
        "prediction_rms_residual_with_prediction_effects_um":
            round(diag_u["rms"]["value_um"], 3) if diag_u else None,
        "prediction_max_residual_with_prediction_effects_U_um":
            round(diag_u["max_abs"]["U_stated_um"], 4) if diag_u else None,
        "prediction_rms_residual_with_prediction_effects_U_um":
            round(diag_u["rms"]["U_stated_um"], 4) if diag_u else None,
        "diagnosed_residual_uncertainty": diag_u,
        "prediction_rms_residual_laser_only_um": round(p_laser.rms_residual_um, 3),
        "roundness_before_um": round(g0, 3), "roundness_after_um": round(g1, 3),
        "roundness_before_U_um": round(U0, 3), "roundness_after_U_um": round(U1, 3),
        "roundness_budget": budget.source,
        "improvement_pct": round(improvement, 2),
        "ideal_roundness_um": round(p_final.ideal_G_um, 3),
        "ideal_improvement_pct": round(p_final.ideal_improvement_pct, 2),
        "achieved_of_ideal_pct": round(100.0 * improvement / p_final.ideal_improvement_pct, 1)
        if p_final.ideal_improvement_pct > 0 else None,
        "before": {k: round(v, 3) for k, v in _roundness(before).items()},
        "after": {k: round(v, 3) for k, v in _roundness(after).items()},
        "compensator": stats,
        "effects": diag["effects"] if diag else None,
        "diagnose_gap": diag["gap"] if diag else None,
        "diagnose_uncertainty": diag.get("uncertainty") if diag else None,
        "table4": {"chosen_best_count": table4["chosen_best_count"], "n_terms": table4["n_terms"],
                   "y_positioning": table4["y_positioning"], "rows": table4["rows"]},
        "build_check": build, "clib_check": clib_check,
        "model": str(final_model.relative_to(out_dir)) if final_model.is_relative_to(out_dir)
        else str(final_model),
        "paper": PAPER,
    }
    res.timings_s["total"] = round(time.perf_counter() - t_start, 2)
    res.summary["timings_s"] = res.timings_s
    (out_dir / "index.html").write_text(_report_html(res, table4, diag is not None))
    log(f"[6/6] report: {out_dir / 'index.html'} ({res.timings_s['total']:.1f} s)")
    return res


# --------------------------------------------------------------------------- report


def fmt_U(U_um: float) -> str:
    """An expanded uncertainty with two significant digits below 0.1 um (a U of 0.002 um
    printed as 0.00 would read as none), two decimals above."""
    return f"{U_um:.2f}" if U_um >= 0.1 else f"{U_um:.2g}"


def _td(v: Any, nd: int = 2) -> str:
    if v is None:
        return "<td>-</td>"
    if isinstance(v, bool):
        return f"<td>{_yes_no(v)}</td>"
    if isinstance(v, float):
        return f"<td>{v:.{nd}f}</td>"
    return f"<td>{html.escape(str(v))}</td>"


def _yes_no(v: Any) -> str:
    """A check's outcome in words (a report is read by people, not Python)."""
    if v is None:
        return "not checked"
    if isinstance(v, bool):
        return "yes" if v else "no"
    return html.escape(str(v))


def _timings(timings_s: dict[str, float]) -> str:
    return ", ".join(f"{html.escape(k.replace('_', ' '))} {v:.1f} s" for k, v in timings_s.items())


def _clib_check(c: dict[str, Any] | None) -> str:
    if not c:
        return "not run"
    return (f"{c.get('n_points')} points, max |f32 - reference| {c.get('max_diff_f32_nm')} nm, "
            f"max |q - reference| {c.get('max_diff_q_nm')} nm (bound {c.get('bound_nm')} nm)")


def _U_cell(e: dict[str, Any]) -> str:
    """An effect's U (k = 2), and where it comes from when the Monte Carlo's is stated."""
    if e.get("U") is None:
        return "-"
    return f"{e['U']:.3g}" + (" (Monte Carlo)" if e.get("U_from") == "Monte Carlo" else "")


def _diagnose_budget(unc: dict[str, Any] | None, effects: list[dict[str, Any]]) -> str:
    """The diagnosis's budget, folded: each effect's lines (u) and the Monte Carlo's U."""
    if not unc:
        return ""
    names: list[str] = []
    for e in effects:
        names += [k for k in (e.get("budget_u") or {}) if k not in names]

    def small(e: dict[str, Any], n: str) -> bool:  # below 0.1 % of the effect's u
        return ((e.get("budget_u") or {}).get(n) or 0.0) < 1e-3 * max(e.get("u") or 0.0, 1e-300)

    # a line negligible for every effect (the bar's length: the circle's radius absorbs it)
    gone = [n for n in names if all(small(e, n) for e in effects)]
    names = [n for n in names if n not in gone]
    head = "".join(f"<th>{html.escape(n)}</th>" for n in names)
    rows = "".join(
        f"<tr><td class='l'>{html.escape(e['key'])}</td>"
        + "".join("<td>&ndash;</td>" if small(e, n) else
                  f"<td>{(e.get('budget_u') or {}).get(n) or 0.0:.2g}</td>" for n in names)
        + f"<td>{e.get('U_first_order') or e.get('U') or 0.0:.3g}</td>"
        + (f"<td>{e['U_mc']:.3g} ({100 * e['mc_agreement']:+.1f} %)</td>"
           if e.get("U_mc") is not None and e.get("mc_agreement") is not None
           else "<td>-</td>") + "</tr>" for e in effects)
    note = ("&ndash;: below 0.1 % of the effect's u." + (
        " Negligible for every effect, not shown: " + html.escape(", ".join(gone)) + "."
        if gone else ""))
    mc = unc.get("monte_carlo") or {}
    return ("<details><summary>Budget of the named effects (standard uncertainties u, in "
            "each effect's unit)</summary>"
            f"<table><tr><th class='l'>effect</th>{head}<th>U first order</th>"
            f"<th>U Monte Carlo</th></tr>{rows}</table>"
            f"<p class='small'>{note} {html.escape(unc.get('method', ''))}. Monte Carlo (GUM S1): "
            f"{mc.get('draws', 0)} draws re-running the final fit, {mc.get('agree_within_10pct', 0)} "
            f"of {mc.get('of', 0)} figures within 10 %; beyond, its U is stated.</p></details>")


def _gap_U(g: dict[str, Any], key: str) -> str:
    v, U = g.get(key), g.get(key[:-3] + "_U_um")
    if v is None:
        return "<td>-</td>"
    return f"<td>{v:.3f}" + (f" &plusmn; {U:.3f}" if U is not None else "") + "</td>"


def _gap_table(gap: dict[str, Any]) -> str:
    rows = ""
    for label, before, after in (("fitted data", gap.get("before"), gap.get("after")),
                                 ("held-out data", gap.get("held_out_before"),
                                  gap.get("held_out_after"))):
        if before and after:
            rows += (f"<tr><td>{label}</td>{_gap_U(before, 'rms_um')}{_gap_U(after, 'rms_um')}"
                     f"{_gap_U(before, 'max_um')}{_gap_U(after, 'max_um')}</tr>")
    return ("<table><tr><th>residual (um)</th><th>RMS before</th><th>RMS after</th>"
            f"<th>max before</th><th>max after</th></tr>{rows}</table>") if rows else ""


def _counters(c: dict[str, Any] | None) -> str:
    return ", ".join(f"{html.escape(str(k).replace('_', ' '))} {_yes_no(v)}" for k, v in (c or {}).items())


def _demo_status(s: dict[str, Any]) -> tuple[str, list[str]]:
    """The band's verdict: every check passed (pass) or which failed (fail)."""
    failed = []
    b, c = s.get("build_check") or {}, s.get("clib_check")
    if b.get("generated_c_compiles") is False:
        failed.append("the generated C does not compile")
    if b.get("header_crc_matches") is False:
        failed.append("the generated header's CRC differs from model.bin's")
    if c and max(c["max_diff_f32_nm"], c["max_diff_q_nm"]) > c["bound_nm"]:
        failed.append("the C library and the reference disagree beyond the bound")
    if s["roundness_after_um"] >= s["roundness_before_um"]:
        failed.append("the compensation did not improve the roundness")
    return ("fail" if failed else "pass"), failed


def residual_sentence(s: dict[str, Any]) -> str:
    """Why the table's prediction residual and the diagnosed model's differ (one sentence)."""
    servo = [e for e in (s.get("effects") or []) if e["id"] == "servo_mismatch"]
    with_fx = s.get("prediction_max_residual_with_prediction_effects_um")
    if with_fx is None:
        return ""
    what = (f"the servo mismatch of {servo[0]['plane']} ({servo[0]['value']:.2f} ms lag)"
            if servo else "the prediction-only effects")
    return (f"The table's prediction leaves {s['prediction_max_residual_um']:.2f} um (max) of the "
            f"measured circle, the diagnosed model {with_fx:.2f} um: the model also holds {what}, "
            "a dynamic error that depends on feed and direction, which a position table cannot "
            "hold.")


def _report_html(res: DemoResult, table4: dict[str, Any], with_diag: bool) -> str:
    import datetime as dt

    from abbe import __version__
    from abbe.analysis.certificate import band, page_head
    s = res.summary
    p = PAPER
    y = table4["y_positioning"] or {}
    t4 = "".join(
        f"<tr><td>{html.escape(r['name'])}</td><td>{html.escape(r['family'])}</td><td>{r['unit']}</td>"
        + _td(r["chosen_emax"], 3) + _td(r["paper_fourier3_emax"], 3)
        + _td(r["paper_poly7_emax"], 3) + _td(r["chosen_r2"], 4) + "</tr>"
        for r in table4["rows"])
    status, failed = _demo_status(s)
    why = residual_sentence(s)
    c = s.get("clib_check")
    checks = ("C library = float64 reference within "
              f"{max(c['max_diff_f32_nm'], c['max_diff_q_nm']):.3g} nm (bound {c['bound_nm']:g} nm)"
              if c else "C library check not run")
    checks += (f"; generated C compiles: {_yes_no(s['build_check'].get('generated_c_compiles'))}"
               f"; header CRC matches: {_yes_no(s['build_check']['header_crc_matches'])}")
    headline = (f"{'All checks pass' if status == 'pass' else 'FAILED: ' + html.escape('; '.join(failed))}"
                f" &mdash; compensated roundness G {s['roundness_before_um']:.2f} &plusmn; "
                f"{s['roundness_before_U_um']:.2f} &rarr; {s['roundness_after_um']:.2f} &plusmn; "
                f"{s['roundness_after_U_um']:.2f} um (U, k = 2; "
                f"{s['improvement_pct']:.1f} % better, "
                f"{s['achieved_of_ideal_pct']} % of what the model could ideally give)")
    with_fx = s.get("prediction_max_residual_with_prediction_effects_um")
    body = ("<table><tr><th class='l'>figure</th><th>max (um)</th><th>RMS (um)</th>"
            "<th>U, k = 2 (um)</th></tr>"
            f"<tr><td class='l'>measured circle, not compensated: roundness G</td>"
            f"<td>{s['roundness_before_um']:.2f}</td><td>&ndash;</td>"
            f"<td>{s['roundness_before_U_um']:.2f}</td></tr>"
            f"<tr><td class='l'>compensated in the loop by the C library: roundness G</td>"
            f"<td>{s['roundness_after_um']:.2f}</td><td>&ndash;</td>"
            f"<td>{s['roundness_after_U_um']:.2f}</td></tr>"
            f"<tr><td class='l'>prediction residual, table (what a controller applies)</td>"
            f"<td>{s['prediction_max_residual_um']:.2f}</td>"
            f"<td>{s['prediction_rms_residual_um']:.2f}</td>"
            f"<td>{fmt_U(s['prediction_max_residual_U_um'])} (max), "
            f"{fmt_U(s['prediction_rms_residual_U_um'])} (RMS)</td></tr>"
            + (f"<tr><td class='l'>prediction residual, diagnosed model (table + servo)</td>"
               f"<td>{with_fx:.2f}</td>"
               f"<td>{s['prediction_rms_residual_with_prediction_effects_um']:.2f}</td>"
               f"<td>{fmt_U(s['prediction_max_residual_with_prediction_effects_U_um'])} (max), "
               f"{fmt_U(s['prediction_rms_residual_with_prediction_effects_U_um'])} (RMS)</td></tr>"
               if with_fx is not None else "")
            + "</table>"
            + (f"<p>{html.escape(why)}</p>" if why else "")
            + f"<p class='small'>{html.escape(checks)}.</p>")
    rows = [("Machine", f"{s['machine']} (three-axis, simulated: the paper's geometry)"),
            ("Test", f"6D laser lines X, Y, Z (fit); ballbar {s['ballbar']} (check and "
                     "compensation in the loop)"),
            ("Date", dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%d")),
            ("Software", f"abbe {__version__}; tables in model.bin (CRC "
                         f"{s['build_check']['model_crc']})")]
    out = page_head(f"abbe demo: {s['machine']}, error model and compensation", rows)
    out.append(band(status, headline, body))
    out.append("<div class='plots'><img src='ballbar_before.png' alt='ballbar before'>"
               "<img src='ballbar_after.png' alt='ballbar after'></div>")
    notes = "".join(f"<li>{html.escape(n)}</li>" for n in res.notes)
    if notes:
        out.append(f"<ul>{notes}</ul>")
    out.append("<h2>Details</h2>")
    if with_diag:
        eff_rows = "".join(
            f"<tr><td class='l'>{html.escape(e['id'])}</td><td>{e['value']:.4g} {html.escape(e['unit'])}</td>"
            f"<td>{_U_cell(e)}</td>"
            f"<td>[{e['ci95'][0]:.4g}, {e['ci95'][1]:.4g}]</td>"
            f"<td class='l'>{html.escape(e.get('compensated_by', ''))}</td></tr>"
            for e in (s["effects"] or []))
        gap = s["diagnose_gap"] or {}
        out.append(
            "<h2>What the laser-only model misses (diagnose)</h2>"
            "<table><tr><th class='l'>effect</th><th>value</th><th>U (k = 2)</th>"
            "<th>95 % interval</th><th class='l'>compensated by</th></tr>"
            f"{eff_rows or '<tr><td colspan=5>nothing significant is missing</td></tr>'}</table>"
            f"{_diagnose_budget(s.get('diagnose_uncertainty'), s['effects'] or [])}"
            "<details><summary>Gap before / after, prediction plot</summary>"
            f"<p>The gap between measurement and prediction, before and after the named effects "
            f"were added to the model (U, k = 2: the ballbar's budget and the readings' noise):</p>"
            f"{_gap_table(gap)}"
            f"<p>Details: <a href='diagnose/'>diagnose/</a>.</p>"
            f"<img src='predict_updated.png' class='wide' alt='prediction, updated'></details>")
    out.append(
        "<h2>Prediction with the laser-only model</h2>"
        f"<p>Residual max {s['prediction_max_residual_laser_only_um']} um, RMS "
        f"{s['prediction_rms_residual_laser_only_um']} um.</p>"
        "<details><summary>Prediction plot</summary>"
        "<img src='predict_laser_only.png' class='wide' alt='prediction, laser only'></details>")
    out.append(
        "<h2>Fit (held-out metrics, the paper's Table 4 layout)</h2>"
        f"<p>Y positioning error d_y(y), the paper's example: chosen model emax "
        f"{y.get('chosen_emax') or float('nan'):.3f} um, 3rd-order Fourier "
        f"{y.get('paper_fourier3_emax') or float('nan'):.3f} um, 7th-order polynomial "
        f"{y.get('paper_poly7_emax') or float('nan'):.3f} um (paper: "
        f"{p['table4']['fourier3']['emax_um']} / {p['table4']['poly7']['emax_um']} um in-sample). "
        f"The chosen model has the lowest held-out emax on {table4['chosen_best_count']} of "
        f"{table4['n_terms']} terms. Full report: <a href='fit/report/index.html'>fit/report/</a>.</p>"
        "<details><summary>Every term (18 rows)</summary>"
        "<table><tr><th class='l'>term</th><th>chosen family</th><th>unit</th><th>emax chosen</th>"
        f"<th>emax Fourier-3</th><th>emax poly-7</th><th>R&sup2; chosen</th></tr>{t4}</table>"
        "</details>")
    b, a = s["before"], s["after"]
    out.append(
        "<h2>Against the paper (Zhang &amp; Chen 2021, &sect;4)</h2>"
        "<details><summary>abbe's figures beside the paper's, ballbar parameters, compensator "
        "counters, timings</summary>"
        "<table><tr><th></th><th>abbe</th><th>paper</th></tr>"
        f"<tr><td>prediction max residual, table through the C library (um)</td>{_td(s['prediction_max_residual_um'])}{_td(p['prediction_max_residual_um'])}</tr>"
        f"<tr><td>... with the prediction-only effects (servo lag) too (um)</td>{_td(with_fx)}<td>-</td></tr>"
        f"<tr><td>roundness before (um)</td>{_td(s['roundness_before_um'])}{_td(p['roundness_before_um'])}</tr>"
        f"<tr><td>ideal compensated roundness (um)</td>{_td(s['ideal_roundness_um'])}{_td(p['ideal_roundness_um'])}</tr>"
        f"<tr><td>ideal improvement (%)</td>{_td(s['ideal_improvement_pct'])}{_td(p['ideal_improvement_pct'])}</tr>"
        f"<tr><td>roundness after (um)</td>{_td(s['roundness_after_um'])}{_td(p['roundness_after_um'])}</tr>"
        f"<tr><td>improvement (%)</td>{_td(s['improvement_pct'])}{_td(p['improvement_pct'])}</tr>"
        f"<tr><td>achieved / ideal improvement (%)</td>{_td(s['achieved_of_ideal_pct'], 1)}<td>91.4</td></tr>"
        "</table>"
        "<table><tr><th></th><th>G both</th><th>G CCW</th><th>G CW</th><th>centre X</th>"
        "<th>centre Y</th><th>H</th></tr>"
        f"<tr><td>before</td>{''.join(_td(v) for v in b.values())}</tr><tr><td>after</td>"
        f"{''.join(_td(v) for v in a.values())}</tr></table>"
        f"<p>Compensator counters: {_counters(s['compensator'])}.</p>"
        f"<p>Timings: {_timings(res.timings_s)}. Units: um, urad, mm.</p></details>")
    out.append("<p class='small'>abbe demo: fit from 6D laser lines, tables for the C library, "
               "prediction of the ballbar test, diagnosis of what the model misses, compensation "
               "in the loop on the virtual machine with the C compensator.</p></body></html>")
    return "\n".join(out) + "\n"
