"""Why a linear drift is stated on a warm-up law: the check's own noise, or the method?

python host_tools/bench/bench_drift_law.py noise --seed S CASE [CASE ...] [--axis X]
python host_tools/bench/bench_drift_law.py coverage --laser FILE.csv [--sigma UM]
       [--rate UM_PER_H] [--draws N]
python host_tools/bench/bench_drift_law.py redraw --seed S --model-from DIR --work DIR
       [--draws N] CASE

The second generator's drift is linear in time (cases/independent2/instruments.py,
``Effects.term_delta``). The diagnosis searches its warm-up time constant on a grid
(linear, 0.5 .. 4 x the span: candidates.Engine._tau_grid) and states the rate at the
origin of the best one with the grid's BIC mixture as its 95 % interval
(shape.drift_tau_average).

``noise``: builds each case twice with the same draws (as built / the check lasers'
noise zeroed; no ``abbe fit``), takes the difference of the drift axis' linear channel
(exactly the noise of that check) and regresses it on t and t^2 (t the drift variable,
h from the check's first reading) with every (direction, target) cell free. Prints the
t^2 coefficient's z (its sd from the generator's own sigma), signed so that + is a
decelerating warm-up of the case's drift (the curvature the grid's finite time constants
carry); compare with the diagnosis' ``tau_alternatives`` (diagnose.json).

``coverage``: Monte Carlo of the grid's mixture rule on a LINEAR truth with white noise at
``sigma`` on a laser file's times and cells (its linear channel only; one check): how
often the mixture's 95 % interval holds the truth, how often the linear law is the best
one, and how often the stated value (the best law's) is both > 10 % off and outside its
interval (the issue's done-when). A denser grid (8, 16, 32 x span added) for comparison.

``redraw``: the real pipeline on fresh noise: the case rebuilt with every draw the same but
the check lasers' noise (fresh seeds 0 .. N-1), the model copied from ``--model-from`` (the
round's built case), ``abbe diagnose`` run on each; prints the drift's value, interval,
whether the truth is inside, and the linear law's weight.
"""
from __future__ import annotations

import argparse
import csv
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy import stats

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

GRID_FACTORS = (0.5, 1.0, 2.0, 4.0)   # candidates.TAU_GRID_FACTORS (read, not imported: a bench)


def _laser(path: Path) -> np.ndarray:
    """(n, 4): time_s, target_mm, 1 for the + direction, linear_um of a 6D laser CSV."""
    rows = list(csv.DictReader(path.open()))
    return np.array([[float(q["time_s"]), float(q["target_mm"]), q["direction"] == "+",
                      float(q["linear_um"])] for q in rows])


def _cells(a: np.ndarray) -> np.ndarray:
    """(n, k) indicator of each reading's (direction, target) cell."""
    idx = np.unique(a[:, 1:3], axis=0, return_inverse=True)[1].ravel()
    return np.eye(int(idx.max()) + 1)[idx]


