"""``abbe diagnose``: name what the model is missing, add it to the table, show the gap shrink.

    abbe diagnose MACHINE.toml --model OUT/model.bin [--ballbar NAME ...] [--laser AXIS ...]
                  [--json FILE|-] -o OUT2/
    abbe diagnose --iso230-2 FILE --axis X [--model M.bin] [--json FILE] -o OUT2/

See docs/effects.md (the catalogue and the method) and docs/formats.md ("diagnose JSON").
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from abbe.cli.conventions import examples, json_file, json_option, json_to_stdout, list_option
from abbe.cli.options import in_range, int_range


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "diagnose", help="name the effects the model is missing (ballbar / laser / ISO 230-2 "
                         "checks), add them to the table, show the gap shrink",
        description="Predict every check measurement with the model through the C library, "
                    "compare, test the catalogue of missing effects (docs/effects.md) with "
                    "stepwise selection (F-test against the noise, BIC, held-out data), name "
                    "what is missing with values and 95 % intervals, write the updated table "
                    "(blob, C, JSON) and show the residual before and after. On a five-axis "
                    "table-table machine file (a [rotary] section) it runs the five-axis "
                    "discrepancy workflow instead: a location-only identification of the "
                    "plan, then the catalogue's five-axis effects (cyclic angular error of "
                    "C, pivot drift, C wobble) judged on held-out probing positions, written "
                    "to diagnose_five_axis.json and report.txt (--model is not used there: "
                    "the model is identified from the same plan; docs/effects.md). On a "
                    "[chain] machine file (head-head, head-table, dual-rotary table) it "
                    "names a missing error motion (or, with --model chain_fit.json, a "
                    "changed location error) from the probing / R-test residuals, judged "
                    "on held-out probing positions (diagnose_chain.json; docs/concepts.md). "
                    "Thermal "
                    "records (ISO 230-3): `abbe thermal diagnose` names the missing thermal "
                    "effect (channel, input, lag; docs/thermal.md).",
        epilog=examples("abbe diagnose examples/vmc500/machine.toml --model fit-out/model.bin "
                        "--ballbar circle1 -o diagnose-out",
                        "abbe diagnose examples/trunnion5ax/machine.toml -o diagnose5  "
                        "# five-axis",
                        "abbe diagnose --iso230-2 x_iso230_2.dat --axis X -o diagnose-x"))
    p.add_argument("machine", nargs="?", help="machine file (TOML) with the check tests")
    p.add_argument("--model", help="the current model: table blob (model.bin) or table JSON; "
                                   "optional with --iso230-2 (default: position-only model)")
    list_option(p, "--ballbar", metavar="NAME", help="ballbar tests to use")
    list_option(p, "--laser", metavar="AXIS", help="laser lines to use (X, Y, Z)")
    p.add_argument("--iso230-2", dest="iso", metavar="FILE",
                   help="repeated positioning runs: ESS ecmc .dat or laser CSV")
    p.add_argument("--axis", help="axis of --iso230-2 data (X, Y or Z)")
    json_option(p, "the diagnose JSON (OUT/diagnose.json)")
    p.add_argument("-o", "--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--alpha", type=in_range(0.0, 0.5, lo_open=True, hi_open=True), default=0.05,
                   help="largest posterior probability that a named effect is absent, (0, 0.5) "
                        "(default 0.05: an evidence ratio of 19; docs/effects.md section 3)")
    p.add_argument("--min-effect-um", type=in_range(0.0, 1000.0, "um"), default=0.15,
                   help="smallest effect (RMS on the checks, um) worth naming, [0, 1000] "
                        "(default 0.15)")
    list_option(p, "--candidates", metavar="ID",
                   help="restrict the catalogue (ids or keys, e.g. squareness_xy backlash_x)")
    p.add_argument("--model-temp-c", type=in_range(-50.0, 150.0, "deg C"), default=None,
                   metavar="C",
                   help="temperature (deg C) at which the model was measured: the reference "
                        "of the thermal term (default: the table's, else the lowest logged)")
    p.add_argument("--rezeroed", action="store_true",
                   help="the laser was re-zeroed before every run (a zero offset per run)")
    p.add_argument("--backend", choices=("c", "reference"), default="c",
                   help="predict through the C library (default) or the float64 reference")
    p.add_argument("--no-plots", action="store_true", help="do not write the PNG plots")
    p.add_argument("--mc", type=int_range(0, 100_000), default=DEFAULT_MC_DRAWS,
                   metavar="N",
                   help="Monte Carlo draws (GUM S1) checking the effects' and the gaps' U "
                        f"(k = 2), 0 = none (default {DEFAULT_MC_DRAWS}; each draw re-runs the "
                        "final fit; docs/uncertainty.md, \"Diagnosis\")")
    p.set_defaults(func=run)


#: none by default (each draw re-runs the final fit: 200 draws about 5 s on the demo; the
#: demo runs 100)
DEFAULT_MC_DRAWS = 0


def run(args: argparse.Namespace) -> int:
    if args.machine and not args.iso:  # a [rotary] machine: the five-axis workflow
        from abbe.cli.diagnose_five_axis import run_five_axis_diagnose
        from abbe.cli.fit_five_axis import is_five_axis
        if is_five_axis(args.machine):
            return run_five_axis_diagnose(args)
        from abbe.cli.fit_chain import is_chain_machine
        if is_chain_machine(args.machine):  # head-head, head-table, dual-rotary table
            from abbe.cli.diagnose_chain import run_chain_diagnose
            return run_chain_diagnose(args)
    from abbe.diagnose.report import format_text

    res, written = diagnose_three_axis(args)
    if json_to_stdout(args):
        sys.stdout.write(Path(written["diagnose.json"]).read_text(encoding="utf-8"))
        return 0
    sys.stdout.write(format_text(res, str(written["model.bin"])))
    print(f"wrote {len(written)} files to {args.out}"
          + (f" and {args.json}" if json_file(args) else ""))
    return 0


def diagnose_three_axis(args: argparse.Namespace) -> tuple[Any, dict[str, Path]]:
    """The three-axis diagnosis of ``args`` (parsed by this command's parser): the
    DiagnoseResult and the files written (name -> path). The demo calls it to keep the
    result (its residuals) as well as the files."""
    from abbe.diagnose.effects import catalogue
    from abbe.diagnose.report import write_outputs
    from abbe.diagnose.results import DiagnoseOptions
    from abbe.diagnose.run import diagnose_machine, diagnose_positioning
    from abbe.errors import AbbeInputError

    if args.candidates:
        known = {e.key for e in catalogue()} | {e.family for e in catalogue()}
        bad = [c for c in args.candidates if c not in known]
        if bad:
            raise AbbeInputError(f"unknown effect {bad[0]!r}; known: {', '.join(sorted(known))}",
                                 field="candidates")
    from abbe.formats.output import Outputs
    Outputs().check_directory(args.out, option="--out")  # before the work; written at the end
    if json_file(args):
        Outputs().check_file(json_file(args), option="--json")
    opts = DiagnoseOptions(alpha=args.alpha, min_effect_um=args.min_effect_um,
                           candidates=args.candidates, backend=args.backend,
                           model_temp_c=args.model_temp_c)
    if args.iso:
        if args.machine or args.ballbar or args.laser:
            raise AbbeInputError("--iso230-2 takes no machine file, --ballbar or --laser",
                                 field="iso230-2")
        if not args.axis:
            raise AbbeInputError("--iso230-2 needs --axis X|Y|Z", field="axis")
        if args.axis.upper() not in ("X", "Y", "Z"):
            raise AbbeInputError(f"expected X, Y or Z, got {args.axis!r}", field="axis")
        res = diagnose_positioning(args.iso, args.axis, args.model, opts, rezeroed=args.rezeroed,
                                   mc_draws=getattr(args, "mc", 0))
        extra = {"input": {"iso230_2": args.iso, "axis": args.axis.upper(),
                           "model": args.model or "position-only (built from the data)"}}
    else:
        if not args.machine:
            raise AbbeInputError("give a machine file (MACHINE.toml --model M.bin) or "
                                 "--iso230-2 FILE --axis X", field="machine")
        if not args.model:
            raise AbbeInputError("--model is required with a machine file (the table to check)",
                                 file=args.machine, field="model")
        res = diagnose_machine(args.machine, args.model, args.ballbar, args.laser, opts,
                               rezeroed=args.rezeroed, mc_draws=getattr(args, "mc", 0))
        extra = {"input": {"machine": args.machine, "model": args.model,
                           "ballbar": args.ballbar, "laser": args.laser}}
    written = write_outputs(res, args.out, json_file(args), plots=not args.no_plots,
                            extra_json=extra)
    return res, written
