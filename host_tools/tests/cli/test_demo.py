"""The README's main job: the demo pipeline on examples/vmc500 meets the
paper's figures (the issue's targets), and writes its report and JSON."""

from __future__ import annotations

import contextlib
import io
import json
from pathlib import Path

import pytest

from abbe.cli.entry import main as cli_main
from abbe.model import clib

pytestmark = pytest.mark.skipif(not clib.available(), reason="C library not built (build/lib/libabbe.so)")

KEYS = ("prediction_max_residual_um", "prediction_max_residual_laser_only_um", "roundness_before_um",
        "roundness_after_um", "improvement_pct", "ideal_improvement_pct")


@pytest.fixture(scope="module")
def demo(tmp_path_factory) -> tuple[Path, dict]:
    out = tmp_path_factory.mktemp("demo")
    # as scripts/demo.sh runs it: the JSON inside the report folder
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        rc = cli_main(["demo", "-o", str(out / "report"), "--json", str(out / "report" / "summary.json")])
    assert rc == 0
    assert not [p for p in out.rglob("*") if ".abbe-" in p.name]   # no staging left
    (out / "printed.txt").write_text(printed.getvalue())
    return out, json.loads((out / "report" / "summary.json").read_text())


def test_demo_prints_the_final_paths(demo) -> None:
    """Every path the demo prints is one the user finds: OUT, never its staging folder."""
    out, _ = demo
    text = (out / "printed.txt").read_text()
    assert ".abbe-" not in text, text
    assert f"{out / 'report' / 'diagnose' / 'model.bin'}" in text, text
    assert "wrote " in text and f"{out / 'report' / 'fit'}" in text, text


def test_demo_report_speaks_words_not_python(demo) -> None:
    out, _ = demo
    html = (out / "report" / "index.html").read_text()
    assert "generated C compiles: yes" in html or "generated C compiles: not checked" in html
    assert "header CRC matches: yes" in html
    assert "True" not in html and "False" not in html


def test_demo_writes_report_and_json(demo) -> None:
    out, s = demo
    for k in KEYS:
        assert isinstance(s[k], (int, float)), k
    html = (out / "report" / "index.html").read_text()
    for img in ("predict_laser_only.png", "ballbar_before.png", "ballbar_after.png"):
        assert img in html and (out / "report" / img).stat().st_size > 10_000
    assert (out / "report" / "fit" / "report" / "index.html").is_file()
    assert s["build_check"]["header_crc_matches"] is True


def test_demo_meets_the_paper(demo) -> None:
    """Compensation at least as good as the paper's measured 58.79 % and within
    90 % of what the model could ideally achieve; prediction within the paper's
    4.5 um max residual with the final model."""
    _, s = demo
    assert s["roundness_before_um"] > 15.0
    assert s["improvement_pct"] >= 58.79
    assert s["improvement_pct"] >= 0.9 * s["ideal_improvement_pct"]
    assert s["prediction_max_residual_um"] <= 4.5
    assert s["compensator"]["limit_trips"] == 0


def test_demo_fit_beats_paper_models_on_wave_type_errors(demo) -> None:
    """The issue's criterion: on wave-type errors (those the example's true
    machine gives a wave), the selected model has a lower held-out emax than
    both the paper's 3rd-order Fourier and 7th-order polynomial."""
    import tomllib

    _, s = demo
    spec = tomllib.loads((Path(__file__).resolve().parents[3] / "examples" / "vmc500" / "spec.toml").read_text())
    wave = {(a, t) for a, terms in spec["errors"].items() for t, shape in terms.items()
            if isinstance(shape, dict) and any(k.startswith("wave_") and k != "wave_phase_deg" for k in shape)}
    assert len(wave) >= 5
    rows = {(r["axis"], r["term"]): r for r in s["table4"]["rows"]}
    assert len(rows) == 18
    for key in sorted(wave):
        r = rows[key]
        assert r["chosen_emax"] < r["paper_fourier3_emax"], key
        assert r["chosen_emax"] < r["paper_poly7_emax"], key


def test_demo_diagnoses_the_squareness_and_the_gap_shrinks(demo) -> None:
    """Issue 5 in the demo: the laser cannot see the XY squareness; diagnose names
    it (true value 30 urad), adds it to the table, and the gap shrinks."""
    out, s = demo
    effects = {e["id"]: e for e in s["effects"]}
    sq = effects["squareness_xy"]
    assert sq["unit"] == "urad" and sq["ci95"][0] <= sq["value"] <= sq["ci95"][1]
    assert 25.0 < sq["value"] < 35.0
    gap = s["diagnose_gap"]
    assert gap["after"]["rms_um"] < 0.5 * gap["before"]["rms_um"]
    assert gap["held_out_after"]["rms_um"] < 0.5 * gap["held_out_before"]["rms_um"]
    assert s["prediction_max_residual_um"] < s["prediction_max_residual_laser_only_um"]
    # the compensated model is the updated one, and it holds the squareness
    from abbe.formats.blob import read_blob
    model = read_blob((out / "report" / s["model"]).read_bytes())
    assert abs(model.squareness_urad[0] - sq["value"]) < 0.01


