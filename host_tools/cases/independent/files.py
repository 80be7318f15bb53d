"""Files of the independent generator, written from docs/formats.md: the machine TOML,
6D laser CSVs, ballbar CSVs (``temp_c`` when a temperature is logged), ESS ``.dat``
positioning files, and the user's current model as a table blob.

The model is what a user has before the check: the machine's smooth terms fitted
by least squares (Chebyshev degree 7 over each travel, from 41 noisy points per
term, zero at the reference point) plus the squareness already known, without
the effects hidden for the case.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cases.independent.measure import CHANNELS, CircleRecord, CirclePlan, LaserPlan, LaserRecord
from cases.independent.physics import AXES, TERM_NAMES, Machine

_COL = {"linear": "linear_um", "straight_h": "straight_h_um", "straight_v": "straight_v_um",
        "pitch": "pitch_urad", "yaw": "yaw_urad", "roll": "roll_urad"}


def _v(x) -> str:
    return "[" + ", ".join(repr(round(float(a), 6)) for a in x) + "]"


def machine_toml(m: Machine, lasers: list[tuple[LaserPlan, str]],
                 circles: list[tuple[CirclePlan, str]], name: str) -> str:
    out = [f"# independent generator case {name}", "[machine]", f'name = "{name}"', ""]
    for a in AXES:
        out += [f"[axes.{a}]", f"travel_mm = {_v(m.travel[a])}", ""]
    out += ["[reference]", f"point_mm = {_v(m.reference)}", "", "[tool]",
            f"offset_mm = {_v(m.declared_tool_mm)}", ""]
    for plan, f in lasers:
        j = AXES.index(plan.axis)
        s, e = list(plan.line_mm), list(plan.line_mm)
        s[j], e[j] = float(plan.targets_mm[0]), float(plan.targets_mm[-1])
        mp = ", ".join(f'{k} = "{v}"' for k, v in (plan.map or {}).items())
        out += [f"[laser.{plan.axis}]", f'file = "{f}"', f"start_mm = {_v(s)}", f"end_mm = {_v(e)}",
                f"map = {{ {mp} }}", ""]
    for plan, f in circles:
        out += [f"[ballbar.{plan.name}]", f'file = "{f}"', f'plane = "{plan.plane}"',
                f"center_mm = {_v(plan.center_mm)}", f"radius_mm = {plan.radius_mm!r}",
                f"feed_mm_min = {plan.feed_mm_min!r}", ""]
    return "\n".join(out)


def laser_csv(rec: LaserRecord, order: list[str] | None = None) -> str:
    cols = ["run", "direction", "target_mm"] + [_COL[c] for c in CHANNELS] + ["time_s"]
    if rec.temp_c is not None:
        cols.append("temp_c")
    if order:
        cols = [c for c in order if c in cols] + [c for c in cols if c not in order]
    inv = {v: k for k, v in _COL.items()}
    lines = [",".join(cols)]
    for i in range(rec.run.size):
        cells = []
        for c in cols:
            if c == "run":
                cells.append(str(int(rec.run[i])))
            elif c == "direction":
                cells.append(str(rec.direction[i]))
            elif c == "target_mm":
                cells.append(f"{rec.target_mm[i]:.4f}")
            elif c == "time_s":
                cells.append(f"{rec.time_s[i]:.2f}")
            elif c == "temp_c":
                cells.append(f"{rec.temp_c[i]:.3f}")  # type: ignore[index]
            else:
                cells.append(f"{rec.values[inv[c]][i]:.4f}")
        lines.append(",".join(cells))
    return "\n".join(lines) + "\n"


def ballbar_csv(rec: CircleRecord) -> str:
    cols = ["direction", "angle_deg", "radial_um", "time_s"] + (["temp_c"] if rec.temp_c is not None else [])
    lines = [",".join(cols)]
    for i in range(rec.angle_deg.size):
        row = [str(rec.direction[i]), f"{rec.angle_deg[i]:.4f}", f"{rec.radial_um[i]:.4f}",
               f"{rec.time_s[i]:.4f}"]
        if rec.temp_c is not None:
            row.append(f"{rec.temp_c[i]:.3f}")
        lines.append(",".join(row))
    return "\n".join(lines) + "\n"


def ess_dat(targets: np.ndarray, fwd_um: np.ndarray, bwd_um: np.ndarray, note: str) -> str:
    """The ESS ecmc ISO 230-2 key=value file (readings in mm = target + deviation)."""
    C, T = fwd_um.shape
    out = [f"TEST_DATA=# {note}", "UNIT=mm", f"CYCLES={C}", f"POSITIONS={T}", "DEC=5"]
    for i in range(T):
        out.append(f"TGT_DATA[{i + 1}]={targets[i]:.6g}")
    for c in range(C):
        for i in range(T):
            out.append(f"REF_DATA_FWD[{i + 1},{c + 1}]={targets[i] + fwd_um[c, i] * 1e-3:.12f}")
        for i in range(T):
            out.append(f"REF_DATA_BWD[{i + 1},{c + 1}]={targets[i] + bwd_um[c, i] * 1e-3:.12f}")
    return "\n".join(out) + "\n"


def fit_model(m: Machine, rng: np.random.Generator, known_squareness: tuple[float, float, float],
              noise_um: float = 0.02) -> "object":
    """The current model (abbe Table): each smooth term least-squares fitted with a
    degree-7 Chebyshev series over the travel from 41 noisy samples, zero at the
    reference point; squareness as known; declared tool offset."""
    from abbe.model.table import AxisTable, Table
    axes = {}
    for j, a in enumerate(AXES):
        lo, hi = m.travel[a]
        g = np.linspace(lo, hi, 41)
        u = (2 * g - lo - hi) / (hi - lo)
        V = np.polynomial.chebyshev.chebvander(u, 7)
        ur = (2 * m.reference[j] - lo - hi) / (hi - lo)
        vr = np.polynomial.chebyshev.chebvander(np.array([ur]), 7)[0]
        coef = {}
        for t in TERM_NAMES:
            sd = noise_um if t[0] == "d" else 3 * noise_um
            y = m.terms[(a, t)](g) + rng.normal(0.0, sd, g.size)
            c, *_ = np.linalg.lstsq(V, y, rcond=None)
            c[0] -= float(vr @ c)
            coef[t] = c
        axes[a] = AxisTable(travel_mm=(float(lo), float(hi)), trend_degree=7, coef=coef)
    return Table(axes=axes, reference_mm=tuple(float(v) for v in m.reference),
                 tool_offset_mm=tuple(float(v) for v in m.declared_tool_mm),
                 squareness_urad=tuple(float(v) for v in known_squareness))


def write_model(path: Path, table: object) -> None:
    from abbe.formats.blob import write_blob
    path.write_bytes(write_blob(table))  # type: ignore[arg-type]
