"""``abbe predict MACHINE.toml --model OUT/model.bin --ballbar NAME``: predict a
ballbar test through the C library and compare it with the measurement
(residual max and RMS, ideal compensated roundness, overlay plot as the paper's
Fig. 8)."""

from __future__ import annotations

import argparse
import json

from abbe.cli.conventions import examples, json_file, json_option, json_to_stdout, list_option, print_json
from abbe.cli.options import int_range


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
    p.add_argument("--mc", type=int_range(0, 100_000), default=200, metavar="N",
                   help="Monte Carlo draws checking the residual's U (GUM S1; its U is stated "
                        "where the first order is more than 10 %% off); default 200, 0 = none")
    json_option(p, "the predictions")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from abbe.analysis.predict import plot_prediction, predict, residual_uncertainty
    from abbe.analysis.uncertainty import ballbar_budget, ballbar_uncertainty
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
        # every figure with U (k = 2) from the ballbar budget (the machine file's, else the
        # class defaults): the measured roundness as abbe ballbar states it, the residual
        # with the model held fixed (docs/uncertainty.md, "prediction residual")
        budget, _limits = ballbar_budget(machine)
        preds = []
        for p in results:
            d = p.to_json()
            G_U = ballbar_uncertainty(p.trace, p.test, p.before, budget).results[
                "G_bidirectional"].U_um
            ru = residual_uncertainty(p, budget, draws=args.mc)
            d.update(roundness_before_U_um=round(G_U, 4),
                     residual_max_U_um=round(ru["max_abs"]["U_stated_um"], 4),
                     residual_rms_U_um=round(ru["rms"]["U_stated_um"], 4),
                     uncertainty=ru)
            preds.append(d)
        doc = {"format": "abbe-predict 1.1", "machine": machine.name, "model": str(args.model),
               "k": 2, "budget": {"source": budget.source, "figures": dict(budget.figures)},
               "predictions": preds}
        if out is not None:
            (out / "predict.json").write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n",
                                              encoding="utf-8")
        if js is not None:
            js.write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    if json_to_stdout(args):
        print_json(doc)
        return 0
    for p, d in zip(results, doc["predictions"]):
        print(f"ballbar {p.name}: measured roundness G = {p.roundness_before_um:.2f} +- "
              f"{d['roundness_before_U_um']:.2f} um (bidirectional; U, k = 2)")
        print(f"  prediction residual: max {p.max_residual_um:.2f} +- {d['residual_max_U_um']:.2f} um, "
              f"RMS {p.rms_residual_um:.2f} +- {d['residual_rms_U_um']:.2f} um (U, k = 2; "
              f"budget: {doc['budget']['source']})")
        print(f"  ideal compensation: G = {p.ideal_G_um:.2f} um "
              f"({p.ideal_improvement_pct:.1f} % better)")
    return 0
