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
    return _scored(chain, setups, truth)


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


# ------------------------------------------------------------ rotary ballbar (issue 39)

BALLBAR_NOISE_UM = 0.3
#: The tool ball's cup run-out (um per axis, spindle frame) and each bar's length error
#: (um, one per test: the bar is re-seated between tests).
CUP_UM, BAR_LENGTH_UM = 20.0, 1.5
BAR_MM = 100.0


def ballbar_plan(tool_side: bool) -> list[tuple[str, np.ndarray]]:
    """(set-up, tool ball tip mm) of a ballbar campaign: one table ball at SPHERE_MM and a
    tool ball at the controlled point; with a tool-side rotary axis a second tool ball
    100 mm longer (a head's axis sees a line's tilt only through two levers)."""
    out = [("K1", np.zeros(3))]
    if tool_side:
        out.append(("K2", np.array([0.0, 0.0, -100.0])))
    return out


def run_ballbar_case(chain, gch: gen.GenChain, rng: np.random.Generator,  # noqa: ANN001
                     probe: bool) -> dict:
    """One campaign of rotary ballbar tests (:func:`cases.chain_generator.ballbar_paths`,
    the bar 100 mm along X, Y and Z from the table ball, each set-up of
    :func:`ballbar_plan`), with ``probe`` a sphere probed over a 5 x 6 grid as well; abbe
    identifies the location errors, judged as :func:`run_case`."""
    truth = gen.random_location(gch, rng)
    setups = []
    for su, tip in ballbar_plan(bool(chain.tool_side)):
        off = rng.normal(0.0, SPHERE_SETUP_UM * 1e-3, 3)
        cup = rng.normal(0.0, CUP_UM * 1e-3, 3)
        for label, path in gen.ballbar_paths(gch):
            for d, e in zip("XYZ", np.eye(3)):
                tool = SPHERE_MM + BAR_MM * e
                obs = gen.ballbar_readings(gch, truth, SPHERE_MM, off, tool, tip, cup, path,
                                           float(rng.normal(0.0, BAR_LENGTH_UM)),
                                           BALLBAR_NOISE_UM, rng)
                setups.append(ChainSetup("ballbar", f"{su}_{label}_{d}", tuple(SPHERE_MM), path,
                                         obs, tuple(tip), BALLBAR_NOISE_UM, tuple(tool), su))
    if probe:
        angles = gen.grid(gch)
        off = rng.normal(0.0, SPHERE_SETUP_UM * 1e-3, 3)
        obs = gen.probe_centres(gch, truth, SPHERE_MM, off, np.zeros(3), angles,
                                PROBE_NOISE_UM, rng)
        setups.append(ChainSetup("probe", "S1", tuple(SPHERE_MM), angles, obs,
                                 (0.0, 0.0, 0.0), PROBE_NOISE_UM))
    return _scored(chain, setups, truth)


def ballbar_campaign(path: Path, cases: int, seed: int, probe: bool = False) -> dict:
    """:func:`campaign` with rotary ballbar tests (:func:`run_ballbar_case`)."""
    chain = load_machine(path).extra["chain"]
    gch = gen.read_chain(path)
    rng = np.random.default_rng(seed)
    t0 = time.perf_counter()
    res = [run_ballbar_case(chain, gch, rng, probe) for _ in range(cases)]
    dt = time.perf_counter() - t0
    rows = [r for c in res for r in c["rows"]]
    worst = max(rows, key=lambda r: r[1] / max(r[2], 1.0 if r[0][1] in "XYZ" else 5.0),
                default=None)
    return {"file": path.name, "chain": chain.name, "kind": chain.kind, "cases": cases,
            "plan": "probing + rotary ballbar" if probe else "rotary ballbar",
            "observable": sorted({r[0] for r in rows}),
            "unobservable": list(res[0]["unobservable"]),
            "unobservable_varies": any(c["unobservable"] != res[0]["unobservable"] for c in res),
            "within": sum(r[3] for r in rows), "compared": len(rows),
            "share_within": sum(r[3] for r in rows) / max(len(rows), 1),
            "cases_all_within": sum(all(r[3] for r in c["rows"]) for c in res),
            "within_interval_only": sum(r[1] <= r[2] for r in rows),
            "rms_weighted": float(np.median([c["rms"] for c in res])),
            "worst": None if worst is None else {"name": worst[0], "error": worst[1],
                                                  "u95": worst[2]},
            "seconds": dt}


def _scored(chain, setups: list[ChainSetup], truth: dict[str, float]) -> dict:  # noqa: ANN001
    """Identify ``setups`` and score each identified location error against ``truth``:
    (name, |error|, u95, within max(u95, 1 um / 5 urad)), with what stays unobservable and
    the weighted RMS residual."""
    fit = identify_chain(chain, setups, explain=False)
    rows = []
    for r in fit.rows:
        if r.value is None:
            continue
        floor = 1.0 if r.unit == "um" else 5.0
        err = abs(r.value - truth[r.name])
        rows.append((r.name, err, r.u95, err <= max(r.u95, floor)))
    return {"rows": rows, "unobservable": fit.unobservable, "rms": fit.rms_weighted}
