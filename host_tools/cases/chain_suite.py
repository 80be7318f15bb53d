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


