"""``abbe ballbar MACHINE.toml NAME [--json FILE|-] [-o DIR]``: ISO 230-4 circular-test evaluation,
polar plot, every result's expanded uncertainty U (k = 2) and, with tolerances, the
ISO 14253-1 verdicts (docs/uncertainty.md)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from abbe.cli.conventions import examples, json_file, json_option, json_to_stdout, print_json
from abbe.cli.options import int_range, iso_date
from abbe.errors import AbbeInputError
from abbe.formats.machine import load_machine
from abbe.formats.output import Outputs


MC_DRAWS = 200


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "ballbar", help="evaluate a ballbar test (ISO 230-4: G, H, centre, radius; polar plot)",
        description="Evaluate the ballbar test NAME of a machine file: least-squares circle, "
                    "centre offset, radius deviation, circular deviation G per direction and "
                    "bidirectional, circular hysteresis H (um; feed-in/out arcs excluded), and "
                    "a polar plot PNG; each result with its expanded uncertainty U (k = 2) "
                    "from the machine file's [uncertainty.ballbar] budget (or the ballbar "
                    "class defaults) and a Monte Carlo check; pass / fail / inconclusive "
                    "against [tolerances.ballbar] (ISO 14253-1).",
        epilog=examples("abbe ballbar examples/vmc500/machine.toml circle1",
                        "abbe ballbar examples/vmc500/machine.toml circle1 -o out/circle1"))
    p.add_argument("machine", help="machine file (TOML) with a [ballbar.NAME] section")
    p.add_argument("name", help="ballbar test name")
    json_option(p, "the JSON (G, H, centre, radius with U and verdicts)")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--plot", metavar="PNG", help="polar plot path (default ballbar_NAME.png)")
    g.add_argument("--no-plot", action="store_true", help="do not write the plot")
    p.add_argument("--mc", type=int_range(0, 100_000), default=MC_DRAWS, metavar="N",
                   help=f"Monte Carlo draws of the independent check (default {MC_DRAWS}; "
                        "0: none)")
    p.add_argument("--date", metavar="YYYY-MM-DD", type=iso_date,
                   help="test date for the report (default: the trace file's date)")
    p.add_argument("-o", "--out", metavar="DIR",
                   help="write DIR/ballbar.json (the --json document), DIR/report.html and "
                        "the polar plot DIR/ballbar_NAME.png (unless --plot / --no-plot)")
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

    from abbe.analysis.uncertainty import (agreement, ballbar_budget, ballbar_uncertainty,
                                           monte_carlo_ballbar)

    folder = outs.directory(args.out, option="--out") if args.out else None
    js = outs.file(json_file(args), option="--json") if json_file(args) else None
    if folder is not None and not args.no_plot and not args.plot:
        plot: Path | None = Path(args.out) / f"ballbar_{args.name}.png"
        staged = folder / plot.name
    else:
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
    budget, limits = ballbar_budget(m)
    unc = ballbar_uncertainty(trace, test, res, budget, limits)
    if args.mc:
        unc.monte_carlo = monte_carlo_ballbar(trace, test, budget, draws=args.mc)
        unc.monte_carlo["agreement"] = agreement(unc.results, unc.monte_carlo)
    if staged is not None:
        plot_polar(res, str(staged), title=f"{m.name} ballbar {args.name}: {test.plane}, "
                   f"R {test.radius_mm:g} mm, F {test.feed_mm_min:g} mm/min")
    d = {"machine": str(m.path), "machine_name": m.name, "file": str(bt.file), **res.to_json(),
         "plot": None if plot is None else str(plot), "uncertainty": unc.to_json(),
         "tolerances": limits or None, "verdicts": unc.verdicts()}
    if folder is not None:
        from abbe.analysis.certificate import ballbar_html, test_date
        (folder / "ballbar.json").write_text(json.dumps(d, indent=2, allow_nan=False) + "\n",
                                             encoding="utf-8")
        rel = None
        if plot is not None and staged is not None and Path(staged).parent == folder:
            rel = plot.name
        (folder / "report.html").write_text(
            ballbar_html(d, args.date or test_date(str(bt.file)), rel), encoding="utf-8")
    if js is not None:
        js.write_text(json.dumps(d, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    if json_to_stdout(args):
        print_json(d)
    elif folder is None:
        print(res.format_text())
        for q, r in unc.results.items():
            line = f"  {q:16s} {r.value_um:9.3f} um  U = {r.U_um:.3f} um (k = 2)"
            if unc.monte_carlo is not None:
                line += f"  Monte Carlo U = {unc.monte_carlo['results'][q]['U_um']:.3f} um"
            print(line)
        for key, v in unc.verdicts().items():
            print(f"  {key[:-3]} {v['value_um']:.3f} +- {v['U_um']:.3f} um vs limit "
                  f"{v['limit_um']:g} um: {v['verdict'].upper()}")
        if plot is not None:
            print(f"  polar plot: {plot}")
    else:
        print(f"wrote {args.out}/ballbar.json and {args.out}/report.html")
    return 0
