"""Five-axis parameters' U (k = 2) against the Monte Carlo (new observations, the exact model
solved again) on examples/trunnion5ax: value / U / MC U per observable parameter.

    python host_tools/bench/bench_five_axis_uncertainty.py [--draws 400]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from abbe.analysis.five_axis import uncertainty as fx  # noqa: E402
from abbe.analysis.five_axis.data import load_plan  # noqa: E402
from abbe.analysis.five_axis.identify import identify  # noqa: E402
from abbe.analysis.five_axis.problem import build_params  # noqa: E402
from abbe.formats.machine import load_machine  # noqa: E402

REPO = Path(__file__).resolve().parents[2]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=400)
    ap.add_argument("--machine", type=Path, default=REPO / "examples" / "trunnion5ax" / "machine.toml")
    a = ap.parse_args()
    spec = load_machine(a.machine).five_axis
    plan = load_plan(spec)
    params = build_params(spec, plan.blocks)
    res = identify(spec, plan.blocks, params)
    t0 = time.perf_counter()
    mc = fx.monte_carlo(spec, plan.blocks, params, res, draws=a.draws, seed=7)
    print(f"{a.draws} draws: {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    print("| parameter | kind | value | U (k = 2) | U MC | U_MC / U - 1 |")
    print("|---|---|---|---|---|---|")
    for n, v in mc["parameters"].items():
        print(f"| {n} | {v['kind']} | {v['value']:.3f} {v['unit']} | {v['U']:.3f} | "
              f"{v['U_mc']:.3f} | {100 * (v['U_mc'] / v['U'] - 1):+.1f} % |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