def test_demo_states_each_named_effect_with_its_uncertainty(demo) -> None:
    """Every named effect and the gap figures carry U (k = 2) and the budget; the Monte
    Carlo (200 draws re-running the final fit) agrees within 10 % on every effect, and
    where a gap figure parts by more, its U is the one stated; the report shows them."""
    out, s = demo
    unc = s["diagnose_uncertainty"]
    figs = unc["monte_carlo"]["figures"]
    assert unc["monte_carlo"]["draws"] == 200
    # the demo's diagnose.json by the independent reader (docs/formats.md, "diagnose JSON")
    from diagnose_json_reader import read_diagnose_uncertainty
    read_diagnose_uncertainty(out / "report" / "diagnose" / "diagnose.json", mc=200)
    for e in s["effects"]:
        assert e["U"] > 0 and e["budget_u"], e["key"]
        assert abs(figs[e["key"]]["agreement"]) <= 0.10, (e["key"], figs[e["key"]])
        assert e["U_from"] == "first order"
    for which in ("before", "after"):
        for fig in ("rms_um", "max_um"):
            g = unc["gap"][which][fig]
            stated = g["U_mc"] if abs(g["mc_agreement"]) > 0.10 else g["U_first_order"]
            assert g["U"] == pytest.approx(stated, rel=1e-4)
            assert s["diagnose_gap"][which][fig[:-3] + "_U_um"] == pytest.approx(g["U"], rel=1e-3)
    page = (out / "report" / "index.html").read_text()
    assert "<th>U (k = 2)</th>" in page and "Budget of the named effects" in page
    sq = next(e for e in s["effects"] if e["key"] == "squareness_xy")
    assert f"{sq['U']:.3g}" in page


def test_demo_report_reads_verdict_first_in_chromium(demo, tmp_path) -> None:
    """The three-axis demo report: machine, test, date, then the band (all checks and the
    compensated roundness) in the top quarter of the first screen, the ballbar plots
    right after it, the details folded below; one sentence says why the table's
    residual and the diagnosed model's differ."""
    from report_shots import assert_band_before, assert_verdict_first, needs_chromium, screenshot
    out, s = demo
    page = (out / "report" / "index.html").read_text()
    assert_band_before(page, "ballbar_before.png", "<details>", "Fit (held-out")
    assert "which a position table cannot hold" in page
    assert f"{s['prediction_max_residual_um']:.2f} um (max)" in page
    assert "@media print" in page
    if needs_chromium.args[0]:
        pytest.skip("chromium not installed: the report is not rendered")
    img = screenshot(out / "report" / "index.html", tmp_path / "shot.png", "demo_three_axis")
    assert assert_verdict_first(img) == "pass"


def test_demo_states_the_roundness_with_its_uncertainty(demo) -> None:
    """G before and after carries U (k = 2) from the same ISO 230-4 budget `abbe ballbar`
    uses: the before-figure's U is the one `abbe ballbar` states for the same circle."""
    out, s = demo
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert cli_main(["ballbar", str(Path(__file__).resolve().parents[3] / "examples" /
                                         "vmc500" / "machine.toml"), s["ballbar"], "--no-plot",
                         "--json", "-"]) == 0
    bb = json.loads(printed.getvalue())["uncertainty"]["results"]["G_bidirectional"]
    assert s["roundness_before_U_um"] == pytest.approx(bb["U_um"], abs=1e-3)
    assert 0 < s["roundness_after_U_um"] < s["roundness_after_um"]
    html = (out / "report" / "index.html").read_text()
    assert (f"{s['roundness_before_um']:.2f} &plusmn; {s['roundness_before_U_um']:.2f} &rarr; "
            f"{s['roundness_after_um']:.2f} &plusmn; {s['roundness_after_U_um']:.2f} um "
            "(U, k = 2") in html


def test_demo_states_the_prediction_residual_with_its_uncertainty(demo) -> None:
    """The table's prediction residual (max |r|, RMS) carries U (k = 2) from the ballbar
    budget: U is k times the quadrature sum of its budget lines, the Monte Carlo of the same
    inputs (200 draws) agrees with the RMS's U within 10 % (first order stated); the max is
    a max over competing readings, where the first order overstates (measured -34 %) and
    the Monte Carlo's U is stated; both stated U are in the report's row."""
    import math
    out, s = demo
    ru = s["prediction_residual_uncertainty"]
    for key, top in (("max_abs", "prediction_max_residual"), ("rms", "prediction_rms_residual")):
        d = ru[key]
        assert d["value_um"] == pytest.approx(s[f"{top}_um"], abs=1e-3)
        assert d["U_um"] == pytest.approx(2 * math.sqrt(sum(v ** 2 for v in d["budget_u_um"].values())))
        ok = abs(d["U_mc_um"] / d["U_um"] - 1) <= 0.10
        assert d["U_stated_um"] == (d["U_um"] if ok else d["U_mc_um"]) > 0
        assert s[f"{top}_U_um"] == pytest.approx(d["U_stated_um"], abs=1e-4)
    assert abs(ru["rms"]["U_mc_um"] / ru["rms"]["U_um"] - 1) <= 0.10, ru["rms"]
    assert ru["rms"]["U_from"].startswith("first order")
    html = (out / "report" / "index.html").read_text()
    from abbe.cli.demo_pipeline import fmt_U
    assert (f"<td>{fmt_U(s['prediction_max_residual_U_um'])} (max), "
            f"{fmt_U(s['prediction_rms_residual_U_um'])} (RMS)</td>") in html
    assert fmt_U(0.0021) == "0.0021" and fmt_U(1.234) == "1.23"


