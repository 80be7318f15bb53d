"""``abbe fit`` for a five-axis machine file (one with a ``[rotary]`` section).

Reads the plan's probing / R-test / indexer files, identifies the location
errors (and the error motions the plan resolves, ``[rotary.fit] harmonics``)
and writes OUT/five_axis.json (the identified table, observability,
dispersion, held-out judgement), OUT/report.txt and OUT/report/ (HTML with
polar plots), atomically (:class:`abbe.formats.output.Outputs`).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from abbe.formats.output import Outputs


def is_five_axis(path: str) -> bool:
    """True when the machine file has a ``[rotary]`` section (bad files raise AbbeInputError)."""
    from abbe.formats.machine import load_machine
    return load_machine(path).five_axis is not None


def run_five_axis(args: argparse.Namespace) -> int:
    from abbe.analysis.five_axis.data import load_plan
    from abbe.analysis.five_axis.identify import identify
    from abbe.analysis.five_axis.problem import build_params
    from abbe.analysis.five_axis.report import text_report, to_json, write_html
    from abbe.formats.machine import load_machine

    t0 = time.perf_counter()
    outs = Outputs()
    try:
        staging = outs.directory(args.out, option="--out")
        machine = load_machine(args.machine)
        spec = machine.five_axis
        plan = load_plan(spec)
        t_read = time.perf_counter()
        params = build_params(spec, plan.blocks)
        res = identify(spec, plan.blocks, params)
        t_fit = time.perf_counter()
        doc = to_json(res, spec, plan)
        doc["provenance"] = {"machine_file": str(machine.path), "sha256": machine.sha256}
        (Path(staging) / "five_axis.json").write_text(
            json.dumps(doc, indent=2, allow_nan=False) + "\n", encoding="utf-8")
        text = text_report(doc)
        (Path(staging) / "report.txt").write_text(text, encoding="utf-8")
        if not args.no_report:
            write_html(res, doc, Path(staging) / "report")
    except BaseException:
        outs.abort()
        raise
    outs.commit()
    if not args.quiet:
        print(text, end="")
    print(f"abbe fit: wrote {args.out} (five-axis {spec.geometry.kind}: rank "
          f"{res.obs.rank} of {res.obs.n_params}, {int(res.obs.observable.sum())} observable)")
    if args.bench:
        print(f"bench: read+sphere fits {1000 * (t_read - t0):8.1f} ms")
        print(f"bench: identification   {1000 * (t_fit - t_read):8.1f} ms")
        print(f"bench: total            {1000 * (time.perf_counter() - t0):8.1f} ms")
    return 0
