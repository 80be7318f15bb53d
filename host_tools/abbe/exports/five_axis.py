"""Five-axis exports: the model, the poses where the residual is taken, the residual.

A five-axis target (``FIVE_AXIS_TARGETS``) writes a rotary geometry (pivots,
offsets, angular zeros) into a controller's kinematics. Its :class:`FiveExport`
carries the controller's own inverse kinematics with the written (quantised)
values: ``joints(w, theta) -> (q, t)``, the linear joint positions q (mm) and the
rotary joint angles t (deg, in the model's convention: the table turns by
t + E0) the controller commands for the programmed workpiece point w (mm) and
rotary axis positions theta (deg) under tool-centre-point control.

The residual is the exact error of the model (:mod:`abbe.model.five_axis`,
homogeneous transforms) at those joints: the actual tool tip (q plus the linear
axes' errors) minus where the workpiece point w actually is (the actual table
transform at t), um in machine coordinates; and the orientation error of the
tool relative to the workpiece, urad. The uncompensated machine commands the
nominal joints (``nominal_joints``, t = theta). Nothing is removed: the model is
referred to the workpiece frame at A = C = 0 (the C axis' zero offset moves the
workpiece there, so it counts).

Poses:

* work volume: every linear-axis grid point of the machine file's travel
  (``volume_points`` per axis) at every rotary grid position (``tilt_points``
  over the tilt travel x ``c_points`` over one turn of C, inside its travel); the
  programmed point is the one that the nominal machine reaches there;
* tool-centre-point path: a fixed workpiece point (``tcp_point``, relative to
  the C axis centre) while C turns one turn with the tilt swinging out to
  ``+tcp_tilt_deg`` and back, then C turns back with the tilt swinging to
  ``-tcp_tilt_deg`` (both clipped to the tilt travel), 1 degree steps of C.
"""

from __future__ import annotations

import json
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from abbe.errors import AbbeInputError
from abbe.exports.target import Option
from abbe.model.five_axis import (
    AXIS_DIRECTION,
    LOCATION_ERRORS,
    MOTION_COMPONENTS,
    FiveAxisErrors,
    TrunnionGeometry,
    linear_axis_errors,
    motion_name,
    nominal_joints,
    rotvec,
    small_rotation,
    table_transform,
)
from abbe.model.table import AXES

FORMAT = "abbe-export-residual-five-axis"
#: Geometry of the blob and the machine file must agree to this, mm (the blob holds nm).
GEOMETRY_TOLERANCE_MM = 1e-6
#: Parts smaller than this everywhere are not listed as not held, um.
FLOOR_UM = 1e-4

#: The pose options every five-axis target has (target modules add their own).
POSE_OPTIONS: dict[str, Option] = {
    "volume_points": Option("int", 5, "linear-axis grid points per axis of the work volume",
                            lo=2, hi=21),
    "tilt_points": Option("int", 9, "tilt axis positions over its travel in the work volume",
                          lo=2, hi=73),
    "c_points": Option("int", 12, "C positions over one turn in the work volume", lo=2, hi=360),
    "tcp_point": Option("axes", {"X": 100.0, "Y": 0.0, "Z": 50.0},
                        "tool-centre-point path: the workpiece point relative to the C axis "
                        "centre, mm", item="float", lo=-2000.0, hi=2000.0),
    "tcp_tilt_deg": Option("float", 90.0, "tool-centre-point path: largest tilt each way, deg",
                           lo=0.0, hi=180.0),
}


@dataclass
class FiveContext:
    """Inputs of a five-axis build.

    geometry: the nominal geometry (machine file: kind, pivots, travel, tool
    length); errors: the model's errors (the blob's values); travel_mm: linear
    axis travel (machine file); not_observable: what the fit could not observe
    (written as 0 in the blob), named from the fit's five_axis.json beside it.
    """

    geometry: TrunnionGeometry
    errors: FiveAxisErrors
    travel_mm: dict[str, tuple[float, float]]
    options: dict[str, Any]
    model_source: str = ""
    machine_source: str = ""
    not_observable: list[str] = field(default_factory=list)