def test_demo_states_the_diagnosed_models_residual_with_its_uncertainty(demo) -> None:
    """The diagnosed model's row (table + servo, the diagnosis's own residual of the circle,
    its set-up removed) carries U (k = 2) from the same ballbar budget as the table's row:
    U is k times the quadrature sum of its budget lines, a 200-draw Monte Carlo of the same
    inputs (the readings redrawn, the diagnosis's set-up removal rerun) agrees with the
    RMS's U within 10 % (first order stated; with the drift's derivative at the centre of
    its interval, before the quadrature over it, it was 22 % low: measured +0.7 % now); the max's stated U is the Monte Carlo's where
    the first order parts by more than 10 %; the row shows both stated U. The figure is the
    circle's, below the table's (the servo is what the table cannot hold)."""
    import math
    out, s = demo
    du = s["diagnosed_residual_uncertainty"]
    for key, top in (("max_abs", "prediction_max_residual_with_prediction_effects"),
                     ("rms", "prediction_rms_residual_with_prediction_effects")):
        d = du[key]
        assert d["value_um"] == pytest.approx(s[f"{top}_um"], abs=1e-3)
        assert d["U_um"] == pytest.approx(2 * math.sqrt(sum(v ** 2 for v in d["budget_u_um"].values())))
        assert d["U_um"] > 0 and d["U_mc_um"] > 0
        ok = abs(d["U_mc_um"] / d["U_um"] - 1) <= 0.10
        assert d["U_stated_um"] == (d["U_um"] if ok else d["U_mc_um"])
        assert s[f"{top}_U_um"] == pytest.approx(d["U_stated_um"], abs=1e-4)
    assert abs(du["rms"]["U_mc_um"] / du["rms"]["U_um"] - 1) <= 0.10, du["rms"]
    assert du["rms"]["U_from"].startswith("first order")
    assert du["monte_carlo"]["draws"] == 200
    # the servo is what the table cannot hold: the diagnosed model leaves less of the circle
    assert du["max_abs"]["value_um"] < s["prediction_max_residual_um"]
    assert du["rms"]["value_um"] < s["prediction_rms_residual_um"]
    html = (out / "report" / "index.html").read_text()
    row = html[html.index("prediction residual, diagnosed model"):]
    row = row[:row.index("</tr>")]
    from abbe.cli.demo_pipeline import fmt_U
    assert (f"<td>{fmt_U(s['prediction_max_residual_with_prediction_effects_U_um'])} (max), "
            f"{fmt_U(s['prediction_rms_residual_with_prediction_effects_U_um'])} (RMS)</td>") in row
    assert "&ndash;" not in row


def test_demo_fit_states_each_axis_iso230_2_with_its_uncertainty(demo, capsys) -> None:
    """`abbe fit` (the demo's fit step) gives each axis' ISO 230-2 results with U (k = 2)
    from the machine file's laser budget: on Y the same U `abbe iso230-2` states for the
    same laser file (its Monte Carlo check is tests/analysis/test_uncertainty.py's); the
    fit report's per-axis line and band carry them."""
    out, _ = demo
    model = json.loads((out / "report" / "fit" / "model.json").read_text())
    capsys.readouterr()
    assert cli_main(["iso230-2", str(Path(__file__).resolve().parents[3] / "examples" / "vmc500"
                                     / "laser" / "y.csv"), "--mc", "0", "--json", "-"]) == 0
    ref = json.loads(capsys.readouterr().out)["uncertainty"]["results"]
    for a in ("X", "Y", "Z"):
        iso = model["axes"][a]["iso230_2"]
        assert iso["U_k"] == 2
        for q in ("E", "A", "B", "R", "M"):
            assert iso[f"{q}_U_um"] > 0, (a, q)
    y = model["axes"]["Y"]["iso230_2"]
    for q in ("E", "A", "B", "R", "M"):
        assert y[f"{q}_um"] == pytest.approx(ref[q]["value_um"], abs=1e-3)
        assert y[f"{q}_U_um"] == pytest.approx(ref[q]["U_um"], abs=1e-3)
    page = (out / "report" / "fit" / "report" / "index.html").read_text()
    assert f"E = {y['E_um']:.2f} &plusmn; {y['E_U_um']:.2f} um" in page
    band = page[page.index("id='verdict'"):]
    assert f"<td>{y['E_um']:.2f} &plusmn; {y['E_U_um']:.2f}</td>" in band[:band.index("</table>")]
