#!/usr/bin/python3
"""Cost of the abbe realtime function per servo period (a benchmark, not a test).

Runs the installed component in halrun on a 1 ms thread for --seconds (60)
with the positions going round the vmc500 ballbar circle (siggen, 0.5 Hz) and
a table made by the abbe CLI from examples/vmc500 (all features: 21 errors,
backlash, thermal), and records HAL's own measurement of the function,
abbe.time (TSC clocks of the function call, written by the thread every
period), with halsampler. Clocks are converted to ns with the TSC rate
measured against CLOCK_MONOTONIC by a small C program.

This is LinuxCNC's POSIX non-realtime mode (no RT kernel here): the median is
the cost; the maximum includes whatever the non-RT scheduler did to the
thread and says nothing about an RT kernel.

  port/linuxcnc/bench/rt_cost.py [--seconds 60] [--variant q|f32|both] [--json OUT]
                                 [--five TABLE]

--five TABLE: a five-axis table (format 1.2, e.g. the golden trunnion5ax fit
host_tools/tests/exports/golden/trunnion5ax-fit/model_five.bin) instead,
the tilt joint on the circle's sine (+/-100 deg) and C on a triangle wave, identity
kinematics (kinstype 0): the five-axis mode's cost per period.

Needs the component installed (port/linuxcnc/build.sh --install); as root it
runs halrun as $ABBE_LCNC_USER (port/linuxcnc/tests/run.sh creates it).
"""

from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from lcnc_common import (REPO, as_user, check, cleanup, give, hal_clean, log,  # noqa: E402
                         main_wrapper, make_table, read_samples, work_dir)

CENTRE = (343.507, -285.09, -286.43)
RADIUS = 100.0

TSC_C = r"""
#include <stdio.h>
#include <time.h>
#include <x86intrin.h>
static double now(void) { struct timespec t; clock_gettime(CLOCK_MONOTONIC, &t); return t.tv_sec + 1e-9 * t.tv_nsec; }
int main(void) {
    double t0 = now(); unsigned long long c0 = __rdtsc();
    while (now() - t0 < 0.5) { }
    double t1 = now(); unsigned long long c1 = __rdtsc();
    printf("%.6f\n", (double)(c1 - c0) / (t1 - t0) / 1e6);
    return 0;
}
"""


def tsc_mhz() -> float:
    with tempfile.TemporaryDirectory() as d:
        src, exe = Path(d) / "tsc.c", Path(d) / "tsc"
        src.write_text(TSC_C)
        subprocess.run(["gcc", "-O2", "-o", str(exe), str(src)], check=True)
        return float(subprocess.run([str(exe)], capture_output=True, text=True, check=True).stdout)


def run(work: Path, table: Path, variant: str, seconds: float, five: bool = False) -> np.ndarray:
    n = int(seconds * 1000)
    script = work / f"bench_{variant}.hal"
    out = work / f"time_{variant}.txt"
    script.write_text("\n".join([
        "loadrt threads name1=servo period1=1000000",
        "loadrt siggen",
        f"loadrt abbe table={table} variant={variant}",
        "loadrt sampler depth=8000 cfg=su",
        "setp siggen.0.frequency 0.5",
        f"setp siggen.0.amplitude {RADIUS}",
        "setp siggen.0.offset 0",
        "loadrt sum2 count=2",
        f"setp sum2.0.offset {CENTRE[0]}",
        f"setp sum2.1.offset {CENTRE[1]}",
        "net cx siggen.0.cosine => sum2.0.in0",
        "net sy siggen.0.sine => sum2.1.in0",
        "net x sum2.0.out => abbe.x.pos-mm",
        "net y sum2.1.out => abbe.y.pos-mm",
        f"setp abbe.z.pos-mm {CENTRE[2]}",
        *(["net sy => abbe.tilt.pos-deg", "net tri siggen.0.triangle => abbe.c.pos-deg",
           "setp abbe.kinstype 0"] if five else []),
        "setp abbe.x.temp-c 23.5", "setp abbe.y.temp-c 21.0", "setp abbe.z.temp-c 18.5",
        "setp abbe.homed 1", "setp abbe.machine-on 1", "setp abbe.enable 1",
        "net t abbe.time => sampler.0.pin.0",
        "net c abbe.cycles => sampler.0.pin.1",
        "addf siggen.0.update servo", "addf sum2.0 servo", "addf sum2.1 servo",
        "addf abbe servo", "addf sampler.0 servo",
        "start",
        f"loadusr -w halsampler -t -n {n + 1000} {out}",
        "",
    ]))
    give(script)
    hal_clean()
    log(f"{variant}: {seconds:.0f} s at 1 kHz")
    res = subprocess.run(as_user(["halrun", "-f", str(script)]), cwd=work, capture_output=True,
                         text=True, stdin=subprocess.DEVNULL, timeout=seconds * 3 + 120)
    check(res.returncode == 0, f"halrun: {res.stdout}{res.stderr}")
    data = read_samples(out, 2)
    check(np.all(np.diff(data[:, 2]) == 1), "the function did not run once per sample")
    return data[1000:, 1]  # the first second (start-up, cold caches) is left out


def summary(clocks: np.ndarray, mhz: float) -> dict:
    ns = clocks / mhz * 1e3
    return {"samples": int(len(ns)), "median_ns": round(float(np.median(ns)), 1),
            "p99_ns": round(float(np.percentile(ns, 99)), 1),
            "p99_9_ns": round(float(np.percentile(ns, 99.9)), 1),
            "max_ns": round(float(ns.max()), 1), "min_ns": round(float(ns.min()), 1),
            "median_clocks": float(np.median(clocks)), "max_clocks": float(clocks.max())}


def cpu_model() -> str:
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return platform.processor()


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--variant", choices=["q", "f32", "both"], default="both")
    ap.add_argument("--json", type=Path, default=REPO / "build-linuxcnc" / "rt_cost.json")
    ap.add_argument("--five", type=Path, help="a five-axis table (format 1.2) instead")
    args = ap.parse_args()
    work = work_dir("abbe-rtcost-")
    try:
        if args.five:
            table = work / "five.bin"
            table.write_bytes(args.five.read_bytes())
            give(table)
        else:
            table = make_table(REPO / "examples/vmc500/truth/true_table.json", work / "vmc500.bin")
        mhz = tsc_mhz()
        lcnc = subprocess.run(["dpkg-query", "-W", "-f=${Version}", "linuxcnc-uspace"],
                              capture_output=True, text=True).stdout
        result = {"mode": "LinuxCNC uspace, POSIX non-realtime (no RT kernel)",
                  "cpu": cpu_model(), "kernel": platform.release(), "linuxcnc": lcnc,
                  "tsc_mhz": round(mhz, 3), "period_ns": 1000000, "seconds": args.seconds,
                  "table": (str(args.five) if args.five else
                            "examples/vmc500/truth/true_table.json (all features)"), "variants": {}}
        for v in (["q", "f32"] if args.variant == "both" else [args.variant]):
            result["variants"][v] = summary(run(work, table, v, args.seconds, bool(args.five)), mhz)
            s = result["variants"][v]
            log(f"{v}: median {s['median_ns']:.0f} ns, p99 {s['p99_ns']:.0f} ns, "
                f"p99.9 {s['p99_9_ns']:.0f} ns, max {s['max_ns']:.0f} ns over {s['samples']} periods")
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(result, indent=1))
        log(f"wrote {args.json} (TSC {mhz:.1f} MHz, {result['cpu']})")
    finally:
        hal_clean()
        cleanup(work)


if __name__ == "__main__":
    main_wrapper(main)
