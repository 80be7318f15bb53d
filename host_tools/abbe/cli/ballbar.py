"""``abbe ballbar MACHINE.toml NAME``: ISO 230-4 circular-test evaluation and polar plot."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from abbe.cli.conventions import examples
from abbe.errors import AbbeInputError
from abbe.formats.machine import load_machine
from abbe.formats.output import Outputs


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "ballbar", help="evaluate a ballbar test (ISO 230-4: G, H, centre, radius; polar plot)",
        description="Evaluate the ballbar test NAME of a machine file: least-squares circle, "
                    "centre offset, radius deviation, circular deviation G per direction and "
                    "bidirectional, circular hysteresis H (um; feed-in/out arcs excluded), and "
                    "a polar plot PNG.",
        epilog=examples("abbe ballbar examples/vmc500/machine.toml circle1"))
    p.add_argument("machine", help="machine file (TOML) with a [ballbar.NAME] section")
    p.add_argument("name", help="ballbar test name")
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--plot", metavar="PNG", help="polar plot path (default ballbar_NAME.png)")
    g.add_argument("--no-plot", action="store_true", help="do not write the plot")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    # scipy (abbe.analysis.iso230_4) is imported inside: every other command would pay for it
    with Outputs() as outs:
        return _run(args, outs)


def _run(args: argparse.Namespace, outs: Outputs) -> int:
    from abbe.analysis.iso230_4 import evaluate_ballbar, plot_polar
    from abbe.formats.ballbar_csv import check_trace_timing
    from abbe.formats.ballbar_file import read_ballbar_file
    from abbe.model.geometry import check_test_in_travel, from_machine

    plot = None if args.no_plot else Path(args.plot or f"ballbar_{args.name}.png")
    staged = None if plot is None else outs.file(plot, option="--plot")
    m = load_machine(args.machine)
    if args.name not in m.ballbar:
        avail = ", ".join(sorted(m.ballbar)) or "none"
        raise AbbeInputError(f"no ballbar test {args.name!r} (available: {avail})",
                             file=str(m.path), field=f"ballbar.{args.name}")
    bt = m.ballbar[args.name]
    test = from_machine(bt)
    travel = {a: s.travel_mm for a, s in m.axes.items()}
    try:
        check_test_in_travel(test, travel, file=str(m.path))
    except AbbeInputError as exc:
        raise AbbeInputError(exc.message, file=exc.file, line=m.line_of(exc.field or ""),
                             field=exc.field) from None
    trace = read_ballbar_file(bt, str(m.path))
    check_trace_timing(trace, test, str(m.path))
    res = evaluate_ballbar(trace, test)
    if staged is not None:
        plot_polar(res, str(staged), title=f"{m.name} ballbar {args.name}: {test.plane}, "
                   f"R {test.radius_mm:g} mm, F {test.feed_mm_min:g} mm/min")
    if args.json:
        d = {"machine": str(m.path), "file": str(bt.file), **res.to_json(),
             "plot": None if plot is None else str(plot)}
        json.dump(d, sys.stdout, indent=2, allow_nan=False)
        sys.stdout.write("\n")
    else:
        print(res.format_text())
        if plot is not None:
            print(f"  polar plot: {plot}")
    return 0
