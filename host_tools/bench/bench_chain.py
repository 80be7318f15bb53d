"""Synthetic campaigns for every kinematic chain (issue 39): the independent generator
(cases/chain_generator.py) hides random location errors, abbe reads the machine file (its
strict ``[chain]`` reader) and identifies them back (abbe.analysis.five_axis.chain_fit).
Scored by cases/chain_suite.py.

Criterion: each observable location error within max(its 95 % interval, 1 um / 5 urad) of
the truth in >= 97 % of the cases; the unobservable ones named.

With ``--motions H``: the generator also hides error motions of both rotary axes (every
ISO 230-7 component, harmonics from the first ISO 230-7 allows up to H, amplitudes up to
1 um / 4 urad), the plan adds a sphere 100 mm further out, and abbe identifies the error
motions up to H as well (cases/chain_suite.py ``motion_campaign``): every observable
location error and motion coefficient judged the same way.

With ``--ballbar``: rotary ballbar data instead (cases/chain_suite.py ``ballbar_campaign``:
each rotary axis turning, the other held at two angles, the bar 100 mm along X, Y and Z
from one table ball; on a machine with a tool-side axis a second tool ball 100 mm longer);
``--ballbar probe`` adds one sphere probed over a 5 x 6 grid.

Usage: python bench/bench_chain.py [--cases N] [--seed S] [--motions H | --ballbar [probe]]
[--json OUT] [machine.toml ...] (default: every file in cases/five_axis_chains/). Prints one table row
per kind.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from cases.chain_suite import CHAINS, ballbar_campaign, campaign, motion_campaign  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="*", type=Path)
    ap.add_argument("--cases", type=int, default=100)
    ap.add_argument("--seed", type=int, default=39)
    ap.add_argument("--json", type=Path)
    ap.add_argument("--motions", type=int, default=0, metavar="H",
                    help="hide and identify error motions up to harmonic H (0: location only)")
    ap.add_argument("--grid", type=int, nargs=2, default=(6, 8), metavar=("N1", "N2"),
                    help="angles per rotary axis with --motions (default 6 8)")
    ap.add_argument("--ballbar", nargs="?", const="alone", choices=("alone", "probe"),
                    help="rotary ballbar campaigns (alone, or with a probed sphere: probe)")
    a = ap.parse_args(argv)
    files = a.files or sorted(CHAINS.glob("*.toml"))
    out = []
    if a.ballbar:
        print("| kind | chain | plan | cases | observable within | share | cases all within | "
              "within the 95 % interval alone | weighted RMS | unobservable | worst | s |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|")
        for f in files:
            r = ballbar_campaign(f, a.cases, a.seed, a.ballbar == "probe")
            out.append(r)
            w = r["worst"] or {"name": "-", "error": 0.0, "u95": 0.0}
            print(f"| {r['kind']} | {r['chain']} | {r['plan']} | {r['cases']} | {r['within']}/"
                  f"{r['compared']} | {100 * r['share_within']:.1f} % | "
                  f"{r['cases_all_within']}/{r['cases']} | "
                  f"{100 * r['within_interval_only'] / max(r['compared'], 1):.1f} % | "
                  f"{r['rms_weighted']:.2f} | {', '.join(r['unobservable'])}"
                  f"{' (varies)' if r['unobservable_varies'] else ''} | {w['name']} "
                  f"{w['error']:.2f} (U {w['u95']:.2f}) | {r['seconds']:.0f} |", flush=True)
        if a.json:
            a.json.write_text(json.dumps(out, indent=2) + "\n", encoding="utf-8")
        return 0 if all(r["share_within"] >= 0.97 for r in out) else 1
    if a.motions:
        print("| kind | chain | cases | location errors within | motion coefficients within "
              "| share | cases all within | within the 95 % interval alone | weighted RMS "
              "(location only) | unobservable | motion coefficients not seen | worst | s |")
        print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
        for f in files:
            r = motion_campaign(f, a.cases, a.seed, a.motions, tuple(a.grid))
            out.append(r)
            n = r["location_compared"] + r["motion_compared"]
            w = r["worst"] or {"name": "-", "error": 0.0, "u95": 0.0}
            print(f"| {r['kind']} | {r['chain']} | {r['cases']} | {r['location_within']}/"
                  f"{r['location_compared']} | {r['motion_within']}/{r['motion_compared']} | "
                  f"{100 * r['share_within']:.1f} % | {r['cases_all_within']}/{r['cases']} | "
                  f"{100 * r['within_interval_only'] / max(n, 1):.1f} % | "
                  f"{r['rms_weighted']:.2f} ({r['rms_location_only']:.2f}) | "
                  f"{', '.join(r['unobservable'])} | "
                  f"{', '.join(r['motion_unobservable']) or '-'} of {r['n_motion']} | "
                  f"{w['name']} {w['error']:.2f} (U {w['u95']:.2f}) | {r['seconds']:.0f} |",
                  flush=True)
        if a.json:
            a.json.write_text(json.dumps(out, indent=2) + "\n", encoding="utf-8")
        return 0 if all(r["share_within"] >= 0.97 for r in out) else 1
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
