"""``abbe printer fit MAP [--skew SKEW.csv] -o OUT``: a printer's bed mesh (Klipper
``SAVE_CONFIG`` block) or height map (RepRapFirmware ``heightmap.csv``) and its skew
artefacts fitted into a table (Z straightness of X and Y, squareness), with the
held-out figure against the firmware's own mesh (docs/klipper.md, "Printer
measurements")."""

from __future__ import annotations

import argparse
import json

from abbe.cli.conventions import examples, json_file, json_option, json_to_stdout, print_json


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "printer", help="printer measurements (bed mesh, height map, skew) into a table",
        description="Fit a printer's bed mesh / height map and skew artefacts into a table: the "
                    "Z straightness of X and Y (Chebyshev, degrees by leave-one-out), the "
                    "squareness from the squares' diagonals, with 95 % intervals and a held-out "
                    "comparison with what the firmware's own mesh correction leaves.",
        epilog=examples("abbe printer fit printer.cfg --skew skew.csv -o printer-fit",
                        "abbe printer fit heightmap.csv --z-travel 0 250 -o printer-fit"))
    sub = p.add_subparsers(dest="printer_cmd", required=True)
    f = sub.add_parser("fit", help="fit a height map (and skew artefacts) into a table",
                       description="Fit a Klipper bed mesh or RepRapFirmware height map (and skew "
                                   "artefacts) into a table, with 95 % intervals and the held-out "
                                   "comparison with the firmware's mesh (docs/klipper.md).",
                       formatter_class=argparse.RawDescriptionHelpFormatter,
                       epilog=examples("abbe printer fit printer.cfg --skew skew.csv -o printer-fit",
                                       "abbe printer fit heightmap.csv --z-travel 0 250 -o printer-fit"))
    f.add_argument("map", help="Klipper printer.cfg (its #*# [bed_mesh NAME]) or RepRapFirmware "
                               "heightmap.csv")
    f.add_argument("--profile", help="the Klipper mesh profile (default: the only one, or 'default')")
    f.add_argument("--skew", help="skew artefacts: CSV plane,ac_mm,bd_mm,ad_mm")
    f.add_argument("--length-u-mm", type=float, default=0.02,
                   help="standard uncertainty of each artefact length, mm (default 0.02, a caliper)")
    f.add_argument("--z-travel", type=float, nargs=2, default=(0.0, 250.0), metavar=("LO", "HI"),
                   help="the Z travel the table states, mm (default 0 250)")
    f.add_argument("-o", "--out", required=True, help="output directory (model.bin, printer_fit.json)")
    json_option(f, "the result (printer_fit.json)")
    f.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import math

    from abbe.analysis.printer_fit import fit_height_map, squareness_from_artefacts, table_of
    from abbe.errors import AbbeInputError
    from abbe.formats.blob import write_blob
    from abbe.formats.output import Outputs
    from abbe.formats.printer_maps import read_height_map, read_skew_csv

    lo, hi = args.z_travel
    if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
        raise AbbeInputError(f"--z-travel {lo} {hi}: expected finite LO < HI", field="--z-travel")
    if not (math.isfinite(args.length_u_mm) and 0 <= args.length_u_mm <= 1):
        raise AbbeInputError(f"{args.length_u_mm}: expected 0..1 mm", field="--length-u-mm")
    maps = read_height_map(args.map)
    if args.profile is not None:
        maps = [m for m in maps if m.name == args.profile]
        if not maps:
            raise AbbeInputError(f"no bed mesh profile {args.profile!r}", file=args.map,
                                 field="--profile")
    elif len(maps) > 1:
        named = [m for m in maps if m.name == "default"]
        if not named:
            raise AbbeInputError(f"{len(maps)} mesh profiles ({', '.join(m.name for m in maps)}): "
                                 "name one with --profile", file=args.map, field="--profile")
        maps = named
    fit = fit_height_map(maps[0])
    if args.skew:
        sq, u95 = squareness_from_artefacts(read_skew_csv(args.skew), args.length_u_mm)
        fit.squareness_urad, fit.squareness_u95_urad = sq, u95
        fit.length_u_mm = args.length_u_mm
    table = table_of(fit, (lo, hi), fit.squareness_urad)
    blob = write_blob(table)
    doc = {"format": "abbe-printer-fit 1.0", **fit.to_json()}
    with Outputs() as outs:
        out = outs.directory(args.out, option="--out")
        js = outs.file(json_file(args), option="--json") if json_file(args) else None
        (out / "model.bin").write_bytes(blob)
        (out / "printer_fit.json").write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n")
        if js is not None:
            js.write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    if json_to_stdout(args):
        print_json(doc)
        return 0
    print(f"abbe printer fit: {fit.source}: {fit.points} points; d_z of X degree {fit.x.degree} "
          f"(95 % +/- {fit.x.u95_um:.1f} um), of Y degree {fit.y.degree} "
          f"(+/- {fit.y.u95_um:.1f} um)")
    print(f"  what a sum of axis straightnesses cannot hold (warp): RMS {fit.nonseparable_rms_um:.1f} um")
    if fit.heldout_points:
        print(f"  held out ({fit.heldout_points} interior points, leave-one-out): abbe "
              f"{fit.heldout_rms_um:.1f} um RMS, the firmware's mesh {fit.firmware_heldout_rms_um:.1f} "
              f"um, uncorrected {fit.raw_rms_um:.1f} um")
    for plane, v in fit.squareness_urad.items():
        print(f"  squareness S_{plane.lower()} {v:.1f} +- "
              f"{2.0 * fit.squareness_u95_urad[plane] / 1.96:.1f} urad (U, k = 2; artefact "
              f"lengths u = {fit.length_u_mm:g} mm)")
    for n in fit.notes:
        print(f"  note: {n}")
    print(f"abbe printer fit: wrote {args.out} (model.bin, printer_fit.json)")
    return 0
