"""The ground truth of a virtual machine: its 18 error functions, squareness and effects.

The simulator's machine (:mod:`abbe.sim.virtual_machine`) is defined by a :class:`MachineTruth`.
Every one of the 18 position-dependent errors (axis j, term dx/dy/dz/ex/ey/ez)
is held **exactly in the library's basis** (Chebyshev trend + two Fourier blocks
per axis, ``abbe.model.table.basis_matrix``), built from physical shape parameters:

* ``slope`` (um/m or urad/m): linear trend (positioning scale error, tilt);
* ``bow`` (um / urad): parabola ``bow * (1 - u^2)``, the value at mid-travel
  relative to the chord through the ends (sag of a guideway);
* ``cantilever`` (um / urad): cubic ``c * s^2 (3 - s) / 2``, s = 0 at the
  fixed end and 1 at the free end (travel max, or min with ``cantilever_end``);
* ``wave`` (um / urad per harmonic) with ``wave_phase_deg``: the long wave of
  the axis (Fourier block 0, period ``wave_period_mm``, phase 0 at travel min),
  the paper's Fig. 4 "wave-type" positioning error;
* the cyclic (screw) error of :class:`Effects` on the own positioning term
  (Fourier block 1, period = screw lead).

Conventions (the same as :mod:`abbe.model.reference`, so a :func:`truth_table` is
directly comparable):

* every term is **relative to the reference point**: its value there is 0;
* straightness terms (the two linear terms of an axis other than its own
  positioning term) have **zero least-squares slope over the travel**: the
  slope of a straightness trace is indistinguishable from a squareness or a
  set-up misalignment, so the truth puts all of it into the squareness
  S_xy, S_xz, S_yz (ISO 230-1 defines squareness between the least-squares
  reference lines);
* units: positions mm, linear terms um, angular terms urad.

Lost motion ``b`` (backlash) makes the tool lag behind the command relative to
the workpiece by ``b/2`` in the direction of motion: error (dX, dY, dZ)
component ``-s_j b_j / 2``. Because X and Y enter Eq. 3 with a minus sign
(``dX = -d_x(x) ...``) and Z with a plus, the own positioning term gets
``-sigma_j s_j b_j / 2`` with ``sigma = (-1, -1, +1)``; the ISO 230-2 reversal of
that term (and the table's ``backlash_um``) is ``B_j = -sigma_j b_j``
(+b for X and Y, -b for Z).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from abbe.errors import AbbeInputError
from abbe.model.table import (
    AXES,
    LINEAR_TERMS,
    OWN_SIGN,
    OWN_TERM,
    TERMS,
    AxisTable,
    FourierBlock,
    Table,
    basis_matrix,
)

TRUTH_FORMAT = "abbe-truth-1"
#: Shape keys of a term, by kind; values are unit-suffixed in the spec and JSON.
SHAPE_KEYS_LINEAR: tuple[str, ...] = ("slope_um_per_m", "bow_um", "cantilever_um", "wave_um",
                                      "wave_phase_deg", "cantilever_end")
SHAPE_KEYS_ANGULAR: tuple[str, ...] = ("slope_urad_per_m", "bow_urad", "cantilever_urad",
                                       "wave_urad", "wave_phase_deg", "cantilever_end")


def is_straightness(axis: str, term: str) -> bool:
    """True for the two straightness terms of ``axis`` (linear, not its own)."""
    return term in LINEAR_TERMS and term != OWN_TERM[axis]


@dataclass
class Effects:
    """Effects beyond the 18 smooth geometric terms (each off when its magnitude is 0).

    squareness_urad: S_xy, S_xz, S_yz (urad), entering as in notes.md §1.
    backlash_um: lost motion b per axis (um, >= 0); backlash_takeup_mm: distance
        over which a reversal is taken up (mm, > 0), the direction state ramps
        linearly from -1 to +1 over it (as the library's compensator does).
        backlash_variation_um: the lost motion varies along the travel,
        b(p) = b + c1 T1(u) + c2 T2(u) + c3 T3(u) (u the normalised travel).
    cyclic_um, cyclic_period_mm, cyclic_phase_deg: screw (cyclic) error of each
        axis' own positioning term, amplitude um, period mm, phase deg (phase 0 at
        travel min).
    thermal_*: machine temperature T(t) = start_c + rise_k (1 - exp(-t / tau_s)),
        t campaign time in s; own positioning term gains
        expansion_ppm_per_k * dT * (p - ref) * 1e-3 + offset_um_per_k * dT (um),
        dT = T - start_c (the library's thermal model with T_ref = start_c).
    servo_lag_ms: position-loop lag per axis (ms); unequal lags distort dynamic
        paths (direction dependent).
    scale_change_ppm: extra positioning scale (ppm, own term gains
        ppm * (p - ref) * 1e-3 um) from campaign time scale_change_from_s on.
    tool_offset_mm: true tool-tip offset minus the one declared in the machine
        file (mm): an unmodelled offset, used by the ballbar tests.
    """

    squareness_urad: tuple[float, float, float] = (0.0, 0.0, 0.0)
    backlash_um: tuple[float, float, float] = (0.0, 0.0, 0.0)
    backlash_takeup_mm: tuple[float, float, float] = (0.1, 0.1, 0.1)
    #: position-dependent lost motion: Chebyshev T1, T2, T3 coefficients (um) of the lost
    #: motion over each axis' travel, per axis (X1, X2, X3, Y1, ..., Z3)
    backlash_variation_um: tuple[float, ...] = (0.0,) * 9
    cyclic_um: tuple[float, float, float] = (0.0, 0.0, 0.0)
    cyclic_period_mm: tuple[float, float, float] = (10.0, 10.0, 10.0)
    cyclic_phase_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    thermal_start_c: float = 20.0
    thermal_rise_k: float = 0.0
    thermal_time_constant_s: float = 3600.0
    thermal_expansion_ppm_per_k: tuple[float, float, float] = (0.0, 0.0, 0.0)
    thermal_offset_um_per_k: tuple[float, float, float] = (0.0, 0.0, 0.0)
    servo_lag_ms: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scale_change_ppm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    scale_change_from_s: float = 0.0
    tool_offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def thermal_on(self) -> bool:
        """True if the thermal drift changes anything."""
        return self.thermal_rise_k != 0.0 and (
            any(v != 0 for v in self.thermal_expansion_ppm_per_k)
            or any(v != 0 for v in self.thermal_offset_um_per_k))

    def backlash_on(self) -> bool:
        return any(v != 0 for v in self.backlash_um)

    def lost_motion_um(self, j: int, pos_mm: np.ndarray, travel_mm: tuple[float, float]) -> np.ndarray:
        """Lost motion (um) of axis j at axis positions (mm), with its variation."""
        c = np.asarray(self.backlash_variation_um[3 * j:3 * j + 3], dtype=np.float64)
        b = float(self.backlash_um[j])
        if not np.any(c):
            return np.full(np.shape(pos_mm), b)
        lo, hi = travel_mm
        u = (2.0 * np.clip(pos_mm, lo, hi) - lo - hi) / (hi - lo)
        return b + np.polynomial.chebyshev.chebval(u, np.concatenate([[0.0], c]))

    def reversal_um(self) -> tuple[float, float, float]:
        """ISO 230-2 reversal B of each own positioning term, um (-sigma_j b_j)."""
        return tuple(float(-OWN_SIGN[a] * self.backlash_um[j])  # type: ignore[return-value]
                     for j, a in enumerate(AXES))


@dataclass
class AxisTruth:
    """True error functions of one axis, exactly in the library basis.

    travel_mm: (min, max) mm. trend_degree: Chebyshev degree (>= 1).
    blocks: Fourier block 0 (long wave) and 1 (cyclic screw error) or None.
    coef[term]: basis coefficients, um (linear) / urad (angular).
    shapes[term]: the shape parameters the coefficients were built from.
    """

    name: str
    travel_mm: tuple[float, float]
    trend_degree: int
    blocks: tuple[FourierBlock | None, FourierBlock | None]
    coef: dict[str, np.ndarray]
    shapes: dict[str, dict[str, Any]] = field(default_factory=dict)
    wave_period_mm: float | None = None

    def axis_table(self) -> AxisTable:
        """The library AxisTable with these coefficients (no backlash/thermal)."""
        return AxisTable(travel_mm=self.travel_mm, trend_degree=self.trend_degree,
                         blocks=self.blocks,
                         coef={t: np.array(self.coef[t], dtype=np.float64) for t in TERMS})

    def values(self, term: str, pos_mm: np.ndarray) -> np.ndarray:
        """True value of ``term`` at axis positions ``pos_mm`` (clamped to the travel):
        um (linear) / urad (angular)."""
        return basis_matrix(self.axis_table(), pos_mm) @ self.coef[term]


@dataclass
class MachineTruth:
    """The complete ground truth of a virtual 3-axis machine.

    travel/reference/tool offset in mm; tool_offset_mm is the offset declared in
    the machine file (the true one adds ``effects.tool_offset_mm``).
    """

    name: str
    seed: int
    reference_mm: tuple[float, float, float]
    tool_offset_mm: tuple[float, float, float]
    axes: dict[str, AxisTruth]
    effects: Effects = field(default_factory=Effects)

    def term_values(self, axis: str, term: str, pos_mm: np.ndarray) -> np.ndarray:
        """True geometric term (without backlash/thermal/scale change/repeatability), um/urad."""
        return self.axes[axis].values(term, pos_mm)

    def temperature_c(self, time_s: np.ndarray) -> np.ndarray:
        """Machine temperature at campaign time ``time_s`` (s), deg C."""
        e = self.effects
        t = np.asarray(time_s, dtype=np.float64)
        return e.thermal_start_c + e.thermal_rise_k * (-np.expm1(-t / e.thermal_time_constant_s))

    def true_tool_offset_mm(self) -> tuple[float, float, float]:
        """Declared tool offset + the unmodelled one, mm."""
        return tuple(float(a + b) for a, b in  # type: ignore[return-value]
                     zip(self.tool_offset_mm, self.effects.tool_offset_mm))
_GL_U, _GL_W = np.polynomial.legendre.leggauss(96)


def _shape_poly_u(shape: dict[str, Any], kind: str, travel: tuple[float, float],
                  ref: float) -> np.ndarray:
    """Power-series coefficients in u of the polynomial part of a shape."""
    lo, hi = travel
    mid, half = 0.5 * (lo + hi), 0.5 * (hi - lo)
    unit = "um" if kind == "linear" else "urad"
    c = np.zeros(4)
    slope = float(shape.get(f"slope_{unit}_per_m", 0.0)) * 1e-3  # per mm
    c[0] += slope * (mid - ref)
    c[1] += slope * half
    bow = float(shape.get(f"bow_{unit}", 0.0))
    c[0] += bow
    c[2] -= bow
    cant = float(shape.get(f"cantilever_{unit}", 0.0))
    if cant:
        # s = (1 + u)/2 (free end at max) or (1 - u)/2 (free end at min); w = s^2 (3 - s) / 2
        sgn = 1.0 if shape.get("cantilever_end", "max") == "max" else -1.0
        s = np.polynomial.Polynomial([0.5, 0.5 * sgn])
        w = s * s * (3.0 - s) / 2.0
        c[: len(w.coef)] += cant * w.coef
    return c


def _wave_coef(shape: dict[str, Any], kind: str, harmonics: int) -> np.ndarray:
    """sin/cos coefficients (block 0 row order) of the wave part of a shape."""
    unit = "um" if kind == "linear" else "urad"
    amps = list(shape.get(f"wave_{unit}", []))
    phases = list(shape.get("wave_phase_deg", [0.0] * len(amps)))
    out = np.zeros(2 * harmonics)
    for n, (a, ph) in enumerate(zip(amps, phases)):
        # a sin(n phi + ph) = a cos(ph) sin(n phi) + a sin(ph) cos(n phi)
        out[2 * n] = a * math.cos(math.radians(ph))
        out[2 * n + 1] = a * math.sin(math.radians(ph))
    return out


def build_axis(name: str, travel_mm: tuple[float, float], ref_mm: float,
               shapes: dict[str, dict[str, Any]], wave_period_mm: float | None,
               cyclic_um: float = 0.0, cyclic_period_mm: float = 10.0,
               cyclic_phase_deg: float = 0.0) -> AxisTruth:
    """Build the exact basis coefficients of one axis from shape parameters.

    ``shapes[term]`` holds the unit-suffixed shape keys (see module doc);
    missing terms are zero. Straightness terms lose their least-squares line over
    the travel; every term is then made 0 at ``ref_mm``.
    """
    lo, hi = float(travel_mm[0]), float(travel_mm[1])
    kinds = {t: ("linear" if t in LINEAR_TERMS else "angular") for t in TERMS}
    polys = {t: _shape_poly_u(shapes.get(t, {}), kinds[t], (lo, hi), ref_mm) for t in TERMS}
    degree = 1
    for t in TERMS:
        nz = np.nonzero(np.abs(polys[t]) > 0)[0]
        if nz.size:
            degree = max(degree, int(nz[-1]))
    harm = 0
    for t in TERMS:
        unit = "um" if kinds[t] == "linear" else "urad"
        harm = max(harm, len(shapes.get(t, {}).get(f"wave_{unit}", [])))
    block0 = None
    if harm:
        period = float(wave_period_mm if wave_period_mm else hi - lo)
        block0 = FourierBlock(period_mm=period, origin_mm=lo, harmonics=harm)
    block1 = None
    if cyclic_um:
        block1 = FourierBlock(period_mm=float(cyclic_period_mm), origin_mm=lo, harmonics=1)
    ax = AxisTruth(name=name, travel_mm=(lo, hi), trend_degree=degree, blocks=(block0, block1),
                   coef={}, shapes={t: dict(shapes.get(t, {})) for t in TERMS},
                   wave_period_mm=None if block0 is None else block0.period_mm)
    n_trend = degree + 1
    for t in TERMS:
        rows = [np.polynomial.chebyshev.poly2cheb(polys[t])[:n_trend]]
        rows[0] = np.pad(rows[0], (0, n_trend - rows[0].size))
        if block0 is not None:
            rows.append(_wave_coef(shapes.get(t, {}), kinds[t], harm))
        if block1 is not None:
            if t == OWN_TERM[name]:
                ph = math.radians(cyclic_phase_deg)
                rows.append(np.array([cyclic_um * math.cos(ph), cyclic_um * math.sin(ph)]))
            else:
                rows.append(np.zeros(2))
        ax.coef[t] = np.concatenate(rows).astype(np.float64)
    # Straightness: remove the continuous least-squares line over the travel
    # (Legendre P0, P1 projections by Gauss-Legendre quadrature; T0 = 1, T1 = u).
    p_gl = 0.5 * (lo + hi) + 0.5 * (hi - lo) * _GL_U
    for t in TERMS:
        if is_straightness(name, t):
            f = ax.values(t, p_gl)
            a0 = 0.5 * float(np.sum(_GL_W * f))
            a1 = 1.5 * float(np.sum(_GL_W * f * _GL_U))
            ax.coef[t][0] -= a0
            ax.coef[t][1] -= a1
    # Relative to the reference point.
    for t in TERMS:
        ax.coef[t][0] -= float(ax.values(t, np.array([ref_mm]))[0])
    return ax
TABLE_PARTS: tuple[str, ...] = ("squareness", "cyclic", "backlash", "thermal", "tool_offset")


def truth_table(truth: MachineTruth, include: tuple[str, ...] | set[str] = TABLE_PARTS) -> Table:
    """The true machine as a library :class:`abbe.model.table.Table`.

    The 18 geometric terms are always included (exactly: they are built in the
    table's basis). ``include`` selects the representable extras: "squareness",
    "cyclic" (Fourier block 1 of the own positioning terms), "backlash"
    (B = -sigma_j b_j, take-up), "thermal" (expansion / offset per K with
    T_ref = thermal start temperature; evaluate with temp_c = T(t)) and
    "tool_offset" (the true tool offset instead of the declared one). Servo lag,
    the time-switched scale change, repeatability and instrument noise cannot be
    represented.
    """
    unknown = set(include) - set(TABLE_PARTS)
    if unknown:
        raise ValueError(f"unknown table parts {sorted(unknown)}; expected {TABLE_PARTS}")
    e = truth.effects
    axes: dict[str, AxisTable] = {}
    rev = e.reversal_um()
    for j, a in enumerate(AXES):
        ax = truth.axes[a]
        at = ax.axis_table()
        if "cyclic" not in include and at.blocks[1] is not None:
            nb0 = at.n_trend() + (0 if at.blocks[0] is None else 2 * at.blocks[0].harmonics)
            at.coef = {t: c[:nb0].copy() for t, c in at.coef.items()}
            at.blocks = (at.blocks[0], None)
        if "backlash" in include and e.backlash_um[j]:
            at.backlash_um = rev[j]
            at.backlash_takeup_mm = float(e.backlash_takeup_mm[j])
        if "thermal" in include and e.thermal_on():
            at.thermal_expansion_ppm_per_k = float(e.thermal_expansion_ppm_per_k[j])
            at.thermal_offset_um_per_k = float(e.thermal_offset_um_per_k[j])
            at.thermal_tref_c = float(e.thermal_start_c)
        axes[a] = at
    tool = truth.true_tool_offset_mm() if "tool_offset" in include else truth.tool_offset_mm
    sq = e.squareness_urad if "squareness" in include else (0.0, 0.0, 0.0)
    return Table(axes=axes, reference_mm=tuple(truth.reference_mm),  # type: ignore[arg-type]
                 tool_offset_mm=tuple(tool), squareness_urad=tuple(sq))  # type: ignore[arg-type]


def truth_term_values(truth: MachineTruth, pos_mm: np.ndarray) -> dict[tuple[str, str], np.ndarray]:
    """The 18 true geometric term values at machine positions (N, 3) mm: um / urad."""
    pos = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
    return {(a, t): truth.term_values(a, t, pos[:, j]) for j, a in enumerate(AXES) for t in TERMS}


def _f(v: Any) -> Any:
    if isinstance(v, (list, tuple)):
        return [_f(x) for x in v]
    if isinstance(v, np.ndarray):
        return [float(x) for x in v.reshape(-1)]
    if isinstance(v, (float, np.floating)):
        return float(v)
    return v


def truth_to_json(truth: MachineTruth, extra: dict[str, Any] | None = None) -> dict[str, Any]:
    """JSON-ready ground truth: every error function's parameters and coefficients,
    every effect magnitude; units in the key names (mm, um, urad, s, deg C)."""
    axes: dict[str, Any] = {}
    for a in AXES:
        ax = truth.axes[a]
        axes[a] = {
            "travel_mm": _f(ax.travel_mm),
            "trend_degree": ax.trend_degree,
            "blocks": [None if b is None else {"period_mm": float(b.period_mm),
                                               "origin_mm": float(b.origin_mm),
                                               "harmonics": int(b.harmonics)}
                       for b in ax.blocks],
            "rows": ax.axis_table().row_names(),
            "shapes": {t: _f(ax.shapes.get(t, {})) for t in TERMS},
            "coef": {f"{t}_{'um' if t in LINEAR_TERMS else 'urad'}": _f(ax.coef[t]) for t in TERMS},
        }
    e = truth.effects
    eff = {k: _f(v) for k, v in asdict(e).items()}
    eff["reversal_B_um"] = _f(e.reversal_um())
    out: dict[str, Any] = {
        "format": TRUTH_FORMAT,
        "conventions": (
            "Terms relative to the reference point; straightness terms have zero "
            "least-squares slope over the travel (the slope is squareness). "
            "coef rows follow abbe.model.table.basis_matrix (rows listed). The spatial "
            "error (dX, dY, dZ) of the tool relative to the workpiece is the exact "
            "(nonlinear) homogeneous-transform chain of docs/formats.md "
            "'Ballbar and simulation'; its linearisation is Eq. 3 (abbe.model.reference)."),
        "machine": {"name": truth.name, "seed": truth.seed,
                    "reference_mm": _f(truth.reference_mm),
                    "tool_offset_mm": _f(truth.tool_offset_mm),
                    "true_tool_offset_mm": _f(truth.true_tool_offset_mm())},
        "axes": axes,
        "effects": eff,
    }
    if extra:
        out.update(extra)
    return out


def dumps_json(d: dict[str, Any]) -> str:
    """Deterministic JSON text (sorted keys, repr floats, trailing newline)."""
    return json.dumps(d, indent=1, sort_keys=True) + "\n"


def truth_from_json(d: dict[str, Any], source: str = "<truth>") -> MachineTruth:
    """Rebuild a :class:`MachineTruth` from :func:`truth_to_json` output."""
    try:
        if d.get("format") != TRUTH_FORMAT:
            raise KeyError("format")
        m = d["machine"]
        axes: dict[str, AxisTruth] = {}
        for a in AXES:
            ad = d["axes"][a]
            blocks = tuple(None if b is None else FourierBlock(float(b["period_mm"]),
                                                               float(b["origin_mm"]),
                                                               int(b["harmonics"]))
                           for b in ad["blocks"])
            coef = {t: np.array(ad["coef"][f"{t}_{'um' if t in LINEAR_TERMS else 'urad'}"],
                                dtype=np.float64) for t in TERMS}
            axes[a] = AxisTruth(name=a, travel_mm=tuple(ad["travel_mm"]),  # type: ignore[arg-type]
                                trend_degree=int(ad["trend_degree"]),
                                blocks=blocks, coef=coef,  # type: ignore[arg-type]
                                shapes=ad.get("shapes", {}),
                                wave_period_mm=None if blocks[0] is None else blocks[0].period_mm)
        ed = d["effects"]
        kw = {}
        for k, v in Effects().__dict__.items():
            if k in ed:
                kw[k] = tuple(ed[k]) if isinstance(v, tuple) else float(ed[k])
        return MachineTruth(name=m["name"], seed=int(m["seed"]),
                            reference_mm=tuple(m["reference_mm"]),  # type: ignore[arg-type]
                            tool_offset_mm=tuple(m["tool_offset_mm"]),  # type: ignore[arg-type]
                            axes=axes, effects=Effects(**kw))
    except (KeyError, TypeError, ValueError) as exc:
        raise AbbeInputError(f"not an abbe truth file ({exc})", file=source) from None


def load_truth(path: str | Path) -> MachineTruth:
    """Read ``truth.json`` written by ``abbe simulate``."""
    from abbe.formats.limits import TRUTH_JSON_MAX_BYTES
    from abbe.formats.structured import load_json
    d, _ = load_json(path, what="truth file", max_bytes=TRUTH_JSON_MAX_BYTES)
    return truth_from_json(d, str(path))
