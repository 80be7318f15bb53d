"""The virtual five-axis machine and its instruments (touch probe, R-test, indexer).

A :class:`VirtualFiveAxis` holds hidden errors (:class:`abbe.model.five_axis.FiveAxisErrors`:
location errors, error motions, squareness, optionally a 3-axis linear table),
a thermal drift of the location errors during the campaign (um/h, urad/h) and
the set-up errors of the instruments:

* touch probe on a calibration sphere: the sphere sits off its nominal place
  (``sphere_offset_mm``) and its true radius differs from the certificate
  (``sphere_radius_error_mm``); the probe triggers after a pre-travel that depends
  on the approach direction (``pretravel_um`` + ``pretravel_lobe_um`` x horizontal
  part, three lobes); the stylus radius the controller uses comes from a
  calibration that took out the mean pre-travel; every trigger point carries noise;
* R-test: the sphere off its nominal place; the three sensors' directions and
  gains off by ``rtest_mount`` (a small 3 x 3 mix); zeroed at the first reading; noise;
* laser + rotary indexer: ``ECC`` relative to the first target, a reversal
  ``rotary_backlash_urad``, noise;
* ballbar with a rotary axis turning (ISO 10791-6 style): the table ball sits off its
  nominal place (``ballbar_table_offset_mm``, workpiece frame), the tool ball off the
  tool's nominal point (``ballbar_tool_offset_mm``, machine frame: its run-out and length
  set-up), the bar's calibrated length is off by ``ballbar_length_error_um``; noise.

Units: mm, um, urad, degrees (angles), seconds (time).
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from abbe.formats.five_axis import indexer_csv, probe_csv, rotary_ballbar_csv, rtest_csv
from abbe.model.five_axis import (LOCATION_ERRORS, MOTION_COMPONENTS, FiveAxisErrors,
                                  TrunnionGeometry, linear_axis_errors, lowest_harmonic,
                                  motion_values, nominal_joints, table_transform)


@dataclass
class VirtualFiveAxis:
    """A five-axis machine with hidden errors and instrument set-up errors (see module)."""

    geometry: TrunnionGeometry
    errors: FiveAxisErrors
    drift_per_h: dict[str, float] = field(default_factory=dict)  # location name -> per hour
    sphere_offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sphere_radius_error_mm: float = 0.0
    pretravel_um: float = 0.0
    pretravel_lobe_um: float = 0.0
    probe_noise_um: float = 0.0
    rtest_mount: np.ndarray = field(default_factory=lambda: np.eye(3))
    rtest_noise_um: float = 0.0
    indexer_noise_urad: float = 0.0
    rotary_backlash_urad: float = 0.0
    ballbar_table_offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    ballbar_tool_offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    ballbar_length_error_um: float = 0.0
    ballbar_noise_um: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        self.rng = np.random.default_rng(self.seed)

    def errors_at(self, t_s: float) -> FiveAxisErrors:
        """The errors at campaign time ``t_s`` (location errors drifted)."""
        loc = dict(self.errors.location)
        for k, r in self.drift_per_h.items():
            loc[k] = loc.get(k, 0.0) + r * t_s / 3600.0
        return FiveAxisErrors(loc, self.errors.motions, self.errors.squareness, self.errors.linear)

    def sphere_centre(self, sphere_mm: np.ndarray, angles_deg: np.ndarray, t_s: float) -> np.ndarray:
        """True machine position (mm) of the sphere's centre at ``angles_deg`` (tilt, C)."""
        return self.table_point(np.asarray(sphere_mm, dtype=np.float64)
                                + np.asarray(self.sphere_offset_mm), angles_deg, t_s)

    def table_point(self, w_mm: np.ndarray, angles_deg: np.ndarray, t_s: float) -> np.ndarray:
        """True machine position (mm) of the workpiece point ``w_mm`` at ``angles_deg``."""
        T = table_transform(self.geometry, self.errors_at(t_s), np.asarray(angles_deg)[None, :])[0]
        return T[:3, :3] @ np.asarray(w_mm, dtype=np.float64) + T[:3, 3]

    # ---------------------------------------------------------------- instruments

    def probe(self, sphere_mm: tuple[float, float, float], radius_mm: float, stylus_mm: float,
              angles_deg: np.ndarray, t0_s: float = 0.0, n_points: int = 7,
              s_per_point: float = 4.0, s_per_position: float = 20.0) -> dict[str, np.ndarray]:
        """Probe the sphere at every angle pair (M, 2): trigger points and times.

        Directions (machine frame): the pole and ``n_points - 1`` points on a circle at
        20 degrees latitude, approached along the line through the centre the
        controller expects (nominal kinematics), starting 2 mm outside.
        """
        g = self.geometry
        ang = np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)
        k = n_points - 1
        phi = np.arange(k) * 2 * np.pi / k
        lat = np.deg2rad(20.0)
        dirs = np.vstack([[0.0, 0.0, 1.0], np.column_stack([np.cos(lat) * np.cos(phi),
                                                            np.cos(lat) * np.sin(phi),
                                                            np.full(k, np.sin(lat))])])
        horiz = 1.0 - dirs[:, 2] ** 2
        lobe = np.cos(3 * np.arctan2(dirs[:, 1], dirs[:, 0])) * horiz
        pretravel_mm = (self.pretravel_um * (1.0 + horiz) + self.pretravel_lobe_um * lobe) * 1e-3
        # The calibration on a reference sphere took out the mean pre-travel.
        stylus_true = stylus_mm + float(np.mean(pretravel_mm))
        r_true = radius_mm + self.sphere_radius_error_mm
        pos_i, t_out, ang_out, pts = [], [], [], []
        t = t0_s
        expected = nominal_joints(g, np.asarray(sphere_mm)[None, :].repeat(len(ang), 0), ang)
        for m in range(len(ang)):
            t += s_per_position
            for j, n in enumerate(dirs):
                t += s_per_point
                c = self.sphere_centre(np.asarray(sphere_mm), ang[m], t)
                reach = r_true + stylus_true - pretravel_mm[j]
                start = expected[m] + n * (radius_mm + stylus_mm + 2.0)
                q = start
                for _ in range(3):  # the tool error depends (weakly) on where it triggers
                    e, _r = linear_axis_errors(g, self.errors, q[None, :])
                    o = start + e[0] * 1e-3 - c
                    b = -2.0 * float(n @ o)
                    disc = b * b - 4.0 * (float(o @ o) - reach * reach)
                    s = (-b - np.sqrt(disc)) / 2.0  # first contact moving along -n
                    q = start - n * s
                pos_i.append(m)
                t_out.append(t)
                ang_out.append(ang[m])
                pts.append(q + self.rng.normal(0.0, self.probe_noise_um * 1e-3, 3))
        return {"position": np.asarray(pos_i), "t_s": np.asarray(t_out),
                "angles_deg": np.asarray(ang_out), "points_mm": np.asarray(pts)}

    def rtest(self, sphere_mm: tuple[float, float, float], angles_deg: np.ndarray,
              t0_s: float = 0.0, s_per_reading: float = 1.0) -> dict[str, np.ndarray]:
        """R-test readings along a path of angle pairs (M, 2) under tool-centre-point control."""
        g = self.geometry
        ang = np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)
        s_nom = np.asarray(sphere_mm, dtype=np.float64)
        q = nominal_joints(g, s_nom[None, :].repeat(len(ang), 0), ang)
        e, _r = linear_axis_errors(g, self.errors, q)
        t = t0_s + s_per_reading * np.arange(len(ang))
        d = np.array([self.sphere_centre(s_nom, ang[i], t[i]) for i in range(len(ang))])
        d = (d - q) * 1e3 - e
        read = d @ np.asarray(self.rtest_mount).T
        read = read - read[0]
        read = read + self.rng.normal(0.0, self.rtest_noise_um, read.shape)
        read[0] = 0.0  # zeroed at the first reading
        return {"t_s": t, "angles_deg": ang, "displacement_um": read}

    def ballbar(self, table_ball_mm: np.ndarray, tool_ball_mm: np.ndarray, angles_deg: np.ndarray,
                t0_s: float = 0.0, s_per_reading: float = 1.0) -> dict[str, np.ndarray]:
        """Rotary ballbar readings along a path of angle pairs (M, 2): the tool ball held
        under tool-centre-point control at ``tool_ball_mm`` (workpiece coordinates), the
        table ball at ``table_ball_mm``; measured minus nominal length (um)."""
        g = self.geometry
        ang = np.asarray(angles_deg, dtype=np.float64).reshape(-1, 2)
        w_tool = np.asarray(tool_ball_mm, dtype=np.float64)
        w_table = np.asarray(table_ball_mm, dtype=np.float64)
        length = float(np.linalg.norm(w_tool - w_table))
        q = nominal_joints(g, w_tool[None, :].repeat(len(ang), 0), ang)
        e, _r = linear_axis_errors(g, self.errors, q)
        tool = q + e * 1e-3 + np.asarray(self.ballbar_tool_offset_mm)
        t = t0_s + s_per_reading * np.arange(len(ang))
        w_true = w_table + np.asarray(self.ballbar_table_offset_mm)
        table = np.array([self.table_point(w_true, ang[i], t[i]) for i in range(len(ang))])
        dev = (np.linalg.norm(tool - table, axis=1) - length) * 1e3 - self.ballbar_length_error_um
        return {"t_s": t, "angles_deg": ang,
                "radial_um": dev + self.rng.normal(0.0, self.ballbar_noise_um, dev.shape)}

    def indexer(self, axis: str, targets_deg: np.ndarray, runs: int = 3) -> dict[str, np.ndarray]:
        """ISO 230-2 cycle of a rotary axis (linear cycle, each target from + and -)."""
        tg = np.asarray(targets_deg, dtype=np.float64)
        ecc = motion_values(self.errors, axis, tg)[:, MOTION_COMPONENTS.index(axis)]
        base = ecc - ecc[0]
        run, dirn, tout, dev = [], [], [], []
        for r in range(1, runs + 1):
            for sgn, order in ((1, tg), (-1, tg[::-1])):
                for x in order:
                    i = int(np.flatnonzero(tg == x)[0])
                    run.append(r)
                    dirn.append(sgn)
                    tout.append(x)
                    dev.append(base[i] + sgn * self.rotary_backlash_urad / 2.0
                               + self.rng.normal(0.0, self.indexer_noise_urad))
        return {"run": np.asarray(run), "direction": np.asarray(dirn),
                "target_deg": np.asarray(tout), "deviation_urad": np.asarray(dev)}


