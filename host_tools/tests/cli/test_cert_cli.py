"""`abbe iso230-2` / `abbe ballbar` with the machine file's [uncertainty] and [tolerances]:
U and verdicts in text and JSON, the -o folder (JSON + HTML report) that `abbe history add`
reads, and bad input in the new sections (exit 2 with file, line, field)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from abbe.cli.entry import main

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "vmc500"

SECTIONS = """
[uncertainty.laser]
instrument = "laser_interferometer"
dead_path_mm = 50.0

[uncertainty.ballbar]
calibration_U_um = 0.5

[tolerances.X]
E_um = 30.0
A_um = 45.0
B_um = 2.0
R_um = 4.5

[tolerances.ballbar]
G_um = 25.0
H_um = 5.0
"""


@pytest.fixture()
def machine(tmp_path: Path) -> Path:
    d = tmp_path / "vmc"
    shutil.copytree(EXAMPLE, d, ignore=shutil.ignore_patterns("truth"))
    m = d / "machine.toml"
    m.write_text(m.read_text() + SECTIONS)
    return m


def test_iso230_2_json_has_u_budget_and_verdicts(machine: Path, capsys) -> None:
    x = str(machine.parent / "laser" / "x.csv")
    assert main(["iso230-2", x, "--machine", str(machine), "--axis", "X", "--json",
                 "-", "--mc", "300"]) == 0
    d = json.loads(capsys.readouterr().out)
    unc = d["uncertainty"]
    assert d["machine"] == "vmc500" and d["axis"] == "X"
    assert unc["budget_inputs"]["declared"] == ["dead_path_mm"]
    for q in ("E", "A", "B", "R", "M"):
        r = unc["results"][q]
        assert r["value_um"] == pytest.approx(d[f"{q}_um"], abs=1e-5)
        assert r["U_um"] == pytest.approx(2 * r["u_um"], abs=2e-6) and r["U_um"] > 0
        assert r["budget"], q
    v = d["verdicts"]
    assert set(v) == {"E_um", "A_um", "B_um", "R_um"}
    # B 2.53 um against 2.0: above the limit by more than its U (0.24) -> fail
    assert v["B_um"]["verdict"] == "fail"
    assert v["A_um"]["verdict"] == "pass"
    for k, w in v.items():
        assert w["verdict"] == ("pass" if w["value_um"] + w["U_um"] <= w["limit_um"] else
                                "fail" if w["value_um"] - w["U_um"] > w["limit_um"] else
                                "inconclusive"), k


def test_iso230_2_text_without_out_keeps_the_table(capsys) -> None:
    assert main(["iso230-2", str(EXAMPLE / "laser" / "x.csv"), "--mc", "0"]) == 0
    out = capsys.readouterr().out
    assert "B (reversal)" in out and "U = " in out and "Monte Carlo" not in out


def test_iso230_2_out_folder_is_what_history_reads(machine: Path, tmp_path: Path,
                                                   capsys) -> None:
    from abbe.history.ingest import read_campaign
    x = str(machine.parent / "laser" / "x.csv")
    out = tmp_path / "iso_x"
    args = ["iso230-2", x, "--machine", str(machine), "--axis", "X", "--mc", "200"]
    assert main(args + ["-o", str(out), "--date", "2021-05-10"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["iso230_2.json", "report.html"]
    capsys.readouterr()
    assert main(args + ["--json", "-"]) == 0
    assert json.loads((out / "iso230_2.json").read_text()) == json.loads(
        capsys.readouterr().out)
    c = read_campaign([str(out)], {"": "X"}, "vmc500")
    assert {r.series for r in c.results} >= {"iso230-2 E X bi", "iso230-2 R X up"}
    html = (out / "report.html").read_text()
    # verdict first: machine, test, date, verdicts, then the numbers with U
    order = [html.index(s) for s in ("vmc500", "ISO 230-2 bidirectional", "2021-05-10",
                                     "Verdicts", "FAIL", "Results with their expanded")]
    assert order == sorted(order)


def test_ballbar_out_folder(machine: Path, tmp_path: Path, capsys) -> None:
    from abbe.history.ingest import read_campaign
    out = tmp_path / "bb"
    assert main(["ballbar", str(machine), "circle1", "-o", str(out), "--mc", "20"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["ballbar.json", "ballbar_circle1.png",
                                                     "report.html"]
    d = json.loads((out / "ballbar.json").read_text())
    assert d["verdicts"]["G_um"]["verdict"] == "pass"
    assert d["uncertainty"]["results"]["radius_dev"]["budget"][2]["name"] == \
        "length calibration"
    c = read_campaign([str(out)], {}, "vmc500")
    assert any(r.series.startswith("ballbar G XY") for r in c.results)
    html = (out / "report.html").read_text()
    assert html.index("Verdicts") < html.index("ballbar_circle1.png") < html.index("Results")


@pytest.mark.parametrize("edit,field", [
    ('[uncertainty.laser]\naccuracy_ppm = -1\n', "uncertainty.laser.accuracy_ppm"),
    ('[uncertainty.laser]\naccuracy_ppm = nan\n', "uncertainty.laser.accuracy_ppm"),
    ('[uncertainty.laser]\ninstrument = "tape"\n', "uncertainty.laser.instrument"),
    ('[uncertainty.laser]\nacuracy_ppm = 1\n', "uncertainty.laser.acuracy_ppm"),
    ('[uncertainty.ballbar]\ninstrument = "laser_interferometer"\n',
     "uncertainty.ballbar.instrument"),
    ('[uncertainty.thermal]\nx = 1\n', "uncertainty.thermal"),
    ('[tolerances.X]\nE_um = 0\n', "tolerances.X.E_um"),
    ('[tolerances.X]\nG_um = 5\n', "tolerances.X.G_um"),
    ('[tolerances.Q]\nE_um = 5\n', "tolerances.Q"),
    ('[tolerances.ballbar]\nG_um = "5"\n', "tolerances.ballbar.G_um"),
])
def test_bad_sections_exit_2_with_file_line_field(tmp_path: Path, capsys, edit: str,
                                                  field: str) -> None:
    m = tmp_path / "machine.toml"
    text = "[axes.X]\ntravel_mm = [0.0, 500.0]\n[reference]\npoint_mm = [0.0, 0.0, 0.0]\n"
    m.write_text(text + edit)
    out = tmp_path / "o"
    assert main(["iso230-2", str(EXAMPLE / "laser" / "x.csv"), "--machine", str(m),
                 "--axis", "X", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    # a section's error names its header line (5), a key's its own line (6)
    line = 5 if field.count(".") == 1 else 6
    assert f"{m}:{line}:" in err and f"field '{field}'" in err, err
    assert not out.exists()


def test_tolerances_per_axis_need_axis(machine: Path, capsys) -> None:
    x = str(machine.parent / "laser" / "x.csv")
    assert main(["iso230-2", x, "--machine", str(machine), "--mc", "0"]) == 2
    assert "--axis" in capsys.readouterr().err


@pytest.mark.parametrize("date", ["2021-13-01", "21-05-10", "2021-02-30", "today"])
def test_bad_date_is_a_usage_error(date: str, capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["iso230-2", str(EXAMPLE / "laser" / "x.csv"), "--date", date])
    assert exc.value.code == 2
    assert "--date" in capsys.readouterr().err


@pytest.mark.skipif(shutil.which("chromium") is None,
                    reason="chromium not installed: the report is not rendered")
def test_report_renders_verdict_first_in_chromium(machine: Path, tmp_path: Path) -> None:
    """The ballbar report rendered by headless Chromium: the overall verdict's colour
    (pass green) fills a band in the top quarter of the page, above the plot."""
    import subprocess

    import numpy as np
    from PIL import Image
    out = tmp_path / "bb"
    assert main(["ballbar", str(machine), "circle1", "-o", str(out), "--mc", "0"]) == 0
    png = tmp_path / "shot.png"
    subprocess.run(["chromium", "--headless", "--no-sandbox", "--disable-gpu",
                    f"--screenshot={png}", "--window-size=1200,1600",
                    (out / "report.html").as_uri()], check=True, capture_output=True,
                   timeout=120)
    img = np.asarray(Image.open(png).convert("RGB")).astype(int)
    green = np.all(np.abs(img - np.array([0xc8, 0xef, 0xc8])) <= 3, axis=2)
    rows = np.flatnonzero(green.sum(axis=1) > 0.5 * img.shape[1])
    assert rows.size > 10, "no full-width verdict band"
    assert rows.max() < img.shape[0] / 4, rows.max()


def _ess_dat() -> Path:
    from fit_helpers import ESS_DAT
    return ESS_DAT


def _needs_ess():
    from real_data import needs_real_data
    return needs_real_data(_ess_dat())


@_needs_ess()
def test_ess_iso230_2_report_reads_verdict_first_in_chromium(tmp_path: Path) -> None:
    """The shared ESS file (real data): without tolerances the band is the "info" colour
    and carries E, M, A, B, R with their U; in the top quarter of the first screen."""
    from report_shots import assert_band_before, assert_verdict_first, needs_chromium, screenshot
    out = tmp_path / "ess"
    assert main(["iso230-2", str(_ess_dat()), "--mc", "200", "-o", str(out)]) == 0
    d = json.loads((out / "iso230_2.json").read_text())
    page = (out / "report.html").read_text()
    assert_band_before(page, "Results with their expanded uncertainty", "<details>")
    band = page[page.index("id='verdict'"):page.index("</div>", page.index("id='verdict'"))]
    for q in ("E", "A", "B", "R", "M"):
        r = d["uncertainty"]["results"][q]
        assert f"{q} {r['value_um']:.2f} &plusmn; {r['U_um']:.2f}" in band
    if needs_chromium.args[0]:
        pytest.skip("chromium not installed: the report is not rendered")
    img = screenshot(out / "report.html", tmp_path / "shot.png", "iso230_2_ess")
    assert assert_verdict_first(img) == "info"
    # printed, the folded budget and per-target tables unfold: more than the one page the
    # screen shows with them folded
    from report_shots import pdf_pages
    assert pdf_pages(out / "report.html", tmp_path / "r.pdf") >= 3
