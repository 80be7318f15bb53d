"""``abbe diagnose MACHINE.toml -o OUT/`` on a five-axis machine file (one with ``[rotary]``).

Runs the discrepancy workflow (:func:`abbe.diagnose.five_axis.diagnose_five_axis`): a
location-only identification of the plan, then the catalogue effects (cyclic ECC,
pivot drift, C wobble) judged on held-out probing positions, and the gap above what a
right model shows on the plan. Writes OUT/diagnose_five_axis.json
and OUT/report.txt atomically (and ``--json FILE``). ``--model`` is not used: the
model is identified from the same plan.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from abbe.cli.conventions import json_file, json_to_stdout
from abbe.formats.output import Outputs


def run_five_axis_diagnose(args: argparse.Namespace) -> int:
    from abbe.analysis.five_axis.data import load_plan
    from abbe.diagnose.five_axis import diagnose_five_axis
    from abbe.formats.machine import load_machine

    with Outputs() as outs:
        staging = outs.directory(args.out, option="--out")
        js = outs.file(json_file(args), option="--json") if json_file(args) else None
        machine = load_machine(args.machine)
        spec = machine.five_axis
        diag = diagnose_five_axis(spec, load_plan(spec).blocks)
        doc = {"format": "abbe-five-axis-diagnose 1.0", "machine": machine.name,
               "kinematics": spec.geometry.kind,
               **diag.to_json(),
               "provenance": {"machine_file": str(machine.path), "sha256": machine.sha256}}
        text = json.dumps(doc, indent=2, allow_nan=False) + "\n"
        (Path(staging) / "diagnose_five_axis.json").write_text(text, encoding="utf-8")
        (Path(staging) / "report.txt").write_text(diag.text(), encoding="utf-8")
        if js is not None:
            js.write_text(text, encoding="utf-8")
    if json_to_stdout(args):
        print(text, end="")
        return 0
    print(diag.text(), end="")
    return 0
