"""Kinematic-chain exports: a fitted chain (``abbe fit`` on a ``[chain]`` machine file,
its chain_fit.json) written as the parameters of a controller's kinematics module, with
the residual the module leaves (docs/exports.md, "Five-axis chains").

A chain target (``CHAIN_TARGETS``) builds a :class:`ChainExport`: the files, and the
module's own inverse kinematics with the written (quantised) values,
``joints(w, theta) -> (q, t)``: the linear joint positions q (mm, abbe's machine
coordinates) and rotary joint angles t (deg, in the chain's convention: the axis turns
by ``direction * t + E0`` about its positive machine axis) the controller commands for
the programmed workpiece point w (mm) at rotary axis positions theta (deg, the chain's
alphabetical columns) under tool-centre-point control.

The residual is the exact error of the fitted chain (:mod:`abbe.model.chain`,
homogeneous transforms, the location errors and the error motions of chain_fit.json; an
unobservable one counts as 0, as the fit writes it) at those joints: the actual tool tip minus where the
workpiece point w actually is (um, machine coordinates), and the tool's orientation
relative to the workpiece against the programmed one (urad, machine frame). The
uncompensated machine commands the nominal chain's joints (t = theta).

Error motions (``[chain.fit] harmonics``): none of LinuxCNC's 5axiskins, maxkins and
xyzab_tdr_kins has a parameter that varies with the angle (their inputs are a pivot length,
rotation points and offsets, and the joints' HOME_OFFSET), so no error motion can be
written; each fitted component (``EXC(C)``: its Fourier coefficients together) is listed
as not held with the size of its own exact error over the poses, and the residual
includes it.

Poses: the work volume (every linear-axis grid point of the machine file's travel at
every rotary grid position: ``rotary_points`` per rotary axis over its travel, one turn
at most; the programmed point is the one the nominal machine reaches there) and a
tool-centre-point path (a fixed workpiece point ``tcp_point`` while the axis with the
longer travel turns one turn, clipped to its travel, and the other swings to
``+tcp_tilt_deg`` and back, then the same back with ``-tcp_tilt_deg``, 1 deg steps).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from abbe.errors import AbbeInputError
from abbe.exports.five_axis import pose_stats
from abbe.exports.five_axis import summary as five_axis_summary
from abbe.exports.target import Option
from abbe.model.chain import (KinematicChain, nominal_joints, tool_tip, tool_transform,
                              workpiece_transform)
from abbe.model.five_axis import MOTION_COMPONENTS, lowest_harmonic, motion_name
from abbe.model.five_axis_base import LOCATION_ERRORS, FiveAxisErrors, rotvec
from abbe.model.table import AXES

FORMAT = "abbe-export-residual-chain"
#: Location errors larger than this are refused as not a fit of this machine (um / urad).
LOCATION_LIMIT = 1.0e5
#: Parts smaller than this everywhere are not listed as not held, um / urad.
FLOOR_UM = 1e-4
#: The nominal chain must be the module's geometry to this, mm.
GEOMETRY_TOL_MM = 1e-9
#: Error motion coefficients larger than this are refused (um / urad).
MOTION_LIMIT = 1.0e4
#: The highest harmonic abbe fit writes ([chain.fit] harmonics).
HARMONICS_MAX = 8

#: The pose options every chain target has.
POSE_OPTIONS: dict[str, Option] = {
    "volume_points": Option("int", 5, "linear-axis grid points per axis of the work volume",
                            lo=2, hi=21),
    "rotary_points": Option("int", 9, "positions per rotary axis over its travel (one turn "
                            "at most) in the work volume", lo=2, hi=73),
    "tcp_point": Option("axes", {"X": 50.0, "Y": 20.0, "Z": -50.0},
                        "tool-centre-point path: the workpiece point, mm", item="float",
                        lo=-2000.0, hi=2000.0),
    "tcp_tilt_deg": Option("float", 60.0, "tool-centre-point path: largest swing of the "
                           "shorter-travel rotary axis each way, deg", lo=0.0, hi=180.0),
}


@dataclass
class ChainContext:
    """Inputs of a chain build: the machine file's nominal chain, the fitted location
    errors (um / urad, unobservable ones absent), linear travel (mm), options, the
    names the fit could not observe, where the inputs came from."""

    chain: KinematicChain
    errors: FiveAxisErrors
    travel_mm: dict[str, tuple[float, float]]
    options: dict[str, Any]
    model_source: str = ""
    machine_source: str = ""
    not_observable: list[str] = field(default_factory=list)


@dataclass
class ChainExport:
    """The output of a chain target build (module docstring for ``joints``)."""

    target: str
    files: dict[str, bytes]
    joints: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
    expressed: list[dict[str, Any]]
    held: tuple[str, ...]
    not_held: list[dict[str, Any]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    assumptions: list[str] = field(default_factory=list)
    sources: list[str] = field(default_factory=list)


# ------------------------------------------------------------------------ loading


def load_chain_context(model: Path, machine, options: dict[str, Any]) -> ChainContext:
    """The context of a chain export: ``model`` abbe fit's chain_fit.json, ``machine`` the
    parsed ``[chain]`` machine file it was fitted from. AbbeInputError when either is
    missing or wrong, or when they disagree."""
    from abbe.formats.text import read_bytes

    name = str(model)
    if machine is None:
        raise AbbeInputError("a kinematics-module target needs --machine: the [chain] machine "
                             "file the chain was fitted with (nominal chain, linear travel)",
                             field="--machine")
    chain = machine.extra.get("chain")
    if chain is None or "chain_plans" not in machine.extra:
        raise AbbeInputError("the machine file has no [chain] section: this target writes a "
                             "fitted kinematic chain (abbe fit on a [chain] machine file)",
                             file=str(machine.path), field="chain")
    data = read_bytes(model, what="fitted chain", max_bytes=1 << 20)
    try:
        doc = json.loads(data.decode("utf-8"))
    except UnicodeDecodeError:
        raise AbbeInputError("expected abbe fit's chain_fit.json (UTF-8 JSON), got bytes that "
                             "are not UTF-8 (a table blob? this target reads the fitted chain)",
                             file=name, field="model") from None
    except json.JSONDecodeError as exc:
        raise AbbeInputError(f"not JSON: {exc.msg} (expected abbe fit's chain_fit.json)",
                             file=name, line=exc.lineno, field="model") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("location"), list):
        raise AbbeInputError("expected abbe fit's chain_fit.json: an object with a "
                             "'location' list", file=name, field="location")
    for key, want in (("chain", chain.name), ("kind", chain.kind)):
        if doc.get(key) != want:
            raise AbbeInputError(f"the fit is of {key} {doc.get(key)!r}, the machine file's "
                                 f"[chain] is {want!r} (a fit of another machine?)",
                                 file=name, field=key)
    want_names = chain.location_names()
    loc: dict[str, float] = {}
    unobs: list[str] = []
    seen: set[str] = set()
    for i, row in enumerate(doc["location"]):
        f = f"location[{i}]"
        if not isinstance(row, dict) or not isinstance(row.get("name"), str):
            raise AbbeInputError("expected an object with a name", file=name, field=f)
        n = row["name"]
        if n not in want_names:
            raise AbbeInputError(f"{n!r} is not a location error of this chain (expected one "
                                 f"of {', '.join(want_names)})", file=name, field=f"{f}.name")
        if n in seen:
            raise AbbeInputError(f"{n} is given twice", file=name, field=f"{f}.name")
        seen.add(n)
        unit = "urad" if n[1] in "ABC" else "um"
        if row.get("unit") != unit:
            raise AbbeInputError(f"{n}: expected unit {unit!r}, got {row.get('unit')!r}",
                                 file=name, field=f"{f}.unit")
        v = row.get("value")
        if v is None:
            unobs.append(n)
            continue
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or abs(v) > LOCATION_LIMIT:
            raise AbbeInputError(f"{n}: expected a finite number of {unit} within "
                                 f"+-{LOCATION_LIMIT:g} or null (not observable), got {v!r}",
                                 file=name, field=f"{f}.value")
        loc[n] = float(v)
    motions, motion_unobs = _motions(doc.get("motions", []), chain, name)
    unobs += motion_unobs
    missing = [n for n in want_names if n not in seen]
    if missing:
        raise AbbeInputError(f"missing location errors: {', '.join(missing)}", file=name,
                             field="location")
    travel = {}
    for a in AXES:
        if a not in machine.axes:
            raise AbbeInputError(f"the machine file has no [axes.{a}]: the work volume needs all "
                                 "three travels", file=str(machine.path), field=f"axes.{a}")
        travel[a] = tuple(float(v) for v in machine.axes[a].travel_mm)
    return ChainContext(chain=chain, errors=FiveAxisErrors(location=loc, motions=motions),
                        travel_mm=travel, options=options, model_source=name,
                        machine_source=Path(machine.path).name, not_observable=unobs)


def _motions(rows: Any, chain: KinematicChain, file: str
             ) -> tuple[dict[tuple[str, str], np.ndarray], list[str]]:
    """The error motions of chain_fit.json's ``motions`` rows (``EXC(C) sin2``, um / urad):
    Fourier coefficients ``[sin 1, cos 1, ...]`` per (axis, component); a row with value
    null is not observable (counts as 0, listed). Bad rows: AbbeInputError."""
    if not isinstance(rows, list):
        raise AbbeInputError("expected a list of error motion coefficients", file=file,
                             field="motions")
    valid = {f"{motion_name(ax, comp)} {trig}{k}": (ax, comp, k, trig)
             for ax in chain.rotaries for comp in MOTION_COMPONENTS
             for k in range(lowest_harmonic(ax, comp), HARMONICS_MAX + 1)
             for trig in ("sin", "cos")}
    vals: dict[str, float] = {}
    unobs: list[str] = []
    for i, row in enumerate(rows):
        f = f"motions[{i}]"
        if not isinstance(row, dict) or not isinstance(row.get("name"), str):
            raise AbbeInputError("expected an object with a name", file=file, field=f)
        n = row["name"]
        if n not in valid:
            raise AbbeInputError(f"{n!r} is not an error motion coefficient of this chain "
                                 f"(expected e.g. '{next(iter(valid))}': ISO 230-7 name, sin or "
                                 f"cos and a harmonic up to {HARMONICS_MAX})", file=file,
                                 field=f"{f}.name")
        if n in vals or n in unobs:
            raise AbbeInputError(f"{n} is given twice", file=file, field=f"{f}.name")
        unit = "um" if valid[n][1] in "XYZ" else "urad"
        if row.get("unit") != unit:
            raise AbbeInputError(f"{n}: expected unit {unit!r}, got {row.get('unit')!r}",
                                 file=file, field=f"{f}.unit")
        v = row.get("value")
        if v is None:
            unobs.append(n)
            continue
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) \
                or abs(v) > MOTION_LIMIT:
            raise AbbeInputError(f"{n}: expected a finite number of {unit} within "
                                 f"+-{MOTION_LIMIT:g} or null (not observable), got {v!r}",
                                 file=file, field=f"{f}.value")
        vals[n] = float(v)
    h = max([valid[n][2] for n in vals] + [0])
    out: dict[tuple[str, str], np.ndarray] = {}
    for n, v in vals.items():
        ax, comp, k, trig = valid[n]
        c = out.setdefault((ax, comp), np.zeros(2 * h))
        c[2 * (k - 1) + (0 if trig == "sin" else 1)] = v
    return out, unobs


def require(ok: bool, ctx: ChainContext, module: str, what: str) -> None:
    """Refuse a chain the module cannot describe (field chain of the machine file)."""
    if not ok:
        raise AbbeInputError(f"{module} cannot describe this chain: {what}",
                             file=ctx.machine_source, field="chain")


def zero_shift_deg(ctx: ChainContext, axis: str) -> float:
    """The change of the joint's HOME_OFFSET (deg) that makes ``axis`` read its true angle:
    the axis turns by ``s t + E0`` = ``s (t + s E0)``, so the joint reads ``s E0`` more."""
    e0 = ctx.errors.location.get(f"E{axis}0{axis}", 0.0)
    return float(ctx.chain.axis(axis).direction * np.degrees(e0 * 1e-6))


def um(ctx: ChainContext, name: str) -> float:
    """A location error in mm (0 when not observable)."""
    return 1e-3 * ctx.errors.location.get(name, 0.0)


# ------------------------------------------------------------------------- poses


def _apply(T: np.ndarray, p: np.ndarray) -> np.ndarray:
    return np.einsum("nij,nj->ni", T[:, :3, :3], p) + T[:, :3, 3]


def programmed_points(chain: KinematicChain, q: np.ndarray, ang: np.ndarray) -> np.ndarray:
    """The workpiece points the nominal machine's tool (the controlled point) is on at
    machine positions q (N, 3) mm and angles (N, 2) deg."""
    tip = _apply(tool_transform(chain, None, ang), np.zeros_like(q))
    T = np.linalg.inv(workpiece_transform(chain, None, ang))
    return _apply(T, q + tip)


def _rotary_grid(lo: float, hi: float, n: int) -> np.ndarray:
    if hi - lo >= 360.0:  # one turn, without its repeated end
        return np.unique(np.clip(lo + np.arange(n) * 360.0 / n, lo, hi))
    return np.linspace(lo, hi, n)


def volume_poses(ctx: ChainContext) -> tuple[np.ndarray, np.ndarray]:
    """(workpiece points (N, 3) mm, rotary positions (N, 2) deg) of the work volume."""
    o, ch = ctx.options, ctx.chain
    s = [np.linspace(*ctx.travel_mm[a], o["volume_points"]) for a in AXES]
    q = np.stack(np.meshgrid(*s, indexing="ij"), -1).reshape(-1, 3)
    r1, r2 = ch.rotaries
    g1 = _rotary_grid(*ch.travel_deg[r1], o["rotary_points"])
    g2 = _rotary_grid(*ch.travel_deg[r2], o["rotary_points"])
    A, B = np.meshgrid(g1, g2, indexing="ij")
    ang = np.column_stack([A.ravel(), B.ravel()])
    Q = np.repeat(q, len(ang), axis=0)
    ANG = np.tile(ang, (len(q), 1))
    return programmed_points(ch, Q, ANG), ANG


def tcp_path(ctx: ChainContext) -> tuple[np.ndarray, np.ndarray]:
    """(workpiece points (N, 3) mm, all the same; rotary positions (N, 2) deg) of the
    tool-centre-point path (module docstring)."""
    o, ch = ctx.options, ctx.chain
    r = ch.rotaries
    span = [ch.travel_deg[a][1] - ch.travel_deg[a][0] for a in r]
    turn = 1 if span[1] >= span[0] else 0
    s = np.linspace(0.0, 1.0, 361)
    bump = np.sin(np.pi * s)
    lo, hi = ch.travel_deg[r[1 - turn]]
    up = np.clip(o["tcp_tilt_deg"] * bump, lo, hi)
    dn = np.clip(-o["tcp_tilt_deg"] * bump, lo, hi)
    c = np.clip(360.0 * s, *ch.travel_deg[r[turn]])
    cols_up = [up, c] if turn == 1 else [c, up]
    cols_dn = [dn, c[::-1]] if turn == 1 else [c[::-1], dn]
    ang = np.concatenate([np.column_stack(cols_up), np.column_stack(cols_dn)[1:]])
    p = o["tcp_point"]
    w0 = np.array([float(p[a]) for a in AXES])
    return np.tile(w0, (len(ang), 1)), ang


# ---------------------------------------------------------------------- residual


def pose_error(chain: KinematicChain, errs: FiveAxisErrors, work_mm: np.ndarray,
               angles_deg: np.ndarray, joints_mm: np.ndarray, joint_angles_deg: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """Exact error at commanded joints: the actual tool tip minus the actual workpiece
    point (N, 3) um; the tool's orientation relative to the workpiece against the
    programmed one, machine frame (N, 3) urad: ``rotvec(R_W,nom R_W,act^T R_T,act
    R_T,nom^T)`` (the linear axes' rotation inside R_T,act)."""
    q = np.asarray(joints_mm, dtype=np.float64).reshape(-1, 3)
    w = np.asarray(work_mm, dtype=np.float64).reshape(-1, 3)
    Wa = workpiece_transform(chain, errs, joint_angles_deg)
    tip = tool_tip(chain, errs, q, joint_angles_deg)
    pos = (tip - _apply(Wa, w)) * 1e3
    Wn = workpiece_transform(chain, None, angles_deg)[:, :3, :3]
    Tn = tool_transform(chain, None, angles_deg)[:, :3, :3]
    Ta = tool_transform(chain, errs, joint_angles_deg)[:, :3, :3]
    tr = lambda M: np.transpose(M, (0, 2, 1))  # noqa: E731
    R = Wn @ tr(Wa[:, :3, :3]) @ Ta @ tr(Tn)
    return pos, rotvec(R) * 1e6


def _both(ctx: ChainContext, exp: ChainExport, W: np.ndarray, A: np.ndarray) -> dict[str, Any]:
    ch, e = ctx.chain, ctx.errors
    q0 = nominal_joints(ch, W, A)
    q, t = exp.joints(W, A)
    return {"residual": pose_stats(*pose_error(ch, e, W, A, q, t)),
            "uncompensated": pose_stats(*pose_error(ch, e, W, A, q0, A))}


def not_held(ctx: ChainContext, held: tuple[str, ...], reason: Callable[[str], str],
             module: str = "this module") -> list[dict[str, Any]]:
    """The fitted location errors the module cannot hold and every fitted error motion
    component (none of these modules has a parameter for one), each with the size of its
    own exact error (the machine otherwise nominal) over the volume and the TCP path."""
    ch = ctx.chain
    poses = {"volume": volume_poses(ctx), "tcp_path": tcp_path(ctx)}
    joints = {k: nominal_joints(ch, W, A) for k, (W, A) in poses.items()}
    items: list[tuple[dict[str, Any], FiveAxisErrors]] = []
    for n in ch.location_names():
        v = ctx.errors.location.get(n, 0.0)
        if n in held or v == 0.0:
            continue
        items.append(({"item": n, "kind": "location", "reason": reason(n)},
                      FiveAxisErrors(location={n: v})))
    for (ax, comp), c in sorted(ctx.errors.motions.items()):
        if not np.any(c):
            continue
        items.append(({"item": motion_name(ax, comp), "kind": "error motion",
                       "coefficients": {f"{'sin' if i % 2 == 0 else 'cos'}{i // 2 + 1}":
                                        round(float(v), 6) for i, v in enumerate(c) if v != 0.0},
                       "reason": f"an error motion of {ax} (a function of its angle): {module} "
                                 "has no parameter that varies with the angle (not exportable "
                                 "to it; abbe's table model_five.bin holds it)"},
                      FiveAxisErrors(location={}, motions={(ax, comp): c})))
    out = []
    for d, only in items:
        big = 0.0
        for k, (W, A) in poses.items():
            pos, rot = pose_error(ch, only, W, A, joints[k], A)
            nn = np.linalg.norm(pos, axis=1)
            r = np.linalg.norm(rot, axis=1)
            d[k] = {"max_um": round(float(np.max(nn)), 4),
                    "rms_um": round(float(np.sqrt(np.mean(nn ** 2))), 4),
                    "orientation_max_urad": round(float(np.max(r)), 4)}
            big = max(big, float(np.max(nn)), float(np.max(r)))
        if big >= FLOOR_UM:
            out.append(d)
    return out


def evaluate(ctx: ChainContext, exp: ChainExport) -> dict[str, Any]:
    """The residual report of one chain export, as written to residual.json."""
    ch, o = ctx.chain, ctx.options
    W, A = volume_poses(ctx)
    vol = {"linear_travel_mm": {a: list(ctx.travel_mm[a]) for a in AXES},
           "rotary_travel_deg": {a: list(ch.travel_deg[a]) for a in ch.rotaries},
           "points_per_linear_axis": o["volume_points"], "rotary_points": o["rotary_points"],
           "poses": int(len(W)), **_both(ctx, exp, W, A)}
    Wp, Ap = tcp_path(ctx)
    path = {"workpiece_point_mm": [round(float(v), 6) for v in Wp[0]],
            "angles_deg": {a: [round(float(Ap[:, i].min()), 6), round(float(Ap[:, i].max()), 6)]
                           for i, a in enumerate(ch.rotaries)},
            "poses": int(len(Wp)), **_both(ctx, exp, Wp, Ap)}
    return {
        "format": FORMAT, "version": 1, "target": exp.target, "model": ctx.model_source,
        "machine": ctx.machine_source, "chain": ch.name, "kind": ch.kind,
        "convention": ("exact chain model (abbe.model.chain) with the fitted location errors: "
                       "tool tip minus the actual workpiece point at the joints the module "
                       "commands, machine coordinates, um; orientation of the tool relative to "
                       "the workpiece, urad; nothing removed"),
        "volume": vol, "tcp_path": path, "held": list(exp.held),
        "expressed": exp.expressed, "not_held": exp.not_held,
        "not_observable": {"items": ctx.not_observable,
                           "note": "not observable by the fit's plan: written at nominal, "
                                   "neither corrected nor sized here"},
        "notes": exp.notes + ([
            "error motions: not exportable to this module (it takes no parameter that varies "
            "with the angle); each fitted component is listed in not_held with its own size "
            "and the residual includes them all: "
            + ", ".join(sorted(motion_name(a, c) for (a, c), v in ctx.errors.motions.items()
                               if np.any(v)))] if any(np.any(v) for v in
                                                      ctx.errors.motions.values()) else []),
        "assumptions": exp.assumptions, "sources": exp.sources,
        "files": sorted(exp.files),
    }


def summary(report: dict[str, Any]) -> str:
    """The lines ``abbe export`` prints for a chain target."""
    return five_axis_summary(report, holder="this module", unobserved="written at nominal")


def home_offset_lines(joint: int, axis: str, old: float, shift: float, why: str,
                      decimals: int, unit: str) -> list[str]:
    """An INI joint section setting HOME_OFFSET = old + shift."""
    from abbe.exports.target import fmt
    return ["", f"[JOINT_{joint}]", f"# {axis}: {why}; HOME_OFFSET today {old:g} {unit}",
            f"HOME_OFFSET = {fmt(old + shift, decimals)}"]


def location_reasons(module: str) -> Callable[[str], str]:
    """Why a location error is not held by ``module`` (a tilt or a translation)."""
    def reason(n: str) -> str:
        axis = n[-1]
        if n in (LOCATION_ERRORS[axis][2], LOCATION_ERRORS[axis][3]):
            return f"a tilt of the {axis} axis line: {module} has exact axis directions"
        return f"a translation of the {axis} axis line {module} has no parameter for"
    return reason
