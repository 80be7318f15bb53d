"""The five-axis identification problem: parameters, data blocks and residuals.

Parameters (:class:`Param`): the machine's errors (location errors of both
rotary axes, optionally the squareness of the linear axes and the error
motions' Fourier coefficients) and the nuisance parameters of the set-ups (the
sphere's position on the table per probing and R-test, the R-test's zero, the
indexer's zero and reversal). Residuals are measured minus predicted through
the exact model (:func:`abbe.model.five_axis.table_transform`), each block
divided by its standard deviation (estimated from the fit).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from abbe.formats.five_axis import FiveAxisSpec
from abbe.model.five_axis import (LOCATION_ERRORS, MOTION_COMPONENTS, SQUARENESS,
                                  FiveAxisErrors, TrunnionGeometry, fourier_rows,
                                  linear_axis_errors, lowest_harmonic, motion_name,
                                  small_rotation,
                                  table_transform)


@dataclass(frozen=True)
class Param:
    """One unknown: ``name`` (ISO name, ``EXC(C) sin2`` or a set-up name), ``kind``
    (location, squareness, motion, wobble, drift, setup), ``unit`` (um / urad), ``scale``: its
    typical size (the solver's scaling)."""

    name: str
    kind: str
    unit: str
    scale: float
    axis: str = ""
    comp: str = ""
    harmonic: int = 0
    trig: str = ""  # "sin" / "cos" of a motion coefficient
    block: str = ""  # the set-up a nuisance parameter belongs to


@dataclass
class Block:
    """A data block: kind ``probe`` / ``rtest`` / ``indexer`` / ``ballbar`` / ``datum`` (a
    probing sphere's declared place: obs (1, 3) um, the sphere unknowns' known values, its
    sigma the declared uncertainty, fixed), its name,
    angles (M, 2) deg (indexer: the target angles in column 1), observations (M, 3) (probe:
    centre mm, R-test: displacement um) or (M,) (indexer urad, ballbar: measured minus
    nominal length um), direction (indexer), the sphere's (ballbar: the table ball's)
    nominal centre (mm), the tool ball's (ballbar, mm), its standard deviation (um or urad)
    and time (s)."""

    kind: str
    name: str
    angles_deg: np.ndarray
    obs: np.ndarray
    sphere_mm: np.ndarray = field(default_factory=lambda: np.zeros(3))
    direction: np.ndarray | None = None
    sigma: float | np.ndarray = 1.0  # per component (x, y, z) for probe and R-test blocks
    time_s: np.ndarray | None = None
    positions: np.ndarray | None = None  # probing position numbers (for reports)
    #: probe blocks: expected RMS 3-D length of the centres' noise from the sphere fits (um)
    noise_floor_um: float | None = None
    #: probe blocks: each centre's noise covariance from its sphere fit (M, 3, 3) um^2
    centre_cov_um2: np.ndarray | None = None
    #: ballbar blocks: the tool ball's nominal centre, workpiece coordinates (mm)
    tool_mm: np.ndarray | None = None
    #: ballbar blocks: the set-up they share (same table ball and tool cup, not moved), or ""
    setup: str = ""
    #: datum blocks: the probing whose sphere it declares (``probe.NAME``)
    of: str = ""
    #: Type B calibration of the instrument: ("scale", U %, source) - a sensitivity error
    #: scales the observations - or ("offset", U um, source) - every reading shifted alike;
    #: U at k = 2, source "declared" or "class default"; None: none declared for this kind
    calibration: tuple[str, float, str] | None = None

    @property
    def balls_key(self) -> str:
        """Whose ball set-up unknowns a ballbar block uses: its own or its shared set-up's."""
        return f"ballbar_setup.{self.setup}" if self.setup else self.key

    @property
    def key(self) -> str:
        """``probe.S1``, ``rtest.R1``, ``indexer.C``: unique among a plan's blocks."""
        return f"{self.kind}.{self.name}"


def build_params(spec: FiveAxisSpec, blocks: list[Block]) -> list[Param]:
    """Every candidate unknown of the plan (before the observability analysis)."""
    g = spec.geometry
    ps: list[Param] = []
    for ax in g.rotaries:
        for i, n in enumerate(LOCATION_ERRORS[ax]):
            ps.append(Param(n, "location", "um" if i < 2 else "urad", 10.0 if i < 2 else 20.0, ax))
    if spec.fit.squareness:
        ps += [Param(s, "squareness", "urad", 20.0) for s in SQUARENESS]
    for ax in g.rotaries:
        for j, comp in enumerate(MOTION_COMPONENTS):
            for k in range(lowest_harmonic(ax, comp), spec.fit.harmonics + 1):
                for trig in ("sin", "cos"):
                    ps.append(Param(f"{motion_name(ax, comp)} {trig}{k}", "motion",
                                    "um" if j < 3 else "urad", 1.0 if j < 3 else 5.0,
                                    ax, comp, k, trig))
    shared: set[str] = set()
    for b in blocks:
        if b.kind in ("probe", "rtest"):
            ps += [Param(f"{b.kind}.{b.name} sphere {c}", "setup", "um", 100.0, block=b.key)
                   for c in "xyz"]
        if b.kind == "rtest":
            ps += [Param(f"rtest.{b.name} zero {c}", "setup", "um", 10.0, block=b.key)
                   for c in "xyz"]
            # The sensor nest's mounting: its directions turned (urad) and its gain off (ppm).
            ps += [Param(f"rtest.{b.name} mount {c}", "setup", "urad", 1000.0, block=b.key)
                   for c in ("a", "b", "c")]
            ps.append(Param(f"rtest.{b.name} mount gain", "setup", "ppm", 1000.0, block=b.key))
        if b.kind == "ballbar":
            # The balls' set-up: the table ball's place on the table (workpiece frame), the
            # tool ball's off the tool's nominal point (machine frame: run-out, length set-up),
            # the bar's length calibration.
            if b.setup and b.balls_key in shared:
                pass  # the set-up's balls are already unknowns
            else:
                who = f"set-up {b.setup}" if b.setup else f"ballbar.{b.name}"
                shared.add(b.balls_key)
                ps += [Param(f"{who} table ball {c}", "setup", "um", 100.0, block=b.balls_key)
                       for c in "xyz"]
                ps += [Param(f"{who} tool ball {c}", "setup", "um", 100.0, block=b.balls_key)
                       for c in "xyz"]
            ps.append(Param(f"ballbar.{b.name} length zero", "setup", "um", 10.0, block=b.key))
        if b.kind == "indexer":
            ps += [Param(f"indexer.{b.name} zero", "setup", "urad", 10.0, block=b.key),
                   Param(f"indexer.{b.name} reversal", "setup", "urad", 10.0, block=b.key)]
    return ps


def errors_from(params: list[Param], x: np.ndarray, harmonics: int) -> FiveAxisErrors:
    """The machine errors of a parameter vector (set-up and drift parameters left out)."""
    harmonics = max([harmonics] + [p.harmonic for p in params if p.kind in ("motion", "wobble")])
    loc: dict[str, float] = {}
    mot: dict[tuple[str, str], np.ndarray] = {}
    sq = {s: 0.0 for s in SQUARENESS}
    for p, v in zip(params, x):
        if p.kind == "location":
            loc[p.name] = float(v)
        elif p.kind == "squareness":
            sq[p.name] = float(v)
        elif p.kind == "motion":
            c = mot.setdefault((p.axis, p.comp), np.zeros(2 * harmonics))
            c[2 * (p.harmonic - 1) + (0 if p.trig == "sin" else 1)] += v
        elif p.kind == "wobble":
            # The counter-rotating once-per-turn tilt of a table axis (docs/effects.md, section
            # 7): (EAC, EBC) = Rz(-C) (wx, wy), i.e. EAC = wx cos C + wy sin C and
            # EBC = -wx sin C + wy cos C (Fourier order [sin1, cos1]).
            ea = mot.setdefault((p.axis, "A"), np.zeros(2 * harmonics))
            eb = mot.setdefault((p.axis, "B"), np.zeros(2 * harmonics))
            if p.comp == "x":
                ea[1] += v
                eb[0] -= v
            else:
                ea[0] += v
                eb[1] += v
    return FiveAxisErrors(loc, mot, (sq["sxy"], sq["sxz"], sq["syz"]))


def _setup(params: list[Param], x: np.ndarray, name: str, what: str) -> np.ndarray:
    return np.array([x[i] for i, p in enumerate(params)
                     if p.kind == "setup" and p.block == name and what in p.name])


def predict_block(g: TrunnionGeometry, params: list[Param], x: np.ndarray, harmonics: int,
                  b: Block, rows: np.ndarray | None = None) -> np.ndarray:
    """What block ``b`` should read for the parameters ``x`` (rows: a subset)."""
    if b.kind == "datum":
        # A measurement of the set-up unknowns themselves (a prior with the declared
        # uncertainty): the sphere's offset from its declared place, um.
        return _setup(params, x, b.of, "sphere")[None, :]
    errs = errors_from(params, x, harmonics)
    ang = b.angles_deg if rows is None else b.angles_deg[rows]
    if b.kind == "indexer":
        tg = ang[:, 1]
        col = MOTION_COMPONENTS.index(b.name)
        c = errs.motions.get((b.name, MOTION_COMPONENTS[col]))
        ecc = fourier_rows(tg, len(c) // 2) @ c if c is not None else np.zeros(tg.size)
        zero, rev = _setup(params, x, b.key, "zero")[0], _setup(params, x, b.key, "reversal")[0]
        d = b.direction if rows is None else b.direction[rows]  # type: ignore[index]
        return ecc + zero + d * rev / 2.0
    s = b.sphere_mm + (_setup(params, x, b.balls_key, "table ball") if b.kind == "ballbar"
                       else _setup(params, x, b.key, "sphere")) * 1e-3
    T = table_transform(g, errs, ang)
    centre = np.einsum("nij,j->ni", T[:, :3, :3], s) + T[:, :3, 3]
    drifts = [(p.comp, float(v)) for p, v in zip(params, x) if p.kind == "drift" and v != 0.0]
    if drifts and b.time_s is not None:
        # A location error drifting linearly in time (per hour): its effect is linear to
        # 1e-4 relative, so one more transform per drifting error gives it at every row.
        # Each drift's move is taken from the undrifted centre: measured from the centre
        # another drift has already moved, a second drift would carry the first one's
        # move times its own rate (a bilinear term as large as the drifts themselves).
        hours = (b.time_s if rows is None else b.time_s[rows]) / 3600.0
        still = centre
        for name, rate in drifts:
            moved = FiveAxisErrors({**errs.location, name: errs.location.get(name, 0.0) + 1.0},
                                   errs.motions, errs.squareness)
            T1 = table_transform(g, moved, ang)
            per = np.einsum("nij,j->ni", T1[:, :3, :3], s) + T1[:, :3, 3] - still
            centre = centre + per * (rate * hours)[:, None]
    if b.kind == "probe":
        e, _r = linear_axis_errors(g, errs, centre)
        return centre - e * 1e-3  # the probe reads machine positions: the tool error subtracts
    if b.kind == "ballbar":
        # The tool ball is held at the nominal place of its workpiece point (tool-centre-point
        # control); the linear axes' errors and its set-up move it; the bar reads the distance.
        Tn = table_transform(g, None, ang)
        q = np.einsum("nij,j->ni", Tn[:, :3, :3], b.tool_mm) + Tn[:, :3, 3]
        e, _r = linear_axis_errors(g, errs, q)
        tool = q + (e + _setup(params, x, b.balls_key, "tool ball")) * 1e-3
        length = float(np.linalg.norm(b.tool_mm - b.sphere_mm))  # type: ignore[operator]
        return ((np.linalg.norm(tool - centre, axis=1) - length) * 1e3
                + _setup(params, x, b.key, "length zero")[0])
    Tn = table_transform(g, None, ang)
    q = np.einsum("nij,j->ni", Tn[:, :3, :3], b.sphere_mm) + Tn[:, :3, 3]
    e, _r = linear_axis_errors(g, errs, q)
    mount = _setup(params, x, b.key, "mount")  # a, b, c (urad), gain (ppm)
    nest = small_rotation(mount[None, :3] * 1e-6)[0] * (1.0 + mount[3] * 1e-6)
    return ((centre - q) * 1e3 - e) @ nest.T + _setup(params, x, b.key, "zero")


def residual_block(g: TrunnionGeometry, params: list[Param], x: np.ndarray, harmonics: int,
                   b: Block, rows: np.ndarray | None = None) -> np.ndarray:
    """Measured minus predicted of block ``b`` in its unit (um, urad), flattened."""
    obs = b.obs if rows is None else b.obs[rows]
    pred = predict_block(g, params, x, harmonics, b, rows)
    r = obs - pred
    if b.kind == "probe":
        r = r * 1e3
    return r.ravel()


def residuals(g: TrunnionGeometry, params: list[Param], x: np.ndarray, harmonics: int,
              blocks: list[Block], rows: dict[str, np.ndarray] | None = None) -> np.ndarray:
    """All blocks' residuals divided by their standard deviations."""
    out = []
    for b in blocks:
        r = residual_block(g, params, x, harmonics, b, None if rows is None else rows.get(b.key))
        sig = np.asarray(b.sigma, dtype=np.float64)
        out.append((r.reshape(-1, sig.size) / sig).ravel() if sig.size > 1 else r / sig)
    return np.concatenate(out)
