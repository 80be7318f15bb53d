"""The independent generator's machine: smooth geometric errors plus physical effects.

Geometric errors (notes.md §1: per linear axis three translations d_x, d_y, d_z in
um and three rotations eps_x, eps_y, eps_z in urad, functions of that axis'
position) are a Legendre series P0..P5 of the normalised position plus one free
sine whose wavelength is not tied to the travel: *not* the library's Chebyshev +
Fourier basis, so the model (a least-squares fit, :func:`fit_model`) has a real,
if small, approximation error. Each term is zero at the reference point; the
two straightness terms of an axis have no least-squares slope over the travel
(ISO 230-1: that slope is the squareness, held in S_xy, S_xz, S_yz).

Effects act on the axis' own positioning term (unless said otherwise), with
shapes of their own (docs/effects.md gives the physics, not these shapes):

* lost motion b (um): the carriage lags its command by b/2 inside the play, so the
  own term gains -s b/2 with the direction state s taken up after each reversal
  over a distance L by a ``play`` (L = b itself, a sharp step), ``linear``,
  ``exp`` (95 % at L) or ``smooth`` (smoothstep) law, L possibly different for
  reversals to + and to -; its ISO 230-2 reversal is B = -b (a lagging drive reads
  low on the + approach);
* position-dependent lost motion b(p) = b + a Legendre series of the position;
* scale: k (ppm) about the reference point, and/or a bow (um, sag at mid-travel
  relative to the chord) of the positioning error;
* cyclic screw error: amplitude (um) at the lead (mm), a 20 % second harmonic;
* thermal: the temperature rises linearly or exponentially in time; the axis grows
  by alpha (ppm/K) about the screw's fixed bearing (a travel end) and its zero
  shifts by o (um/K);
* servo: each axis follows its command with a pure delay or a first-order lag of
  time constant tau (ms);
* an unmodelled tool offset (mm) and a straightness bow (sine arch, um).

Units: positions mm, linear errors um, angles urad, time s, temperature deg C.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.polynomial import legendre

AXES: tuple[str, str, str] = ("X", "Y", "Z")
TERM_NAMES: tuple[str, ...] = ("dx", "dy", "dz", "ex", "ey", "ez")
#: own positioning term of each axis: the translation along the axis itself
OWN_TERM: dict[str, str] = {"X": "dx", "Y": "dy", "Z": "dz"}


@dataclass
class SmoothTerm:
    """f(p) = sum_k c_k P_k(u) + A sin(2 pi p / wl + phi) - (a0 + a1 p), clamped to the
    travel (u = normalised position in [-1, 1]); (a0, a1) make it zero at the
    reference point and, for straightness terms, remove the least-squares line."""

    travel: tuple[float, float]
    leg: np.ndarray
    sine_amp: float = 0.0
    sine_wl_mm: float = 1.0
    sine_phase: float = 0.0
    a0: float = 0.0
    a1: float = 0.0

    def raw(self, p: np.ndarray) -> np.ndarray:
        lo, hi = self.travel
        q = np.clip(np.asarray(p, dtype=np.float64), lo, hi)
        u = (2.0 * q - lo - hi) / (hi - lo)
        return (legendre.legval(u, self.leg)
                + self.sine_amp * np.sin(2.0 * math.pi * q / self.sine_wl_mm + self.sine_phase))

    def __call__(self, p: np.ndarray) -> np.ndarray:
        lo, hi = self.travel
        q = np.clip(np.asarray(p, dtype=np.float64), lo, hi)
        return self.raw(q) - (self.a0 + self.a1 * q)


def random_term(rng: np.random.Generator, travel: tuple[float, float], ref: float,
                scale: float, straightness: bool) -> SmoothTerm:
    """A random smooth term of typical size ``scale`` (um or urad)."""
    lo, hi = travel
    leg = rng.normal(0.0, 1.0, 6) * scale * np.array([0.0, 0.8, 0.6, 0.4, 0.25, 0.15])
    wl = (hi - lo) * rng.uniform(0.7, 1.8)
    t = SmoothTerm(travel, leg, float(rng.normal(0.0, 0.3 * scale)), float(wl),
                   float(rng.uniform(0, 2 * math.pi)))
    if straightness:
        g = np.linspace(lo, hi, 801)
        a1, a0 = np.polyfit(g, t.raw(g), 1)
        t.a1 = float(a1)
    t.a0 = float(t.raw(np.array([ref]))[0] - t.a1 * ref)
    return t


@dataclass
class LostMotion:
    """Lost motion of one drive: b_um (>= 0) taken up after a reversal by ``shape``
    over takeup_up_mm (reversal to + motion) / takeup_down_mm (to - motion);
    ``shape`` "play" takes it up over b itself. ``leg_um``: Legendre coefficients of a
    position-dependent part of b (P1, P2, ...), um."""

    b_um: float
    shape: str = "linear"
    takeup_up_mm: float = 0.1
    takeup_down_mm: float = 0.1
    leg_um: tuple[float, ...] = ()

    def b_at(self, p: np.ndarray, travel: tuple[float, float]) -> np.ndarray:
        lo, hi = travel
        u = (2.0 * np.clip(p, lo, hi) - lo - hi) / (hi - lo)
        if not self.leg_um:
            return np.full(np.shape(p), self.b_um)
        return self.b_um + legendre.legval(u, np.concatenate([[0.0], self.leg_um]))

    def fraction(self, d_mm: np.ndarray, to_plus: bool) -> np.ndarray:
        """Taken-up fraction of the play after travelling d_mm since the reversal."""
        L = (self.b_um * 1e-3 if self.shape == "play" else
             (self.takeup_up_mm if to_plus else self.takeup_down_mm))
        x = np.asarray(d_mm, dtype=np.float64) / max(L, 1e-9)
        if self.shape in ("play", "linear"):
            return np.clip(x, 0.0, 1.0)
        if self.shape == "exp":
            return -np.expm1(-3.0 * x)
        if self.shape == "smooth":
            c = np.clip(x, 0.0, 1.0)
            return c * c * (3.0 - 2.0 * c)
        raise ValueError(self.shape)


def lost_motion_state(path_mm: np.ndarray, lm: LostMotion, s_start: float) -> np.ndarray:
    """Direction state s in [-1, 1] along a densely sampled path of one axis (mm):
    after each reversal s goes from its value there toward the new direction by
    the take-up law of the distance travelled since; at rest it keeps its value."""
    p = np.asarray(path_mm, dtype=np.float64)
    out = np.empty(p.size)
    out[0] = s_start
    if p.size < 2:
        return out
    dp = np.diff(p)
    mv = np.sign(dp)
    s_rev = s_start
    i = 0
    n = dp.size
    while i < n:
        if mv[i] == 0:
            out[i + 1] = out[i]
            i += 1
            continue
        j = i
        while j + 1 < n and mv[j + 1] in (0.0, mv[i]):
            j += 1
        seg = slice(i + 1, j + 2)
        dist = np.abs(p[seg] - p[i])
        target = float(mv[i])
        s_rev = out[i]
        out[seg] = s_rev + (target - s_rev) * lm.fraction(dist, target > 0)
        i = j + 1
    return out


@dataclass
class Thermal:
    """Warm-up of one axis: T(t) = t0 + rate t (``linear``), t0 + rise (1 - exp(-t / tau))
    (``exp``) or t0 + rise (t / tau) exp(1 - t / tau) (``rise_fall``: warms, peaks at tau,
    cools); own term gains alpha dT (p - fixed_mm) 1e-3 + offset dT (um), dT = T - T(0).
    record_temp: the instruments write temp_c (sensor noise sensor_k)."""

    axis: str
    profile: str
    t0_c: float
    rate_k_per_h: float = 0.0
    rise_k: float = 0.0
    tau_h: float = 1.0
    alpha_ppm_per_k: float = 0.0
    fixed_mm: float = 0.0
    offset_um_per_k: float = 0.0
    record_temp: bool = True
    sensor_k: float = 0.01

    def temperature(self, t_s: np.ndarray) -> np.ndarray:
        h = np.asarray(t_s, dtype=np.float64) / 3600.0
        if self.profile == "linear":
            return self.t0_c + self.rate_k_per_h * h
        if self.profile == "rise_fall":   # warms, peaks at tau, cools again (a pause)
            x = h / self.tau_h
            return self.t0_c + self.rise_k * x * np.exp(1.0 - x)
        return self.t0_c + self.rise_k * -np.expm1(-h / self.tau_h)


@dataclass
class Servo:
    """Position loops: ``model`` "delay" (x(t) = u(t - tau)) or "first_order"
    (tau x' = u - x); tau_ms per axis."""

    model: str
    tau_ms: tuple[float, float, float]


@dataclass
class Effects:
    squareness_urad: tuple[float, float, float] = (0.0, 0.0, 0.0)   # S_xy, S_xz, S_yz
    lost_motion: dict[str, LostMotion] = field(default_factory=dict)
    scale: dict[str, tuple[float, float]] = field(default_factory=dict)  # axis -> (ppm, bow um)
    #: axis -> (amplitude um, lead mm, phase rad, second-harmonic ratio)
    cyclic: dict[str, tuple[float, float, float, float]] = field(default_factory=dict)
    thermal: Thermal | None = None
    servo: Servo | None = None
    tool_offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: (axis, term) -> sag (um) of a sine arch on a straightness term
    bow: dict[tuple[str, str], float] = field(default_factory=dict)


@dataclass
class Machine:
    """A 3-axis VMC: travels, reference point, declared tool offset, the 18 smooth terms
    and the effects. ``terms[(axis, name)]`` are functions of that axis' position."""

    travel: dict[str, tuple[float, float]]
    reference: tuple[float, float, float]
    declared_tool_mm: tuple[float, float, float]
    terms: dict[tuple[str, str], SmoothTerm]
    effects: Effects = field(default_factory=Effects)

    def geometric(self, axis: str, name: str, p: np.ndarray) -> np.ndarray:
        """The smooth term plus the static effects that are part of the geometry
        (scale, bow of the positioning, cyclic error, straightness arch), um / urad."""
        p = np.asarray(p, dtype=np.float64)
        v = self.terms[(axis, name)](p)
        e = self.effects
        j = AXES.index(axis)
        lo, hi = self.travel[axis]
        ref = self.reference[j]
        if name == OWN_TERM[axis]:
            if axis in e.scale:
                k, bow = e.scale[axis]
                v = v + k * 1e-3 * (p - ref) + bow * (_sag(p, lo, hi) - _sag(np.array(ref), lo, hi))
            if axis in e.cyclic:
                a, lead, ph, h2 = e.cyclic[axis]
                w = 2.0 * math.pi / lead

                def cyc(q: np.ndarray) -> np.ndarray:
                    return a * (np.sin(w * q + ph) + h2 * np.sin(2.0 * w * q + 1.3 * ph))
                v = v + cyc(p) - cyc(np.array(ref))
        if (axis, name) in e.bow:
            s = (np.clip(p, lo, hi) - lo) / (hi - lo)
            s_ref = (ref - lo) / (hi - lo)
            v = v + e.bow[(axis, name)] * (np.sin(math.pi * s) - math.sin(math.pi * s_ref))
        return v

    def own_dynamic(self, axis: str, p: np.ndarray, state: np.ndarray | None,
                    time_s: np.ndarray | None) -> np.ndarray:
        """Lost motion and thermal drift on the own positioning term, um."""
        p = np.asarray(p, dtype=np.float64)
        out = np.zeros(p.shape)
        lm = self.effects.lost_motion.get(axis)
        if lm is not None and state is not None:
            out -= np.asarray(state) * lm.b_at(p, self.travel[axis]) / 2.0
        th = self.effects.thermal
        if th is not None and th.axis == axis and time_s is not None:
            dT = th.temperature(time_s) - th.temperature(np.array(0.0))
            out += th.alpha_ppm_per_k * dT * (p - th.fixed_mm) * 1e-3 + th.offset_um_per_k * dT
        return out


def _sag(p: np.ndarray, lo: float, hi: float) -> np.ndarray:
    u = (2.0 * np.clip(p, lo, hi) - lo - hi) / (hi - lo)
    return 1.0 - u * u


def random_machine(rng: np.random.Generator) -> Machine:
    """A machine with random travels, reference point and smooth terms (no effects)."""
    spans = {"X": rng.choice([400.0, 500.0, 600.0, 800.0]), "Y": rng.choice([300.0, 400.0, 500.0]),
             "Z": rng.choice([250.0, 300.0, 400.0])}
    travel = {"X": (0.0, float(spans["X"])), "Y": (-float(spans["Y"]), 0.0),
              "Z": (-float(spans["Z"]), 0.0)}
    ref = tuple(float(lo + (hi - lo) * rng.uniform(0.25, 0.75)) for lo, hi in
                (travel[a] for a in AXES))
    terms = {}
    for j, a in enumerate(AXES):
        for name in TERM_NAMES:
            lin = name[0] == "d"
            sc = (3.0 if lin else 10.0) * rng.uniform(0.5, 1.5)
            straight = lin and name != OWN_TERM[a]
            terms[(a, name)] = random_term(rng, travel[a], ref[j], sc, straight)
    tool = (0.0, 0.0, float(rng.choice([0.0, 0.0, 80.0])))
    return Machine(travel=travel, reference=ref, declared_tool_mm=tool, terms=terms)