def probing_positions(geom: TrunnionGeometry, n_tilt: int, n_c: int, passes: int = 1) -> np.ndarray:
    """(passes * n_tilt * n_c, 2) angle pairs (tilt, C) deg in the order they are probed:
    tilt from its travel's middle 80 %, C round its travel, tilt by tilt.

    ``passes`` > 1 is the diagnosis plan (docs/programs.md, "Five-axis programs"): the grid
    is run again with the tilts and the C angles in the opposite order and, on a table
    that turns a full revolution, C shifted by a ``1 / passes`` share of its step. Every
    pose's neighbours are then probed at two times far apart, so a drift during the
    campaign no longer moves with the pose (in one pass time and tilt go together and the
    location errors take most of a drift), and C is seen at ``passes * n_c`` angles (cyclic
    errors of higher order)."""
    if passes < 1:
        raise ValueError(f"passes must be >= 1, got {passes}")
    tilt, table = geom.rotaries
    lo, hi = geom.travel_deg[tilt]
    lo_c, hi_c = geom.travel_deg[table]
    span = min(hi_c - lo_c, 360.0)
    ta = np.linspace(max(lo, -90.0) * 0.8 if lo < 0 else lo, min(hi, 90.0) * 0.8, n_tilt)
    out = []
    for p in range(passes):
        if span >= 360.0:
            tc = lo_c + (np.arange(n_c) + p / passes) * span / n_c
        else:  # a partial turn: the same angles (its ends are its travel's)
            tc = np.linspace(lo_c, hi_c, n_c)
        ta_p = ta[::-1] if p % 2 else ta
        tc = tc[::-1] if p % 2 else tc
        A, C = np.meshgrid(ta_p, tc, indexing="ij")
        out.append(np.column_stack([A.ravel(), C.ravel()]))
    return np.vstack(out)


