"""Seeded synthetic 6D laser data sets for tests and the fit benchmark.

``make_dataset(out_dir, seed=...)`` writes ``machine.toml`` and one laser CSV per
axis (docs/formats.md) whose readings come from known error shapes:

* own positioning term: linear scale error + a wave (paper Fig. 4 type:
  a fundamental and its 2nd harmonic, period ``wave_period_mm``) + reversal;
* straightness: sag (bow) and cantilever (cubic) shapes + a set-up slope
  (which Eq. 1 detrending removes);
* angles: smooth (low-order) shapes, one with a gentle long wave;
* run-to-run noise (Gaussian, per reading) and a slow per-run drift.

Readings = map sign * term (the shared machine-file convention), so
``truth(axis, term, pos)`` is the model term the fit should recover (before
detrending / reference adaptation). Units: mm, um, urad.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from abbe.formats.machine import DEFAULT_MAPS as MAPS

AXES = ("X", "Y", "Z")
TRAVEL_MM = {"X": (0.0, 500.0), "Y": (-400.0, 0.0), "Z": (-300.0, 0.0)}
REFERENCE_MM = (163.626, -212.772, -290.704)
OWN = {"X": "dx", "Y": "dy", "Z": "dz"}
CSV_COLUMNS = ("run", "direction", "target_mm", "linear_um", "straight_h_um", "straight_v_um",
               "pitch_urad", "yaw_urad", "roll_urad", "time_s")
_CHANNEL_COLUMN = {"linear": "linear_um", "straight_h": "straight_h_um",
                   "straight_v": "straight_v_um", "pitch": "pitch_urad", "yaw": "yaw_urad",
                   "roll": "roll_urad"}


@dataclass
class Synthetic:
    """What was generated: file paths and the true terms.

    truth[(axis, term)](pos_mm) -> value (um / urad), the model term without
    noise, reversal or drift. reversal_um[axis]: true B = mean(+) - mean(-) of
    the own positioning term. noise: per-reading standard deviation (um / urad).
    """

    machine: Path
    laser: dict[str, Path]
    truth: dict[tuple[str, str], Callable[[np.ndarray], np.ndarray]]
    reversal_um: dict[str, float]
    noise: float
    targets_mm: dict[str, np.ndarray] = field(default_factory=dict)


def _shapes(axis: str, rng: np.random.Generator, wave_amp_um: float, wave_period_mm: float
            ) -> dict[str, Callable[[np.ndarray], np.ndarray]]:
    lo, hi = TRAVEL_MM[axis]
    span = hi - lo

    def u(p: np.ndarray) -> np.ndarray:
        return (2 * np.asarray(p, dtype=float) - lo - hi) / span

    ph1, ph2 = rng.uniform(0, 2 * np.pi, 2)
    scale = rng.uniform(-20, 20)          # um/m
    sag = rng.uniform(2, 6) * rng.choice([-1, 1])
    cant = rng.uniform(1, 4) * rng.choice([-1, 1])
    setup = rng.uniform(-30, 30)          # um/m set-up misalignment
    a = rng.uniform(-1, 1, 6)
    P = wave_period_mm

    def pos(p: np.ndarray) -> np.ndarray:
        p = np.asarray(p, dtype=float)
        return (scale * (p - lo) / 1000.0
                + wave_amp_um * np.sin(2 * np.pi * p / P + ph1)
                + 0.35 * wave_amp_um * np.sin(4 * np.pi * p / P + ph2))

    def s1(p: np.ndarray) -> np.ndarray:   # sag (bow)
        return sag * (1 - u(p) ** 2) + setup * (np.asarray(p) - lo) / 1000.0

    def s2(p: np.ndarray) -> np.ndarray:   # cantilever: grows toward one end
        x = (u(p) + 1) / 2
        return cant * x ** 3 - 0.5 * setup * (np.asarray(p) - lo) / 1000.0

    def e1(p: np.ndarray) -> np.ndarray:
        return 6 * a[0] * u(p) + 4 * a[1] * u(p) ** 2

    def e2(p: np.ndarray) -> np.ndarray:
        return 8 * a[2] * u(p) ** 2 + 3 * a[3] * u(p) ** 3 + 2 * a[4]

    def e3(p: np.ndarray) -> np.ndarray:   # gentle long wave on one angle
        return 3 * a[5] * u(p) + 1.5 * np.sin(2 * np.pi * (np.asarray(p) - lo) / (0.8 * span))

    others = [t for t in ("dx", "dy", "dz") if t != OWN[axis]]
    return {OWN[axis]: pos, others[0]: s1, others[1]: s2, "ex": e1, "ey": e2, "ez": e3}


def write_laser_csv(path: Path, targets_mm: np.ndarray, readings: dict[str, np.ndarray],
                    time_s: np.ndarray | None = None) -> None:
    """Write a laser CSV in measured order: per run the ``+`` pass ascending, then
    the ``-`` pass descending. readings[channel]: (n_runs, 2, T), direction 0 = +."""
    n_runs = next(iter(readings.values())).shape[0]
    T = targets_mm.size
    path.parent.mkdir(parents=True, exist_ok=True)
    cols = [c for c in CSV_COLUMNS if c != "time_s" or time_s is not None]
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(cols)
        for r in range(n_runs):
            for d, sign in ((0, "+"), (1, "-")):
                idx = range(T) if d == 0 else range(T - 1, -1, -1)
                for i in idx:
                    row = [r + 1, sign, f"{targets_mm[i]:.3f}"]
                    row += [f"{readings[ch][r, d, i]:.4f}" for ch in _CHANNEL_COLUMN]
                    if time_s is not None:
                        row.append(f"{time_s[r, d, i]:.1f}")
                    w.writerow(row)


def machine_toml(laser_files: dict[str, str], lines: dict[str, tuple[tuple, tuple]],
                 name: str = "synthetic") -> str:
    """Text of a machine file for the standard synthetic geometry."""
    out = [f'[machine]\nname = "{name}"\n']
    for a in AXES:
        lo, hi = TRAVEL_MM[a]
        out.append(f"[axes.{a}]\ntravel_mm = [{lo}, {hi}]\n")
    out.append(f"[reference]\npoint_mm = [{', '.join(str(v) for v in REFERENCE_MM)}]\n")
    out.append("[tool]\noffset_mm = [0.0, 0.0, 0.0]\n")
    for a, f in laser_files.items():
        s, e = lines[a]
        m = ", ".join(f'{ch} = "{v}"' for ch, v in MAPS[a].items())
        out.append(f'[laser.{a}]\nfile = "{f}"\nstart_mm = [{", ".join(map(str, s))}]\n'
                   f'end_mm = [{", ".join(map(str, e))}]\nmap = {{ {m} }}\n')
    return "\n".join(out)


def make_dataset(out_dir: str | Path, *, seed: int = 0, n_targets: int | dict[str, int] = 51,
                 n_runs: int = 5, axes: tuple[str, ...] = AXES, noise: float = 0.15,
                 wave_amp_um: float = 2.5, wave_period_mm: float | dict[str, float] = 73.0,
                 reversal_um: float | dict[str, float] = 3.0, drift_um: float = 0.2,
                 jitter_mm: float = 0.0,
                 reversal_gradient_um: float | dict[str, float] = 0.0) -> Synthetic:
    """Write a seeded synthetic data set (machine.toml + laser/<axis>.csv) to ``out_dir``.

    n_targets per axis (int for all), evenly spaced over the travel, optionally
    jittered by up to ``jitter_mm`` (ends kept) so they are not evenly spaced as
    ISO 230-2 advises. noise: per-reading std (um or urad); drift_um: per-run
    offset std of linear channels; reversal_um: B of the own positioning term, at
    mid-travel; reversal_gradient_um: how much B grows from the - end of the travel to
    the + end (linear in the position; 0 = a constant reversal).
    """
    out_dir = Path(out_dir)
    rng = np.random.default_rng(seed)
    truth: dict[tuple[str, str], Callable[[np.ndarray], np.ndarray]] = {}
    files: dict[str, str] = {}
    paths: dict[str, Path] = {}
    lines: dict[str, tuple[tuple, tuple]] = {}
    rev: dict[str, float] = {}
    tg: dict[str, np.ndarray] = {}
    for j, a in enumerate(AXES):
        if a not in axes:
            continue
        nt = n_targets[a] if isinstance(n_targets, dict) else n_targets
        P = wave_period_mm[a] if isinstance(wave_period_mm, dict) else wave_period_mm
        B = reversal_um[a] if isinstance(reversal_um, dict) else reversal_um
        G = reversal_gradient_um[a] if isinstance(reversal_gradient_um, dict) \
            else reversal_gradient_um
        shapes = _shapes(a, rng, wave_amp_um, P)
        for t, f in shapes.items():
            truth[(a, t)] = f
        lo, hi = TRAVEL_MM[a]
        targets = np.linspace(lo, hi, nt)
        if jitter_mm > 0:
            targets[1:-1] += rng.uniform(-jitter_mm, jitter_mm, nt - 2)
        targets = np.round(targets, 3)
        tg[a] = targets
        readings: dict[str, np.ndarray] = {}
        drift = rng.normal(0, drift_um, n_runs)
        for ch, spec in MAPS[a].items():
            sign = 1.0 if spec[0] == "+" else -1.0
            term = spec[1:]
            val = np.broadcast_to(shapes[term](targets), (n_runs, 2, nt)).copy()
            if term == OWN[a]:
                b_at = B + G * ((targets - lo) / (hi - lo) - 0.5)
                val[:, 0, :] += b_at / 2
                val[:, 1, :] -= b_at / 2
            if term in ("dx", "dy", "dz"):
                val += drift[:, None, None]
            val += rng.normal(0, noise, val.shape)
            readings[ch] = sign * val
        feed_mm_s = 200.0 / 60.0
        step_s = np.abs(np.diff(targets)).mean() / feed_mm_s + 2.0
        time_s = np.zeros((n_runs, 2, nt))
        k = 0.0
        for r in range(n_runs):
            for d in (0, 1):
                idx = range(nt) if d == 0 else range(nt - 1, -1, -1)
                for i in idx:
                    time_s[r, d, i] = k
                    k += step_s
        fname = f"laser/{a.lower()}.csv"
        write_laser_csv(out_dir / fname, targets, readings, time_s)
        files[a] = fname
        paths[a] = (out_dir / fname).resolve()
        start = list(REFERENCE_MM)
        end = list(REFERENCE_MM)
        start[j], end[j] = (hi, lo) if a != "X" else (lo, hi)
        lines[a] = (tuple(start), tuple(end))
        rev[a] = B
    mpath = out_dir / "machine.toml"
    mpath.write_text(machine_toml(files, lines))
    return Synthetic(machine=mpath.resolve(), laser=paths, truth=truth, reversal_um=rev,
                     noise=noise, targets_mm=tg)
