"""Scoring of the chain campaigns (bench/bench_chain.py, tests/analysis/test_chain_fit.py):
data from the independent generator (cases/chain_generator.py, which imports nothing of
abbe), identification by abbe (its machine-file reader and abbe.analysis.five_axis.chain_fit)."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from abbe.analysis.five_axis.chain_fit import ChainSetup, identify_chain
from abbe.formats.machine import load_machine
from cases import chain_generator as gen

CHAINS = Path(__file__).resolve().parent / "five_axis_chains"
SPHERE_MM = np.array([50.0, 20.0, 30.0])
PROBE_NOISE_UM = 0.5
RTEST_NOISE_UM = 0.3
SPHERE_SETUP_UM = 50.0


def plan(tool_side: bool) -> list[tuple[str, str, np.ndarray, np.ndarray]]:
    """(kind, name, sphere mm, tip mm) of the campaign's set-ups: a sphere probed at two
    heights, an R-test on the first; a tool-side rotary axis adds a stylus 100 mm longer."""
    out = [("probe", "S1", SPHERE_MM, np.zeros(3)),
           ("probe", "S2", SPHERE_MM + [0.0, 0.0, 100.0], np.zeros(3)),
           ("rtest", "R1", SPHERE_MM, np.zeros(3))]
    if tool_side:
        out.append(("probe", "S3", SPHERE_MM, np.array([0.0, 0.0, -100.0])))
    return out


def run_case(path: Path, chain, gch: gen.GenChain, rng: np.random.Generator) -> dict:  # noqa: ANN001
    truth = gen.random_location(gch, rng)
    angles = gen.grid(gch)
    setups = []
    for kind, name, sphere, tip in plan(bool(chain.tool_side)):
        off = rng.normal(0.0, SPHERE_SETUP_UM * 1e-3, 3)
        if kind == "probe":
            obs = gen.probe_centres(gch, truth, sphere, off, tip, angles, PROBE_NOISE_UM, rng)
            sig = PROBE_NOISE_UM
        else:
            obs = gen.rtest_readings(gch, truth, sphere, off, tip, angles, RTEST_NOISE_UM, rng)
            sig = RTEST_NOISE_UM
        setups.append(ChainSetup(kind, name, tuple(sphere), angles, obs, tuple(tip), sig))
    fit = identify_chain(chain, setups, explain=False)
    rows = []
    for r in fit.rows:
        if r.value is None:
            continue
        floor = 1.0 if r.unit == "um" else 5.0
        err = abs(r.value - truth[r.name])
        rows.append((r.name, err, r.u95, err <= max(r.u95, floor)))
    return {"rows": rows, "unobservable": fit.unobservable, "rms": fit.rms_weighted}


def campaign(path: Path, cases: int, seed: int) -> dict:
    chain = load_machine(path).extra["chain"]
    gch = gen.read_chain(path)
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    res = [run_case(path, chain, gch, rng) for _ in range(cases)]
    dt = time.perf_counter() - t0
    per_error: dict[str, list[bool]] = {}
    worst: dict[str, float] = {}
    for r in res:
        for name, err, _u, ok in r["rows"]:
            per_error.setdefault(name, []).append(ok)
            worst[name] = max(worst.get(name, 0.0), err)
    n_ok = sum(ok for v in per_error.values() for ok in v)
    n_all = sum(len(v) for v in per_error.values())
    cases_ok = sum(all(ok for *_x, ok in r["rows"]) for r in res)
    # the intervals alone (no 1 um / 5 urad floor): are they honest 95 % intervals?
    in_u95 = sum(err <= u for r in res for _n, err, u, _ok in r["rows"])
    return {"file": path.name, "chain": chain.name, "kind": chain.kind, "cases": cases,
            "observable": sorted(per_error), "unobservable": list(res[0]["unobservable"]),
            "within": n_ok, "compared": n_all, "share_within": n_ok / max(n_all, 1),
            "cases_all_within": cases_ok, "within_interval_only": in_u95,
            "per_error_within": {k: int(sum(v)) for k, v in per_error.items()},
            "worst_error": worst, "seconds": dt}




# ------------------------------------------------------------ error motions (issue 39)

#: Sizes of the hidden error motions (each harmonic's amplitude U(0, size)).
MOTION_UM, MOTION_URAD = 1.0, 4.0


def motion_plan(tool_side: bool) -> list[tuple[str, str, np.ndarray, np.ndarray]]:
    """The set-ups error motions need: the location plan (:func:`plan`) plus a sphere
    100 mm further out (70 mm along X and Y): a radial or tilt motion moves spheres at
    every radius alike, a line's place and tilt do not."""
    return plan(tool_side) + [("probe", "S4", SPHERE_MM + [70.0, 70.0, 0.0], np.zeros(3))]


