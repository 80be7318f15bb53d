"""``abbe export MODEL --format F -o OUT [--machine M.toml] [--set NAME=VALUE ...]``:
write a model in a controller's native compensation format, with the residual the
target leaves (docs/exports.md)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from abbe.cli.conventions import examples, json_file, json_option, json_to_stdout, list_option


def register(subparsers: argparse._SubParsersAction) -> None:
    from abbe.exports import CHAIN_TARGETS, FIVE_AXIS_TARGETS, TARGETS

    names = list(TARGETS) + list(FIVE_AXIS_TARGETS) + list(CHAIN_TARGETS)

    p = subparsers.add_parser(
        "export", help="write a model in a controller's compensation format, with its residual",
        description="Write the model (table blob, table JSON or a fit/import model.json) in a "
                    "controller's native compensation format and report what the target leaves "
                    "uncompensated over the work volume and the machine file's ballbar circles "
                    "(OUT/residual.json); a five-axis target (" + ", ".join(FIVE_AXIS_TARGETS)
                    + ") writes the rotary geometry of abbe fit's model_five.bin and needs the "
                    "machine file; a kinematics-module target (" + ", ".join(CHAIN_TARGETS)
                    + ") writes the location errors of abbe fit's chain_fit.json (a [chain] "
                    "machine file) as the module's parameters. Targets: " + ", ".join(names) + ".",
        epilog=examples("abbe export fit-out/model.bin --format linuxcnc-comp -o lcnc "
                        "--machine examples/vmc500/machine.toml",
                        "abbe export model.bin -f sinumerik-cec -o cec --set tables=8 points=200",
                        "abbe export model.bin -f fanuc-pitch --list-options -o x",
                        "abbe export fit5/model_five.bin -f linuxcnc-trt -o trt "
                        "--machine examples/trunnion5ax/machine.toml",
                        "abbe export fitc/chain_fit.json -f linuxcnc-xyzab-tdr -o tdr "
                        "--machine machine.toml"))
    p.add_argument("model", type=Path, help="model: model.bin, table JSON, model.json, "
                   "model_five.bin or chain_fit.json")
    p.add_argument("--format", "-f", required=True, choices=names, metavar="F",
                   help="target: " + ", ".join(names))
    p.add_argument("-o", "--out", type=Path, required=True, help="output directory")
    p.add_argument("--machine", type=Path,
                   help="machine file: its travel is the work volume, its ballbar circles are "
                        "evaluated (default: the model's travel, no circles)")
    list_option(p, "--set", default=[], metavar="NAME=VALUE",
                help="target options (repeatable); --list-options shows them")
    p.add_argument("--list-options", action="store_true", help="print the target's options")
    json_option(p, "the residual report (OUT/residual.json)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from abbe.exports import (run_chain_export, run_export, run_five_export, target_module,
                              write_files)
    from abbe.exports.chain_kins import summary as chain_summary
    from abbe.exports.five_axis import summary as five_summary
    from abbe.exports.residual import summary
    from abbe.formats.machine import load_machine
    from abbe.formats.model_file import load_table
    from abbe.formats.output import Outputs

    mod = target_module(args.format)
    if args.list_options:
        for name, o in mod.OPTIONS.items():
            print(f"{name} ({o.describe()}, default {o.show_default()}): {o.help}")
        return 0
    with Outputs() as outs:
        staging = outs.directory(args.out, option="--out")  # checked before the work
        js = outs.file(json_file(args), option="--json") if json_file(args) else None
        machine = load_machine(args.machine) if args.machine else None
        if getattr(mod, "CHAIN", False):
            exp, report = run_chain_export(args.model, args.format, args.set, machine)
        elif getattr(mod, "FIVE_AXIS", False):
            exp, report = run_five_export(args.model, args.format, args.set, machine)
        else:
            exp, report = run_export(load_table(args.model), args.format, args.set, machine,
                                     str(args.model))
        write_files(staging, exp, report)
        doc = json.dumps(report, indent=2, allow_nan=False) + "\n"
        if js is not None:
            js.write_text(doc, encoding="utf-8")
        text = doc if json_to_stdout(args) else None
    if text is not None:
        sys.stdout.write(text)
    else:
        show = (chain_summary if getattr(mod, "CHAIN", False) else
                five_summary if getattr(mod, "FIVE_AXIS", False) else summary)
        print(show(report).replace("wrote ", f"wrote {args.out}/: ", 1))
    return 0