#: The bar directions of the ISO 10791-6 style set-ups, relative to the turning axis.
BALLBAR_DIRECTIONS = ("radial", "tangential", "axial")


@dataclass(frozen=True)
class BallbarSetup:
    """One rotary ballbar test: its name, the balls' nominal centres (workpiece mm) and the
    angle path (M, 2) deg (tilt, C) the axes follow under tool-centre-point control."""

    name: str
    turning: str
    direction: str
    table_ball_mm: tuple[float, float, float]
    tool_ball_mm: tuple[float, float, float]
    path_deg: np.ndarray
    setup: str = ""  # the set-up (table ball and tool cup left in place) it shares


def ballbar_setups(geom: TrunnionGeometry, table_ball_mm: tuple[float, float, float],
                   length_mm: float = 100.0, step_deg: float = 10.0,
                   directions: tuple[str, ...] = BALLBAR_DIRECTIONS,
                   turning: tuple[str, ...] = ("C", "tilt"), tilt_for_c_deg: float = 0.0,
                   setup: str = "", suffix: str = "") -> list[BallbarSetup]:
    """ISO 10791-6 style set-ups with the table ball at ``table_ball_mm`` (workpiece, off C's
    axis): C turns a full revolution there and back (tilt at ``tilt_for_c_deg``) with X/Y
    interpolating, and the tilt axis turns over 80 % of its travel and back (C at 0) with
    Y/Z (A) or X/Z (B) interpolating; the bar radial (from the turning axis' line to the
    table ball, perpendicular to the axis), tangential or axial (along the axis), tool ball
    on the side away from the table. ``setup``: the tests share one set-up (the table ball
    and the tool cup stay; only the bar's direction changes); ``suffix`` ends their names."""
    tilt, _c = geom.rotaries
    w = np.asarray(table_ball_mm, dtype=np.float64)
    out = []
    for which in turning:
        ax = "C" if which == "C" else tilt
        k = np.asarray({"A": (1.0, 0.0, 0.0), "B": (0.0, 1.0, 0.0), "C": (0.0, 0.0, 1.0)}[ax])
        r = w - geom.pivot(ax)
        r = r - k * float(r @ k)
        if np.linalg.norm(r) < 1.0:
            raise ValueError(f"the table ball must sit off {ax}'s axis for a rotary ballbar test")
        radial = r / np.linalg.norm(r)
        tang = np.cross(k, radial)
        axial = k if ax == "C" else k * (1.0 if w[0 if ax == "A" else 1] >= 0 else -1.0)
        if ax == "C":
            fwd = np.arange(0.0, 360.0 + 1e-9, step_deg)
            path = np.column_stack([np.full(fwd.size, tilt_for_c_deg), fwd])
        else:
            lo, hi = geom.travel_deg[tilt]
            lo, hi = max(lo, -90.0) * 0.8, min(hi, 90.0) * 0.8
            fwd = np.linspace(lo, hi, int(np.ceil((hi - lo) / step_deg)) + 1)
            path = np.column_stack([fwd, np.zeros(fwd.size)])
        path = np.vstack([path, path[-2::-1]])  # there and back: the reversal shows
        for d in directions:
            u = {"radial": radial, "tangential": tang, "axial": axial}[d]
            out.append(BallbarSetup(f"{ax}_{d}{suffix}", ax, d, tuple(w),
                                    tuple(w + length_mm * u), path, setup))
    return out


