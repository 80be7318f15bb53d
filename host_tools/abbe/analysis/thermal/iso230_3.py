"""ISO 230-3 evaluation of a thermal record: drift per channel, tilts, the envelope.

Per displacement channel (um, from its start): the drift over time, its range (max - min,
ISO 230-3's "thermal drift" of the spindle test) and the value at the end; per sensor pair
of one direction (a :class:`abbe.formats.thermal_machine.TiltPair`) the tilt (urad, from
the pair's difference over its spacing); the envelope: the largest drift range of any
channel and when each channel reached its extremes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from abbe.formats.thermal_machine import DISPLACEMENT_CALIBRATION_U_PCT, TiltPair
from abbe.formats.thermal_record import ThermalRecord


@dataclass(frozen=True)
class Drift:
    """One signal's drift in ``unit`` (um, urad, K): ``range`` (max - min), ``final`` (at
    the record's end), the extremes and their hours, all from the signal's start."""

    name: str
    unit: str
    range: float
    final: float
    max: float
    max_h: float
    min: float
    min_h: float


def tilt_signal(rec: ThermalRecord, pair: TiltPair) -> np.ndarray:
    """The pair's tilt over the record, urad, from its start: b = (x_up - x_low) / L,
    a = -(y_up - y_low) / L (a rotation about +X moves a point at +z to -y)."""
    i = rec.channel_names.index(pair.lower)
    j = rec.channel_names.index(pair.upper)
    d = (rec.disp_um[:, j] - rec.disp_um[0, j]) - (rec.disp_um[:, i] - rec.disp_um[0, i])
    sign = 1.0 if pair.output == "b" else -1.0
    return sign * d / pair.spacing_mm * 1e3


def drift_of(name: str, unit: str, hours: np.ndarray, v: np.ndarray) -> Drift:
    imax, imin = int(np.argmax(v)), int(np.argmin(v))
    return Drift(name, unit, float(v[imax] - v[imin]), float(v[-1]), float(v[imax]),
                 float(hours[imax]), float(v[imin]), float(hours[imin]))


def evaluate_record(rec: ThermalRecord, pairs: list[TiltPair]) -> dict:
    """The ISO 230-3 figures of a record (plain data, JSON-ready)."""
    h = rec.hours
    drifts = [drift_of(n, "um", h, rec.disp_um[:, k] - rec.disp_um[0, k])
              for k, n in enumerate(rec.channel_names)]
    tilts = [drift_of(f"tilt {p.output} ({p.upper}-{p.lower})", "urad", h, tilt_signal(rec, p))
             for p in pairs]
    temps = [drift_of(n, "K", h, rec.temps_c[:, k] - rec.temps_c[0, k])
             for k, n in enumerate(rec.temp_names)]
    env = max(drifts, key=lambda d: d.range)
    return {"duration_h": float(h[-1] - h[0]), "samples": int(h.size),
            "channels": [d.__dict__ for d in drifts], "tilts": [d.__dict__ for d in tilts],
            "temperatures": [d.__dict__ for d in temps],
            "envelope": {"channel": env.name, "range_um": env.range}}


#: First order and Monte Carlo further apart than this: the Monte Carlo's U is stated
AGREEMENT = 0.10


def _noise_sd(x: np.ndarray) -> float:
    """A sensor's reading noise (its unit): the scatter of second differences, sqrt(6)
    sigma for white noise; a smooth drift sampled densely adds almost nothing to it."""
    if x.size < 3:
        return 0.0
    return float(np.std(np.diff(x, 2), ddof=1) / np.sqrt(6.0))


def range_uncertainty(rec: ThermalRecord, spec, iso: dict, draws: int = 200,
                      seed: int = 20237) -> dict:  # noqa: ANN001 (ThermalSpec)
    """U (k = 2) of every ISO 230-3 range (channels um, tilts urad, temperatures K) and the
    budget, with a Monte Carlo check (GUM S1); adds ``u``, ``U``, ``U_first_order``,
    ``U_mc``, ``U_from`` and ``budget_u`` to each drift of ``iso`` and returns the
    ``uncertainty`` section.

    Inputs per sensor: its sensitivity (Type B: a displacement channel's
    ``calibration_U_pct``, the temperature sensors' ``temperature_calibration_U_pct``,
    k = 2, normal: a scale error changes the range by the same fraction) and its reading
    noise (Type A: from the record's second differences; the max and the min each the
    largest of competing readings, exact distribution of the largest of independent
    normals; the first reading, the zero, cancels). A tilt combines its
    two channels over their spacing (sensitivity by central differences of the range).
    The Monte Carlo redraws every sensitivity and a noise per reading and evaluates the
    ranges again; beyond 10 % its U is stated (the max and min compete over readings)."""
    from abbe.analysis.uncertainty import K, _max_moments
    X = np.concatenate([rec.disp_um, rec.temps_c], axis=1).astype(np.float64)
    nd = rec.disp_um.shape[1]
    names = list(rec.channel_names) + list(rec.temp_names)
    u_rel = np.empty(X.shape[1])
    src = []
    for j, n in enumerate(names):
        if j < nd:
            c = spec.channels.get(n)
            U = c.calibration_U_pct if c is not None else DISPLACEMENT_CALIBRATION_U_PCT
            src.append(f"calibration U = {U:g} % (k = 2, "
                       f"{'declared' if c is not None and c.calibration_declared else 'class default'})")
        else:
            U = spec.temperature_calibration_U_pct
            src.append(f"calibration U = {U:g} % (k = 2, "
                       f"{'declared' if spec.temperature_calibration_declared else 'class default'})")
        u_rel[j] = U / 100.0 / K
    sigma = np.array([_noise_sd(X[:, j]) for j in range(X.shape[1])])
    # every signal as weights on the columns of X: a channel, a tilt, a temperature
    W = []
    for j in range(nd):
        w = np.zeros(X.shape[1])
        w[j] = 1.0
        W.append(w)
    for p in spec.tilt_pairs():
        w = np.zeros(X.shape[1])
        sign = 1.0 if p.output == "b" else -1.0
        w[rec.channel_names.index(p.upper)] = sign / p.spacing_mm * 1e3
        w[rec.channel_names.index(p.lower)] = -sign / p.spacing_mm * 1e3
        W.append(w)
    for j in range(nd, X.shape[1]):
        w = np.zeros(X.shape[1])
        w[j] = 1.0
        W.append(w)
    Wm = np.array(W).T  # (M, S)
    drifts = iso["channels"] + iso["tilts"] + iso["temperatures"]

    def ranges(Xd: np.ndarray) -> np.ndarray:
        v = Xd @ Wm
        v = v - v[0]
        return v.max(axis=0) - v.min(axis=0)

    base = ranges(X)
    eps = 1e-4
    c_scale = np.empty((X.shape[1], Wm.shape[1]))
    for j in range(X.shape[1]):
        up, dn = X.copy(), X.copy()
        up[:, j] *= 1 + eps
        dn[:, j] *= 1 - eps
        c_scale[j] = (ranges(up) - ranges(dn)) / (2 * eps)
    u_B = np.abs(c_scale) * u_rel[:, None]               # (M, S)
    # reading noise: the max and the min are each the largest of many readings that
    # compete for it (a flat peak of a slow drift), whose spread is smaller than one
    # reading's: the exact distribution of the largest of independent normals, as ISO
    # 230-2's E (abbe.analysis.uncertainty); sqrt(2) sigma when one reading stands out
    s_sig = np.sqrt((Wm ** 2).T @ sigma ** 2)  # (S,) the signal's reading noise
    v_all = X @ Wm
    u_A = np.array([np.sqrt(_max_moments(v_all[:, i], np.full(v_all.shape[0], s_sig[i]))[1]
                            + _max_moments(-v_all[:, i], np.full(v_all.shape[0], s_sig[i]))[1])
                    if s_sig[i] > 0 else 0.0 for i in range(Wm.shape[1])])
    u1 = np.sqrt((u_B ** 2).sum(axis=0) + u_A ** 2)
    rng = np.random.default_rng(seed)
    F = np.empty((draws, Wm.shape[1]))
    for k in range(draws):
        Xd = X * (1 + rng.normal(0.0, u_rel)) + rng.normal(0.0, 1.0, X.shape) * sigma
        F[k] = ranges(Xd)
    U_mc = K * F.std(axis=0, ddof=1) if draws > 1 else np.full(Wm.shape[1], np.nan)
    agree = 0
    for i, d in enumerate(drifts):
        U1 = K * float(u1[i])
        ok = draws > 1 and U1 > 0 and abs(U_mc[i] / U1 - 1.0) <= AGREEMENT
        agree += bool(ok)
        U = U1 if (ok or draws <= 1) else float(U_mc[i])
        budget = {names[j]: round(float(u_B[j, i]), 6) for j in range(X.shape[1])
                  if u_B[j, i] > 0}
        budget["reading noise (Type A)"] = round(float(u_A[i]), 6)
        d.update(u=round(U / K, 6), U=round(U, 6), U_first_order=round(U1, 6),
                 U_mc=None if draws <= 1 else round(float(U_mc[i]), 6),
                 U_from=("first order (the Monte Carlo agrees within 10 %)" if ok else
                         "first order (no Monte Carlo run)" if draws <= 1 else
                         "Monte Carlo (the first order is more than 10 % off)"),
                 budget_u=budget)
        assert abs(base[i] - d["range"]) < 1e-6 * max(1.0, abs(d["range"])), d["name"]
    env = iso["envelope"]
    ch = next(d for d in iso["channels"] if d["name"] == env["channel"])
    env["U_um"] = ch["U"]
    return {"method": "GUM: each range's sensitivities first order (central differences), "
                      "its reading noise from the exact distribution of the largest (and "
                      "smallest) of competing readings, checked by a Monte Carlo "
                      "(GUM S1) that redraws every sensitivity and a noise per reading",
            "k": K,
            "sensors": {n: {"sensitivity": src[j], "noise_sd": round(float(sigma[j]), 6),
                            "unit": "um" if j < nd else "K"} for j, n in enumerate(names)},
            "not_included": "the sensors' mounting (a nest that moves with temperature), the "
                            "record's own representativeness (one warm-up)",
            "monte_carlo": {"draws": draws, "seed": seed, "agree": agree, "of": len(drifts)}}
