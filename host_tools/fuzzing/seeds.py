"""A small valid workspace for fuzzing and the argument lines of every command.

:func:`make_workspace` simulates a small campaign (one X laser line of 11 targets x 2
runs, one ballbar circle sampled every 2 deg) with ``abbe simulate`` and adds an ESS
``.dat`` file, the example table (blob + JSON), a declared-dialect laser export
(semicolon, decimal comma, nm, arcsec, a units row), and the ISO 230-1 error files
``abbe import`` reads: the example table exported with ``abbe export --format isg-csv``
(ISG CSV + ``.lis``, coarse: at most 240 records) and an Etalon exchange file written
here from the same table (21 grid points per curve). Everything is seeded: the same
bytes every time.
"""

from __future__ import annotations

import re
import shutil
from dataclasses import dataclass
from pathlib import Path

SPEC = """
[machine]
name = "fuzz"
seed = 7
travel_mm = { X = [0.0, 500.0], Y = [-400.0, 0.0], Z = [-300.0, 0.0] }
reference_mm = [163.626, -212.772, -290.704]

[errors.X]
dx = { slope_um_per_m = 24.0, bow_um = 3.0 }
dy = { bow_um = 7.0 }
ez = { slope_urad_per_m = 16.0, bow_urad = 10.0 }

[effects.squareness]
xy_urad = 30.0

[noise]
laser_linear_um = 0.1
ballbar_um = 0.1

[laser.X]
start_mm = [0.0, -212.772, -290.704]
end_mm = [500.0, -212.772, -290.704]
spacing_mm = 50.0
runs = 2
dwell_s = 1.0

[ballbar.circle1]
plane = "XY"
center_mm = [343.507, -285.09, -286.43]
radius_mm = 100.0
feed_mm_min = 2000.0
sample_deg = 2.0
feed_arc_deg = 10.0
"""

DAT = """TEST_DATA=# fuzz seed
UNIT=mm
CYCLES=3
POSITIONS=8
DEC=5
"""


def _dat() -> str:
    out = [DAT] + [f"TGT_DATA[{i}]={10 * (i - 1) + (i % 3)}\n" for i in range(1, 9)]
    for d, sgn in (("FWD", 1.0), ("BWD", -1.0)):
        for i in range(1, 9):
            for c in range(1, 4):
                v = 10.0 * (i - 1) + (i % 3) + 0.001 * ((i * c) % 5) + sgn * 0.002 \
                    + 0.0005 * ((i * i) % 4)
                out.append(f"REF_DATA_{d}[{i},{c}]={v:.6f}\n")
    return "".join(out)


DECLARED = """
[laser.X.columns]
delimiter = ";"
decimal = ","
skip_lines = 2
units_row = true
run = "Run"
direction = "Dir"
direction_values = ["fwd", "bwd"]
target = "Position"
linear = { column = "Lin. dev.", sign = -1 }
yaw = "Yaw"
"""


@dataclass
class Workspace:
    """Paths of the seed files (all under ``root``)."""

    root: Path
    machine: Path
    spec: Path
    laser: Path
    ballbar: Path
    dat: Path
    blob: Path
    table_json: Path
    declared_machine: Path
    declared_laser: Path
    isg_csv: Path
    isg_lis: Path
    etalon: Path
    rtl: Path
    b5r: Path
    renishaw_machine: Path
    five_axis_machine: Path
    five_axis_probe: Path
    five_axis_rtest: Path
    five_axis_indexer: Path
    #: Renishaw files from the independent writer (cases/renishaw_public.py): an .rtl in
    #: cp1250 with Czech user text and an EQUIPMENT:: section, a Ballbar 20-layout .b5r,
    #: and a machine file naming both.
    rtl_windows: Path | None = None
    b5r_ballbar20: Path | None = None
    renishaw20_machine: Path | None = None


