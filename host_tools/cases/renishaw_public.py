"""An independent writer of Renishaw files, written from the public evidence only (not
from abbe's readers, which it never imports; it imports nothing of ``abbe``).

* ``.rtl`` laser exports as the public Java parser reads them (Paolico/AxisCorection,
  src/main/java/model/RtlParser.java at b06d718: WINDOWS-1250 text, l.44-45; sections
  ``NAME::``; ``Key : value`` lines; targets after ``Targets :``; deviation rows ``run
  target value`` with even runs listing the targets backwards), in a Windows code page
  with non-ASCII user text, CRLF line ends, and a section abbe does not use
  (``EQUIPMENT::``, which a public reader of Renishaw's rotary exports meets).
* ``.b5r`` ballbar files in the layout of the real Ballbar 5 / Ballbar 20 files published
  in RynShuster/WatchTower (testData/BallBar/*.b5r): ``TEST_DOCUMENT``, ``TEST_SPEC``/
  ``INSTRUMENT``/``DYNAMIC_BALLBAR`` with ``NOMINAL_LENGTH``, ``PROGRAMMED_FEEDRATE``,
  ``START_ANGLE``, ``END_ANGLE``, ``OVERSHOOT_ANGLE``, ``TEST_RADIUS``, ``PLANE VIEW=...
  TEST_PLANE=...``, ``RUN_SPEC``; ``EQUIPMENT``; ``RUN_RESULTS``/``BALLBAR_RUN`` with
  ``RUN_DIRECTION``, ``SAMPLE_RATE``, ``START_INDEX``, ``END_INDEX``, ``READINGS`` (mm)
  and the run's ``FEATURE`` results; ``ANALYSIS`` elements. The readings are made from a
  known circle (centre offset, radius change, a 2-theta shape), so a reader's evaluation
  can be checked against the truth this module computes with its own least squares.
* the shape of the one public generator of ``.b5r`` files
  (RynShuster/WatchTower scripts/generate-synth-ballbar.py): results only, no readings.
"""

from __future__ import annotations

import math

import numpy as np

#: User text with characters of the Central European code page (cp1250) and of cp1252.
CZECH_USER_TEXT = {"Machine": "Frézka MCV 1000 – hala č. 2", "Serial No": "SN-4711",
                   "Date": "12.12.2016", "By": "Jiří Nováček", "Axis": "X",
                   "Location": "Dílna Brno, Žabovřesky", "TITLE": "Lineární osa X"}
WESTERN_USER_TEXT = {"Machine": "Fräsmaschine", "By": "Jürgen Müller", "Axis": "X",
                     "Location": "Montréal, Façade", "TITLE": "Straße 5"}


def rtl_bytes(targets_mm, passes_um, *, owner: str = "Linear", user_text: dict | None = None,
              encoding: str = "cp1250", newline: str = "\r\n", equipment_after: str | None =
              "ENVIRONMENT", equipment_lines: tuple[str, ...] = (
                  "Laser : XL-80 s/n 123456", "Compensator : XC-80 (kalibrováno 03/2016)",
                  "Optics : Linear 1×"), env: bool = True) -> bytes:
    """An ``.rtl`` file: ``passes_um[p][i]`` is pass p+1's deviation at target i+1 (list
    order); Run-count = len(passes_um) (two passes a bidirectional cycle)."""
    t = [float(x) for x in targets_mm]
    n_t, n_p = len(t), len(passes_um)
    sec: dict[str, list[str]] = {}
    sec["HEADER"] = ["File type  : rtl", f"Owner      : {owner}", "Version no : V20.02.02"]
    tl = [" ".join(f"{x:.3f}" for x in t[i:i + 5]) for i in range(0, n_t, 5)]
    sec["TARGET DATA"] = ["Filetype  : ISO", f"Target-count: {n_t}", "Targets :", *tl,
                          "Flags: 0 0 2 0"]
    ut = CZECH_USER_TEXT if user_text is None else user_text
    sec["USER-TEXT"] = [f"{k}: {v}" for k, v in ut.items()]
    sec["RUNS"] = [f"Run-count:{n_p}"]
    rows = ["Run Target Data:"]
    for p in range(n_p):
        order = range(n_t) if p % 2 == 0 else range(n_t - 1, -1, -1)
        rows += [f"{p + 1:<3} {i + 1:<6} {float(passes_um[p][i]):.4f}" for i in order]
    sec["DEVIATIONS"] = rows
    if env:
        sec["ENVIRONMENT"] = [
            "Air temp   : 20.337280 20.384956 0", "Air press  : 99.039005 99.049346 1",
            "Air humid  : 46.954897 46.893887", "Mat temp 1 : 20.203292 20.321342 0",
            "Mat temp 2 : -10.000000 -10.000000 0", "Mat temp 3 : -10.000000 -10.000000 0",
            "Env factor : 0.31641096 0.31641067", "Exp coeff  : 8.000000 8.000000 0",
            'Date Time  : "10:46 Dec 12 2016" "11:01 Dec 12 2016"', "Final Data : 1 0"]
    out: list[str] = []
    for name in ("HEADER", "TARGET DATA", "USER-TEXT", "RUNS", "DEVIATIONS", "ENVIRONMENT"):
        if name in sec:
            out += [f"{name}::", *sec[name], ""]
        if equipment_after == name:
            out += ["EQUIPMENT::", *equipment_lines, ""]
    out += ["EOF::", ""]
    return newline.join(out).encode(encoding)


