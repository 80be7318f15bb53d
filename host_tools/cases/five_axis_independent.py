"""An independent generator of five-axis campaigns, for evaluation only.

Written from the ISO 230-1 / ISO 230-7 notation (/work/shared/reference/five-axis.md),
**not** from ``abbe.model.five_axis`` or ``abbe.sim.five_axis``: it imports
neither (nor any other part of ``abbe``). Its kinematics: each rotary axis is an
actual *line* (a point and a unit direction) about which Rodrigues' formula
turns the table by the commanded angle plus the angular zero; the location
errors move and tilt that line (C: through ``P_C + (EX0C, EY0C, 0)`` with
direction ``(EB0C, -EA0C, 1)``; A: ``P_A + (0, EY0A, EZ0A)``, ``(1, EC0A, -EB0A)``;
B: ``P_B + (EX0B, 0, EZ0B)``, ``(-EC0B, 1, EA0B)``). Error motions are sums of
sines with amplitudes and phases (not the product's sin/cos coefficients),
applied as a small rigid motion at the axis' point after the rotation. The
probe puts its trigger points straight on the sphere (actual centre + direction
x (radius + stylus - pre-travel)), the R-test reads the centre's displacement
through a misaligned sensor nest, the rotary ballbar (ISO 10791-6: C turning with
X/Y following, the tilt axis turning with the other two following; bar radial,
tangential or axial) reads the distance between a table ball that moves with the
table and a tool ball held at its nominal place, with both balls set up off their
nominal places and the bar's length calibration off. It writes the documented files
(docs/formats.md, "Five-axis machine file") with its own writers.

Selection thresholds and defaults of the identification are never tuned on these
cases; ``bench/bench_five_axis.py`` and ``tests/analysis/test_five_axis_independent.py``
only measure.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

LOC = {"C": ("EX0C", "EY0C", "EA0C", "EB0C", "EC0C"),
       "A": ("EY0A", "EZ0A", "EB0A", "EC0A", "EA0A"),
       "B": ("EX0B", "EZ0B", "EA0B", "EC0B", "EB0B")}
#: Which location errors no single-sphere plan with an unknown sphere position can see:
#: the angular zeros turn the sphere about its axis, which a shifted sphere also does.
ALWAYS_UNSEEN = {"A": {"EC0C", "EA0A"}, "B": {"EC0C", "EB0B"}}


def rodrigues(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation matrix about a unit vector by ``angle`` rad."""
    k = axis / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def small(rx: float, ry: float, rz: float) -> np.ndarray:
    """Rotation by a small rotation vector (rad), exactly (Rodrigues)."""
    v = np.array([rx, ry, rz])
    a = float(np.linalg.norm(v))
    return np.eye(3) if a == 0 else rodrigues(v / a, a)


@dataclass
class Motion:
    """An error motion: sum_k amp_k sin(k t + phase_k), um or urad."""

    amp: dict[int, float] = field(default_factory=dict)
    phase: dict[int, float] = field(default_factory=dict)

    def at(self, deg: float) -> float:
        t = math.radians(deg)
        return sum(a * math.sin(k * t + self.phase[k]) for k, a in self.amp.items())