def noise(seed: int, names: list[str], axis: str) -> None:
    """Print the t^2 z of each case's check-laser noise on ``axis`` (see the module doc)."""
    import bench_independent2_ab as B
    import cases.independent2.suite as S
    orig = S.laser_rows
    state: dict = {"zero": False, "sigma": {}, "sign": {}}

    def laser(rng, m, eff, ax, targets, signs, runs, t0_h, nz, effect_out=None):  # type: ignore[no-untyped-def]
        if eff is not None:
            state["sigma"][ax], state["sign"][ax] = nz["laser_um"], signs["linear"]
            if state["zero"]:
                nz = {k: 0.0 for k in nz}
        return orig(rng, m, eff, ax, targets, signs, runs, t0_h, nz, effect_out)
    S.laser_rows = laser
    cases = {c.name: c for c in B.suite(seed, per_single=5, per_pair=3, n_clean=20, per_limit=1)}
    for name in names:
        with tempfile.TemporaryDirectory() as tmp:
            state["zero"] = False
            b = S.build(cases[name], Path(tmp) / "a", fit=False)
            state["zero"] = True
            S.build(cases[name], Path(tmp) / "b", fit=False)
            f = f"laser/check_{axis.lower()}.csv"
            a, z = _laser(Path(tmp) / "a" / f), _laser(Path(tmp) / "b" / f)
        nz = a[:, 3] - z[:, 3]
        t = (a[:, 0] - a[0, 0]) / 3600.0
        X = np.column_stack([_cells(a), t, t * t])
        beta, *_ = np.linalg.lstsq(X, nz, rcond=None)
        sd = state["sigma"][axis] * np.sqrt(np.linalg.inv(X.T @ X)[-1, -1])
        key = f"thermal_drift_{axis.lower()}"
        rate = b.truth.get(key, {}).get("value", float("nan"))
        # in reading units the drift is sign * rate * t; decelerating: t^2 of the other sign
        dec = -np.sign(state["sign"][axis] * rate) * beta[-1] / sd
        print(f"{seed} {name}: truth {rate:.3f} um/h, laser sigma {state['sigma'][axis]:.4f} um, "
              f"noise t^2 z (+ = decelerating) {dec:+.2f}", flush=True)


def _mixture_ci(v: np.ndarray, sd: np.ndarray, w: np.ndarray) -> tuple[float, float]:
    xs = np.linspace(float(np.min(v - 10 * sd)), float(np.max(v + 10 * sd)), 4001)
    cdf = (w[:, None] * stats.norm.cdf((xs[None, :] - v[:, None]) / sd[:, None])).sum(0)
    return float(xs[np.searchsorted(cdf, 0.025)]), float(xs[np.searchsorted(cdf, 0.975)])


def coverage(path: Path, sigma: float, rate: float, draws: int) -> None:
    """Print the mixture rule's coverage on a linear truth (see the module doc)."""
    a = _laser(path)
    t = (a[:, 0] - a[0, 0]) / 3600.0
    span = float(t.max())
    C = _cells(a)
    rng = np.random.default_rng(1)
    Y = rate * t[None, :] + rng.normal(0.0, sigma, (draws, t.size))
    for label, factors in (("grid linear + 0.5-4 x span (main)", GRID_FACTORS),
                           ("denser: + 8, 16, 32 x span", GRID_FACTORS + (8.0, 16.0, 32.0))):
        laws = [t] + [f * span * (1.0 - np.exp(-t / (f * span))) for f in factors]
        P = []
        for col in laws:
            X = np.column_stack([C, col])
            pinv = np.linalg.pinv(X)
            P.append((pinv[-1], X @ pinv, sigma * np.sqrt(np.linalg.inv(X.T @ X)[-1, -1])))
        sd = np.array([p[2] for p in P])
        cover = lin = outside = 0
        for y in Y:
            v = np.array([p[0] @ y for p in P])
            e = [y - p[1] @ y for p in P]
            rss = np.array([float(x @ x) for x in e])
            w = np.exp(-(rss - rss.min()) / (2.0 * sigma ** 2))
            lo, hi = _mixture_ci(v, sd, w / w.sum())
            inside = lo <= rate <= hi
            best = int(np.argmin(rss))
            cover += inside
            lin += best == 0
            outside += (abs(v[best] / rate - 1.0) > 0.10) and not inside
        print(f"{label}: truth inside the 95 % interval {cover / draws:.3f}, linear best "
              f"{lin / draws:.3f}, value > 10 % off and outside {outside / draws:.4f} "
              f"({draws} draws)", flush=True)


