"""``abbe diagnose MACHINE.toml -o OUT/ [--model chain_fit.json]`` on a ``[chain]`` machine
file (head-head, head-table, dual-rotary table, or a trunnion written as a chain).

Runs :func:`abbe.diagnose.chain.diagnose_chain` on the file's probing and R-test set-ups:
the base model (``--model``: an ``abbe fit`` chain_fit.json, its location errors and error
motions held; without it the plan's location-only fit), then the catalogue (every error
motion component and harmonic of both rotary axes; with a model, every location error)
judged on held-out probing positions. Writes OUT/diagnose_chain.json and OUT/report.txt
atomically (and ``--json FILE``).
"""

from __future__ import annotations

import argparse

from abbe.cli.diagnose_five_axis import write_diagnosis


def run_chain_diagnose(args: argparse.Namespace) -> int:
    from abbe.analysis.five_axis.chain_fit import setups_from_machine
    from abbe.diagnose.chain import diagnose_chain, model_values
    from abbe.errors import AbbeInputError
    from abbe.formats.machine import load_machine
    from abbe.formats.structured import load_json

    machine = load_machine(args.machine)
    chain = machine.extra["chain"]
    model = None
    if args.model:
        doc, _tf = load_json(args.model, what="chain fit JSON", max_bytes=16 * 1024 * 1024)
        if not isinstance(doc, dict) or "location" not in doc or doc.get("chain") != chain.name:
            raise AbbeInputError(f"expected the chain_fit.json `abbe fit` wrote for chain "
                                 f"{chain.name!r} (keys chain, location, motions)",
                                 file=str(args.model), field="chain")
        model = model_values(doc)
    # the diagnosis' checks are 3-D centres and R-test readings: rotary ballbar tests are
    # read by `abbe fit` only (docs/concepts.md, "the kinematic chain")
    setups = [s for s in setups_from_machine(machine) if s.kind != "ballbar"]
    if not any(s.kind == "probe" for s in setups):
        raise AbbeInputError("abbe diagnose on a [chain] machine file needs at least one "
                             "[probing.NAME] section (its positions are the held-out data)",
                             file=str(args.machine), field="probing")
    def build() -> tuple[dict, str]:
        diag = diagnose_chain(chain, setups, model, machine.extra["chain_plans"].folds)
        doc = {"format": "abbe-chain-diagnose 1.0", "machine": machine.name, **diag.to_json(),
               "provenance": {"machine_file": str(machine.path), "sha256": machine.sha256,
                              "model": str(args.model) if args.model else None}}
        return doc, diag.text()

    return write_diagnosis(args, "diagnose_chain.json", build)
