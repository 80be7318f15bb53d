"""``abbe iso230-2 FILE [--json]``: ISO 230-2 positioning evaluation of one axis (laser CSV,
Renishaw ``.rtl`` or ESS ``.dat``), with what was done about 20 deg C."""

from __future__ import annotations

import argparse
import json
import sys

from abbe.analysis.iso230_2 import evaluate
from abbe.cli.conventions import examples
from abbe.formats.positioning import load_positioning
from abbe.formats.renishaw_rtl import RTL_ENCODINGS


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "iso230-2", help="ISO 230-2 bidirectional positioning evaluation (B, R, E, A, M in um)",
        description="Evaluate bidirectional positioning data per ISO 230-2: a laser CSV "
                    "(run,direction,target_mm,linear_um; with temp_c and expansion_ppm_per_k "
                    "normalised to 20 deg C), a Renishaw .rtl export (Linear) or an ESS ecmc "
                    ".dat file. The output says what was done about 20 deg C.",
        epilog=examples("abbe iso230-2 examples/vmc500/laser/x.csv --json",
                        "abbe iso230-2 x_axis.rtl"))
    p.add_argument("file", help="laser CSV, Renishaw .rtl or ecmc ISO 230-2 .dat file")
    p.add_argument("--encoding", choices=RTL_ENCODINGS, default=None,
                   help="a .rtl file's text encoding (default: UTF-8 when the file is valid "
                        "UTF-8, else cp1250, the Windows code page the public parsers read)")
    p.add_argument("--json", action="store_true",
                   help="print JSON (B_um, R_um, E_um, A_um, M_um + per-target detail)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    data = load_positioning(args.file, encoding=args.encoding)
    res = evaluate(data)
    if args.json:
        d = {"file": args.file, **res.to_json()}
        if data.notes:
            d["input_notes"] = list(data.notes)
        json.dump(d, sys.stdout, indent=2)
        sys.stdout.write("\n")
    else:
        print(res.format_text())
        for note in data.notes:
            print(f"input: {note}")
    return 0
