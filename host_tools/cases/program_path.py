"""Judging a measurement program's recorded path (docs/programs.md, "What was checked in
which interpreter"): shared by the LinuxCNC proof (port/linuxcnc/tests/program_sim.py,
run by the system python3) and the grblHAL one (port/grblhal/tests/program_sim.py), so
this module needs numpy only.

A record is what an interpreter did with one program: ``t_s`` (N,) s, ``pos_mm`` (N, 3)
the commanded / stepped position in machine coordinates, ``stops`` the programmed stops
as [start, end] s, ``seconds`` and ``program`` (its file name); ``kinematics``
(accel_mm_s2, feed_mm_min) when the record has no samples while the machine stands
(:func:`bracket`). The expectations come
from the program text only (its header comments, :func:`params_of`), never from abbe.

``tol_mm`` is the interpreter's position resolution: a point the program states is
reached when the record is within it (LinuxCNC's trajectory planner: 1e-6 mm; grblHAL's
planner rounds every block end to whole steps: half a step); ``late_s`` how much longer
than stated a dwell may be (the interpreter's restart after it).
"""

from __future__ import annotations

import re

import numpy as np

#: Positions of a stationary trajectory are exactly equal.
STILL_MM = 1e-9


class PathCheckFailed(AssertionError):
    """A recorded path breaks what its program states."""


def check(cond: bool, what: str) -> None:
    if not cond:
        raise PathCheckFailed(what)


def params_of(text: str) -> dict[str, str]:
    """``(key = value)`` header comments and the ``(targets mm: ...)`` lines of a program."""
    p = dict(re.findall(r"^\((\w+) = ([^)]*)\)$", text, flags=re.M))
    t = re.findall(r"^\(targets mm: ([^)]*)\)$", text, flags=re.M)
    if t:
        p["targets_mm"] = " ".join(t)
    return p


def bracket(t: np.ndarray, a: int, b: int, pos: np.ndarray | None = None,
            kin: dict | None = None) -> tuple[float, float]:
    """A still interval's duration between the samples: at least t[b] - t[a], at most from
    the sample before to the sample after (a late sample only widens the bracket).

    ``kin`` (accel_mm_s2, feed_mm_min): the record has no sample between the last moving
    one (a - 1) and the first at the stop (a), grblHAL's Simulator (its planner is empty
    there): the machine arrived at most the time the distance between them takes from
    rest (triangle, or trapezoid at the feed) after t[a - 1], so the stop lasted at least
    t[b] - t[a - 1] - that time."""
    lo, hi = float(t[b] - t[a]), float(t[min(b + 1, len(t) - 1)] - t[max(a - 1, 0)])
    if kin is not None and pos is not None and a > 0:
        d = float(np.linalg.norm(pos[a] - pos[a - 1]))
        acc, v = kin["accel_mm_s2"], kin["feed_mm_min"] / 60.0
        tail = 2.0 * np.sqrt(d / acc) if d <= v * v / acc else d / v + v / acc
        lo = max(lo, float(t[b] - t[a - 1]) - tail)
    return lo, hi


def dwell_ok(lo: float, hi: float, want: float, late_s: float = 0.3) -> bool:
    """The stated dwell lies inside the bracket, or at most ``late_s`` (the planner's
    restart: 0.3 s in LinuxCNC) below its lower end."""
    return hi >= want - 1e-3 and lo <= want + late_s


def segments(t: np.ndarray, pos: np.ndarray, singles: bool = False) -> list[tuple[int, int]]:
    """Runs of samples [i, j] with the position unchanged; with ``singles`` also every
    other sample as [k, k] (a record without samples while the machine stands, where a
    stop can be one sample after a gap: :func:`bracket`)."""
    still = np.all(np.abs(np.diff(pos, axis=0)) <= STILL_MM, axis=1)
    out, i = [], None
    for k, s in enumerate(still):
        if s and i is None:
            i = k
        elif not s and i is not None:
            out.append((i, k))
            i = None
    if i is not None:
        out.append((i, len(t) - 1))
    if singles:
        inside = np.zeros(len(t), dtype=bool)
        for a, b in out:
            inside[a:b + 1] = True
        out = sorted(out + [(k, k) for k in np.flatnonzero(~inside).tolist()])
    return out