@dataclass
class FiveExport:
    """The output of a five-axis target build (module docstring for ``joints``)."""

    target: str
    files: dict[str, bytes]
    joints: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]
    expressed: list[dict[str, Any]]
    not_held: list[dict[str, Any]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    assumptions: list[str] = field(default_factory=list)
    sources: list[str] = field(default_factory=list)


# ------------------------------------------------------------------------ loading


def load_five_context(model: Path, machine, options: dict[str, Any]) -> FiveContext:
    """The context of a five-axis export: ``model`` a format 1.2 table (``abbe fit``'s
    model_five.bin), ``machine`` the parsed machine file with its ``[rotary]`` section.
    AbbeInputError when either is missing or wrong, or when they disagree."""
    from abbe.formats.five_axis_blob import read_five_blob
    from abbe.formats.text import read_bytes
    from abbe.model.table import TableError

    name = str(model)
    if machine is None:
        raise AbbeInputError("a five-axis target needs --machine: the machine file with the "
                             "[rotary] section the model was fitted with (rotary travel, tool "
                             "length, linear travel)", field="--machine")
    spec = machine.five_axis
    if spec is None:
        raise AbbeInputError("the machine file has no [rotary] section: a five-axis target "
                             "needs the trunnion's nominal geometry", file=str(machine.path),
                             field="rotary")
    data = read_bytes(model, what="model", max_bytes=1 << 20)
    try:
        tab = read_five_blob(data, source=name)
    except TableError as exc:
        raise AbbeInputError(f"{exc.message} (a five-axis target reads a format 1.2 table with "
                             "a rotary section: abbe fit's model_five.bin)", file=name,
                             field=exc.field or "model") from None
    g = spec.geometry
    if tab.kind != g.kind:
        raise AbbeInputError(f"the model is {tab.kind}, the machine file's [rotary] kinematics "
                             f"is {g.kind}", file=str(machine.path), field="rotary.kinematics")
    for what, a, b in (("rotation point", tab.rot_point_mm, g.rot_point_mm),
                       ("tilt axis offset", tab.offset_mm, g.offset_mm)):
        if max(abs(x - y) for x, y in zip(a, b)) > GEOMETRY_TOLERANCE_MM:
            raise AbbeInputError(f"the model's nominal {what} {list(a)} mm is not the machine "
                                 f"file's {list(b)} mm (a model of another machine?)",
                                 file=str(machine.path), field="rotary")
    travel = {}
    for a in AXES:
        if a not in machine.axes:
            raise AbbeInputError(f"the machine file has no [axes.{a}]: the work volume needs all "
                                 "three travels", file=str(machine.path), field=f"axes.{a}")
        travel[a] = tuple(float(v) for v in machine.axes[a].travel_mm)
    return FiveContext(geometry=g, errors=tab.errors, travel_mm=travel, options=options,
                       model_source=name, machine_source=Path(machine.path).name,
                       not_observable=_not_observable(Path(model), data))


def _not_observable(model: Path, data: bytes) -> list[str]:
    """The names the fit wrote as 0 (not observable), from five_axis.json beside the model
    when its ``blob.crc32`` is this model's; else [] (nothing is known)."""
    side = model.parent / "five_axis.json"
    try:
        doc = json.loads(side.read_text(encoding="utf-8"))
        blob = doc["blob"]
        if blob["crc32"] != f"0x{zlib.crc32(data[:-4]) & 0xFFFFFFFF:08X}":
            return []
        return [str(v) for v in blob["written_as_zero_not_observable"]]
    except (OSError, ValueError, KeyError, TypeError):
        return []


# ----------------------------------------------------------------- the geometry


def identified_lines(ctx: FiveContext) -> tuple[np.ndarray, np.ndarray]:
    """(C axis centre, a point of the tilt axis line), mm, machine coordinates at zero
    angles, with the location errors a translation holds: the C line at rot_point +
    (EX0C, EY0C, 0), the tilt line at rot_point + offset + (0, EY0A, EZ0A) (B:
    (EX0B, 0, EZ0B)). The model moves each line rigidly about its nominal pivot, so
    these are the actual lines' points (their tilts aside)."""
    g, loc = ctx.geometry, ctx.errors.location
    c = np.asarray(g.rot_point_mm, dtype=np.float64) + 1e-3 * np.array(
        [loc.get("EX0C", 0.0), loc.get("EY0C", 0.0), 0.0])
    t = np.asarray(g.pivot(g.tilt), dtype=np.float64).copy()
    n1, n2 = LOCATION_ERRORS[g.tilt][:2]
    i1, i2 = [k for k in range(3) if k != "ABC".index(g.tilt)]
    t[i1] += 1e-3 * loc.get(n1, 0.0)
    t[i2] += 1e-3 * loc.get(n2, 0.0)
    return c, t


def identified_direction(ctx: FiveContext, axis: str) -> np.ndarray:
    """Unit direction of ``axis``' actual line at zero angles (machine coordinates): the
    nominal direction turned by its two tilts (the model's Rx Ry Rz of the location
    errors, :func:`abbe.model.five_axis.axis_transform`)."""
    loc = ctx.errors.location
    names = LOCATION_ERRORS[axis]
    k = "XYZ".index({"A": "X", "B": "Y", "C": "Z"}[axis])
    phi = np.zeros(3)
    phi[[i for i in range(3) if i != k]] = [loc.get(names[2], 0.0), loc.get(names[3], 0.0)]
    v = small_rotation(phi * 1e-6)[0] @ np.asarray(AXIS_DIRECTION[axis], dtype=np.float64)
    return v / np.linalg.norm(v)


def axis_rotation(v: np.ndarray, angles_deg: np.ndarray) -> np.ndarray:
    """(N, 3, 3) right-handed rotations by ``angles_deg`` about the unit vector v."""
    a = np.deg2rad(np.asarray(angles_deg, dtype=np.float64).reshape(-1))
    K = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    s, c = np.sin(a)[:, None, None], np.cos(a)[:, None, None]
    return np.eye(3)[None] + s * K[None] + (1.0 - c) * (K @ K)[None]


def unobservable_notes(ctx: FiveContext, held: set[str]) -> list[str]:
    """The note naming the held items the fit could not observe (written at nominal)."""
    unobs = [n for n in ctx.not_observable if n in held]
    return (["written at their nominal value (not observable by the fit): " + ", ".join(unobs)]
            if unobs else [])


def zero_offsets_deg(ctx: FiveContext) -> dict[str, float]:
    """The angular zero offsets (E{A,B}0{A,B}, EC0C) of the rotary axes, deg: the table
    turns by joint + E0."""
    g, loc = ctx.geometry, ctx.errors.location
    return {a: float(np.degrees(loc.get(f"E{a}0{a}", 0.0) * 1e-6)) for a in g.rotaries}


# ------------------------------------------------------------------------- poses


def volume_poses(ctx: FiveContext) -> tuple[np.ndarray, np.ndarray]:
    """(workpiece points (N, 3) mm, rotary positions (N, 2) deg) of the work volume."""
    o = ctx.options
    g = ctx.geometry
    tilt, table = g.rotaries
    s = [np.linspace(*ctx.travel_mm[a], o["volume_points"]) for a in AXES]
    q = np.stack(np.meshgrid(*s, indexing="ij"), -1).reshape(-1, 3)
    ta = np.linspace(*g.travel_deg[tilt], o["tilt_points"])
    lo, hi = g.travel_deg[table]
    tc = np.clip(np.arange(o["c_points"]) * 360.0 / o["c_points"], lo, hi)
    A, C = np.meshgrid(ta, np.unique(tc), indexing="ij")
    ang = np.column_stack([A.ravel(), C.ravel()])
    Q = np.repeat(q, len(ang), axis=0)
    ANG = np.tile(ang, (len(q), 1))
    T = np.linalg.inv(table_transform(g, None, ANG))
    W = np.einsum("nij,nj->ni", T[:, :3, :3], Q) + T[:, :3, 3]
    return W, ANG


def tcp_path(ctx: FiveContext) -> tuple[np.ndarray, np.ndarray]:
    """(workpiece points (N, 3) mm, all the same; rotary positions (N, 2) deg) of the
    tool-centre-point path (module docstring)."""
    o = ctx.options
    g = ctx.geometry
    tilt, table = g.rotaries
    lo, hi = g.travel_deg[tilt]
    s = np.linspace(0.0, 1.0, 361)
    bump = np.sin(np.pi * s)
    a_up = np.clip(o["tcp_tilt_deg"] * bump, lo, hi)
    a_dn = np.clip(-o["tcp_tilt_deg"] * bump, lo, hi)
    c = np.clip(360.0 * s, *g.travel_deg[table])
    ang = np.concatenate([np.column_stack([a_up, c]), np.column_stack([a_dn, c[::-1]])[1:]])
    p = o["tcp_point"]
    w0 = np.asarray(g.rot_point_mm) + np.array([float(p[a]) for a in AXES])
    return np.tile(w0, (len(ang), 1)), ang


# ---------------------------------------------------------------------- residual


def pose_error(geom: TrunnionGeometry, errs: FiveAxisErrors, work_mm: np.ndarray,
               angles_deg: np.ndarray, joints_mm: np.ndarray,
               joint_angles_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact error at commanded joints: tool tip minus the actual workpiece point (N, 3)
    um, and the tool's orientation relative to the workpiece against the programmed one
    (N, 3) urad (module docstring)."""
    Ta = table_transform(geom, errs, joint_angles_deg)
    Rn = table_transform(geom, None, angles_deg)[:, :3, :3]
    dl, rl = linear_axis_errors(geom, errs, joints_mm)
    w_act = np.einsum("nij,nj->ni", Ta[:, :3, :3], work_mm) + Ta[:, :3, 3]
    pos = (joints_mm + dl * 1e-3 - w_act) * 1e3
    R = small_rotation(rl * 1e-6) @ Rn @ np.transpose(Ta[:, :3, :3], (0, 2, 1))
    return pos, rotvec(R) * 1e6


def pose_stats(pos: np.ndarray, rot: np.ndarray) -> dict[str, Any]:
    """Max and RMS of the tip's position error per axis and in norm (um) and of the
    orientation error (urad) over a set of poses."""
    out: dict[str, Any] = {}
    for k, a in enumerate(AXES):
        v = pos[:, k]
        out[f"d{a}"] = {"max_um": round(float(np.max(np.abs(v))), 4),
                        "rms_um": round(float(np.sqrt(np.mean(v ** 2))), 4)}
    n = np.linalg.norm(pos, axis=1)
    out["norm"] = {"max_um": round(float(np.max(n)), 4),
                   "rms_um": round(float(np.sqrt(np.mean(n ** 2))), 4)}
    r = np.linalg.norm(rot, axis=1)
    out["orientation"] = {"max_urad": round(float(np.max(r)), 4),
                          "rms_urad": round(float(np.sqrt(np.mean(r ** 2))), 4)}
    return out


def _both(ctx: FiveContext, exp: FiveExport, W: np.ndarray, ANG: np.ndarray) -> dict[str, Any]:
    g, e = ctx.geometry, ctx.errors
    q0 = nominal_joints(g, W, ANG)
    q, t = exp.joints(W, ANG)
    return {"residual": pose_stats(*pose_error(g, e, W, ANG, q, t)),
            "uncompensated": pose_stats(*pose_error(g, e, W, ANG, q0, ANG))}


def _only(errs: FiveAxisErrors, what: tuple[str, Any]) -> FiveAxisErrors:
    """A copy of ``errs`` holding only one item."""
    kind, key = what
    out = FiveAxisErrors()
    if kind == "location":
        out.location = {key: errs.location[key]}
    elif kind == "motion":
        out.motions = {key: errs.motions[key]}
    elif kind == "squareness":
        sq = [0.0, 0.0, 0.0]
        sq[key] = errs.squareness[key]
        out.squareness = tuple(sq)  # type: ignore[assignment]
    else:
        out.linear = errs.linear
    return out


def model_items(ctx: FiveContext) -> list[tuple[str, str, tuple[str, Any]]]:
    """(label, kind, selector) of every nonzero item of the model."""
    from abbe.model.five_axis import SQUARENESS

    e = ctx.errors
    out = []
    for axis in ctx.geometry.rotaries:
        for n in LOCATION_ERRORS[axis]:
            if e.location.get(n, 0.0) != 0.0:
                out.append((n, "location", ("location", n)))
        for c in MOTION_COMPONENTS:
            v = e.motions.get((axis, c))
            if v is not None and np.any(np.asarray(v) != 0.0):
                out.append((motion_name(axis, c), "error motion", ("motion", (axis, c))))
    for i, n in enumerate(SQUARENESS):
        if e.squareness[i] != 0.0:
            out.append((n, "squareness", ("squareness", i)))
    if e.linear is not None:
        out.append(("linear axes (3-axis table, Eq. 3)", "linear", ("linear", None)))
    return out


def not_held(ctx: FiveContext, cannot: Callable[[str, str], str | None]) -> list[dict[str, Any]]:
    """The model's items the target cannot hold, each with the size of its own exact error
    (the machine otherwise nominal) over the work volume and the tool-centre-point path.
    ``cannot(label, kind)`` gives the reason, or None when the item is held."""
    g = ctx.geometry
    poses = {"volume": volume_poses(ctx), "tcp_path": tcp_path(ctx)}
    joints = {k: nominal_joints(g, W, A) for k, (W, A) in poses.items()}
    out = []
    for label, kind, sel in model_items(ctx):
        reason = cannot(label, kind)
        if reason is None:
            continue
        only = _only(ctx.errors, sel)
        d: dict[str, Any] = {"item": label, "kind": kind, "reason": reason}
        big = 0.0
        for k, (W, A) in poses.items():
            pos, rot = pose_error(g, only, W, A, joints[k], A)
            n = np.linalg.norm(pos, axis=1)
            r = np.linalg.norm(rot, axis=1)
            d[k] = {"max_um": round(float(np.max(n)), 4),
                    "rms_um": round(float(np.sqrt(np.mean(n ** 2))), 4),
                    "orientation_max_urad": round(float(np.max(r)), 4)}
            big = max(big, float(np.max(n)), float(np.max(r)))
        if big >= FLOOR_UM:
            out.append(d)
    return out


def evaluate(ctx: FiveContext, exp: FiveExport) -> dict[str, Any]:
    """The residual report of one five-axis export, as written to residual.json."""
    g = ctx.geometry
    o = ctx.options
    W, A = volume_poses(ctx)
    vol = {"linear_travel_mm": {a: list(ctx.travel_mm[a]) for a in AXES},
           "rotary_travel_deg": {a: list(g.travel_deg[a]) for a in g.rotaries},
           "points_per_linear_axis": o["volume_points"], "tilt_points": o["tilt_points"],
           "c_points": o["c_points"], "poses": int(len(W)), **_both(ctx, exp, W, A)}
    Wp, Ap = tcp_path(ctx)
    path = {"workpiece_point_mm": [round(float(v), 6) for v in Wp[0]],
            "tilt_deg": [round(float(Ap[:, 0].min()), 6), round(float(Ap[:, 0].max()), 6)],
            "runs": (f"C 0 -> 360 deg with {g.tilt} swinging to +{o['tcp_tilt_deg']:g} deg and "
                     f"back, then C 360 -> 0 with {g.tilt} swinging to -{o['tcp_tilt_deg']:g} "
                     "(clipped to the travel), 1 deg steps of C"),
            "poses": int(len(Wp)), **_both(ctx, exp, Wp, Ap)}
    return {
        "format": FORMAT, "version": 1, "target": exp.target, "model": ctx.model_source,
        "machine": ctx.machine_source, "kinematics": g.kind,
        "convention": ("exact model (abbe.model.five_axis): tool tip minus the actual workpiece "
                       "point at the joints the controller commands, machine coordinates, um; "
                       "orientation of the tool relative to the workpiece, urad; nothing removed"),
        "volume": vol, "tcp_path": path,
        "expressed": exp.expressed, "not_held": exp.not_held,
        "not_observable": {"items": ctx.not_observable,
                           "note": ("written as 0 by abbe fit (not observable with the "
                                    "measurement plan): neither corrected nor sized here")
                           if ctx.not_observable else
                           "no five_axis.json of this model beside it: unknown"},
        "notes": exp.notes, "assumptions": exp.assumptions, "sources": exp.sources,
        "files": sorted(exp.files),
    }


def summary(report: dict[str, Any], holder: str = "this target",
            unobserved: str = "written as 0 by the fit") -> str:
    """The lines ``abbe export`` prints for a five-axis target (``holder``: what does
    not hold the listed errors; ``unobserved``: what the table holds for the errors the
    plan cannot see)."""
    lines = [f"abbe export {report['target']}: wrote {', '.join(report['files'])}"]
    for key, what in (("volume", "work volume"), ("tcp_path", "tool-centre-point path")):
        r, u = report[key]["residual"], report[key]["uncompensated"]
        lines.append(f"  {what} ({report[key]['poses']} poses), |E| max / RMS um: residual "
                     f"{r['norm']['max_um']:.3f} / {r['norm']['rms_um']:.3f}, uncompensated "
                     f"{u['norm']['max_um']:.3f} / {u['norm']['rms_um']:.3f}")
    if report["not_held"]:
        lines.append(f"  not held by {holder} (own size, volume / TCP path, max um):")
        for d in sorted(report["not_held"], key=lambda d: -d["volume"]["max_um"]):
            lines.append(f"    {d['item']}: {d['volume']['max_um']:.3f} / "
                         f"{d['tcp_path']['max_um']:.3f} ({d['reason']})")
    if report["not_observable"]["items"]:
        lines.append(f"  not observable ({unobserved}): "
                     + ", ".join(report["not_observable"]["items"]))
    return "\n".join(lines)