def random_errors(geom: TrunnionGeometry, rng: np.random.Generator, loc_um: float = 20.0,
                  loc_urad: float = 50.0, motion_um: float = 0.0, motion_urad: float = 0.0,
                  harmonics: int = 3) -> FiveAxisErrors:
    """Hidden errors of a plausible size: location errors N(0, loc_um / loc_urad), error
    motions with harmonics up to ``harmonics`` and amplitude ~ motion_um / motion_urad."""
    loc: dict[str, float] = {}
    for ax in geom.rotaries:
        for i, n in enumerate(LOCATION_ERRORS[ax]):
            loc[n] = float(rng.normal(0.0, loc_um if i < 2 else loc_urad))
    mot: dict[tuple[str, str], np.ndarray] = {}
    if motion_um or motion_urad:
        for ax in geom.rotaries:
            for j, comp in enumerate(MOTION_COMPONENTS):
                lo = lowest_harmonic(ax, comp)
                c = np.zeros(2 * harmonics)
                c[2 * (lo - 1):] = rng.normal(0.0, (motion_um if j < 3 else motion_urad)
                                              / np.sqrt(harmonics), 2 * (harmonics - lo + 1))
                mot[(ax, comp)] = c
    return FiveAxisErrors(loc, mot)


def truth_json(vm: VirtualFiveAxis) -> dict:
    """The hidden truth of a virtual machine as JSON (units in the keys)."""
    e = vm.errors
    return {"kinematics": vm.geometry.kind,
            "location": {k: float(v) for k, v in e.location.items()},
            "motions": {f"{a}.{c}": [float(x) for x in v] for (a, c), v in e.motions.items()},
            "squareness_urad": [float(v) for v in e.squareness],
            "drift_per_h": dict(vm.drift_per_h),
            "sphere_offset_mm": list(vm.sphere_offset_mm),
            "sphere_radius_error_mm": vm.sphere_radius_error_mm,
            "pretravel_um": vm.pretravel_um, "pretravel_lobe_um": vm.pretravel_lobe_um,
            "probe_noise_um": vm.probe_noise_um, "rtest_noise_um": vm.rtest_noise_um,
            "ballbar_table_offset_mm": list(vm.ballbar_table_offset_mm),
            "ballbar_tool_offset_mm": list(vm.ballbar_tool_offset_mm),
            "ballbar_length_error_um": vm.ballbar_length_error_um,
            "ballbar_noise_um": vm.ballbar_noise_um}