def _declared_export(laser_csv: Path, out: Path) -> None:
    """The laser CSV as an instrument export: preamble, semicolons, decimal comma, units
    row, nm and arcsec, the linear sign flipped, directions as fwd/bwd, CRLF, a BOM."""
    lines = laser_csv.read_text().splitlines()
    hdr = lines[0].split(",")
    ix = {n: i for i, n in enumerate(hdr)}
    rows = ["\ufeffExported by LaserTool 4.2", "Axis;X", "Run;Dir;Position;Lin. dev.;Yaw",
            ";;[mm];[nm];[arcsec]"]
    for ln in lines[1:]:
        c = ln.split(",")
        lin_nm = -float(c[ix["linear_um"]]) * 1000.0
        yaw_as = float(c[ix["yaw_urad"]]) / 4.84813681109536
        cells = [c[ix["run"]], "fwd" if c[ix["direction"]] == "+" else "bwd",
                 c[ix["target_mm"]], f"{lin_nm:.1f}", f"{yaw_as:.5f}"]
        rows.append(";".join(x.replace(".", ",") for x in cells))
    out.write_bytes(("\r\n".join(rows) + "\r\n").encode("utf-8"))


_ISO = {"dx": "X", "dy": "Y", "dz": "Z", "ex": "A", "ey": "B", "ez": "C"}


def _etalon(table, out: Path, points: int = 21) -> None:
    """An Etalon exchange file (Vendor variant) of ``table``'s terms and squareness."""
    import numpy as np

    from abbe.model.reference import term_values
    from abbe.model.table import AXES
    lines = ["// fuzz seed: Etalon exchange format (Vendor variant), mm and rad"]
    for k, name in enumerate(("C0Y", "B0Z", "A0Z")):
        s = table.squareness_urad[k] * (-1.0 if name == "B0Z" else 1.0)
        lines += [f"[{name}]", f"VALUE = {s * 1e-6:.12e}"]
    for a in AXES:
        q = np.linspace(*table.axes[a].travel_mm, points)
        for t in ("dx", "dy", "dz", "ex", "ey", "ez"):
            v = term_values(table, a, t, q) * (1e-3 if t[0] == "d" else 1e-6)
            lines += [f"[E{_ISO[t]}{a}]", "Gridpoints = {"]
            lines += [f"   {x:.4f} {y:.12e}" for x, y in zip(q, v)]
            lines.append(f"}}  // end of E{_ISO[t]}{a}")
    out.write_text("\n".join(lines) + "\n")


def make_workspace(root: Path) -> Workspace:
    """Create the seed workspace under ``root`` (a fresh folder)."""
    from abbe.cli.entry import main
    from abbe.paths import examples_dir

    root.mkdir(parents=True, exist_ok=True)
    spec = root / "spec.toml"
    spec.write_text(SPEC)
    camp = root / "camp"
    rc = main(["simulate", str(spec), "-o", str(camp)])
    if rc != 0:
        raise RuntimeError(f"abbe simulate of the fuzz seed failed ({rc})")
    dat = root / "x.dat"
    dat.write_text(_dat())
    ex = examples_dir() / "paper_table"
    blob, tjson = root / "model.bin", root / "model.json"
    shutil.copyfile(ex / "model.bin", blob)
    shutil.copyfile(ex / "model.json", tjson)
    declared_laser = camp / "laser" / "x_export.csv"
    _declared_export(camp / "laser" / "x.csv", declared_laser)
    text = (camp / "machine.toml").read_text()
    dm = camp / "machine_declared.toml"
    text = text.replace('file = "laser/x.csv"', 'file = "laser/x_export.csv"')
    text = re.sub(r'^map = \{ linear = "\+dx".*$', 'map = { linear = "+dx", yaw = "-ez" }', text,
                  flags=re.M)
    dm.write_text(text + DECLARED)
    isg = root / "isg"
    if main(["export", str(blob), "--format", "isg-csv", "-o", str(isg), "--set",
             "max_records=240"]) != 0:
        raise RuntimeError("abbe export isg-csv of the fuzz seed failed")
    from abbe.formats.blob import read_blob_file
    etalon = root / "lasertracer.exc"
    _etalon(read_blob_file(blob)[1], etalon)
    rtl, b5r, rmach = _renishaw(camp)
    rtl_w, b5r_20, rmach_20 = _renishaw_public(camp)
    five = root / "trunnion5ax"  # the five-axis example's campaign, its truth left out
    five.mkdir()
    for n in ("machine.toml", "probe.csv", "rtest.csv", "indexer_C.csv"):
        shutil.copyfile(examples_dir() / "trunnion5ax" / n, five / n)
    return Workspace(root=root, machine=camp / "machine.toml", spec=spec,
                     laser=camp / "laser" / "x.csv", ballbar=camp / "ballbar" / "circle1.csv",
                     dat=dat, blob=blob, table_json=tjson, declared_machine=dm,
                     declared_laser=declared_laser, isg_csv=isg / "volcomp.csv",
                     isg_lis=isg / "volcomp.lis", etalon=etalon, rtl=rtl, b5r=b5r,
                     renishaw_machine=rmach, five_axis_machine=five / "machine.toml",
                     five_axis_probe=five / "probe.csv", five_axis_rtest=five / "rtest.csv",
                     five_axis_indexer=five / "indexer_C.csv", rtl_windows=rtl_w,
                     b5r_ballbar20=b5r_20, renishaw20_machine=rmach_20)


