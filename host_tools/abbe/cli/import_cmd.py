"""``abbe import FILE -o OUT [--format F] [--machine M.toml | --reference X Y Z]``: ISO
230-1 component errors (a TF5280 ISG CSV table or its .lis, an Etalon exchange file)
into an abbe table (OUT/model.bin, OUT/model.json with the fit diagnostics)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from abbe.cli.conventions import examples
from abbe.cli.options import in_range, int_range
from abbe.formats.limits import IMPORT_MAX_POINTS

#: machine coordinates (mm): a table holds int32 nm
COORD_MM = in_range(-2147.0, 2147.0, "mm")

FORMATS = ("isg-csv", "isg-lis", "etalon")


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "import", help="ISO 230-1 error files (ISG CSV, TF5280 .lis, Etalon) -> an abbe table",
        description="Read ISO 230-1 component errors (Beckhoff TF5280 ISG CSV or its .lis list "
                    "file, Etalon exchange format) and fit them into an abbe table with the "
                    "model selection of abbe fit (docs/exports.md, 'abbe import').",
        epilog=examples("abbe import volcomp.lis -o imported --machine examples/vmc500/machine.toml",
                        "abbe import lasertracer.exc -o imported --reference 163.626 -212.772 "
                        "-290.704"))
    p.add_argument("file", type=Path, help="error file")
    p.add_argument("--format", choices=FORMATS,
                   help="isg-csv, isg-lis or etalon (default: .lis -> isg-lis, .csv -> isg-csv, "
                        "else etalon)")
    p.add_argument("-o", "--out", type=Path, required=True, help="output directory")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--machine", type=Path, help="machine file: reference point, tool offset, travel")
    g.add_argument("--reference", type=COORD_MM, nargs=3, metavar=("X", "Y", "Z"),
                   help="reference point, mm in [-2147, 2147] (every linear term is 0 there)")
    p.add_argument("--tool-offset", type=COORD_MM, nargs=3, metavar=("X", "Y", "Z"),
                   help="tool offset of the model, mm (with --reference; default 0 0 0)")
    p.add_argument("--no-unfold", action="store_true",
                   help="the file's lever arms are already about the reference point")
    p.add_argument("--max-points", type=int_range(5, IMPORT_MAX_POINTS), default=201,
                   help=f"positions per axis used by the fit, 5..{IMPORT_MAX_POINTS} "
                        "(default 201)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from abbe.analysis.import_model import import_components
    from abbe.errors import AbbeInputError
    from abbe.formats.etalon import read_etalon
    from abbe.formats.isg_csv import read_isg_csv, read_list
    from abbe.formats.machine import load_machine
    from abbe.formats.output import Outputs

    if args.machine and args.tool_offset:
        raise AbbeInputError("the machine file gives the tool offset", field="--tool-offset")
    fmt = args.format or {".lis": "isg-lis", ".csv": "isg-csv"}.get(args.file.suffix.lower(),
                                                                    "etalon")
    with Outputs() as outs:
        staging = outs.directory(args.out, option="--out")  # checked before the work
        data = {"isg-csv": read_isg_csv, "isg-lis": read_list, "etalon": read_etalon}[fmt](
            args.file)
        if args.machine:
            m = load_machine(args.machine)
            ref, tool = m.reference_mm, m.tool_offset_mm
            travel = {a: m.axes[a].travel_mm for a in m.axes}
        else:
            tool = tuple(args.tool_offset) if args.tool_offset else (0.0, 0.0, 0.0)
            ref, travel = tuple(args.reference), None
        res = import_components(data, ref, tool, travel, unfold=not args.no_unfold,
                                max_points=args.max_points)
        (staging / "model.bin").write_bytes(res.blob)
        (staging / "model.json").write_text(json.dumps(res.model_json, indent=2, allow_nan=False)
                                            + "\n", encoding="utf-8")
    print(f"abbe import: {args.file} ({fmt}) -> {args.out}/model.bin, model.json "
          f"(CRC-32 {res.model_json['table']['crc32']})")
    for a, d in res.model_json["axes"].items():
        worst = max(d["terms"].items(), key=lambda kv: next(v for k, v in kv[1].items()
                                                            if k.startswith("conversion")))
        w = next(v for k, v in worst[1].items() if k.startswith("conversion"))
        print(f"  axis {a}: {d['positions']} positions, {len(d['terms'])} terms; largest "
              f"conversion residual {w:g} ({worst[1]['iso_name']})")
    if res.model_json["ignored"]:
        print("  ignored (not part of a 3-axis model): " + ", ".join(res.model_json["ignored"]))
    for n in res.model_json["notes"]:
        print(f"  note: {n}")
    return 0
