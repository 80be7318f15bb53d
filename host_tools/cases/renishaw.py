"""Renishaw sample files written from the public descriptions (docs/formats.md, "Renishaw
laser .rtl" and "Renishaw ballbar .b5r"): a writer of each format, independent of the
readers, used by the reader tests, the fuzzers and the closed-loop test."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def rtl_text(targets_mm, passes, *, owner: str = "Linear", flags: str = "0 0 2 0",
             env: dict[str, str] | None = None, axis: str = "X", newline: str = "\r\n",
             plain: bool = False) -> str:
    """An .rtl file: ``passes`` (P, T) deviations in target-list order, odd passes listed
    1..T, even passes T..1, like the public writer (C#) and parser (Java) do. ``plain``:
    no digits outside the data (no version, dates or serial number: for the fuzzers,
    where every number must be data)."""
    t = list(targets_mm)
    out = ["HEADER::", "File type  : rtl", f"Owner      : {owner}"]
    out += [] if plain else ["Version no : V20.02.02"]
    out += ["",
           "TARGET DATA::", "Filetype  : ISO", f"Target-count: {len(t)}", "Targets :"]
    for i in range(0, len(t), 5):
        out.append(" ".join(f"{v:.3f}" for v in t[i:i + 5]))
    user = (["Machine:  vmc", f"Axis:{axis}"] if plain else
            ["Machine:  vmc500", "Serial No:  0001", "Date:2026-12-02 05:00:00", "By:abbe tests",
             f"Axis:{axis}", "Location:lab", "TITLE:sample"])
    out += [f"Flags: {flags}", "", "USER-TEXT::"] + user + ["", "RUNS::", f"Run-count:{len(passes)}", "", "DEVIATIONS::",
            "Run Target Data:"]
    n_t = len(t)
    for p, row in enumerate(passes, start=1):
        idx = range(1, n_t + 1) if p % 2 else range(n_t, 0, -1)
        for j in idx:
            out.append(f"{p}   {j}      {row[j - 1]:.4f}")
    if env is not None:
        out += ["", "ENVIRONMENT::"] + [f"{k:<11}: {v}" for k, v in env.items()]
    out += ["", "EOF::", ""]
    return newline.join(out)


#: The environment of the public sample (RtlEnvironment.java's comments).
PUBLIC_ENV = {"Air temp": "20.337280 20.384956 0", "Air press": "99.039005 99.049346 1",
              "Air humid": "46.954897 46.893887", "Mat temp 1": "20.203292 20.321342 0",
              "Mat temp 2": "-10.000000 -10.000000 0", "Mat temp 3": "-10.000000 -10.000000 0",
              "Env factor": "0.31641096 0.31641067", "Exp coeff": "8.000000 8.000000 0",
              "Date Time": '"10:46 Dec 12 2016" "11:01 Dec 12 2016"', "Final Data": "1 0"}


def rtl_from_updown(targets_mm, up_um, down_um, **kw) -> str:
    """An .rtl file from ascending targets and (n, T) up / down deviations (um)."""
    passes = []
    for u, d in zip(up_um, down_um):
        passes += [list(u), list(d)]
    return rtl_text(targets_mm, passes, **kw)


def sample_rtl(seed: int = 1, n_runs: int = 5) -> tuple[str, np.ndarray, np.ndarray, np.ndarray]:
    """A 5-run linear test over 11 uneven targets with a slope, a wave, 3 um reversal."""
    rng = np.random.default_rng(seed)
    t = np.array([0.0, 48.3, 97.1, 151.9, 199.2, 252.6, 301.4, 348.8, 402.5, 449.7, 500.0])
    base = 0.012 * t + 2.0 * np.sin(2 * np.pi * t / 170.0)
    up = base[None, :] + 1.5 + rng.normal(0, 0.3, (n_runs, t.size))
    down = base[None, :] - 1.5 + rng.normal(0, 0.3, (n_runs, t.size))
    return rtl_from_updown(t, up, down, env=PUBLIC_ENV), t, np.round(up, 4), np.round(down, 4)


def write(path: Path, text: str) -> Path:
    path.write_bytes(text.encode("utf-8"))
    return path


def b5r_text(*, plane=("X", "Y"), radius_mm=100.0, feed_mm_min=200.0, sample_rate_hz=10.0,
             overrun_deg=45.0, ccw_um=(), cw_um=(), data_dt="UT_LENGTH_UM",
             features: dict[str, tuple[str, str]] | None = None, machine: str = "vmc500",
             plain: bool = False) -> str:
    """A .b5r file: the public parsers' metadata and FEATURE elements, the raw data as
    abbe assumes it (renishaw_b5r's module doc). ``plain``: no digits outside the data."""
    a, b = plane
    feats = features if features is not None else {
        "AF_CIRCULARITY": ("UT_LENGTH_UM", "5.2"), "AF_SQUARENESS": ("UT_SQUARENESS", "-12.0")}
    fx = "\n".join(f'      <FEATURE NAME="{k}" DT="{dt}">{v}</FEATURE>' for k, (dt, v) in feats.items())

    def data(v):
        rows = [" ".join(f"{x:.4f}" for x in v[i:i + 10]) for i in range(0, len(v), 10)]
        return "\n".join(rows)
    head = ("<BALLBAR_FILE>\n  <TEST_SPEC NAME=\"plain\">\n" if plain else f'''<?xml version="1.0" encoding="utf-8"?>
<BALLBAR_FILE VERSION="5">
  <TEST_SPEC NAME="{a}{b} 360 {radius_mm:g}mm">
    <OPERATOR>abbe tests</OPERATOR>
    <DATE_STARTED>2026-12-02 05:30</DATE_STARTED>
    <MACHINE_TESTED NAME="{machine}"/>
    <SERIAL_NUMBER>QC20-0001</SERIAL_NUMBER>
    <LAST_CALIBRATED>2026-01-15</LAST_CALIBRATED>
''')
    return head + f'''    <PLANE TEST_PLANE="{a}{b}">
      <A_AXIS_NAME>{a}</A_AXIS_NAME>
      <B_AXIS_NAME>{b}</B_AXIS_NAME>
    </PLANE>
    <RADIUS DT="UT_LENGTH_MM">{radius_mm:g}</RADIUS>
    <FEEDRATE DT="UT_FEEDRATE">{feed_mm_min:g}</FEEDRATE>
    <SAMPLE_RATE DT="UT_FREQUENCY">{sample_rate_hz:g}</SAMPLE_RATE>
    <OVERRUN_ARC DT="UT_ANGLE">{overrun_deg:g}</OVERRUN_ARC>
  </TEST_SPEC>
  <RUN DIRECTION="CCW">
    <DATA DT="{data_dt}">
{data(list(ccw_um))}
    </DATA>
  </RUN>
  <RUN DIRECTION="CW">
    <DATA DT="{data_dt}">
{data(list(cw_um))}
    </DATA>
  </RUN>
  <ANALYSIS NAME="RENISHAW_DIAGNOSTICS">
{fx}
  </ANALYSIS>
</BALLBAR_FILE>
'''


def b5r_from_trace(csv_path: Path, *, radius_mm=100.0, feed_mm_min=200.0, sample_rate_hz=10.0,
                   overrun_deg=45.0, **kw) -> tuple[str, np.ndarray, np.ndarray]:
    """A .b5r file resampling an abbe ballbar CSV (angle -> time at the feed): the same
    circle, so both must evaluate alike. Returns (text, ccw_um, cw_um)."""
    import csv
    rows = list(csv.DictReader(open(csv_path)))
    deg_per_s = np.degrees(feed_mm_min / 60.0 / radius_mm)
    n = int(np.floor((360.0 + 2 * overrun_deg) / deg_per_s * sample_rate_hz + 1e-6)) + 1
    t = np.arange(n) / sample_rate_hz
    out = []
    for d, ang in (("ccw", -overrun_deg + deg_per_s * t), ("cw", 360 + overrun_deg - deg_per_s * t)):
        a = np.array([float(r["angle_deg"]) for r in rows if r["direction"] == d])
        v = np.array([float(r["radial_um"]) for r in rows if r["direction"] == d])
        o = np.argsort(a)
        out.append(np.interp(ang, a[o], v[o]))
    return b5r_text(radius_mm=radius_mm, feed_mm_min=feed_mm_min, sample_rate_hz=sample_rate_hz,
                    overrun_deg=overrun_deg, ccw_um=out[0], cw_um=out[1], **kw), out[0], out[1]
