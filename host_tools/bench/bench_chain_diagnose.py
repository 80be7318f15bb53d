"""Five-axis diagnose on every kinematic chain (issue 39), judged on the independent
generator (cases/chain_generator.py, which imports nothing of abbe).

Per kind and case, the generator hides random location errors and ONE of: nothing
(clean), an error motion (a random ISO 230-7 component of a random rotary axis at a
random harmonic the plan resolves, 2-4 um / 10-20 urad), or - against a model that holds
the true location errors - one location error changed by 8-15 um / 40-80 urad. The plan:
spheres at two heights, an R-test, a longer stylus on a machine with a tool-side axis,
a 6 x 8 grid. abbe.diagnose.chain.diagnose_chain names what is missing; scored: the
hidden effect named first (exactly, or as ambiguous with it), nothing named on clean
cases, the held-out gap before and after. A changed location error the plan cannot see
(:func:`identify_chain`'s unobservable set: the sphere's place takes it, or it is one
error with another) is scored apart: nothing should be named for it, or (their sum
seen) it or a name ambiguous with it.

Usage: python bench/bench_chain_diagnose.py [--cases N] [--seed S] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from abbe.analysis.five_axis.chain_fit import ChainSetup, identify_chain  # noqa: E402
from abbe.diagnose.chain import diagnose_chain  # noqa: E402
from abbe.formats.machine import load_machine  # noqa: E402
from cases import chain_generator as gen  # noqa: E402
from cases.chain_suite import (CHAINS, PROBE_NOISE_UM, RTEST_NOISE_UM, SPHERE_SETUP_UM,  # noqa: E402
                               plan)

GRID = (6, 8)


def _setups(chain, gch, loc, motions, rng):  # noqa: ANN001, ANN202
    angles = gen.grid(gch, *GRID)
    out = []
    for kind, name, sphere, tip in plan(bool(chain.tool_side)):
        off = rng.normal(0.0, SPHERE_SETUP_UM * 1e-3, 3)
        if kind == "probe":
            obs = gen.probe_centres(gch, loc, sphere, off, tip, angles, PROBE_NOISE_UM, rng,
                                    motions)
            sig = PROBE_NOISE_UM
        else:
            obs = gen.rtest_readings(gch, loc, sphere, off, tip, angles, RTEST_NOISE_UM, rng,
                                     motions)
            sig = RTEST_NOISE_UM
        out.append(ChainSetup(kind, name, tuple(sphere), angles, obs, tuple(tip), sig))
    return out


def run_case(chain, gch, what: str, rng: np.random.Generator) -> dict:  # noqa: ANN001
    loc = gen.random_location(gch, rng)
    motions: dict = {}
    model = None
    hidden = ""
    if what == "motion":
        ax = gch.names[int(rng.integers(2))]
        comp = "XYZABC"[int(rng.integers(6))]
        k = int(rng.integers(gen.first_harmonic(ax, comp), 3))  # up to the 2nd harmonic
        size = rng.uniform(2.0, 4.0) if comp in "XYZ" else rng.uniform(10.0, 20.0)
        motions = {f"{ax}.{comp}": gen.ErrorMotion({k: float(size)},
                                                   {k: float(rng.uniform(0, 2 * np.pi))})}
        hidden = f"E{comp}{ax}({ax}) {k}"
    elif what == "location":
        model = dict(loc)
        ax = gch.names[int(rng.integers(2))]
        name = gen.location_names(ax)[int(rng.integers(5))]
        pos = name[1] in "XYZ"
        step = rng.uniform(8.0, 15.0) if pos else rng.uniform(40.0, 80.0)
        loc = dict(loc)
        loc[name] += float(step * rng.choice([-1.0, 1.0]))
        hidden = name
    setups = _setups(chain, gch, loc, motions, rng)
    # a location error the plan cannot see (the sphere's place takes it, or it is one
    # error with another) has nothing to be named by: scored apart
    unseen = hidden in identify_chain(chain, setups, explain=False).unobservable \
        if what == "location" else False
    t0 = time.perf_counter()
    d = diagnose_chain(chain, setups, model)
    dt = time.perf_counter() - t0
    names = [n.candidate.key for n in d.named]
    first = d.named[0] if d.named else None
    exact = bool(first and first.candidate.key == hidden)
    amb = bool(first and not exact and hidden in [k for k, _r in first.ambiguous_with])
    return {"what": what, "hidden": hidden, "named": names, "exact": exact, "ambiguous": amb,
            "unobservable": unseen,
            "gap_before_um": d.gap_before_um, "gap_after_um": d.gap_after_um,
            "heldout_before_um": d.heldout_before_um, "heldout_after_um": d.heldout_after_um,
            "seconds": dt}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=6, help="cases per kind and effect type")
    ap.add_argument("--seed", type=int, default=392)
    ap.add_argument("--json", type=Path)
    a = ap.parse_args(argv)
    rng = np.random.default_rng(a.seed)
    out = []
    print("| kind | hidden | cases | named first (exact) | named as ambiguous with it | "
          "other name / nothing | hidden but unobservable alone: nothing, it or ambiguous | "
          "clean: false names | median gap before -> after um | s per case |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for f in sorted(CHAINS.glob("*.toml")):
        chain = load_machine(f).extra["chain"]
        gch = gen.read_chain(f)
        for what in ("clean", "motion", "location"):
            res = [run_case(chain, gch, what, rng) for _ in range(a.cases)]
            out += [{"file": f.name, **r} for r in res]
            hid = [r for r in res if r["unobservable"]]
            seen = [r for r in res if not r["unobservable"]]
            ex = sum(r["exact"] for r in seen)
            am = sum(r["ambiguous"] for r in seen)
            false = sum(bool(r["named"]) for r in res) if what == "clean" else "-"
            other = "-" if what == "clean" else len(seen) - ex - am
            # nothing named, or (one error with another: their sum is seen) named as
            # ambiguous with the hidden one
            quiet = (f"{sum(not r['named'] or r['ambiguous'] or r['exact'] for r in hid)}"
                     f"/{len(hid)}"
                     if what == "location" else "-")
            gb = float(np.median([r["gap_before_um"] for r in res]))
            ga = float(np.median([r["gap_after_um"] for r in res]))
            sec = float(np.mean([r["seconds"] for r in res]))
            print(f"| {chain.kind} ({chain.name}) | {what} | {a.cases} | "
                  f"{ex if what != 'clean' else '-'} | {am if what != 'clean' else '-'} | "
                  f"{other} | {quiet} | {false} | {gb:.3f} -> {ga:.3f} | {sec:.1f} |", flush=True)
            for r in res:
                if r["unobservable"]:
                    print(f"    unobservable: hidden {r['hidden']}, named {r['named']}", flush=True)
                elif what != "clean" and not (r["exact"] or r["ambiguous"]):
                    print(f"    missed: hidden {r['hidden']}, named {r['named']}", flush=True)
                if what == "clean" and r["named"]:
                    print(f"    false: named {r['named']}", flush=True)
    if a.json:
        a.json.write_text(json.dumps(out, indent=2) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
