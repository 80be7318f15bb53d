"""``abbe predict MACHINE.toml --model OUT/model.bin --ballbar NAME``: predict a
ballbar test through the C library and compare it with the measurement
(residual max and RMS, ideal compensated roundness, overlay plot as the paper's
Fig. 8)."""

from __future__ import annotations

import argparse
import json

from abbe.cli.conventions import examples, json_file, json_option, json_to_stdout, list_option, print_json


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "predict", help="predict a ballbar test from a model (C library) and compare",
        description="Predict the ballbar trace from the model through the C library, compare it "
                    "with the measurement and report the residual and the roundness an exact "
                    "compensation of the prediction would leave.",
        epilog=examples("abbe predict examples/vmc500/machine.toml --model fit-out/model.bin "
                        "--ballbar circle1"))
    p.add_argument("machine", help="machine file (TOML)")
    p.add_argument("--model", required=True, help="table blob (model.bin)")
    list_option(p, "--ballbar", required=True, metavar="NAME",
                   help="ballbar test of the machine file (repeatable)")
    p.add_argument("-o", "--out", help="directory for the overlay plots (PNG)")
    json_option(p, "the predictions")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from abbe.analysis.predict import plot_prediction, predict
    from abbe.formats.machine import load_machine

    from abbe.formats.output import Outputs

    with Outputs() as outs:
        out = outs.directory(args.out, option="--out") if args.out else None
        js = outs.file(json_file(args), option="--json") if json_file(args) else None
        machine = load_machine(args.machine)
        results = [predict(machine, args.model, name) for name in args.ballbar]  # all or nothing
        if out is not None:
            for p in results:
                plot_prediction(p, out / f"predict_{p.name}.png")
        doc = {"format": "abbe-predict 1.0", "machine": machine.name, "model": str(args.model),
               "predictions": [p.to_json() for p in results]}
        if out is not None:
            (out / "predict.json").write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n",
                                              encoding="utf-8")
        if js is not None:
            js.write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    if json_to_stdout(args):
        print_json(doc)
        return 0
    for p in results:
        print(f"ballbar {p.name}: measured roundness G = {p.roundness_before_um:.2f} um (bidirectional)")
        print(f"  prediction residual: max {p.max_residual_um:.2f} um, RMS {p.rms_residual_um:.2f} um")
        print(f"  ideal compensation: G = {p.ideal_G_um:.2f} um "
              f"({p.ideal_improvement_pct:.1f} % better)")
    return 0
