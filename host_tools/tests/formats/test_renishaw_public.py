"""The Renishaw readers against files written by an independent writer
(cases/renishaw_public.py: from the public Java parser and the real Ballbar 5 / 20 files,
not from abbe's readers): Windows code pages with non-ASCII user text, sections abbe does
not use, the Ballbar 20 element names; every refusal names file, line and field (exit 2).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest

from abbe.analysis.iso230_4 import evaluate_ballbar
from abbe.errors import AbbeInputError
from abbe.formats.positioning import load_positioning
from abbe.formats.renishaw_b5r import read_b5r
from abbe.formats.renishaw_rtl import read_rtl

from cases.renishaw_public import (CZECH_USER_TEXT, WESTERN_USER_TEXT, b5r_ballbar20,
                                   b5r_public_generator_shape, bidirectional_passes, rtl_bytes)

ROOT = Path(__file__).resolve().parents[3]
VMC = ROOT / "examples" / "vmc500"
ABBE = [sys.executable, "-m", "abbe.cli"]
TARGETS = [0.0, 48.3, 97.1, 151.9, 199.2, 252.6]


def _rtl(tmp_path: Path, name: str = "x.rtl", **kw) -> tuple[Path, list[np.ndarray]]:
    passes = kw.pop("passes", None) or bidirectional_passes(5, len(TARGETS))
    p = tmp_path / name
    p.write_bytes(rtl_bytes(TARGETS, passes, **kw))
    return p, passes


def _abbe(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(ABBE + list(args), capture_output=True, text=True)


# ------------------------------------------------------------------------------- .rtl

@pytest.mark.parametrize("encoding,user,expect_enc,how", [
    ("cp1250", CZECH_USER_TEXT, "cp1250", "default"),
    ("utf-8", CZECH_USER_TEXT, "utf-8", "detected"),
])
def test_rtl_windows_code_page_user_text_is_read(tmp_path, encoding, user, expect_enc, how):
    p, passes = _rtl(tmp_path, encoding=encoding, user_text=user)
    r = read_rtl(p)
    assert (r.encoding, r.encoding_source) == (expect_enc, how)
    for k, v in user.items():
        assert r.text[k] == v
    assert r.sections_not_used == [("EQUIPMENT", r.sections_not_used[0][1])]
    # The numbers are the writer's, in list order, whatever the text encoding.
    np.testing.assert_allclose(r.passes, np.round(np.array(passes), 4), atol=1e-12)


def test_rtl_declared_code_pages(tmp_path):
    p, _ = _rtl(tmp_path, encoding="cp1252", user_text=WESTERN_USER_TEXT)
    assert read_rtl(p, encoding="cp1252").text["By"] == "Jürgen Müller"
    # Undeclared, the bytes are not UTF-8 and are read in cp1250 (the Java parser's):
    # the numbers are the same, only letters outside ASCII may differ.
    r = read_rtl(p)
    assert r.encoding == "cp1250" and r.text["Axis"] == "X"
    np.testing.assert_array_equal(r.passes, read_rtl(p, encoding="cp1252").passes)
    g = tmp_path / "gbk.rtl"
    g.write_bytes(rtl_bytes(TARGETS, bidirectional_passes(2, len(TARGETS)),
                            user_text={"Machine": "加工中心 VMC850", "By": "张伟"}, encoding="gbk",
                            equipment_lines=("Laser : XL-80",)))
    assert read_rtl(g, encoding="gbk").text["By"] == "张伟"


def test_rtl_undecodable_byte_names_its_line(tmp_path):
    p, _ = _rtl(tmp_path)
    raw = p.read_bytes().replace("Jiří".encode("cp1250"), b"Ji\x81i")  # 0x81: not cp1250
    p.write_bytes(raw)
    with pytest.raises(AbbeInputError, match="0x81") as e:
        read_rtl(p)
    assert e.value.line == raw[:raw.index(b"\x81")].count(b"\r\n") + 1
    with pytest.raises(AbbeInputError, match="unknown encoding"):
        read_rtl(p, encoding="ebcdic")


@pytest.mark.parametrize("where", ["USER-TEXT", "RUNS", "DEVIATIONS", "ENVIRONMENT"])
def test_rtl_equipment_section_anywhere_is_skipped_and_reported(tmp_path, where):
    p, passes = _rtl(tmp_path, equipment_after=where)
    plain, _ = _rtl(tmp_path, "plain.rtl", equipment_after=None, passes=passes)
    a, b = load_positioning(p), load_positioning(plain)
    np.testing.assert_array_equal(a.up_um, b.up_um)
    np.testing.assert_array_equal(a.down_um, b.down_um)
    assert any("EQUIPMENT:: (line" in n for n in a.notes)
    assert not any("EQUIPMENT" in n for n in b.notes)


def test_rtl_cli_reports_encoding_and_sections(tmp_path):
    p, _ = _rtl(tmp_path)
    r = _abbe("iso230-2", str(p))
    assert r.returncode == 0, r.stderr
    assert "input: text read as cp1250" in r.stdout and "EQUIPMENT::" in r.stdout
    j = json.loads(_abbe("iso230-2", str(p), "--json", "-").stdout)
    assert any("EQUIPMENT" in n for n in j["input_notes"])
    r = _abbe("iso230-2", str(p), "--encoding", "cp1252", "--json", "-")
    assert r.returncode == 0 and "declared" in json.loads(r.stdout)["input_notes"][0]


def _line_of(p: Path, text: str, encoding: str = "cp1250") -> int:
    lines = p.read_bytes().decode(encoding).split("\r\n")
    return next(i for i, ln in enumerate(lines, 1) if ln.startswith(text))


@pytest.mark.parametrize("owner", ["Angular", "Straightness"])
def test_rtl_owner_refused_by_iso230_2_names_the_line(tmp_path, owner):
    p, _ = _rtl(tmp_path, owner=owner)
    r = _abbe("iso230-2", str(p))
    assert r.returncode == 2
    assert f"{p}:{_line_of(p, 'Owner')}:" in r.stderr and "Owner" in r.stderr, r.stderr


def test_rtl_one_cycle_refused_names_the_line(tmp_path):
    p, _ = _rtl(tmp_path, passes=bidirectional_passes(1, len(TARGETS)))
    r = _abbe("iso230-2", str(p))
    assert r.returncode == 2
    assert f"{p}:{_line_of(p, 'Run-count')}:" in r.stderr and "Run-count" in r.stderr, r.stderr


def test_rtl_channel_refusal_in_a_machine_file_names_the_line(tmp_path):
    shutil.copytree(VMC, tmp_path / "m")
    p, _ = _rtl(tmp_path / "m" / "laser", owner="Angular")
    mf = tmp_path / "m" / "machine.toml"
    mf.write_text(mf.read_text().replace('file = "laser/x.csv"', 'file = "laser/x.rtl"', 1))
    from abbe.formats.laser_file import read_laser_line
    from abbe.formats.machine import load_machine
    m = load_machine(mf)
    with pytest.raises(AbbeInputError) as e:
        read_laser_line(m.laser["X"], channels=tuple(m.laser["X"].map))
    assert e.value.line == _line_of(p, "Owner") and e.value.field == "Owner"


def test_rtl_section_before_header_or_after_eof_is_refused(tmp_path):
    p, _ = _rtl(tmp_path)
    text = p.read_bytes().decode("cp1250")
    for bad, line in (("EQUIPMENT::\r\nLaser : XL-80\r\n" + text, 1),
                      (text + "EQUIPMENT::\r\n", text.count("\r\n") + 1)):
        p.write_bytes(bad.encode("cp1250"))
        with pytest.raises(AbbeInputError) as e:
            read_rtl(p)
        assert e.value.line == line, str(e.value)


# ------------------------------------------------------------------------------- .b5r

def _eval(t):
    return evaluate_ballbar(t.trace, types.SimpleNamespace(
        name="c", plane=t.plane, radius_mm=t.radius_mm, feed_mm_min=t.feed_mm_min))


@pytest.mark.parametrize("kw", [
    {},                                                    # 45 deg start, as Ballbar 5's sample
    {"start_deg": 180.0, "overshoot_deg": 180.0, "radius_mm": 50.0, "feed_mm_min": 1500.0,
     "actual_feed_mm_min": 1493.2, "sample_hz": 125.0},      # as the Ballbar 20 file
    {"plane": ("Z", "X"), "view": "+B+A", "start_deg": 250.0},
    {"plane": ("Y", "Z"), "start_deg": 0.0, "overshoot_deg": 10.0},
])
def test_b5r_ballbar20_layout_evaluates_to_the_writers_truth(tmp_path, kw):
    text, truth = b5r_ballbar20(**kw)
    p = tmp_path / "c.b5r"
    p.write_text(text, encoding="utf-8")
    t = read_b5r(p)
    assert t.plane == "".join(kw.get("plane", ("X", "Y")))
    assert t.names["RADIUS"] == "TEST_RADIUS" and t.names["FEEDRATE"] == "PROGRAMMED_FEEDRATE"
    assert t.metadata["operator"] == "Łukasz Żółć" and t.metadata["serial_number"] == "BB-1"
    assert t.metadata["software"].startswith("Renishaw Ballbar 20")
    assert t.features["CCW/AF_CIRCULARITY"][1] == "mm"
    assert "ISO230_4 2005/AF_CIRCULAR_DEVIATION_CCW" in t.features
    res = _eval(t)
    for d in ("ccw", "cw"):
        w = truth[d.upper()]
        cf = res.per_direction[d]
        assert cf.center_um[0] == pytest.approx(w["a_um"], abs=0.01)
        assert cf.center_um[1] == pytest.approx(w["b_um"], abs=0.01)
        assert cf.radius_dev_um == pytest.approx(w["rho_um"], abs=0.01)
        assert cf.G_um == pytest.approx(w["G_um"], abs=0.01)
        # The data arc [START_ANGLE, START_ANGLE + 360): END_INDEX - START_INDEX samples.
        assert res.n_samples[d] in (w["n_data"], w["n_data"] + 1)

def test_b5r_ballbar20_in_a_machine_file(tmp_path):
    shutil.copytree(VMC, tmp_path / "m")
    mf = tmp_path / "m" / "machine.toml"
    text, _ = b5r_ballbar20(radius_mm=100.0, feed_mm_min=200.0, sample_hz=10.0,
                            start_deg=0.0, overshoot_deg=45.0)
    (tmp_path / "m" / "ballbar" / "c.b5r").write_text(text, encoding="utf-8")
    mf.write_text(mf.read_text().replace("ballbar/circle1.csv", "ballbar/c.b5r"))
    r = _abbe("ballbar", str(mf), "circle1", "--no-plot", "--json", "-")
    assert r.returncode == 0, r.stderr
    mf.write_text(mf.read_text().replace("radius_mm = 100.0", "radius_mm = 90.0"))
    r = _abbe("ballbar", str(mf), "circle1", "--no-plot")
    assert r.returncode == 2 and "TEST_RADIUS" in r.stderr and "c.b5r:" in r.stderr, r.stderr


def _line(text: str, needle: str) -> int:
    return text[:text.index(needle)].count("\n") + 1


@pytest.mark.parametrize("make,needle,field,msg", [
    (lambda: b5r_public_generator_shape(), "<BALLBAR_RUN>", "READINGS", "results only"),
    (lambda: b5r_ballbar20(readings=False)[0], "<BALLBAR_RUN>", "READINGS", "results only"),
    (lambda: b5r_ballbar20(start_deg=250.0, arc_deg=220.0, overshoot_deg=2.0)[0],
     "<READINGS>", "READINGS", "not the full circle"),
    (lambda: b5r_ballbar20(nominal_mm=150.0)[0], "<NOMINAL_LENGTH>", "NOMINAL_LENGTH",
     "disagree"),
    (lambda: b5r_ballbar20(actual_feed_mm_min=1600.0)[0], "<SAMPLE_RATE>40.000", "SAMPLE_RATE",
     "not consistent"),
    (lambda: b5r_ballbar20()[0].replace("<RUN_DIRECTION>CW</RUN_DIRECTION>\n      <RUN_TEMP",
                                        "<RUN_DIRECTION>CCW</RUN_DIRECTION>\n      <RUN_TEMP"),
     "<BALLBAR_RUN>", "RUN_DIRECTION", "expected one BALLBAR_RUN"),
    (lambda: b5r_ballbar20(plane=("X", "Z"))[0], "<A_AXIS_NAME>", "A_AXIS_NAME",
     "not interpreted"),
    (lambda: b5r_ballbar20()[0].replace("<START_INDEX>", "<START_INDEX>9999", 1),
     "<START_INDEX>", "START_INDEX", None),
])
def test_b5r_ballbar20_refusals_name_line_and_element(tmp_path, make, needle, field, msg):
    text = make()
    p = tmp_path / "bad.b5r"
    p.write_text(text, encoding="utf-8")
    with pytest.raises(AbbeInputError, match=msg) as e:
        read_b5r(p)
    assert e.value.file == str(p) and e.value.field == field, str(e.value)
    assert e.value.line == _line(text, needle), str(e.value)


# A check against real files of Renishaw's software when they are on this machine (they are
# public, RynShuster/WatchTower testData/BallBar, but carry no licence: not in the project).
REAL_DIR = os.environ.get("ABBE_RENISHAW_B5R_DIR")


@pytest.mark.skipif(not REAL_DIR, reason="SKIPPED: real Ballbar 5/20 files not given "
                                         "(set ABBE_RENISHAW_B5R_DIR)")
def test_b5r_real_files_match_renishaws_own_results():
    files = sorted(Path(REAL_DIR).glob("*.b5r"))
    assert files
    n_full = 0
    for f in files:
        try:
            t = read_b5r(f)
        except AbbeInputError as e:   # a partial arc (ISO 230-4 evaluates full circles)
            assert "full circle" in str(e) and e.line is not None
            continue
        n_full += 1
        res = _eval(t)
        for d in ("ccw", "cw"):
            cf, D = res.per_direction[d], d.upper()
            assert cf.center_um[0] == pytest.approx(t.features[f"{D}/AF_CENTRE_OFFSET_A"][0]
                                                    * 1e3, abs=0.06)
            assert cf.center_um[1] == pytest.approx(t.features[f"{D}/AF_CENTRE_OFFSET_B"][0]
                                                    * 1e3, abs=0.06)
            assert cf.G_um == pytest.approx(t.features[f"{D}/AF_CIRCULARITY"][0] * 1e3,
                                            abs=0.1)
            assert t.radius_mm + cf.radius_dev_um * 1e-3 == pytest.approx(
                t.features[f"{D}/AF_BEST_RADIUS"][0], abs=6e-5)
    assert n_full >= 1


# ------------------------------------------------------------------ property: code pages

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

_CODE_PAGES = ("utf-8", "cp1250", "cp1252", "gbk")
_COMMON = "AZaz09 -_./(),;:#+*'\""
_ALPHABET = {
    "cp1250": _COMMON + "ŽžŠšČčŘřĚěŮůÁáÍíÓóÚúŁłŃńŚśŹźŻżŐőŰűÂâ–—„“”…°×",
    "cp1252": _COMMON + "ÄäÖöÜüßÉéÈèÀàÇçÑñØøÆæÅå€–—„“”…°×",
    "gbk": _COMMON + "加工中心机床张伟李测试激光轴线性误差",
    "utf-8": _COMMON + "ŽžÄäß€加工Ωπ😀–",
}


@st.composite
def _rtl_in_a_code_page(draw):
    enc = draw(st.sampled_from(_CODE_PAGES))
    # Letters and punctuation each code page can write (no line ends).
    chars = st.sampled_from(_ALPHABET[enc])
    user = {k: draw(st.text(chars, min_size=1, max_size=20)).strip(" \t") or "x"
            for k in ("Machine", "By", "Location", "TITLE")}
    n_t = draw(st.integers(2, 7))
    t = np.round(np.cumsum(draw(st.lists(st.floats(0.5, 100.0), min_size=n_t, max_size=n_t))), 3)
    cyc = draw(st.integers(2, 4))
    vals = draw(st.lists(st.floats(-999.0, 999.0), min_size=2 * cyc * n_t, max_size=2 * cyc * n_t))
    passes = [np.round(vals[i * n_t:(i + 1) * n_t], 4) for i in range(2 * cyc)]
    where = draw(st.sampled_from([None, "USER-TEXT", "RUNS", "DEVIATIONS", "ENVIRONMENT"]))
    nl = draw(st.sampled_from(["\r\n", "\n"]))
    try:
        raw = rtl_bytes(t, passes, user_text=user, encoding=enc, equipment_after=where,
                        newline=nl, equipment_lines=("Laser : XL-80",))
    except UnicodeEncodeError:
        raw = None
    return enc, user, t, passes, raw


@settings(max_examples=int(os.environ.get("ABBE_FUZZ_EXAMPLES", "60")), derandomize=True,
          database=None, deadline=None)
@given(_rtl_in_a_code_page())
def test_rtl_in_any_code_page_reads_back(case):
    enc, user, t, passes, raw = case
    if raw is None:
        return
    import tempfile
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "x.rtl"
        p.write_bytes(raw)
        r = read_rtl(p, encoding=enc)
        for k, v in user.items():
            assert r.text[k] == v
        np.testing.assert_array_equal(r.targets_mm, t)
        np.testing.assert_allclose(r.passes, np.array(passes), atol=0)
        auto = read_rtl(p)            # undeclared: the numbers never depend on the code page
        np.testing.assert_array_equal(auto.passes, r.passes)