def bidirectional_passes(n_cycles: int, n_targets: int, seed: int = 3) -> list[np.ndarray]:
    """Passes of a bidirectional test (list order), um: a slope, a reversal and noise."""
    rng = np.random.default_rng(seed)
    base = np.linspace(0.0, 6.0, n_targets)
    out = []
    for _ in range(n_cycles):
        out.append(base + 1.5 + rng.normal(0, 0.3, n_targets))
        out.append(base - 1.5 + rng.normal(0, 0.3, n_targets))
    return out


def own_circle_fit(theta_deg: np.ndarray, r_mm: np.ndarray) -> tuple[float, float, float, float]:
    """(a, b, rho, range) of r ~ rho + a cos + b sin, by this module's own least squares (mm)."""
    th = np.radians(theta_deg)
    m = np.column_stack([np.ones_like(th), np.cos(th), np.sin(th)])
    c, *_ = np.linalg.lstsq(m, r_mm, rcond=None)
    res = r_mm - m @ c
    return float(c[1]), float(c[2]), float(c[0]), float(res.max() - res.min())


def b5r_ballbar20(*, plane=("X", "Y"), view: str = "+A+B", radius_mm: float = 100.0,
                  feed_mm_min: float = 1000.0, actual_feed_mm_min: float | None = None,
                  start_deg: float = 45.0, arc_deg: float = 360.0, overshoot_deg: float = 45.0,
                  sample_hz: float = 40.0, offset_mm=(0.0123, -0.0071), rho_mm: float = -0.0035,
                  shape_mm: float = 0.0021, cw_offset_shift_mm: float = 0.0004,
                  software: str = "Renishaw Ballbar 20", nominal_mm: float | None = None,
                  machine: str = "Fräse 5 – Halle 2", readings: bool = True
                  ) -> tuple[str, dict]:
    """A Ballbar 5/20-layout ``.b5r`` text and the truth of each run: ``truth[dir]`` =
    {"a_um", "b_um", "rho_um", "G_um", "n", "theta_deg", "r_mm"} from this module's fit of
    the data arc it wrote. Angles from the A axis toward the B axis (as the real files'
    centre offsets show); the CW run covers the same arc backwards."""
    a_name, b_name = plane
    feed = actual_feed_mm_min or feed_mm_min
    deg_s = math.degrees(feed / 60.0 / radius_mm)
    n_data = int(round(arc_deg / deg_s * sample_hz))         # samples over the data arc
    n_over = int(round(overshoot_deg / deg_s * sample_hz))
    si, ei = n_over, n_over + n_data
    n = ei + n_over + 1
    end_deg = (start_deg + arc_deg) % 360.0
    runs_xml, truth = [], {}
    for d in ("CCW", "CW"):
        i = np.arange(n)
        frac = (i - si) / (ei - si)
        theta = start_deg + arc_deg * frac if d == "CCW" else start_deg + arc_deg * (1 - frac)
        a, b = offset_mm
        if d == "CW":
            a += cw_offset_shift_mm
        th = np.radians(theta)
        r = rho_mm + a * np.cos(th) + b * np.sin(th) + shape_mm * np.cos(2 * th)
        r = np.round(r, 5)
        sel = slice(si, ei + 1) if d == "CCW" else slice(si, ei + 1)
        fa, fb, frho, g = own_circle_fit(theta[sel], r[sel])
        truth[d] = {"a_um": fa * 1e3, "b_um": fb * 1e3, "rho_um": frho * 1e3, "G_um": g * 1e3,
                    "n": n, "n_data": ei - si, "theta_deg": theta, "r_mm": r}
        body = " ".join(f"{x:+.5f}" for x in r)
        rd = f"      <READINGS>{body}</READINGS>\n" if readings else ""
        runs_xml.append(f"""    <BALLBAR_RUN>
      <RUN_DIRECTION>{d}</RUN_DIRECTION>
      <RUN_TEMPERATURE>20.0</RUN_TEMPERATURE>
      <START_INDEX>{si}</START_INDEX>
      <END_INDEX>{ei}</END_INDEX>
      <SAMPLE_RATE>{sample_hz:.3f}</SAMPLE_RATE>
{rd}      <FEATURE NAME="AF_CENTRE_OFFSET_A" DT="UT_LENGTH_MM" STATUS="AF_TOLERANCE_OK">{fa:.4f}</FEATURE>
      <FEATURE NAME="AF_CENTRE_OFFSET_B" DT="UT_LENGTH_MM" STATUS="AF_TOLERANCE_OK">{fb:.4f}</FEATURE>
      <FEATURE NAME="AF_BEST_RADIUS" DT="UT_LENGTH_MM">{radius_mm + frho:.4f}</FEATURE>
      <FEATURE NAME="AF_CIRCULARITY" DT="UT_LENGTH_MM">{g:.4f}</FEATURE>
      <FEATURE NAME="AF_CALCULATED_FEEDRATE" DT="UT_FEEDRATE">{feed:.1f}</FEATURE>
    </BALLBAR_RUN>""")
    nominal = radius_mm if nominal_mm is None else nominal_mm
    text = f"""<?xml version="1.0" encoding="utf-8" standalone="yes"?>
<TEST_DOCUMENT>
  <TEST_SPEC NAME="{a_name}{b_name} {arc_deg:g}deg {radius_mm:g}mm" version="2.0">
    <INSTRUMENT MANUFACTURER="Renishaw" MODEL="QC20-W">
      <DYNAMIC_BALLBAR CALIBRATION_REQUIRED="true">
        <NOMINAL_LENGTH>{nominal:g}</NOMINAL_LENGTH>
        <PROGRAMMED_FEEDRATE>{feed_mm_min:g}</PROGRAMMED_FEEDRATE>
        <START_ANGLE>{start_deg:g}</START_ANGLE>
        <END_ANGLE>{end_deg:g}</END_ANGLE>
        <OVERSHOOT_ANGLE>{overshoot_deg:g}</OVERSHOOT_ANGLE>
        <TEST_RADIUS>{radius_mm:g}</TEST_RADIUS>
        <PLANE VIEW="{view}" TEST_PLANE="{a_name}{b_name}">
          <A_AXIS_NAME>{a_name}</A_AXIS_NAME>
          <B_AXIS_NAME>{b_name}</B_AXIS_NAME>
        </PLANE>
        <RUN_SPEC>
          <RUN_DIRECTION>CCW</RUN_DIRECTION>
          <RUN_DIRECTION>CW</RUN_DIRECTION>
          <FEATURE_SPEC NAME="AF_FEEDRATE" DT="UT_FEEDRATE">
            <TOLERANCE LEVEL="WARNING"><LOWER_LIMIT>{0.9 * feed_mm_min:g}</LOWER_LIMIT><UPPER_LIMIT>{1.1 * feed_mm_min:g}</UPPER_LIMIT></TOLERANCE>
          </FEATURE_SPEC>
        </RUN_SPEC>
        <CENTRE></CENTRE>
        <SPINDLE_NUMBER>1</SPINDLE_NUMBER>
        <SAMPLE_RATE>{sample_hz * 0.95:.10g}</SAMPLE_RATE>
        <AVERAGING ENABLED="True" />
        <TEMP_MATERIAL_COEFFICIENT>0</TEMP_MATERIAL_COEFFICIENT>
      </DYNAMIC_BALLBAR>
    </INSTRUMENT>
    <ANALYSIS_SPEC NAME="RENISHAW_DIAGNOSTICS" />
  </TEST_SPEC>
  <OPERATOR>Łukasz Żółć</OPERATOR>
  <COMMENT NAME="PRE_TEST_COMMENT">nach Wartung – ověření</COMMENT>
  <DATE_STARTED>20261204-101500</DATE_STARTED>
  <DATE_COMPLETED>20261204-101700</DATE_COMPLETED>
  <MACHINE_TESTED NAME="{machine}" />
  <EQUIPMENT>
    <BALLBAR><MANUFACTURER>Renishaw</MANUFACTURER><MODEL>QC20</MODEL><SERIAL_NUMBER>BB-1</SERIAL_NUMBER><LAST_CALIBRATED>20260101</LAST_CALIBRATED></BALLBAR>
    <CALIBRATOR><MODEL>100MM_BALLBAR_CALIBRATOR</MODEL><SERIAL_NUMBER>CAL-2</SERIAL_NUMBER><CALIBRATED_LENGTH>100.0012</CALIBRATED_LENGTH><LAST_CALIBRATED>20260102</LAST_CALIBRATED></CALIBRATOR>
    <SOFTWARE><AUTHOR>Renishaw</AUTHOR><TITLE>{software}</TITLE><VERSION>20.00.1.2</VERSION></SOFTWARE>
  </EQUIPMENT>
  <RUN_RESULTS>
{chr(10).join(runs_xml)}
  </RUN_RESULTS>
  <ANALYSIS NAME="RENISHAW_DIAGNOSTICS" version="2.1">
    <FEATURE NAME="AF_SQUARENESS" DT="UT_SQUARENESS">-10.3</FEATURE>
    <FEATURE NAME="AF_CIRCULARITY" DT="UT_LENGTH_UM">{truth['CCW']['G_um']:.1f}</FEATURE>
    <FEATURE NAME="AF_SCALE_MISMATCH" DT="UT_LENGTH_UM" VALID="False">0.0</FEATURE>
  </ANALYSIS>
  <ANALYSIS NAME="ISO230_4" version="2005">
    <FEATURE NAME="AF_CIRCULAR_DEVIATION_CCW" DT="UT_LENGTH_UM">{truth['CCW']['G_um']:.1f}</FEATURE>
  </ANALYSIS>
</TEST_DOCUMENT>
"""
    return text, truth


