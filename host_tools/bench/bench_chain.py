"""Synthetic campaigns for every kinematic chain (issue 39): the independent generator
(cases/chain_generator.py) hides random location errors, abbe reads the machine file (its
strict ``[chain]`` reader) and identifies them back (abbe.analysis.five_axis.chain_fit).
Scored by cases/chain_suite.py.

Criterion: each observable location error within max(its 95 % interval, 1 um / 5 urad) of
the truth in >= 97 % of the cases; the unobservable ones named.

Usage: python bench/bench_chain.py [--cases N] [--seed S] [--json OUT] [machine.toml ...]
(default: every file in cases/five_axis_chains/). Prints one table row per kind.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from cases.chain_suite import CHAINS, campaign  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="*", type=Path)
    ap.add_argument("--cases", type=int, default=100)
    ap.add_argument("--seed", type=int, default=39)
    ap.add_argument("--json", type=Path)
    a = ap.parse_args(argv)
    files = a.files or sorted(CHAINS.glob("*.toml"))
    out = []
    print("| kind | chain | cases | observable within | share | cases all within | "
          "within the 95 % interval alone | unobservable | s |")
    print("|---|---|---|---|---|---|---|---|---|")
    for f in files:
        r = campaign(f, a.cases, a.seed)
        out.append(r)
        print(f"| {r['kind']} | {r['chain']} | {r['cases']} | {r['within']}/{r['compared']} | "
              f"{100 * r['share_within']:.1f} % | {r['cases_all_within']}/{r['cases']} | "
              f"{100 * r['within_interval_only'] / max(r['compared'], 1):.1f} % | "
              f"{', '.join(r['unobservable'])} | {r['seconds']:.0f} |")
    if a.json:
        a.json.write_text(json.dumps(out, indent=2) + "\n", encoding="utf-8")
    return 0 if all(r["share_within"] >= 0.97 for r in out) else 1


if __name__ == "__main__":
    raise SystemExit(main())
