#!/usr/bin/python3
"""The centre of a calibration sphere on LinuxCNC's xyzac-trt sample table, for a simulated
touch probe (a HAL userspace component; program_sim.py loads it with ``loadusr -Wn
sphereprobe`` and builds the probe itself in the servo thread: :data:`PROBE_HAL`).

  sphere_probe.py --ball X Y Z --rot-point X Y Z --offset Y Z

Pins: ``sphereprobe.a|c`` (in, the rotary joints, deg), ``sphereprobe.cx|cy|cz`` (out, mm):
the sphere at ``--ball`` on the table (workpiece coordinates = machine coordinates at A = C
= 0) turned as the trt geometry says (C about the rotation point, then A about the rotation
point + offsets); ``sphereprobe.a-used|c-used`` (out, deg): the joint angles that centre was
computed for. The distance test runs every servo period in realtime components (sum2, mult2,
comp, and2): the trip comes at most one period late. This userspace loop lags the table (on
a loaded machine by much more than its 1 ms), while a real sphere turns with it: realtime
components let the probe trip only while the centre is the one for the joints' present
angles (their squared differences, deg^2, below 1e-18). The rotary axes stand still while
the probe moves near the ball, so that costs the probing nothing; while the table turns,
with the probe at the safe height above the sphere's sweep, a stale centre could otherwise
put the ball under the probe ("Probe tripped during non-probe move").
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import time

#: halcmd lines of the realtime probe: ``{reach2}`` the squared trip distance (mm^2).
#: ``sp_on.in1`` enables it (0 at start: the R-test's nest on the ball is no probe).
PROBE_HAL = """loadrt sum2 names=sp_dx,sp_dy,sp_dz,sp_s1,sp_s2,sp_da,sp_dc,sp_s3
loadrt mult2 names=sp_qx,sp_qy,sp_qz,sp_qa,sp_qc
loadrt comp names=sp_in,sp_fr
loadrt and2 names=sp_on,sp_ok
addf sp_dx servo-thread
addf sp_dy servo-thread
addf sp_dz servo-thread
addf sp_qx servo-thread
addf sp_qy servo-thread
addf sp_qz servo-thread
addf sp_s1 servo-thread
addf sp_s2 servo-thread
addf sp_in servo-thread
addf sp_on servo-thread
addf sp_da servo-thread
addf sp_dc servo-thread
addf sp_qa servo-thread
addf sp_qc servo-thread
addf sp_s3 servo-thread
addf sp_fr servo-thread
addf sp_ok servo-thread
net J0:pos-fb sp_dx.in0
net J1:pos-fb sp_dy.in0
net J2:pos-fb sp_dz.in0
net J3:pos-fb sphereprobe.a sp_da.in0
net J4:pos-fb sphereprobe.c sp_dc.in0
net :sp-a-used sphereprobe.a-used sp_da.in1
net :sp-c-used sphereprobe.c-used sp_dc.in1
setp sp_da.gain1 -1
setp sp_dc.gain1 -1
net :sp-da sp_da.out sp_qa.in0 sp_qa.in1
net :sp-dc sp_dc.out sp_qc.in0 sp_qc.in1
net :sp-qa sp_qa.out sp_s3.in0
net :sp-qc sp_qc.out sp_s3.in1
net :sp-dang2 sp_s3.out sp_fr.in0
setp sp_fr.in1 1e-18
net :sp-cx sphereprobe.cx sp_dx.in1
net :sp-cy sphereprobe.cy sp_dy.in1
net :sp-cz sphereprobe.cz sp_dz.in1
setp sp_dx.gain1 -1
setp sp_dy.gain1 -1
setp sp_dz.gain1 -1
net :sp-dx sp_dx.out sp_qx.in0 sp_qx.in1
net :sp-dy sp_dy.out sp_qy.in0 sp_qy.in1
net :sp-dz sp_dz.out sp_qz.in0 sp_qz.in1
net :sp-qx sp_qx.out sp_s1.in0
net :sp-qy sp_qy.out sp_s1.in1
net :sp-s1 sp_s1.out sp_s2.in0
net :sp-qz sp_qz.out sp_s2.in1
net :sp-d2 sp_s2.out sp_in.in0
setp sp_in.in1 {reach2}
net :sp-inside sp_in.out sp_on.in0
setp sp_on.in1 0
net :sp-enabled sp_on.out sp_ok.in0
net :sp-fresh sp_fr.out sp_ok.in1
net :sim-probe sp_ok.out motion.probe-input"""


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--ball", type=float, nargs=3, required=True)
    ap.add_argument("--rot-point", type=float, nargs=3, default=(0.0, 0.0, 0.0))
    ap.add_argument("--offset", type=float, nargs=2, default=(0.0, 0.0), help="y z (A/C)")
    args = ap.parse_args()
    import hal
    h = hal.component("sphereprobe")
    for n in "ac":
        h.newpin(n, hal.HAL_FLOAT, hal.HAL_IN)
    for n in ("cx", "cy", "cz", "a-used", "c-used"):
        h.newpin(n, hal.HAL_FLOAT, hal.HAL_OUT)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    bx, by, bz = args.ball
    rx, ry, rz = args.rot_point
    oy, oz = args.offset

    def update() -> None:
        a_deg, c_deg = h["a"], h["c"]
        c, a = math.radians(c_deg), math.radians(a_deg)
        x1 = rx + math.cos(c) * (bx - rx) - math.sin(c) * (by - ry)  # C about the z axis
        y1 = ry + math.sin(c) * (bx - rx) + math.cos(c) * (by - ry)
        py, pz = ry + oy, rz + oz  # then A about the line through the A centre
        h["cx"] = x1
        h["cy"] = py + math.cos(a) * (y1 - py) - math.sin(a) * (bz - pz)
        h["cz"] = pz + math.sin(a) * (y1 - py) + math.cos(a) * (bz - pz)
        h["a-used"], h["c-used"] = a_deg, c_deg  # after the centre: never ahead of it

    update()
    h.ready()
    try:
        while True:
            update()
            time.sleep(0.001)
    except (KeyboardInterrupt, SystemExit):
        return 0


if __name__ == "__main__":
    sys.exit(main())