def _renishaw(camp: Path) -> tuple[Path, Path, Path]:
    """The campaign's X line as a Renishaw .rtl file (linear) and its circle as a .b5r
    file (sampled at 20 Hz), and a machine file naming both."""
    from cases.renishaw import PUBLIC_ENV, b5r_from_trace, rtl_from_updown
    from abbe.formats.laser_csv import read_laser_csv
    d = read_laser_csv(camp / "laser" / "x.csv", channels=("linear",))
    v = d.channels["linear"]
    rtl = camp / "laser" / "x.rtl"
    env = dict(PUBLIC_ENV)
    env.pop("Date Time")  # text with digits: every number of the seed must be data
    # Final Data takes one or two integers, not interpreted (R6): deleting one of them
    # leaves a valid file, so it is no data number either (a long run found it, seed 34).
    env.pop("Final Data")
    rtl.write_text(rtl_from_updown(d.targets_mm, v[:, 0, :], v[:, 1, :], env=env, plain=True),
                   newline="")
    b5r = camp / "ballbar" / "circle1.b5r"
    b5r.write_text(b5r_from_trace(camp / "ballbar" / "circle1.csv", feed_mm_min=2000.0,
                                  sample_rate_hz=20.0, overrun_deg=10.0, plain=True)[0])
    text = (camp / "machine.toml").read_text()
    text = text.replace('file = "laser/x.csv"', 'file = "laser/x.rtl"')
    text = text.replace('file = "ballbar/circle1.csv"', 'file = "ballbar/circle1.b5r"')
    text = re.sub(r'^map = \{ linear = "\+dx".*$', 'map = { linear = "+dx" }', text, flags=re.M)
    rm = camp / "machine_renishaw.toml"
    rm.write_text(text)
    return rtl, b5r, rm


def _renishaw_public(camp: Path) -> tuple[Path, Path, Path]:
    """The campaign's X line as an .rtl file in cp1250 with non-ASCII user text and an
    EQUIPMENT:: section, a Ballbar 20-layout .b5r of the campaign's circle (its plane,
    radius and feed; readings of a known circle), and a machine file naming both: the
    independent writer's shapes (cases/renishaw_public.py)."""
    from abbe.formats.laser_csv import read_laser_csv
    from abbe.formats.machine import load_machine
    from cases.renishaw_public import b5r_ballbar20, rtl_bytes
    d = read_laser_csv(camp / "laser" / "x.csv", channels=("linear",))
    v = d.channels["linear"]
    passes = []
    for r in range(v.shape[0]):
        passes += [v[r, 0, :], v[r, 1, :]]
    rtl = camp / "laser" / "x_cp1250.rtl"
    rtl.write_bytes(rtl_bytes(d.targets_mm, passes, encoding="cp1250",
                              equipment_after="DEVIATIONS"))
    bt = load_machine(camp / "machine.toml").ballbar["circle1"]
    plane = {"XY": ("X", "Y"), "ZX": ("Z", "X"), "YZ": ("Y", "Z")}[bt.plane]
    b5r = camp / "ballbar" / "circle1_bb20.b5r"
    b5r.write_text(b5r_ballbar20(plane=plane, radius_mm=bt.radius_mm, feed_mm_min=bt.feed_mm_min,
                                 sample_hz=20.0, start_deg=45.0, overshoot_deg=45.0)[0],
                   encoding="utf-8")
    text = (camp / "machine.toml").read_text()
    text = text.replace('file = "laser/x.csv"', 'file = "laser/x_cp1250.rtl"')
    text = text.replace('file = "ballbar/circle1.csv"', 'file = "ballbar/circle1_bb20.b5r"')
    text = re.sub(r'^map = \{ linear = "\+dx".*$', 'map = { linear = "+dx" }', text, flags=re.M)
    rm = camp / "machine_renishaw20.toml"
    rm.write_text(text)
    return rtl, b5r, rm