@dataclass
class Campaign:
    """One hidden machine and its plan."""

    kind: str  # xyzac-trt / xyzbc-trt
    pivot_c: np.ndarray  # mm
    offset: np.ndarray  # tilt axis point minus C axis point, mm
    tool_mm: float
    loc: dict[str, float]
    motions: dict[str, Motion]  # "C.X" .. "C.C", "A.X" ...
    sphere_nominal: np.ndarray  # workpiece (= machine at zero angles), mm
    sphere_shift_mm: np.ndarray
    radius_mm: float
    radius_error_mm: float
    stylus_mm: float
    pretravel_um: float  # residual direction-dependent part after calibration
    noise_um: float
    drift_um_per_h: float  # the tilt axis' point drifts in Z during the campaign
    rtest: bool
    n_tilt: int = 4
    n_c: int = 8
    seed: int = 0
    fit_harmonics: int = 0  # > 0: the machine file asks the fit for error motions up to it
    ballbar: bool = False  # add a rotary ballbar set-up (the tests of ballbar_tests())
    probe: bool = True  # False: a ballbar-only plan
    passes: int = 1  # 2: the diagnosis plan (docs/programs.md), the grid again backwards

    @property
    def tilt(self) -> str:
        return "A" if self.kind == "xyzac-trt" else "B"

    # ------------------------------------------------------------------ kinematics

    def _line(self, axis: str, t_s: float) -> tuple[np.ndarray, np.ndarray, float]:
        L = self.loc
        if axis == "C":
            p = self.pivot_c + 1e-3 * np.array([L["EX0C"], L["EY0C"], 0.0])
            d = np.array([1e-6 * L["EB0C"], -1e-6 * L["EA0C"], 1.0])
            z = L["EC0C"]
        elif axis == "A":
            p = self.pivot_c + self.offset + 1e-3 * np.array(
                [0.0, L["EY0A"], L["EZ0A"] + self.drift_um_per_h * t_s / 3600.0])
            d = np.array([1.0, 1e-6 * L["EC0A"], -1e-6 * L["EB0A"]])
            z = L["EA0A"]
        else:
            p = self.pivot_c + self.offset + 1e-3 * np.array(
                [L["EX0B"], 0.0, L["EZ0B"] + self.drift_um_per_h * t_s / 3600.0])
            d = np.array([-1e-6 * L["EC0B"], 1.0, 1e-6 * L["EA0B"]])
            z = L["EB0B"]
        return p, d / np.linalg.norm(d), z

    def _turn(self, axis: str, deg: float, x: np.ndarray, t_s: float) -> np.ndarray:
        p, d, zero = self._line(axis, t_s)
        y = p + rodrigues(d, math.radians(deg) + 1e-6 * zero) @ (x - p)
        m = {c: self.motions[f"{axis}.{c}"].at(deg) if f"{axis}.{c}" in self.motions else 0.0
             for c in "XYZABC"}
        R = small(1e-6 * m["A"], 1e-6 * m["B"], 1e-6 * m["C"])
        return p + R @ (y - p) + 1e-3 * np.array([m["X"], m["Y"], m["Z"]])

    def actual(self, w: np.ndarray, tilt_deg: float, c_deg: float, t_s: float) -> np.ndarray:
        """Machine position of workpiece point ``w`` (mm) on the machine with its errors."""
        return self._turn(self.tilt, tilt_deg, self._turn("C", c_deg, w, t_s), t_s)

    def nominal(self, w: np.ndarray, tilt_deg: float, c_deg: float) -> np.ndarray:
        kx = np.eye(3)[0 if self.tilt == "A" else 1]
        pc, pt = self.pivot_c, self.pivot_c + self.offset
        y = pc + rodrigues(np.array([0.0, 0.0, 1.0]), math.radians(c_deg)) @ (w - pc)
        return pt + rodrigues(kx, math.radians(tilt_deg)) @ (y - pt)

    # ------------------------------------------------------------------ instruments

    def positions(self) -> list[tuple[float, float]]:
        """The probing order. Pass 1: tilt by tilt upwards, C round from 0. Every later pass
        (docs/programs.md, "--passes"): C moved on by step / passes, and every other pass
        walked backwards (last tilt first, C downwards)."""
        out: list[tuple[float, float]] = []
        step = 360.0 / self.n_c
        for k in range(self.passes):
            order = [(float(a), float((j + k / self.passes) * step))
                     for a in np.linspace(-72.0, 72.0, self.n_tilt) for j in range(self.n_c)]
            out += order[::-1] if k % 2 else order
        return out

    def probe_rows(self, rng: np.random.Generator) -> tuple[list[str], float]:
        rows = [f"position,t_s,{self.tilt.lower()}_deg,c_deg,x_mm,y_mm,z_mm"]
        dirs = [np.array([0.0, 0.0, 1.0])] + [
            np.array([math.cos(math.radians(30)) * math.cos(u), math.cos(math.radians(30))
                      * math.sin(u), math.sin(math.radians(30))])
            for u in np.arange(4) * math.pi / 2]
        s_true = self.sphere_nominal + self.sphere_shift_mm
        t = 0.0
        for i, (a, c) in enumerate(self.positions()):
            t += 30.0
            for n in dirs:
                t += 5.0
                centre = self.actual(s_true, a, c, t)
                pre = self.pretravel_um * (n[0] ** 2 - n[1] ** 2)  # anisotropic residual
                reach = self.radius_mm + self.radius_error_mm + self.stylus_mm - 1e-3 * pre
                p = centre + n * reach + rng.normal(0.0, 1e-3 * self.noise_um, 3)
                rows.append(f"{i},{t:.1f},{a:.6f},{c:.6f},{p[0]:.6f},{p[1]:.6f},{p[2]:.6f}")
        return rows, t

    def rtest_rows(self, rng: np.random.Generator, t0: float) -> list[str]:
        rows = [f"t_s,{self.tilt.lower()}_deg,c_deg,dx_um,dy_um,dz_um"]
        nest = small(0.01, -0.008, 0.012) * 1.005  # sensor directions and gain off
        s_true = self.sphere_nominal + self.sphere_shift_mm
        zero = None
        t = t0
        for a in (0.0, -45.0, -90.0):
            for c in np.arange(0.0, 360.0, 10.0):
                t += 2.0
                d = 1e3 * (self.actual(s_true, a, c, t) - self.nominal(self.sphere_nominal, a, c))
                r = nest @ d
                zero = r if zero is None else zero
                r = r - zero + rng.normal(0.0, 0.3, 3)
                rows.append(f"{t:.1f},{a:.6f},{c:.6f},{r[0]:.5f},{r[1]:.5f},{r[2]:.5f}")
        return rows

    def ballbar_tests(self) -> list[tuple[str, np.ndarray, np.ndarray, list[tuple[float, float]]]]:
        """(name, table ball, tool ball, angle path) of the ballbar tests: one table ball 60 mm
        above the table, 70..110 mm off C's line; C turning round and back at tilt 0 and at
        tilt -45 deg, the tilt axis turning -72..72 deg and back at C = 0; a 100 mm bar."""
        kc = np.array([0.0, 0.0, 1.0])
        kt = np.eye(3)[0 if self.tilt == "A" else 1]
        u = 0.7 + 0.1 * (self.seed % 5)
        table = self.pivot_c + np.array([90.0 * math.cos(u), 90.0 * math.sin(u), 60.0])
        out = []
        cs = [float(c) for c in np.arange(0.0, 360.0 + 1e-9, 15.0)]
        ts = [float(a) for a in np.linspace(-72.0, 72.0, 17)]
        for axis, k, p in (("C", kc, self.pivot_c), (self.tilt, kt, self.pivot_c + self.offset)):
            v = table - p
            rad = v - k * float(v @ k)
            rad /= np.linalg.norm(rad)
            dirs = {"radial": rad, "tangential": np.cross(k, rad), "axial": k}
            for d, n in dirs.items():
                if axis == "C":
                    for tilt in (0.0, -45.0):
                        path = [(tilt, c) for c in cs + cs[-2::-1]]
                        out.append((f"C{int(-tilt)}_{d}", table, table + 100.0 * n, path))
                elif d != "tangential":
                    path = [(a, 0.0) for a in ts + ts[-2::-1]]
                    out.append((f"{axis}_{d}", table, table + 100.0 * n, path))
        return out

    def ballbar_rows(self, rng: np.random.Generator, t0: float, table: np.ndarray,
                     tool: np.ndarray, path: list[tuple[float, float]]) -> tuple[list[str], float]:
        rows = [f"t_s,{self.tilt.lower()}_deg,c_deg,radial_um"]
        shift = self.sphere_shift_mm[::-1] * 0.8  # the table ball, placed by hand
        cup = np.array([0.012, -0.02, 0.03])  # the tool ball off the spindle's line and length
        calib_um = 1.5
        length = float(np.linalg.norm(tool - table))
        t = t0
        for a, c in path:
            t += 1.0
            ball = self.actual(table + shift, a, c, t)
            held = self.nominal(tool, a, c) + cup
            r = 1e3 * (float(np.linalg.norm(held - ball)) - length) - calib_um
            rows.append(f"{t:.1f},{a:.6f},{c:.6f},{r + rng.normal(0.0, 0.3):.5f}")
        return rows, t

    # ------------------------------------------------------------------ files

    def write(self, out: Path) -> Path:
        """machine.toml, probe.csv (rtest.csv), truth.json into ``out``; the machine file."""
        rng = np.random.default_rng(self.seed + 7919)
        out.mkdir(parents=True, exist_ok=True)
        rows, t_end = self.probe_rows(rng)
        if self.probe:
            (out / "probe.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
        off = ("y_offset_mm", self.offset[1]) if self.tilt == "A" else ("x_offset_mm", self.offset[0])
        s = self.sphere_nominal
        toml = [
            '[machine]\nname = "independent five-axis case"\n',
            "[axes.X]\ntravel_mm = [-800.0, 800.0]\n[axes.Y]\ntravel_mm = [-800.0, 800.0]\n"
            "[axes.Z]\ntravel_mm = [-900.0, 300.0]\n[reference]\npoint_mm = [0.0, 0.0, 0.0]\n",
            f'[rotary]\nkinematics = "{self.kind}"\nx_rot_point_mm = {self.pivot_c[0]:.6f}\n'
            f"y_rot_point_mm = {self.pivot_c[1]:.6f}\nz_rot_point_mm = {self.pivot_c[2]:.6f}\n"
            f"{off[0]} = {off[1]:.6f}\nz_offset_mm = {self.offset[2]:.6f}\n"
            f"tool_length_mm = {self.tool_mm:.3f}\n",
            f"[rotary.{self.tilt}]\ntravel_deg = [-120.0, 120.0]\n[rotary.C]\n"
            "travel_deg = [-360.0, 360.0]\n",
            f"[rotary.fit]\nharmonics = {self.fit_harmonics}\n" if self.fit_harmonics else ""]
        if self.probe:
            toml.append(f'[probing.S1]\nfile = "probe.csv"\nsphere_mm = [{s[0]:.6f}, {s[1]:.6f}, '
                        f"{s[2]:.6f}]\nsphere_radius_mm = {self.radius_mm}\n"
                        f"stylus_radius_mm = {self.stylus_mm}\n")
        if self.rtest:
            (out / "rtest.csv").write_text("\n".join(self.rtest_rows(rng, t_end + 60.0)) + "\n",
                                           encoding="utf-8")
            toml.append(f'[rtest.R1]\nfile = "rtest.csv"\nsphere_mm = [{s[0]:.6f}, {s[1]:.6f}, '
                        f"{s[2]:.6f}]\n")
        t = t_end + 600.0
        for name, table, tool, path in (self.ballbar_tests() if self.ballbar else []):
            rows, t = self.ballbar_rows(rng, t + 60.0, table, tool, path)
            (out / f"bb_{name}.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
            toml.append(f'[rotary_ballbar.{name}]\nfile = "bb_{name}.csv"\nsetup = "one_ball"\n'
                        "table_ball_mm = [" + ", ".join(f"{v:.6f}" for v in table) + "]\n"
                        "tool_ball_mm = [" + ", ".join(f"{v:.6f}" for v in tool) + "]\n")
        (out / "machine.toml").write_text("\n".join(toml), encoding="utf-8")
        truth = {"kind": self.kind, "location": self.loc, "always_unseen": sorted(
            ALWAYS_UNSEEN[self.tilt]), "motions": {k: {"amp": m.amp, "phase": m.phase}
                                                  for k, m in self.motions.items()},
            "rtest": self.rtest, "ballbar": self.ballbar, "probe": self.probe, "seed": self.seed}
        (out / "truth.json").write_text(json.dumps(truth, indent=1) + "\n", encoding="utf-8")
        return out / "machine.toml"


def make_campaign(seed: int, *, n_tilt: int = 4, n_c: int = 8,
                  motion_scale: float = 1.0) -> Campaign:
    """Campaign ``seed``: A/C on even seeds, B/C on odd; an R-test every third; hidden error
    motions every fourth (amplitudes up to 0.6 um / 3 urad times ``motion_scale``); noise,
    set-up errors and a pivot drift always."""
    rng = np.random.default_rng(seed)
    kind = "xyzac-trt" if seed % 2 == 0 else "xyzbc-trt"
    tilt = "A" if kind == "xyzac-trt" else "B"
    loc = {}
    for ax in ("C", tilt):
        for i, n in enumerate(LOC[ax]):
            loc[n] = float(rng.uniform(-40, 40) if i < 2 else rng.uniform(-80, 80))
    motions: dict[str, Motion] = {}
    if seed % 4 == 3:
        for ax in ("C", tilt):
            for c in "XYZABC":
                own = {"C": "ZC", "A": "XA", "B": "YB"}[ax]
                ks = (1, 2, 3) if c in own else (2, 3)
                size = motion_scale * (0.6 if c in "XYZ" else 3.0)
                motions[f"{ax}.{c}"] = Motion({k: float(rng.uniform(0, size)) for k in ks},
                                              {k: float(rng.uniform(0, 2 * math.pi)) for k in ks})
    off = np.array([0.0, rng.uniform(-40, 40), rng.uniform(-150, -40)]) if tilt == "A" else \
        np.array([rng.uniform(-40, 40), 0.0, rng.uniform(-150, -40)])
    pivot = np.array([rng.uniform(-200, 200), rng.uniform(-200, 200), rng.uniform(-450, -200)])
    r = float(rng.uniform(40, 120))
    u = rng.uniform(0, 2 * math.pi)
    sphere = pivot + np.array([r * math.cos(u), r * math.sin(u), rng.uniform(20, 80)])
    return Campaign(kind, pivot, off, float(rng.uniform(60, 200)), loc, motions, sphere,
                    rng.normal(0, 0.05, 3), 12.5, float(rng.normal(0, 0.002)), 1.5,
                    float(rng.uniform(0, 0.3)), float(rng.uniform(0.2, 0.8)),
                    float(rng.uniform(0, 2.0)), seed % 3 == 0, n_tilt, n_c, seed)


def make_diagnose_campaign(kind: str, seed: int) -> tuple[Campaign, str | None, float]:
    """A campaign for the discrepancy workflow, probed with the diagnosis plan (the grid
    twice, docs/programs.md): ``clean`` (no error motion, no drift),
    ``cyclic`` (an ECC(C) of k = 1..3 cycles per turn, 10-25 urad, with its own phase),
    ``drift`` (the tilt axis' line rising 4-8 um/h) or ``wobble`` (a once-per-turn tilt of
    C, counter-rotating part 10-25 urad). Returns the campaign, the catalogue
    key a diagnosis should name (None for clean) and the true amplitude (urad, um/h)."""
    c = make_campaign(4 * seed + 1 if seed % 2 else 4 * seed)  # no hidden motions (seed % 4 != 3)
    c.motions, c.drift_um_per_h, c.rtest, c.passes = {}, 0.0, False, 2
    rng = np.random.default_rng(10_000 + seed)
    if kind == "cyclic":
        k = int(rng.integers(1, 4))
        amp = float(rng.uniform(10, 25))
        c.motions["C.C"] = Motion({k: amp}, {k: float(rng.uniform(0, 2 * math.pi))})
        return c, f"cyclic C {k}", amp
    if kind == "wobble":
        # A once-per-turn tilt of C: the tilt (EAC, EBC) as a complex number
        # f e^{i(t + pf)} + b e^{-i(t + pb)}; one sphere sees the counter-rotating b only
        # (the forward part is the table face's tilt), so b is the amplitude to name.
        b, f = float(rng.uniform(10, 25)), float(rng.uniform(0, 25))
        pf, pb = float(rng.uniform(0, 2 * math.pi)), float(rng.uniform(0, 2 * math.pi))
        for comp, ph_f, ph_b in (("A", pf + math.pi / 2, pb + math.pi / 2), ("B", pf, pb + math.pi)):
            z = f * complex(math.cos(ph_f), math.sin(ph_f)) + b * complex(math.cos(ph_b),
                                                                          math.sin(ph_b))
            c.motions[f"C.{comp}"] = Motion({1: abs(z)}, {1: math.atan2(z.imag, z.real)})
        return c, "wobble C", backward_tilt(c.motions["C.A"], c.motions["C.B"])
    if kind == "drift":
        c.drift_um_per_h = float(rng.uniform(4, 8))
        return c, f"pivot drift {c.tilt}", c.drift_um_per_h
    return c, None, 0.0


def backward_tilt(ea: Motion, eb: Motion, n: int = 720) -> float:
    """Amplitude (urad) of the counter-rotating part of a tilt (EAC, EBC)(t): the mean of
    (EAC + i EBC) e^{i t} over a turn (numerically)."""
    t = np.arange(n) * 360.0 / n
    z = np.array([ea.at(x) + 1j * eb.at(x) for x in t]) * np.exp(1j * np.deg2rad(t))
    return float(abs(z.mean()))