def in_travel(pos: np.ndarray, travel: dict, tol_mm: float = 1e-6) -> None:
    """Every recorded point inside the machine file's travel (mm, per axis [lo, hi])."""
    for j, a in enumerate("XYZ"):
        lo, hi = travel[a]
        check(pos[:, j].min() >= lo - tol_mm and pos[:, j].max() <= hi + tol_mm,
              f"the path leaves the {a} travel [{lo}, {hi}]: {pos[:, j].min():.4f} .. "
              f"{pos[:, j].max():.4f}")


def check_positioning(rec: dict, prm: dict, travel: dict, line_mm: list[float],
                      tol_mm: float = 1e-6, late_s: float = 0.3) -> dict:
    """A positioning / straightness / angular line program: the dwells on the line (the
    machine file's line through ``line_mm``) are the captures the program states, in its
    order (linear or pendulum sequence), each at its target, approached from its side
    (the last different position before it), for the stated dwell; the path in the
    travel. Returns the captures and the figures."""
    t, pos = np.asarray(rec["t_s"], dtype=float), np.asarray(rec["pos_mm"], dtype=float)
    in_travel(pos, travel, tol_mm)
    j = "XYZ".index(prm["axis"])
    targets = np.array([float(v) for v in prm["targets_mm"].split()])
    runs, dwell = int(prm["runs"]), float(prm["dwell_s"])
    T = targets.size
    check(T == int(prm["targets"]), f"{rec['program']}: {T} targets listed, the header "
          f"says {prm['targets']}")
    if prm["sequence"] == "linear":
        want = [(i, d, r) for r in range(1, runs + 1)
                for d, idx in ((+1, range(T)), (-1, range(T - 1, -1, -1))) for i in idx]
    else:
        want = [(i, d, r) for i in range(T) for r in range(1, runs + 1) for d in (+1, -1)]
    others = [k for k in range(3) if k != j]
    caps = []
    ov = float(prm["overrun_mm"])
    turns = (np.array([targets[0] - ov, targets[-1] + ov]) if prm["sequence"] == "linear"
             else np.concatenate([targets - ov, targets + ov]))
    kin = rec.get("kinematics")
    turned = 0
    for a, b in segments(t, pos, singles=kin is not None):
        lo_s, hi_s = bracket(t, a, b, pos, kin)
        on_line = all(abs(pos[a, k] - line_mm[k]) <= tol_mm for k in others)
        if lo_s < 0.5 * dwell or not on_line:
            continue
        if np.min(np.abs(turns - pos[a, j])) <= tol_mm:
            # the machine turns at an overrun point: standing there longer (grblHAL's
            # Simulator when the sender lags behind its simulated time) is no capture
            turned += 1
            continue
        caps.append((a, b, lo_s, hi_s))
    check(len(caps) == len(want), f"{rec['program']}: {len(caps)} dwells on the line, the "
          f"program states {len(want)} captures")
    out, durs = [], []
    for (a, b, lo_s, hi_s), (i, d, r) in zip(caps, want):
        x = pos[a, j]
        check(abs(x - targets[i]) <= tol_mm, f"{rec['program']}: capture {len(out) + 1} at "
              f"{x:.4f} mm, expected target {i + 1} = {targets[i]:.4f} mm (run {r}, {d:+d})")
        prev = pos[:a + 1, j]
        moved = np.flatnonzero(np.abs(prev - x) > 1e-6)
        check(moved.size > 0, f"{rec['program']}: no approach before capture {len(out) + 1}")
        side = np.sign(x - prev[moved[-1]])
        check(side == d, f"{rec['program']}: target {i + 1} run {r} approached from the "
              f"{'+' if side < 0 else '-'} side, expected a {'+' if d > 0 else '-'} approach")
        check(dwell_ok(lo_s, hi_s, dwell, late_s), f"{rec['program']}: dwell of {lo_s:.3f}..{hi_s:.3f} s "
              f"at target {i + 1}, programmed {dwell} s")
        durs.append((lo_s, hi_s))
        out.append({"target": i, "dir": d, "run": r, "pos_mm": pos[a].tolist(),
                    "dwell_s": round(lo_s, 4)})
    lo_all, hi_all = np.array(durs).T
    return {"captures": out, "n": len(out), "stops_at_overrun": turned, "dwell_s": {"min": round(float(lo_all.min()), 4),
                                                       "max": round(float(lo_all.max()), 4)},
            "dwell_bracket_s": {"lo_min": round(float(lo_all.min()), 4),
                                "hi_max": round(float(hi_all.max()), 4)},
            "seconds": round(rec["seconds"], 2)}


