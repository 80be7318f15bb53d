#!/usr/bin/python3
"""A simulated touch probe on a calibration sphere for LinuxCNC's xyzac-trt sample (a HAL
userspace component; program_sim.py loads it with ``loadusr -Wn sphereprobe``).

  sphere_probe.py --ball X Y Z --reach MM --rot-point X Y Z --offset Y Z

Pins: ``sphereprobe.x|y|z|a|c`` (in, the joints' positions: mm, deg), ``sphereprobe.enable``
(in, false at start: the R-test's nest on the ball is no probe), ``sphereprobe.tripped``
(out, to ``motion.probe-input``). The sphere sits at ``--ball`` on the table (workpiece
coordinates = machine coordinates at A = C = 0) and turns with it as the trt geometry
says (C about the rotation point, then A about the rotation point + offsets); the probe
trips while the stylus centre is within ``--reach`` (sphere + stylus radius) of it.
Polled every 0.2 ms: at a probing feed of F mm/min the trip comes up to ~F / 60 x 0.3 um
late, along the approach (a pre-travel the sphere fit's radius absorbs).
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import time

import hal


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--ball", type=float, nargs=3, required=True)
    ap.add_argument("--reach", type=float, required=True)
    ap.add_argument("--rot-point", type=float, nargs=3, default=(0.0, 0.0, 0.0))
    ap.add_argument("--offset", type=float, nargs=2, default=(0.0, 0.0), help="y z (A/C)")
    args = ap.parse_args()
    h = hal.component("sphereprobe")
    for n in "xyzac":
        h.newpin(n, hal.HAL_FLOAT, hal.HAL_IN)
    h.newpin("enable", hal.HAL_BIT, hal.HAL_IN)
    h.newpin("tripped", hal.HAL_BIT, hal.HAL_OUT)
    h.ready()
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    bx, by, bz = args.ball
    rx, ry, rz = args.rot_point
    oy, oz = args.offset
    r2 = args.reach ** 2
    try:
        while True:
            c, a = math.radians(h["c"]), math.radians(h["a"])
            # C about the rotation point (z axis) ...
            x1 = rx + math.cos(c) * (bx - rx) - math.sin(c) * (by - ry)
            y1 = ry + math.sin(c) * (bx - rx) + math.cos(c) * (by - ry)
            z1 = bz
            # ... then A about the line through rotation point + (0, y-offset, z-offset)
            py, pz = ry + oy, rz + oz
            y2 = py + math.cos(a) * (y1 - py) - math.sin(a) * (z1 - pz)
            z2 = pz + math.sin(a) * (y1 - py) + math.cos(a) * (z1 - pz)
            d2 = (h["x"] - x1) ** 2 + (h["y"] - y2) ** 2 + (h["z"] - z2) ** 2
            h["tripped"] = bool(h["enable"]) and d2 <= r2
            time.sleep(0.0002)
    except (KeyboardInterrupt, SystemExit):
        return 0


if __name__ == "__main__":
    sys.exit(main())