def write_campaign(vm: VirtualFiveAxis, out: Path, *, positions: np.ndarray,
                   sphere_mm: tuple[float, float, float] = (0.0, 0.0, 0.0),
                   sphere_radius_mm: float = 12.5, stylus_radius_mm: float = 1.5,
                   rtest_path: np.ndarray | None = None, indexer_targets: np.ndarray | None = None,
                   harmonics: int = 0, name: str = "virtual five-axis",
                   ballbar: list[BallbarSetup] | None = None, probing: bool = True) -> Path:
    """Simulate a campaign into the folder ``out``: machine.toml, probe.csv (and rtest.csv,
    indexer_C.csv, ballbar_<name>.csv), truth.json. ``probing`` False leaves the probing
    out (a ballbar-only plan). Ballbar set-ups' ball positions are relative to the rotation
    point, as ``sphere_mm``. Returns the machine file's path."""
    g = vm.geometry
    tilt, table = g.rotaries
    out.mkdir(parents=True, exist_ok=True)
    sphere = tuple(np.asarray(g.rot_point_mm) + np.asarray(sphere_mm))
    t_end = 0.0
    if probing:
        p = vm.probe(sphere, sphere_radius_mm, stylus_radius_mm, positions)  # type: ignore[arg-type]
        (out / "probe.csv").write_text(probe_csv(tilt, p["position"], p["t_s"], p["angles_deg"],
                                                 p["points_mm"]), encoding="utf-8")
        t_end = float(p["t_s"][-1])
    offs = ("y_offset_mm", "z_offset_mm") if tilt == "A" else ("x_offset_mm", "z_offset_mm")
    ov = (g.offset_mm[1], g.offset_mm[2]) if tilt == "A" else (g.offset_mm[0], g.offset_mm[2])
    lines = [f'[machine]\nname = "{name}"\n',
             "[axes.X]\ntravel_mm = [-500.0, 500.0]\n[axes.Y]\ntravel_mm = [-500.0, 500.0]\n"
             "[axes.Z]\ntravel_mm = [-600.0, 200.0]\n",
             "[reference]\npoint_mm = [0.0, 0.0, 0.0]\n",
             f'[rotary]\nkinematics = "{g.kind}"\nx_rot_point_mm = {g.rot_point_mm[0]!r}\n'
             f"y_rot_point_mm = {g.rot_point_mm[1]!r}\nz_rot_point_mm = {g.rot_point_mm[2]!r}\n"
             f"{offs[0]} = {ov[0]!r}\n{offs[1]} = {ov[1]!r}\ntool_length_mm = {g.tool_length_mm!r}\n",
             f"[rotary.{tilt}]\ntravel_deg = {list(g.travel_deg[tilt])!r}\n",
             f"[rotary.{table}]\ntravel_deg = {list(g.travel_deg[table])!r}\n",
             f"[rotary.fit]\nharmonics = {harmonics}\n"]
    if probing:
        lines.append(f'[probing.S1]\nfile = "probe.csv"\nsphere_mm = {[float(v) for v in sphere]!r}\n'
                     f"sphere_radius_mm = {sphere_radius_mm!r}\n"
                     f"stylus_radius_mm = {stylus_radius_mm!r}\n")
    if rtest_path is not None:
        r = vm.rtest(sphere, rtest_path, t0_s=t_end + 60.0)  # type: ignore[arg-type]
        (out / "rtest.csv").write_text(rtest_csv(tilt, r["t_s"], r["angles_deg"],
                                                 r["displacement_um"]), encoding="utf-8")
        lines.append(f'[rtest.R1]\nfile = "rtest.csv"\nsphere_mm = {[float(v) for v in sphere]!r}\n')
    if indexer_targets is not None:
        ix = vm.indexer(table, indexer_targets)
        (out / f"indexer_{table}.csv").write_text(
            indexer_csv(ix["run"], ix["direction"], ix["target_deg"], ix["deviation_urad"]),
            encoding="utf-8")
        lines.append(f'[indexer.{table}]\nfile = "indexer_{table}.csv"\n')
    t = t_end
    for bs in ballbar or []:
        rp = np.asarray(g.rot_point_mm)
        wt, wb = rp + np.asarray(bs.table_ball_mm), rp + np.asarray(bs.tool_ball_mm)
        t += 120.0  # set the bar up
        b = vm.ballbar(wt, wb, bs.path_deg, t0_s=t)
        t = float(b["t_s"][-1])
        fn = f"ballbar_{bs.name}.csv"
        (out / fn).write_text(rotary_ballbar_csv(tilt, b["t_s"], b["angles_deg"], b["radial_um"]),
                              encoding="utf-8")
        lines.append(f'[rotary_ballbar.{bs.name}]\nfile = "{fn}"\n'
                     f"table_ball_mm = {[float(v) for v in wt]!r}\n"
                     f"tool_ball_mm = {[float(v) for v in wb]!r}\n"
                     + (f'setup = "{bs.setup}"\n' if bs.setup else ""))
    (out / "machine.toml").write_text("\n".join(lines), encoding="utf-8")
    (out / "truth.json").write_text(json.dumps(truth_json(vm), indent=2) + "\n", encoding="utf-8")
    return out / "machine.toml"
