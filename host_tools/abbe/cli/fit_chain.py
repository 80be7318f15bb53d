"""``abbe fit`` on a ``[chain]`` machine file (head-head, head-table, dual-rotary table, or
a trunnion written as a chain): the location errors from its probing and R-test files,
with what the plan cannot see (abbe.analysis.five_axis.chain_fit). Writes chain_fit.json
and report.txt into the output directory."""

from __future__ import annotations

import argparse
import json
import time

from abbe.formats.output import Outputs


def is_chain_machine(path: str) -> bool:
    """True when the machine file describes its kinematics by ``[chain]`` (bad files raise
    AbbeInputError)."""
    from abbe.formats.machine import load_machine
    return "chain_plans" in load_machine(path).extra


def run_chain(args: argparse.Namespace) -> int:
    from abbe.analysis.five_axis.chain_fit import (fit_to_json, identify_chain, report_rows,
                                                   reweight, setups_from_machine)
    from abbe.errors import AbbeInputError
    from abbe.formats.machine import load_machine

    t0 = time.perf_counter()
    machine = load_machine(args.machine)
    chain = machine.extra["chain"]
    setups = setups_from_machine(machine)
    if not setups:
        raise AbbeInputError("a [chain] machine file needs at least one [probing.NAME] or "
                             "[rtest.NAME] section to fit", file=str(args.machine), field="chain")
    fit = identify_chain(chain, setups, explain=False)
    setups = reweight(chain, setups, fit)
    fit = identify_chain(chain, setups)
    text = "\n".join(report_rows(fit)) + "\n"
    outs = Outputs()
    try:
        staging = outs.directory(args.out, option="--out")
        (staging / "chain_fit.json").write_text(json.dumps(fit_to_json(fit, setups), indent=2)
                                                + "\n", encoding="utf-8")
        (staging / "report.txt").write_text(text, encoding="utf-8")
    except BaseException:
        outs.abort()
        raise
    outs.commit()
    if not args.quiet:
        print(text, end="")
    print(f"abbe fit: wrote {args.out} ({chain.name}, {chain.kind}: rank {fit.rank} of "
          f"{fit.n_unknowns}, {len(fit.observable)} of 10 location errors observable)")
    if args.bench:
        print(f"bench: total {1000 * (time.perf_counter() - t0):8.1f} ms")
    return 0
