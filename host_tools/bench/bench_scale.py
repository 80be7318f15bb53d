"""Benchmark: time and peak memory of the readers and ``abbe fit`` on dense laser lines.

A continuous (on-the-fly) capture: 5 bidirectional runs over T targets of the X line
(500 mm), all six channels and time_s, so 10 T rows. For each size the commands run
as fresh processes; the peak resident memory is the child's ru_maxrss. The budget
(docs/formats.md, "Limits"): a 10^6-row line is read and fitted within 2 GiB and
linear time (twice the rows, about twice the time and the memory above the baseline).

    python host_tools/bench/bench_scale.py [--rows 100000 1000000] [--report]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

MACHINE = """
[machine]
name = "dense"
[axes.X]
travel_mm = [0.0, 500.0]
[axes.Y]
travel_mm = [-400.0, 0.0]
[axes.Z]
travel_mm = [-300.0, 0.0]
[reference]
point_mm = [163.626, -212.772, -290.704]
[laser.X]
file = "x.csv"
start_mm = [0.0, -212.772, -290.704]
end_mm = [500.0, -212.772, -290.704]
map = { linear = "+dx", straight_h = "+dy", straight_v = "+dz", pitch = "-ey", yaw = "-ez", roll = "+ex" }
"""


def write_line(path: Path, rows: int, seed: int = 1) -> None:
    """A dense line of ``rows`` readings (5 runs x 2 directions x rows/10 targets)."""
    rng = np.random.default_rng(seed)
    T = rows // 10
    t = np.linspace(0.0, 500.0, T)
    with open(path, "w") as fh:
        fh.write("run,direction,target_mm,linear_um,straight_h_um,straight_v_um,pitch_urad,"
                 "yaw_urad,roll_urad,time_s\n")
        clock = 0.0
        for r in range(1, 6):
            for d, tt in (("+", t), ("-", t[::-1])):
                n = tt.size
                lin = 5 * np.sin(tt / 80.0) + 0.01 * tt + rng.normal(0, 0.1, n) + (1.5 if d == "+" else -1.5)
                sh = 2 * np.sin(tt / 200.0) + rng.normal(0, 0.2, n)
                sv = -3 * ((tt - 250) / 250) ** 2 + rng.normal(0, 0.2, n)
                p = 0.02 * tt + rng.normal(0, 0.3, n)
                y = 4 * np.cos(tt / 120.0) + rng.normal(0, 0.3, n)
                ro = rng.normal(0, 0.3, n)
                time_s = clock + np.arange(n) * 0.01
                clock = float(time_s[-1]) + 1.0
                block = np.column_stack([tt, lin, sh, sv, p, y, ro, time_s])
                lines = [f"{r},{d}," + ",".join(f"{v:.4f}" for v in row) for row in block]
                fh.write("\n".join(lines) + "\n")


def run(cmd: list[str]) -> tuple[float, float, int]:
    """(wall s, peak RSS MiB of that child, exit status) of one fresh process."""
    t0 = time.perf_counter()
    with tempfile.TemporaryFile() as err:
        p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err)
        _, status, usage = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t0
        rc = os.waitstatus_to_exitcode(status)
        if rc != 0:
            err.seek(0)
            print(err.read().decode()[-2000:])
    p.returncode = rc  # reaped by wait4
    return wall, usage.ru_maxrss / 1024.0, rc


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, nargs="+", default=[100_000, 1_000_000])
    ap.add_argument("--report", action="store_true", help="also write the PNG/HTML report")
    args = ap.parse_args()
    py = sys.executable
    print(f"{'rows':>9} {'targets':>8} {'MiB':>6} | {'read+ISO s':>10} {'MiB':>6} | "
          f"{'fit s':>7} {'MiB':>6}")
    for rows in sorted(args.rows):
        with tempfile.TemporaryDirectory(prefix="abbe-scale-") as d:
            d = Path(d)
            write_line(d / "x.csv", rows)
            (d / "machine.toml").write_text(MACHINE)
            size = (d / "x.csv").stat().st_size / (1 << 20)
            w1, m1, rc1 = run([py, "-m", "abbe.cli", "iso230-2", str(d / "x.csv")])
            fit = [py, "-m", "abbe.cli", "fit", str(d / "machine.toml"), "-o", str(d / "out"),
                   "--no-clib-check", "-q"] + ([] if args.report else ["--no-report"])
            w2, m2, rc2 = run(fit)
            if rc1 or rc2:
                return 1
            print(f"{rows:>9} {rows // 10:>8} {size:>6.1f} | {w1:>10.2f} {m1:>6.0f} | "
                  f"{w2:>7.2f} {m2:>6.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