def true_coefficient(motions: dict, name: str) -> float:
    """The generator's error motion as the product's Fourier coefficient ``name``
    (``EXC(C) sin2``): amp sin(k t + ph) = amp cos(ph) sin k t + amp sin(ph) cos k t."""
    head, term = name.split(" ")
    m = motions.get(f"{head[2]}.{head[1]}")
    k = int(term[3:])
    if m is None or k not in m.amp:
        return 0.0
    a, ph = m.amp[k], m.phase[k]
    return float(a * (np.cos(ph) if term.startswith("sin") else np.sin(ph)))


def run_motion_case(chain, gch: gen.GenChain, rng: np.random.Generator,  # noqa: ANN001
                    harmonics: int = 2, grid: tuple[int, int] = (6, 8),
                    location_only: bool = True) -> dict:
    """One campaign with hidden location errors and error motions up to ``harmonics``,
    identified with ``harmonics``: every observable location error and motion coefficient
    judged against max(95 %, 1 um / 5 urad). ``location_only``: also fit the location
    errors alone (the weighted RMS the error motions leave without motion unknowns)."""
    truth = gen.random_location(gch, rng)
    motions = gen.random_motions(gch, rng, harmonics, MOTION_UM, MOTION_URAD)
    angles = gen.grid(gch, *grid)
    setups = []
    for kind, name, sphere, tip in motion_plan(bool(chain.tool_side)):
        off = rng.normal(0.0, SPHERE_SETUP_UM * 1e-3, 3)
        if kind == "probe":
            obs = gen.probe_centres(gch, truth, sphere, off, tip, angles, PROBE_NOISE_UM, rng,
                                    motions)
            sig = PROBE_NOISE_UM
        else:
            obs = gen.rtest_readings(gch, truth, sphere, off, tip, angles, RTEST_NOISE_UM, rng,
                                     motions)
            sig = RTEST_NOISE_UM
        setups.append(ChainSetup(kind, name, tuple(sphere), angles, obs, tuple(tip), sig))
    fit = identify_chain(chain, setups, explain=False, harmonics=harmonics)
    rows = []
    for r in fit.rows + fit.motion_rows:
        if r.value is None:
            continue
        floor = 1.0 if r.unit == "um" else 5.0
        t = truth[r.name] if r.name in truth else true_coefficient(motions, r.name)
        err = abs(r.value - t)
        rows.append((r.name, err, r.u95, err <= max(r.u95, floor)))
    return {"rows": rows, "unobservable": fit.unobservable,
            "motion_unobservable": [r.name for r in fit.motion_rows if r.value is None],
            "n_motion": len(fit.motion_rows), "rms": fit.rms_weighted,
            "rms_location_only": identify_chain(chain, setups, explain=False).rms_weighted
            if location_only else float("nan")}


def motion_campaign(path: Path, cases: int, seed: int, harmonics: int = 2,
                    grid: tuple[int, int] = (6, 8), location_only: bool = True) -> dict:
    """:func:`campaign` with hidden error motions (:func:`run_motion_case`)."""
    chain = load_machine(path).extra["chain"]
    gch = gen.read_chain(path)
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    res = [run_motion_case(chain, gch, rng, harmonics, grid, location_only)
           for _ in range(cases)]
    dt = time.perf_counter() - t0
    loc = [r for c in res for r in c["rows"] if "(" not in r[0]]
    mot = [r for c in res for r in c["rows"] if "(" in r[0]]
    # the name's second letter says the unit: X Y Z um, A B C urad (EX0C, EXC(C) sin2)
    worst = max((r for r in loc + mot),
                key=lambda r: r[1] / max(r[2], 1.0 if r[0][1] in "XYZ" else 5.0), default=None)
    return {"file": path.name, "chain": chain.name, "kind": chain.kind, "cases": cases,
            "harmonics": harmonics, "grid": list(grid),
            "unobservable": list(res[0]["unobservable"]),
            "motion_unobservable": list(res[0]["motion_unobservable"]),
            "n_motion": res[0]["n_motion"],
            "location_within": sum(r[3] for r in loc), "location_compared": len(loc),
            "motion_within": sum(r[3] for r in mot), "motion_compared": len(mot),
            "share_within": sum(r[3] for r in loc + mot) / max(len(loc + mot), 1),
            "within_interval_only": sum(r[1] <= r[2] for r in loc + mot),
            "cases_all_within": sum(all(r[3] for r in c["rows"]) for c in res),
            "rms_weighted": float(np.median([c["rms"] for c in res])),
            "rms_location_only": float(np.median([c["rms_location_only"] for c in res])),
            "worst": None if worst is None else {"name": worst[0], "error": worst[1],
                                                  "u95": worst[2]},
            "seconds": dt}
