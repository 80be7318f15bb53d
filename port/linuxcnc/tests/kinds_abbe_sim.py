#!/usr/bin/python3
"""abbe's HAL component inside LinuxCNC's three other five-axis samples (issue 39).

  flock /tmp/abbe-linuxcnc.lock python3 port/linuxcnc/tests/kinds_abbe_sim.py \
      [--kind bridgemill|max5|xyzab-tdr] [--json OUT]

kinds_sim.py's runs (the same headless sample copies, poses, TCP on and off, the same
independent forward kinematics of the true machine) with the component in the loop:
the table is WRITTEN from the chain model (kinds_abbe_offline.py: the case's nominal
geometry as a KinematicChain with its injected ISO 230-1 location errors, format 1.4,
not fitted), loaded by `loadrt abbe`, its offsets on axis.x/y/z.eoffset-counts
(OFFSET_AV_RATIO 0.2), its inputs the joints' pos-cmd, kinstype the samples'
:kinstype-select signal (maxkins has one kinematics: a constant). After each move a
2 s dwell lets the rate-limited offset settle; the tool tip (from LinuxCNC's joints,
correction included) minus the programmed point is checked <= BOUND_UM in both modes.
Needs the component installed (port/linuxcnc/build.sh --install, as run.sh does).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parents[2] / "host_tools"))

import kinds_abbe_offline as off  # noqa: E402
import kinds_sim as ks  # noqa: E402
from abbe.formats.chain_blob import write_chain_blob  # noqa: E402

BOUND_UM = 0.5
ANGLE_JOINTS = {"bridgemill": (3, 4), "max5": (4, 5), "xyzab-tdr": (3, 4)}
# (kins_tcp, kins_identity) per case; maxkins / trivkins: one kinematics each
KINS = {"bridgemill": (0, 1), "max5": (0, 1), "xyzab-tdr": (1, 0)}


def abbe_hal(case: ks.Case, table: Path, ini_name: str) -> str:
    t, c = ANGLE_JOINTS[case.name]
    tcp, ident = KINS[case.name]
    lines = [f"loadrt abbe table={table}", "addf abbe servo-thread",
             "net abbe-j0 joint.0.pos-cmd => abbe.x.pos-mm", "net abbe-j1 joint.1.pos-cmd => abbe.y.pos-mm",
             "net abbe-j2 joint.2.pos-cmd => abbe.z.pos-mm",
             f"net abbe-jt joint.{t}.pos-cmd => abbe.tilt.pos-deg", f"net abbe-jc joint.{c}.pos-cmd => abbe.c.pos-deg",
             f"setp abbe.kins-identity {ident}", f"setp abbe.kins-tcp {tcp}"]
    if case.name == "max5":
        lines.append(f"setp abbe.kinstype {ident if ini_name == case.off_ini else tcp}")
    else:
        lines.append("net :kinstype-select => abbe.kinstype")
    # basic_sim.tcl (bridgemill, xyzab-tdr) nets motion.motion-enabled to sample:enable; max5's
    # own HAL files leave it free
    lines += ["net abbe-homed motion.is-all-homed => abbe.homed",
              "net abbe-on motion.motion-enabled => abbe.machine-on" if case.name == "max5"
              else "net sample:enable => abbe.machine-on"]
    for ax in "xyz":
        lines += [f"net abbe-{ax}-counts abbe.{ax}.counts => axis.{ax}.eoffset-counts",
                  f"setp axis.{ax}.eoffset-enable 1", f"setp abbe.{ax}.warn-mm 0.5",
                  f"setp abbe.{ax}.limit-mm 1.0", f"setp abbe.{ax}.rate-mm-per-s 1.0"]
    lines += ["net abbe-scale abbe.eoffset-scale => axis.x.eoffset-scale axis.y.eoffset-scale "
              "axis.z.eoffset-scale", "setp abbe.fade-s 0.2", "setp abbe.enable 1"]
    return "\n".join(lines) + "\n"


def add_abbe(case: ks.Case, cfg: Path, ini_name: str) -> None:
    """The component into a headless copy: a HALFILE after the sample's, OFFSET_AV_RATIO
    in the linear axes' sections (wherever they are: the INI or what it includes)."""
    marker = cfg / (ini_name + ".abbe")
    if marker.exists():
        return
    marker.write_text("")
    ch = off.chain_of(case.name)
    table = cfg / "abbe-kinds.bin"
    table.write_bytes(write_chain_blob(ch, off.errors_of(case, ch)))
    hal = cfg / f"abbe-kinds-{Path(ini_name).stem}.hal"
    hal.write_text(abbe_hal(case, table, ini_name))
    ini = cfg / ini_name
    files = [ini] + [cfg / ln.split(None, 1)[1].strip() for ln in ini.read_text().splitlines()
                     if ln.startswith("#INCLUDE")]
    for f in files:
        out, section, last_halfile = [], "", None
        for line in f.read_text().splitlines():
            s = line.strip()
            if s.startswith("["):
                section = s
            out.append(line)
            if s in ("[AXIS_X]", "[AXIS_Y]", "[AXIS_Z]"):
                out.append("OFFSET_AV_RATIO = 0.2")
            if section == "[HAL]" and s.split("=")[0].strip() == "HALFILE":
                last_halfile = len(out)
        if f == ini and last_halfile is not None:
            out.insert(last_halfile, f"HALFILE = {hal.name}")
        f.write_text("\n".join(out) + "\n")


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--kind", choices=sorted(ks.CASES), action="append")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--keep", action="store_true")
    args = ap.parse_args()
    headless = ks.headless

    def headless_abbe(case: ks.Case, cfg: Path, ini_name: str) -> Path:
        ini = headless(case, cfg, ini_name)
        add_abbe(case, cfg, ini_name)
        return ini

    moves = ks._moves

    def moves_dwell(case: ks.Case, values: dict, tcp: bool) -> list[str]:
        m = moves(case, values, tcp)
        return [x.replace(" (pose)", "") for x in m] + ["G4 P2.0 (pose)"]

    ks.headless = headless_abbe  # type: ignore[assignment]
    ks._moves = moves_dwell  # type: ignore[assignment]
    report, fails = {}, []
    for name in args.kind or sorted(ks.CASES):
        case = ks.CASES[name]
        res = ks.run_case(case, args.keep)
        for mode in ("tcp_on", "tcp_off"):
            r = res.get(mode, {})
            if not r.get("ok") or r.get("poses") != len(case.poses):
                fails.append(f"{name} {mode}: the run failed")
            elif r["max_norm_um"] > BOUND_UM:
                fails.append(f"{name} {mode}: {r['max_norm_um']:.4f} um with abbe (bound {BOUND_UM})")
        report[name] = res
        print(f"[kinds abbe] {name}: tcp_on {res.get('tcp_on', {}).get('max_norm_um')} um, "
              f"tcp_off {res.get('tcp_off', {}).get('max_norm_um')} um (with abbe)", flush=True)
    text = json.dumps(report, indent=2)
    print(text)
    if args.json:
        args.json.write_text(text + "\n")
    print("PASS" if not fails else "FAIL: " + "; ".join(fails))
    return 1 if fails else 0


if __name__ == "__main__":
    sys.exit(main())
