"""``abbe iso230-2 FILE [--json FILE|-] [-o DIR]``: ISO 230-2 positioning evaluation of one axis
(laser CSV, Renishaw ``.rtl`` or ESS ``.dat``), with what was done about 20 deg C, every
result's expanded uncertainty U (k = 2) and, with tolerances, the ISO 14253-1 verdicts."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from abbe.analysis.iso230_2 import evaluate
from abbe.cli.conventions import examples, json_file, json_option, json_to_stdout, print_json
from abbe.cli.options import int_range, iso_date
from abbe.errors import AbbeInputError
from abbe.formats import ess_dat
from abbe.formats.positioning import load_positioning
from abbe.formats.renishaw_rtl import RTL_ENCODINGS
from abbe.formats.uncertainty_spec import CLASSES, LASER_CLASSES, Budget, default_budget

MC_DRAWS = 2000


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "iso230-2", help="ISO 230-2 bidirectional positioning evaluation (B, R, E, A, M in um, "
                         "with U and verdicts)",
        description="Evaluate bidirectional positioning data per ISO 230-2: a laser CSV "
                    "(run,direction,target_mm,linear_um; with temp_c and expansion_ppm_per_k "
                    "normalised to 20 deg C), a Renishaw .rtl export (Linear) or an ESS ecmc "
                    ".dat file. The output says what was done about 20 deg C, gives every "
                    "result's expanded uncertainty U (k = 2, ISO/TR 230-9) with its budget and "
                    "a Monte Carlo check, and, when the machine file states tolerances, "
                    "pass / fail / inconclusive (ISO 14253-1; docs/uncertainty.md).",
        epilog=examples("abbe iso230-2 examples/vmc500/laser/x.csv --json -",
                        "abbe iso230-2 x.csv --machine machine.toml --axis X -o out/iso_x",
                        "abbe iso230-2 x_axis.rtl"))
    p.add_argument("file", help="laser CSV, Renishaw .rtl or ecmc ISO 230-2 .dat file")
    p.add_argument("--encoding", choices=RTL_ENCODINGS, default=None,
                   help="a .rtl file's text encoding (default: UTF-8 when the file is valid "
                        "UTF-8, else cp1250, the Windows code page the public parsers read)")
    json_option(p, "the JSON (B_um, R_um, E_um, A_um, M_um + per-target detail, "
                   "uncertainty, verdicts)")
    p.add_argument("--machine", metavar="TOML",
                   help="machine file whose [uncertainty.laser] budget and [tolerances.AXIS] "
                        "limits apply")
    p.add_argument("--axis", help="the axis measured (names the [tolerances.AXIS] section)")
    p.add_argument("--instrument", choices=LASER_CLASSES,
                   help="instrument class whose default budget applies when the machine file "
                        "declares none (default: laser_interferometer for .csv / .rtl, "
                        "laser_triangulation for ecmc .dat)")
    p.add_argument("--mc", type=int_range(0, 100_000), default=MC_DRAWS, metavar="N",
                   help=f"Monte Carlo draws of the independent check (default {MC_DRAWS}; "
                        "0: none)")
    p.add_argument("--date", metavar="YYYY-MM-DD", type=iso_date,
                   help="test date for the report (default: the measurement file's date)")
    p.add_argument("-o", "--out", metavar="DIR",
                   help="write DIR/iso230_2.json (the --json document) and DIR/report.html")
    p.set_defaults(func=run)


def _budget(args: argparse.Namespace) -> tuple[Budget, dict[str, float], str | None]:
    """The budget, the axis' limits and the machine's name, from the options."""
    limits: dict[str, float] = {}
    name = None
    budget = None
    if args.machine:
        from abbe.formats.machine import load_machine
        m = load_machine(args.machine)
        name = m.name
        spec = m.extra.get("uncertainty")
        if spec is not None:
            budget = spec.laser
            if args.axis is not None and args.axis not in m.axes:
                raise AbbeInputError(f"axis {args.axis!r} is not in the machine file (axes: "
                                     f"{', '.join(m.axes)})", file=str(m.path), field="--axis")
            if args.axis is not None:
                limits = dict(spec.tolerances.get(args.axis, {}))
            elif any(a in spec.tolerances for a in m.axes):
                raise AbbeInputError("the machine file states tolerances per axis: give --axis",
                                     file=str(m.path), field="--axis")
    if budget is None:
        cls = args.instrument or ("laser_triangulation" if ess_dat.looks_like_dat(Path(args.file))
                                  else "laser_interferometer")
        budget = default_budget(cls)
        budget.source = ("--instrument" if args.instrument else "class defaults for the file "
                         "type") + " (docs/uncertainty.md)"
    elif args.instrument and args.instrument != budget.instrument:
        raise AbbeInputError(f"--instrument {args.instrument} but the machine file declares "
                             f"{budget.instrument}", file=args.machine,
                             field="uncertainty.laser.instrument")
    assert budget.instrument in CLASSES
    return budget, limits, name


def document(args: argparse.Namespace) -> tuple[dict[str, Any], Any, Any, list[str]]:
    """The JSON document of one evaluation (what --json prints and -o writes), the
    evaluation, its uncertainty and the reader's input notes."""
    from abbe.analysis.uncertainty import agreement, iso230_2_uncertainty, monte_carlo_iso230_2
    budget, limits, machine = _budget(args)
    data = load_positioning(args.file, encoding=args.encoding)
    res = evaluate(data)
    unc = iso230_2_uncertainty(res, budget, limits)
    if args.mc:
        unc.monte_carlo = monte_carlo_iso230_2(data, res, budget, draws=args.mc)
        unc.monte_carlo["agreement"] = agreement(unc.results, unc.monte_carlo)
    d = {"file": args.file, **res.to_json(), "machine": machine, "axis": args.axis,
         "uncertainty": unc.to_json(), "tolerances": limits or None,
         "verdicts": unc.verdicts()}
    if data.notes:
        d["input_notes"] = list(data.notes)
    return d, res, unc, list(data.notes)