class _FreshNoise:
    """The generator's rng, but the draws at the laser's noise sigmas come from ``fresh``
    (the generator's own draw is still taken, so every later draw stays the same)."""

    def __init__(self, rng: np.random.Generator, fresh: np.random.Generator, sigmas: set) -> None:
        self.rng, self.fresh, self.sigmas = rng, fresh, sigmas

    def normal(self, loc: float = 0.0, scale: float = 1.0, size=None):  # type: ignore[no-untyped-def]
        if size is None and scale in self.sigmas:
            self.rng.normal(loc, scale)
            return self.fresh.normal(loc, scale)
        return self.rng.normal(loc, scale, size)

    def __getattr__(self, k: str):  # type: ignore[no-untyped-def]
        return getattr(self.rng, k)


def redraw(seed: int, name: str, model_from: Path, work: Path, draws: int) -> None:
    """Diagnose the case on ``draws`` fresh check-laser noises (see the module doc)."""
    import json
    import shutil
    import subprocess
    import bench_independent2_ab as B
    import cases.independent2.suite as S
    orig = S.laser_rows
    state = {"k": 0}

    def laser(rng, m, eff, ax, targets, signs, runs, t0_h, nz, effect_out=None):  # type: ignore[no-untyped-def]
        if eff is not None:
            fresh = np.random.default_rng([state["k"], "XYZ".index(ax)])
            rng = _FreshNoise(rng, fresh, {nz["laser_um"], nz["straight_um"], nz["angle_urad"]})
        return orig(rng, m, eff, ax, targets, signs, runs, t0_h, nz, effect_out)
    S.laser_rows = laser
    case = {c.name: c for c in B.suite(seed, per_single=5, per_pair=3, n_clean=20,
                                       per_limit=1)}[name]
    abbe = str(Path(sys.executable).with_name("abbe"))
    for k in range(draws):
        state["k"] = k
        d = work / f"{name}_{k}"
        if d.exists():
            shutil.rmtree(d)
        b = S.build(case, d, fit=False)
        shutil.copytree(model_from / "model", d / "model")
        subprocess.run([abbe, "diagnose", "machine.toml", "--model", "model/model.bin", "-o",
                        "out", "--no-plots"], cwd=d, capture_output=True, check=False)
        r = json.loads((d / "out" / "diagnose.json").read_text())
        shutil.rmtree(d)
        es = [e for e in r["effects"] if e["key"].startswith("thermal_drift")]
        if not es:
            print(f"{k}: no drift named; named {[e['key'] for e in r['effects']]}", flush=True)
            continue
        e = es[0]
        truth = b.truth[e["key"]]["value"] if e["key"] in b.truth else float("nan")
        lo, hi = e["ci95"]
        wl = [a["weight"] for a in e["evidence"].get("tau_alternatives") or [] if a["tau"] is None]
        print(f"{k}: truth {truth:.3f} value {e['value']:.3f} [{lo:.3f}, {hi:.3f}] inside "
              f"{lo <= truth <= hi} >10% {abs(e['value'] / truth - 1.0) > 0.10} linear weight "
              f"{wl[0] if wl else float('nan'):.3f}; others {[x['key'] for x in r['effects'] if x is not e]}",
              flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    n = sub.add_parser("noise")
    n.add_argument("--seed", type=int, required=True)
    n.add_argument("--axis", default="X")
    n.add_argument("cases", nargs="+")
    c = sub.add_parser("coverage")
    c.add_argument("--laser", type=Path, required=True)
    c.add_argument("--sigma", type=float, default=0.1)
    c.add_argument("--rate", type=float, default=-7.0)
    c.add_argument("--draws", type=int, default=4000)
    r = sub.add_parser("redraw")
    r.add_argument("--seed", type=int, required=True)
    r.add_argument("--model-from", type=Path, required=True)
    r.add_argument("--work", type=Path, required=True)
    r.add_argument("--draws", type=int, default=30)
    r.add_argument("case")
    args = ap.parse_args()
    if args.cmd == "noise":
        noise(args.seed, args.cases, args.axis)
    elif args.cmd == "redraw":
        args.work.mkdir(parents=True, exist_ok=True)
        redraw(args.seed, args.case, args.model_from, args.work, args.draws)
    else:
        coverage(args.laser, args.sigma, args.rate, args.draws)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
