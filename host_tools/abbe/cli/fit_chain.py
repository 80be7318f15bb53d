"""``abbe fit`` on a ``[chain]`` machine file (head-head, head-table, dual-rotary table, or
a trunnion written as a chain): the location errors (and with ``[chain.fit] harmonics``
the error motions) from its probing, R-test and rotary ballbar files, with what the plan cannot see (abbe.analysis.five_axis.chain_fit). Writes chain_fit.json,
report.txt and the HTML report (report/index.html) into the output directory, and for a head-head, head-table or dual
rotary table chain model_five.bin (format 1.4, the C runtime's and the LinuxCNC
component's table)."""

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
    from abbe.analysis.five_axis.chain_uncertainty import (monte_carlo_chain,
                                                           state_monte_carlo_chain)
    from abbe.errors import AbbeInputError
    from abbe.formats.machine import load_machine

    t0 = time.perf_counter()
    machine = load_machine(args.machine)
    chain = machine.extra["chain"]
    setups = setups_from_machine(machine)
    if not setups:
        raise AbbeInputError("a [chain] machine file needs at least one [probing.NAME], "
                             "[rtest.NAME] or [rotary_ballbar.NAME] section to fit",
                             file=str(args.machine), field="chain")
    h = machine.extra["chain_plans"].harmonics
    fit = identify_chain(chain, setups, explain=False, harmonics=h)
    setups = reweight(chain, setups, fit, h)
    fit = identify_chain(chain, setups, harmonics=h)
    doc = {"format": "abbe-chain-fit 1.0", "machine": machine.name,
           **fit_to_json(fit, setups),
           "provenance": {"machine_file": str(machine.path), "sha256": machine.sha256}}
    stated: dict[str, float] = {}
    if getattr(args, "mc", 0):  # GUM S1 check of every U; its U stated beyond 10 %
        stated = state_monte_carlo_chain(doc, monte_carlo_chain(chain, setups, fit,
                                                                draws=args.mc, seed=1))
    text = "\n".join(report_rows(fit, stated)) + "\n"
    outs = Outputs()
    try:
        staging = outs.directory(args.out, option="--out")
        doc["blob"] = write_chain_table(fit, staging)
        (staging / "chain_fit.json").write_text(json.dumps(doc, indent=2) + "\n",
                                                encoding="utf-8")
        (staging / "report.txt").write_text(text, encoding="utf-8")
        from abbe.analysis.certificate import test_date
        from abbe.analysis.five_axis.chain_report import write_chain_html
        write_chain_html(doc, text, staging / "report", test_date(str(machine.path)),
                         {st.name: st.kind for st in setups})
    except BaseException:
        outs.abort()
        raise
    outs.commit()
    if not args.quiet:
        print(text, end="")
    table = (f"model_five.bin (format 1.4, {doc['blob']['bytes']} B)" if doc["blob"].get("file")
             else f"no table: {doc['blob']['reason']}")
    mot = (f", {sum(r.value is not None for r in fit.motion_rows)} of {len(fit.motion_rows)} "
           f"error motion coefficients (harmonics {h})" if h else "")
    print(f"abbe fit: wrote {args.out} ({chain.name}, {chain.kind}: rank {fit.rank} of "
          f"{fit.n_unknowns}, {len(fit.observable)} of 10 location errors{mot} observable; "
          f"{table})")
    if args.bench:
        print(f"bench: total {1000 * (time.perf_counter() - t0):8.1f} ms")
    return 0


def write_chain_table(fit, staging) -> dict:  # noqa: ANN001 (ChainFit, Path)
    """Write model_five.bin (format 1.4) for a kind 3-5 chain into ``staging``: the
    location errors and error motions in the fit's convention (an error the plan cannot see alone holds the
    value the convention gives it, the ones fixed at 0 hold 0: a workpiece datum absorbs
    what they leave, docs/concepts.md). Returns the JSON entry: the file, its size and
    CRC-32 and the convention, or ``file`` None and the reason (a table-table trunnion
    written as a chain: its table is the ``[rotary]`` machine file's format 1.2 one)."""
    import zlib

    from abbe.formats.chain_blob import write_chain_blob
    from abbe.model.table import TableError

    rows = fit.rows + fit.motion_rows
    held = {**fit.values, **fit.motion_values}
    convention = {"fixed_at_zero": [r.name for r in rows if r.status == "fixed at 0"],
                  "held_in_convention": {r.name: held[r.name] for r in rows
                                         if r.status == "convention"}}
    try:
        blob = write_chain_blob(fit.chain, fit.errors())
    except TableError as exc:
        return {"file": None, "reason": str(exc), "convention": convention}
    (staging / "model_five.bin").write_bytes(blob)
    return {"file": "model_five.bin", "format": "1.4", "bytes": len(blob),
            "crc32": f"0x{zlib.crc32(blob[:-4]) & 0xFFFFFFFF:08X}", "convention": convention}
