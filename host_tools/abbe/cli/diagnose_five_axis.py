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
from typing import Callable

from abbe.cli.conventions import json_file, json_to_stdout
from abbe.formats.output import Outputs


def run_five_axis_diagnose(args: argparse.Namespace) -> int:
    from abbe.analysis.five_axis.data import load_plan
    from abbe.diagnose.five_axis import diagnose_five_axis
    from abbe.formats.machine import load_machine

    def build() -> tuple[dict, str]:
        machine = load_machine(args.machine)
        spec = machine.five_axis
        diag = diagnose_five_axis(spec, load_plan(spec).blocks)
        doc = {"format": "abbe-five-axis-diagnose 1.0", "machine": machine.name,
               "kinematics": spec.geometry.kind,
               **diag.to_json(),
               "provenance": {"machine_file": str(machine.path), "sha256": machine.sha256}}
        return doc, diag.text()

    return write_diagnosis(args, "diagnose_five_axis.json", build)


def write_diagnosis(args: argparse.Namespace, json_name: str,
                    build: Callable[[], tuple[dict, str]]) -> int:
    """Run ``build`` (the diagnosis: its JSON document and its text report) once the
    output folder ``--out`` and ``--json FILE`` are claimed, so a bad output path fails
    before the work; write OUT/``json_name`` and OUT/report.txt atomically (and the
    ``--json`` file), then print the JSON (``--json -``) or the report. Exit code 0."""
    with Outputs() as outs:
        staging = outs.directory(args.out, option="--out")
        js = outs.file(json_file(args), option="--json") if json_file(args) else None
        doc, report = build()
        text = json.dumps(doc, indent=2, allow_nan=False) + "\n"
        (Path(staging) / json_name).write_text(text, encoding="utf-8")
        (Path(staging) / "report.txt").write_text(report, encoding="utf-8")
        if js is not None:
            js.write_text(text, encoding="utf-8")
    print(text if json_to_stdout(args) else report, end="")
    return 0
