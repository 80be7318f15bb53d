"""``abbe thermal {evaluate,fit,diagnose} MACHINE.toml``: ISO 230-3 thermal records
(docs/thermal.md)."""

from __future__ import annotations

import argparse
import json

from abbe.cli.conventions import examples, json_file, json_option, json_to_stdout, print_json
from abbe.cli.options import int_range
from abbe.errors import AbbeInputError
from abbe.formats.machine import load_machine
from abbe.formats.output import Outputs


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "thermal", help="ISO 230-3 thermal records: evaluate, identify a dynamic thermal model",
        description="Thermal tests (ISO 230-3) of the machine file's [thermal] section "
                    "(docs/thermal.md): evaluate the record (drift per channel, tilts, the "
                    "envelope), identify the dynamic model the C runtime runs (thermal.json) "
                    "and score it on held-out hours, or diagnose the thermal effect a static "
                    "model misses.",
        epilog=examples("abbe thermal evaluate examples/spindle_thermal/machine.toml -o evaluate",
                        "abbe thermal fit examples/spindle_thermal/machine.toml -o thermal-out",
                        "abbe thermal diagnose examples/spindle_thermal/machine.toml -o diag"))
    sub = p.add_subparsers(dest="thermal_command", metavar="SUBCOMMAND")
    sub.required = True
    e = sub.add_parser("evaluate", help="ISO 230-3 figures of the record",
                       description="ISO 230-3 evaluation of the [thermal] section's record: "
                                   "drift of every channel, tilts from sensor pairs, envelope; "
                                   "-o DIR writes DIR/iso230_3.json (what abbe history add "
                                   "reads) and DIR/report.html with the drift plot.",
                       epilog=examples("abbe thermal evaluate MACHINE.toml -o evaluate",
                                       "abbe thermal evaluate MACHINE.toml --json -"))
    e.add_argument("machine", help="machine file (TOML) with a [thermal] section")
    e.add_argument("-o", "--out", metavar="DIR",
                   help="output folder: iso230_3.json, report.html, drift.png")
    e.add_argument("--mc", type=int_range(0, 100_000), default=200, metavar="N",
                   help="Monte Carlo draws checking every range's U (GUM S1; its U is stated "
                        "where the first order is more than 10 %% off); default 200, 0 = none")
    json_option(e, "the figures")
    e.set_defaults(func=run_evaluate)
    f = sub.add_parser("fit", help="identify the model, write thermal.json and the report",
                       description="Identify the dynamic thermal model on the identification "
                                   "hours, score it on the held-out hours against the "
                                   "uncompensated drift and a static regression on every "
                                   "temperature; write thermal.json, fit.json, index.html.",
                       epilog=examples("abbe thermal fit MACHINE.toml -o thermal-out"))
    f.add_argument("machine", help="machine file (TOML) with a [thermal] section")
    f.add_argument("-o", "--out", required=True, help="output folder")
    f.set_defaults(func=run_fit)
    d = sub.add_parser("diagnose", help="name the thermal effect the static model misses",
                       description="Name, per channel, the lagged thermal effect (input, time "
                                   "constant, gain with intervals) that today's one-sensor "
                                   "static term misses; show the held-out gap before and after.",
                       epilog=examples("abbe thermal diagnose MACHINE.toml -o diagnose-out"))
    d.add_argument("machine", help="machine file (TOML) with a [thermal] section")
    d.add_argument("-o", "--out", required=True, help="output folder")
    d.set_defaults(func=run_diagnose)


def _load(path: str):
    from abbe.formats.thermal_machine import check_against_record
    from abbe.formats.thermal_record import read_thermal_record
    m = load_machine(path)
    spec = m.extra.get("thermal")
    if spec is None:
        raise AbbeInputError("no [thermal] section: it names the record and declares its "
                             "sensors and channels (docs/thermal.md)", file=str(m.path),
                             field="thermal")
    rec = read_thermal_record(spec.record, spec.sheet)
    check_against_record(spec, rec.temp_names, rec.channel_names, str(m.path), m.line_of)
    h = rec.hours
    for key, (a, b) in (("identify_hours", spec.identify_hours),
                        ("validate_hours", spec.validate_hours)):
        if int(((h >= a) & (h <= b)).sum()) < 10:
            raise AbbeInputError(f"[{a:g}, {b:g}] h holds fewer than 10 samples of the record "
                                 f"({h[0]:g}-{h[-1]:g} h)", file=str(m.path),
                                 line=m.line_of(f"thermal.{key}"), field=f"thermal.{key}")
    span = spec.identify_hours[1] - spec.identify_hours[0]
    if span < 2 * spec.cycle_hours:
        raise AbbeInputError(f"the identification hours hold {span / spec.cycle_hours:.2f} "
                             f"cycles of {spec.cycle_hours:g} h: the leave-one-cycle-out "
                             "selection needs at least 2", file=str(m.path),
                             line=m.line_of("thermal.cycle_hours"), field="thermal.cycle_hours")
    return m, spec, rec


