"""``abbe demo --five-axis``: the trunnion5ax example identified and compared with its truth."""

from __future__ import annotations

import json
from pathlib import Path

from abbe.cli.entry import main


def test_demo_five_axis(tmp_path: Path) -> None:
    """The flagship plan (trunnion5ax_complete: a datum sphere at a second height) ends in a
    complete calibration: all ten location errors observed, each within its interval of
    the truth, nothing named as unseen, nothing fixed by convention."""
    out, js = tmp_path / "demo", tmp_path / "s.json"
    assert main(["demo", "--five-axis", "-o", str(out), "--json", str(js)]) == 0
    s = json.loads(js.read_text())
    assert s["machine"] == "trunnion5ax_complete" and s["kinematics"] == "xyzac-trt"
    assert s["within_interval_or_1um_5urad"] == s["observable_location_errors"] == 10
    assert s["unobservable"] == []
    assert s["heldout_after_um"] < s["heldout_before_um"] / 5
    assert (out / "report" / "index.html").is_file() and (out / "truth_comparison.txt").is_file()
    doc = json.loads((out / "five_axis.json").read_text())
    assert doc["rotary_positioning"]["C"]["A_urad"] > 0
    assert doc["observability"]["fixed_by_convention"] == []
    assert doc["observability"]["confounded_groups"] == []
    loc = {r["name"]: r for r in doc["parameters"] if r["kind"] == "location"}
    assert all(r["observable"] and r["U"] > 0 for r in loc.values()) and len(loc) == 10
    assert "datum.D1" in doc["block_sigma"] and doc["block_sigma"]["datum.D1"] == [1.0]
    comparison = (out / "truth_comparison.txt").read_text()
    assert "not observable" not in comparison and " NO" not in comparison


def test_demo_five_axis_without_the_datum(tmp_path: Path) -> None:
    """The plan without the datum and second height (examples/trunnion5ax) still names what
    it cannot see: the angular zeros and the C line's y and tilt stay confounded."""
    from abbe.paths import examples_dir

    out, js = tmp_path / "demo", tmp_path / "s.json"
    assert main(["demo", "--five-axis", "--example", str(examples_dir() / "trunnion5ax"),
                 "-o", str(out), "--json", str(js)]) == 0
    s = json.loads(js.read_text())
    assert s["within_interval_or_1um_5urad"] == s["observable_location_errors"] >= 4
    assert {"EA0A", "EY0C", "EA0C", "EC0C"} <= set(s["unobservable"])


def test_diagnose_cli_on_a_five_axis_file(tmp_path: Path, capsys) -> None:
    from cases.five_axis_hidden import make_case

    mf, expected, _amp = make_case("cyclic", 1, tmp_path / "case")
    out, js = tmp_path / "diag", tmp_path / "d.json"
    assert main(["diagnose", str(mf), "-o", str(out), "--json", str(js)]) == 0
    doc = json.loads(js.read_text())
    assert [n["effect"] for n in doc["named"]] == [expected]
    assert doc["heldout_after_um"] < doc["heldout_before_um"]
    assert (out / "report.txt").read_text().startswith("Five-axis discrepancy")
    assert "Named:" in capsys.readouterr().out


def test_five_axis_report_reads_verdict_first_in_chromium(tmp_path: Path) -> None:
    """The five-axis demo report: the location errors identified (value, interval) in the
    band at the top, the error-motion plots, then one short table of what the plan could
    not see with the measurement that would see it (one row per measurement, not one
    per parameter); every parameter folded below."""
    import re

    import pytest

    from abbe.analysis.five_axis.report import ONE_MEASUREMENT
    from report_shots import assert_band_before, assert_verdict_first, needs_chromium, screenshot
    out = tmp_path / "demo"
    assert main(["demo", "--five-axis", "-o", str(out)]) == 0
    doc = json.loads((out / "five_axis.json").read_text())
    page = (out / "report" / "index.html").read_text()
    machine_unseen = [p for p in doc["parameters"] if not p["observable"] and p["kind"] != "setup"]
    assert_band_before(page, "motions_", "Every parameter")
    band = page[page.index("id='verdict'"):page.index("</div>", page.index("id='verdict'"))]
    for p in doc["parameters"]:
        if p["kind"] == "location" and p["observable"]:
            assert f"<td class='l'>{p['name']}</td><td>{p['value']:.3f}</td>" in band
    if machine_unseen:  # one row per measurement that would see them, not per parameter
        assert_band_before(page, "What this plan could not see")
        unseen = page[page.index("What this plan could not see"):page.index("<h2>Details")]
        n_rows = len(re.findall("<tr>", unseen)) - 1
        assert 0 < n_rows <= len(ONE_MEASUREMENT) and n_rows < len(machine_unseen)
        for p in machine_unseen:
            assert p["name"].split(" ")[0] in unseen
    else:
        assert "The plan sees every error it models" in page
    if needs_chromium.args[0]:
        pytest.skip("chromium not installed: the report is not rendered")
    img = screenshot(out / "report" / "index.html", tmp_path / "shot.png", "demo_five_axis")
    assert assert_verdict_first(img) in ("pass", "inconclusive")