def b5r_public_generator_shape(plane=("X", "Y")) -> str:
    """The element shape of the public synthetic generator: runs with results only."""
    a, b = plane
    return f"""<?xml version="1.0" encoding="utf-8" standalone="yes"?>
<TEST_DOCUMENT>
  <TEST_SPEC NAME="50mm {a}{b} 1500" version="2.0">
    <INSTRUMENT MANUFACTURER="Renishaw" MODEL="QC10">
      <DYNAMIC_BALLBAR CALIBRATION_REQUIRED="true">
        <NOMINAL_LENGTH>50</NOMINAL_LENGTH>
        <PROGRAMMED_FEEDRATE>1500</PROGRAMMED_FEEDRATE>
        <PLANE VIEW="+A+B" TEST_PLANE="{a}{b}">
          <A_AXIS_NAME>{a}</A_AXIS_NAME>
          <B_AXIS_NAME>{b}</B_AXIS_NAME>
        </PLANE>
      </DYNAMIC_BALLBAR>
    </INSTRUMENT>
  </TEST_SPEC>
  <OPERATOR>SYNTHETIC_OP_01</OPERATOR>
  <DATE_STARTED>20260401-080000</DATE_STARTED>
  <MACHINE_TESTED NAME="TEST-1" />
  <RUN_RESULTS>
    <BALLBAR_RUN>
      <RUN_DIRECTION>CCW</RUN_DIRECTION>
      <FEATURE NAME="AF_CIRCULARITY" DT="UT_LENGTH_MM">0.0061</FEATURE>
    </BALLBAR_RUN>
    <BALLBAR_RUN>
      <RUN_DIRECTION>CW</RUN_DIRECTION>
      <FEATURE NAME="AF_CIRCULARITY" DT="UT_LENGTH_MM">0.0063</FEATURE>
    </BALLBAR_RUN>
  </RUN_RESULTS>
</TEST_DOCUMENT>
"""