def run_evaluate(args: argparse.Namespace) -> int:
    from abbe.analysis.thermal.iso230_3 import evaluate_record, range_uncertainty
    from abbe.analysis.thermal.report import write_record_report
    with Outputs() as outs:
        folder = outs.directory(args.out) if args.out else None
        out = outs.file(json_file(args), option="--json") if json_file(args) else None
        m, spec, rec = _load(args.machine)
        iso = evaluate_record(rec, spec.tilt_pairs())
        unc = range_uncertainty(rec, spec, iso, draws=args.mc)
        doc = {"format": "abbe-iso230-3 1.1", "machine": m.name, "record": rec.file, **iso,
               "uncertainty": unc}
        text = json.dumps(doc, indent=1, allow_nan=False) + "\n"
        if out is not None:
            out.write_text(text, encoding="utf-8")
        if folder is not None:
            (folder / "iso230_3.json").write_text(text, encoding="utf-8")
            write_record_report(doc, rec, folder)
    if json_to_stdout(args):
        print_json(doc)
        return 0
    print(f"abbe thermal evaluate: {rec.file}: {iso['samples']} samples, "
          f"{iso['duration_h']:.1f} h")
    for d in iso["channels"] + iso["tilts"]:
        print(f"  {d['name']:<22} range {d['range']:8.1f} +- {d['U']:5.2f} {d['unit']:<4} "
              f"max {d['max']:7.1f} @ {d['max_h']:5.1f} h  min {d['min']:7.1f} @ "
              f"{d['min_h']:5.1f} h  end {d['final']:7.1f}")
    print(f"  envelope: {iso['envelope']['channel']} {iso['envelope']['range_um']:.1f} +- "
          f"{iso['envelope']['U_um']:.2f} um (U, k = 2: the sensors' calibration and reading "
          "noise, docs/uncertainty.md)")
    if folder is not None:
        print(f"abbe thermal evaluate: wrote {args.out}/iso230_3.json and report.html")
    return 0


def _table_text(res) -> list[str]:
    lines = [f"  {'signal':<8} {'uncomp':>8} {'MLR':>14} {'model':>14}  target"]
    for s in res.channels + [s for s in res.outputs if s.unit == "urad"]:
        lines.append(f"  {s.name:<8} {s.rms_uncomp:8.2f} {s.rms_mlr:8.2f} ({100 * s.rms_mlr / s.rms_uncomp:3.0f} %)"
                     f" {s.rms_comp:8.2f} ({100 * s.ratio:3.0f} %)  {'met' if s.meets else 'MISSED'}"
                     f"  {s.unit}")
    return lines


def run_fit(args: argparse.Namespace) -> int:
    from abbe.analysis.thermal.iso230_3 import evaluate_record, range_uncertainty
    from abbe.analysis.thermal.pipeline import check_model, fit_record
    from abbe.analysis.thermal.report import write_report
    from abbe.model.thermal import as_dict
    with Outputs() as outs:
        out = outs.directory(args.out)
        m, spec, rec = _load(args.machine)
        res = fit_record(rec, spec)
        gap = check_model(res)
        if gap > 1e-9:
            raise RuntimeError(f"the written model differs from the scored one by {gap:g}")
        iso = evaluate_record(rec, spec.tilt_pairs())
        range_uncertainty(rec, spec, iso)  # every range of the report with U (k = 2)
        (out / "thermal.json").write_text(json.dumps(as_dict(res.model), indent=1,
                                                     allow_nan=False), encoding="utf-8")
        summary = {"format": "abbe-thermal-fit 1.0", "machine": m.name,
                   "record": rec.file, "identify_hours": list(spec.identify_hours),
                   "validate_hours": list(spec.validate_hours),
                   "signals": [s.row(res.input_names) for s in
                               res.channels + [s for s in res.outputs if s.unit == "urad"]],
                   "iso230_3": iso}
        from abbe.analysis.thermal.uncertainty import thermal_uncertainty
        summary["uncertainty"] = thermal_uncertainty(res, draws=200)  # issue 37: U (k = 2)
        (out / "fit.json").write_text(json.dumps(summary, indent=1, allow_nan=False,
                                                 default=_none), encoding="utf-8")
        write_report(res, iso, out, machine=m.name, uncertainty=summary["uncertainty"])
    print(f"abbe thermal fit: wrote {args.out}/thermal.json, fit.json, index.html")
    print(f"  held-out hours {spec.validate_hours[0]:g}-{spec.validate_hours[1]:g}, RMS:")
    print("\n".join(_table_text(res)))
    return 0


def _none(v):  # json default: numpy scalars
    return float(v)


def run_diagnose(args: argparse.Namespace) -> int:
    from abbe.diagnose.thermal import diagnose_thermal, write_thermal_report
    with Outputs() as outs:
        out = outs.directory(args.out)
        m, spec, rec = _load(args.machine)
        diag = diagnose_thermal(rec, spec)
        write_thermal_report(diag, rec, spec, out, machine=m.name)
        diag.pop("_series")
        diag = {"format": "abbe-thermal-diagnose 1.0", "machine": m.name, **diag}
        (out / "diagnosis.json").write_text(json.dumps(diag, indent=1, allow_nan=False),
                                            encoding="utf-8")
        (out / "diagnosis.txt").write_text(diag["text"] + "\n", encoding="utf-8")
    print(diag["text"])
    return 0
