"""Which noise makes a name? Redraw one noise source of a second-generator case (issue 36).

python host_tools/bench/bench_noise_source.py --case-seed 926288747 [--effects E1,E2]
       --redraw ballbar|commissioning [--draws N] [--first K] [--ballbar-noise ar1|white|none]
       [--commissioning-noise drawn|none] --work DIR [--out RESULTS.jsonl]

The generator (cases/independent2) draws everything from one random stream: the
machine, the effects, then every instrument's noise. To tell which noise a name comes
from, this script keeps every draw of the case and replaces one source's noise by a
stream of its own (the same number of draws taken from the case's stream, so nothing
else moves):

* ``--redraw ballbar``: the circles' AR(1) noise (``instruments.ar1``), draw k of N;
  the commissioning fit (``abbe fit`` on the laser lines) is made once and reused;
* ``--redraw commissioning``: the white noise of the commissioning laser lines (the fit's
  input), draw k of N, each with its own ``abbe fit``; the checks keep the case's noise.

``--ballbar-noise white`` keeps the circles' noise level without its correlation, ``none``
removes it; ``--commissioning-noise none`` fits noise-free commissioning lines. One JSON line
per draw: what was named, whether a declared tool changed where right, and the tool
offset candidate's value (mm) and log evidence ratio. Positions mm, values um.
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import cases.independent2.instruments as instruments  # noqa: E402
import cases.independent2.suite as suite  # noqa: E402

_ORIGINAL_AR1 = instruments.ar1
_ORIGINAL_LASER_ROWS = suite.laser_rows


class _NoiseOnly:
    """The case's random stream, except that the white noise of the given scales comes
    from ``own`` (the case's draw is still taken, so every later draw is the same)."""

    def __init__(self, rng: np.random.Generator, own: np.random.Generator | None,
                 scales: set[float]) -> None:
        self.rng, self.own, self.scales = rng, own, scales

    def normal(self, loc: Any = 0.0, scale: Any = 1.0, size: Any = None) -> Any:
        v = self.rng.normal(loc, scale, size)
        if size is None and isinstance(scale, float) and scale in self.scales:
            return 0.0 if self.own is None else float(self.own.normal(loc, scale))
        return v

    def __getattr__(self, name: str) -> Any:
        return getattr(self.rng, name)


def _patch(ballbar_rng: list[Any], ballbar_mode: str, fit_rng: list[Any]) -> None:
    """Route the circles' and the commissioning lines' noise (see the module doc)."""
    def ar1(rng: np.random.Generator, n: int, sigma: float, rho: float) -> np.ndarray:
        rng.normal(0.0, 1.0, n)          # the case's draws, taken and not used
        rng.normal(0.0, 1.0)
        if ballbar_mode == "none":
            return np.zeros(n)
        own = ballbar_rng[0] if ballbar_rng[0] is not None else np.random.default_rng(0)
        return _ORIGINAL_AR1(own, n, sigma, 0.0 if ballbar_mode == "white" else rho)

    def laser_rows(rng: Any, m: Any, eff: Any, axis: str, *rest: Any) -> Any:
        if eff is None and fit_rng[0] != "case":       # a commissioning line
            noise = rest[-1] if isinstance(rest[-1], dict) else rest[-2]
            scales = {noise["laser_um"], noise["straight_um"], noise["angle_urad"]}
            rng = _NoiseOnly(rng, fit_rng[0], scales)
        return _ORIGINAL_LASER_ROWS(rng, m, eff, axis, *rest)
    instruments.ar1 = ar1
    suite.laser_rows = laser_rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--case-seed", type=int, required=True)
    ap.add_argument("--effects", default="", help="comma list (suite.SINGLE names); none: clean")
    ap.add_argument("--redraw", choices=("ballbar", "commissioning"), required=True)
    ap.add_argument("--draws", type=int, default=10)
    ap.add_argument("--first", type=int, default=1)
    ap.add_argument("--ballbar-noise", choices=("ar1", "white", "none"), default="ar1")
    ap.add_argument("--commissioning-noise", choices=("drawn", "none"), default="drawn")
    ap.add_argument("--work", required=True)
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    effects = tuple(e for e in a.effects.split(",") if e)
    case = suite.Case("noise_source", "single" if effects else "clean", effects, a.case_seed)
    ballbar_rng: list[Any] = [None]
    fit_rng: list[Any] = ["case" if a.commissioning_noise == "drawn" else None]
    _patch(ballbar_rng, a.ballbar_noise, fit_rng)
    work = Path(a.work)
    base = work / "commissioning"
    rows = []
    for k in range(a.first, a.first + a.draws):
        ballbar_rng[0] = np.random.default_rng([a.case_seed, k, 1])
        if a.redraw == "commissioning":
            if a.commissioning_noise == "drawn":
                fit_rng[0] = np.random.default_rng([a.case_seed, k, 2])
            shutil.rmtree(base, ignore_errors=True)
        if not (base / "model" / "model.bin").exists():
            suite.build(case, base, fit=True)
        d = work / f"draw_{k}"
        shutil.rmtree(d, ignore_errors=True)
        b = suite.build(case, d, fit=False)
        shutil.copytree(base / "model", d / "model")
        b.model = d / "model" / "model.bin"
        res = suite.run(b)
        s = suite.score(b, res)
        tool = res.to_json()["candidates"].get("tool_offset") or {}
        row = {"draw": k, "redraw": a.redraw, "named": s["named"],
               "tool_changed_where_right": s["tool_changed_where_right"],
               "tool_value_mm": tool.get("value"), "tool_log_evidence": tool.get("log_evidence")}
        rows.append(row)
        print(json.dumps(row), flush=True)
        if a.out:
            with open(a.out, "a") as f:
                f.write(json.dumps(row) + "\n")
        shutil.rmtree(d)
    changed = sum(r["tool_changed_where_right"] for r in rows)
    print(f"{len(rows)} draws of the {a.redraw} noise: a declared tool changed where right in "
          f"{changed}; any name in {sum(bool(r['named']) for r in rows)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