def run(args: argparse.Namespace) -> int:
    from abbe.formats.output import Outputs
    with Outputs() as outs:
        staging = outs.directory(args.out, option="--out") if args.out else None
        js = outs.file(json_file(args), option="--json") if json_file(args) else None
        d, res, unc, notes = document(args)
        if js is not None:
            js.write_text(json.dumps(d, indent=2, allow_nan=False) + "\n", encoding="utf-8")
        if staging is not None:
            from abbe.analysis.certificate import iso230_2_html, test_date
            text = json.dumps(d, indent=2, allow_nan=False) + "\n"
            (staging / "iso230_2.json").write_text(text, encoding="utf-8")
            date = args.date or test_date(args.file)
            (staging / "report.html").write_text(iso230_2_html(d, date), encoding="utf-8")
        if json_to_stdout(args):
            print_json(d)
        elif staging is None:
            print(res.format_text())
            for note in notes:
                print(f"input: {note}")
            print(_uncertainty_text(unc))
        else:
            print(f"wrote {args.out}/iso230_2.json and {args.out}/report.html")
    return 0


def _uncertainty_text(unc: Any) -> str:
    out = ["", f"uncertainty (ISO/TR 230-9; {unc.budget.instrument}, {unc.budget.source}); "
           "U = 2 u_c"]
    mc = unc.monte_carlo
    for q, r in unc.results.items():
        line = f"  {q}  {r.value_um:9.2f} um  U = {r.U_um:7.2f} um"
        if mc is not None:
            line += f"   (Monte Carlo U = {mc['results'][q]['U_um']:.2f} um)"
        out.append(line)
    for key, v in unc.verdicts().items():
        out.append(f"  {key[:-3]} {v['value_um']:.2f} +- {v['U_um']:.2f} um vs limit "
                   f"{v['limit_um']:g} um: {v['verdict'].upper()}")
    return "\n".join(out)
