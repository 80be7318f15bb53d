"""``abbe fit`` for a five-axis machine file (one with a ``[rotary]`` section).

Reads the plan's probing / R-test / indexer files, identifies the location
errors (and the error motions the plan resolves, ``[rotary.fit] harmonics``)
and writes OUT/five_axis.json (the identified table, observability,
dispersion, held-out judgement), OUT/model_five.bin (the identified model as a
format 1.2 five-axis table for the C library, :mod:`abbe.formats.five_axis_blob`),
OUT/report.txt and OUT/report/ (HTML with polar plots), atomically
(:class:`abbe.formats.output.Outputs`).
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


def identify_into(machine_path: str | Path, staging: Path, report: bool = True):
    """Identify a five-axis machine file and write five_axis.json, report.txt and report/
    into ``staging``; returns (spec, result, json document, text, timings s)."""
    from abbe.analysis.five_axis.data import load_plan
    from abbe.analysis.five_axis.identify import identify
    from abbe.analysis.five_axis.problem import build_params
    from abbe.analysis.five_axis.report import text_report, to_json, write_html
    from abbe.formats.machine import load_machine

    t0 = time.perf_counter()
    machine = load_machine(machine_path)
    spec = machine.five_axis
    plan = load_plan(spec)
    t_read = time.perf_counter()
    params = build_params(spec, plan.blocks)
    res = identify(spec, plan.blocks, params)
    t_fit = time.perf_counter()
    doc = to_json(res, spec, plan)
    doc["provenance"] = {"machine_file": str(machine.path), "sha256": machine.sha256}
    doc["blob"] = write_table(res, spec, Path(staging))
    (Path(staging) / "five_axis.json").write_text(
        json.dumps(doc, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    text = text_report(doc)
    (Path(staging) / "report.txt").write_text(text, encoding="utf-8")
    if report:
        write_html(res, doc, Path(staging) / "report")
    return spec, res, doc, text, {"read": t_read - t0, "fit": t_fit - t_read}


def write_table(res, spec, staging: Path) -> dict:
    """Write model_five.bin (format 1.2) into ``staging``: the identified errors; the
    ones the plan cannot observe (NaN in the fit) are written as 0, i.e. not
    compensated, and named. Returns the JSON entry describing the file."""
    import zlib

    import numpy as np

    from abbe.analysis.five_axis.problem import errors_from
    from abbe.formats.five_axis_blob import write_five_blob

    finite = np.isfinite(res.x)
    blob = write_five_blob(spec.geometry, errors_from(res.params, np.where(finite, res.x, 0.0), res.harmonics))
    (staging / "model_five.bin").write_bytes(blob)
    return {"file": "model_five.bin", "format": "1.2", "bytes": len(blob),
            "crc32": f"0x{zlib.crc32(blob[:-4]) & 0xFFFFFFFF:08X}",
            "written_as_zero_not_observable": [p.name for p, ok in zip(res.params, finite)
                                               if not ok and p.kind != "setup"]}


def run_five_axis(args: argparse.Namespace) -> int:
    t0 = time.perf_counter()
    outs = Outputs()
    try:
        staging = outs.directory(args.out, option="--out")
        spec, res, _doc, text, times = identify_into(args.machine, staging, not args.no_report)
    except BaseException:
        outs.abort()
        raise
    outs.commit()
    if not args.quiet:
        print(text, end="")
    print(f"abbe fit: wrote {args.out} (five-axis {spec.geometry.kind}: rank "
          f"{res.obs.rank} of {res.obs.n_params}, {int(res.obs.observable.sum())} observable)")
    if args.bench:
        print(f"bench: read+sphere fits {1000 * times['read']:8.1f} ms")
        print(f"bench: identification   {1000 * times['fit']:8.1f} ms")
        print(f"bench: total            {1000 * (time.perf_counter() - t0):8.1f} ms")
    return 0


def demo_five_axis(example: Path, staging: Path) -> dict:
    """``abbe demo --five-axis``: identify the example and compare with its truth (kept in
    ``example/truth/truth.json``, apart from the data). Writes truth_comparison.txt."""
    _spec, _res, doc, _text, _t = identify_into(example / "machine.toml", staging)
    truth = json.loads((example / "truth" / "truth.json").read_text(encoding="utf-8"))
    lines = ["error        identified (95 %)          truth     within"]
    n = n_in = 0
    for r in doc["parameters"]:
        if r["kind"] != "location":
            continue
        tv = truth["location"].get(r["name"], 0.0)
        if not r["observable"]:
            lines.append(f"{r['name']:<12} not observable            {tv:10.3f}  (named)")
            continue
        ok = abs(r["value"] - tv) <= max(r["ci95"], 1.0 if r["unit"] == "um" else 5.0)
        n, n_in = n + 1, n_in + ok
        lines.append(f"{r['name']:<12} {r['value']:10.3f} +- {r['ci95']:7.3f} {r['unit']:<4} "
                     f"{tv:10.3f}  {'yes' if ok else 'NO'}")
    (Path(staging) / "truth_comparison.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
    d = doc["dispersion_um"]
    return {"machine": example.name, "kinematics": doc["kinematics"],
            "observable_location_errors": n, "within_interval_or_1um_5urad": n_in,
            "unobservable": [r["name"] for r in doc["parameters"]
                             if r["kind"] == "location" and not r["observable"]],
            "dispersion_before_um": d["before"], "dispersion_after_um": d["after"],
            "heldout_before_um": d["heldout_before"], "heldout_after_um": d["heldout_after"]}