def check_ballbar(rec: dict, prm: dict, travel: dict, tol_mm: float = 1e-6,
                  late_s: float = 0.3) -> dict:
    """A ballbar program, from its one programmed stop (the ballbar fitted at the feed-in
    arc's start): on the radius (within 10 um), in the circle's plane, the CCW run from
    -feed_arc to 360 + feed_arc deg, the stated pause, the CW run back, the angle never
    turning back inside a run, the data arc at the stated feed (5 %); the path in the
    travel. XY plane (the program's ``plane``)."""
    t, pos = np.asarray(rec["t_s"], dtype=float), np.asarray(rec["pos_mm"], dtype=float)
    in_travel(pos, travel, tol_mm)
    check(prm["plane"] == "XY", f"ballbar: plane {prm['plane']}, this check knows XY")
    c = np.array([float(v) for v in prm["center_mm"].split()])
    R, arc, pause = float(prm["radius_mm"]), float(prm["feed_arc_deg"]), float(prm["pause_s"])
    feed = float(prm["feed_mm_min"])
    check(len(rec["stops"]) == 1, f"ballbar: {len(rec['stops'])} programmed stops, expected 1")
    k0 = int(np.searchsorted(t, rec["stops"][0][0]))  # at the start point, the ballbar fitted
    d = pos[k0:, :2] - c[:2]
    r = np.hypot(d[:, 0], d[:, 1])
    check(np.all(np.abs(pos[k0:, 2] - c[2]) <= tol_mm), "ballbar: Z moves during the circle")
    check(np.max(np.abs(r - R)) < 0.01, f"ballbar: the path leaves the radius by "
          f"{np.max(np.abs(r - R)) * 1000:.1f} um")
    th = np.degrees(np.unwrap(np.arctan2(d[:, 1], d[:, 0])))
    th += 360.0 * np.round((-arc - th[0]) / 360.0)  # the start is the feed-in arc's start
    top = int(np.argmax(th))
    ccw, cw = th[:top + 1], th[top:]
    check(abs(ccw[0] + arc) < 0.01, f"ballbar: the CCW run starts at {ccw[0]:.2f} deg, "
          f"expected {-arc}")
    check(abs(ccw[-1] - (360 + arc)) < 0.01 and abs(cw[-1] + arc) < 0.01,
          f"ballbar: CCW ends at {ccw[-1]:.2f}, CW at {cw[-1]:.2f} deg; expected "
          f"{360 + arc} and {-arc}")
    check(bool(np.all(np.diff(ccw) >= -1e-9) and np.all(np.diff(cw) <= 1e-9)),
          "ballbar: the angle turns back inside a run")
    # the pause at the top, and the feed on the data arc
    seg = [(a, b) for a, b in segments(t[k0:], pos[k0:]) if a <= top <= b]
    check(len(seg) == 1, "ballbar: no pause between the runs")
    lo_s, hi_s = bracket(t, k0 + seg[0][0], k0 + seg[0][1], pos, rec.get("kinematics"))
    check(dwell_ok(lo_s, hi_s, pause, late_s), f"ballbar: pause {lo_s:.3f}..{hi_s:.3f} s between the "
          f"runs, programmed {pause} s")
    tt = t[k0:]
    m = (ccw >= 0) & (ccw <= 360)
    # the mean speed over the data arc (the angle turned over the time it took): a median of
    # sample-to-sample rates depends on how the polling meets the status updates (a sample
    # that sees the previous status gives 0, the next one twice the speed)
    a, ts = ccw[m], tt[:top + 1][m]
    check(a.size >= 2 and ts[-1] > ts[0], "ballbar: no samples on the data arc")
    want = np.degrees(feed / 60.0 / R)
    med = float((a[-1] - a[0]) / (ts[-1] - ts[0]))
    check(abs(med / want - 1) < 0.05, f"ballbar: {med:.2f} deg/s on the data arc, the feed "
          f"gives {want:.2f}")
    return {"ccw_deg": [round(float(ccw[0]), 3), round(float(ccw[-1]), 3)],
            "cw_deg": [round(float(cw[0]), 3), round(float(cw[-1]), 3)],
            "radius_dev_max_um": round(float(np.max(np.abs(r - R)) * 1000), 4),
            "pause_s": round(float(lo_s), 3), "deg_per_s": round(med, 3),
            "seconds": round(rec["seconds"], 2)}
