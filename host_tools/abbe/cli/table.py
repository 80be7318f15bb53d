"""``abbe table``: inspect, evaluate and convert error tables.

Sub-commands:

* ``info MODEL.bin``: validate, print features, per-axis shape and CRC;
* ``eval MODEL.bin X Y Z [X Y Z ...]``: reference spatial error (um) at machine
  positions (mm); ``--clib`` adds the C library's f32 and q results; a five-axis
  table (format 1.2, ``abbe fit``'s model_five.bin) takes joint positions
  X Y Z TILT C (mm, deg; a format 1.4 table of another kind: its two rotary axes in
  alphabetical order, B C or A B) and gives the tool tip's position (um) and
  orientation (urad) error relative to the workpiece;
* ``cgen MODEL.bin -o DIR``: generated C (abbe_model.c / .h; formats 1.0 - 1.3);
* ``from-json MODEL.json -o MODEL.bin``; ``to-json MODEL.bin [-o MODEL.json]``;
* ``thermal MODEL.bin thermal.json -o OUT.bin``: the table with the dynamic thermal
  model as its thermal block (format 1.3; ``--strip``: without it).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from abbe.cli.conventions import examples
from abbe.errors import AbbeInputError
from abbe.cli.options import in_range
from abbe.formats.blob import blob_crc, read_blob_file, write_blob
from abbe.formats.c_source import write_c
from abbe.formats.limits import TABLE_JSON_MAX_BYTES
from abbe.formats.output import Outputs, atomic_write
from abbe.formats.structured import JsonLocator, load_json
from abbe.formats.table_json import table_from_json, table_to_json
from abbe.model.table import AXES, LINEAR_TERMS, Table, feature_names


def _read_bin(path: Path) -> tuple[bytes, Table]:
    return read_blob_file(path)


def _read_any(path: Path):
    """(bytes, 3-axis Table, FiveAxisTable or None): a format 1.2 five-axis table is read
    with every check of ``abbe_five_model_load``; its linear axes are the Table."""
    from abbe.formats.five_axis_blob import is_five_axis_blob, read_five_blob
    from abbe.formats.limits import BLOB_MAX_BYTES
    from abbe.formats.text import read_bytes

    data = read_bytes(path, what="table blob", max_bytes=BLOB_MAX_BYTES)
    if is_five_axis_blob(data):
        five = read_five_blob(data, source=str(path))
        return data, five.errors.linear, five
    return data, read_blob_file(path)[1], None


def _cmd_info(args: argparse.Namespace) -> int:
    from abbe.formats.five_axis_blob import five_table_lines
    from abbe.formats.limits import BLOB_MAX_BYTES
    from abbe.formats.text import read_bytes
    from abbe.formats.thermal_blob import read_thermal_blob

    raw = read_bytes(args.model, what="table blob", max_bytes=BLOB_MAX_BYTES)
    if int.from_bytes(raw[6:8], "little") == 3 and raw[:4] == b"ABBE":
        data = raw
        table, thermal = read_thermal_blob(data, source=str(args.model))  # format 1.3
        five = None
    else:
        data, table, five = _read_any(args.model)
        thermal = None
    total = int.from_bytes(data[8:12], "little")
    minor = int.from_bytes(data[6:8], "little")
    feats = feature_names(table.features()) + (["rotary (five-axis)"] if five else [])
    out = [f"{args.model}: abbe table format 1.{minor}, {total} bytes, CRC-32 0x{blob_crc(data):08X}",
           "features: " + (", ".join(feats) or "none"),
           "reference_mm: " + " ".join(f"{v:.6f}" for v in table.reference_mm)]
    if table.features() & 0x2:
        out.append("tool_offset_mm: " + " ".join(f"{v:.6f}" for v in table.tool_offset_mm))
    if table.features() & 0x1:
        out.append("squareness_urad: S_xy %.4f S_xz %.4f S_yz %.4f" % table.squareness_urad)
    for a in AXES:
        ax = table.axes[a]
        trend = "none" if ax.trend_degree is None else f"degree {ax.trend_degree}"
        blocks = []
        for b, blk in enumerate(ax.blocks):
            if blk is not None:
                blocks.append(f"block{b} {blk.harmonics} harmonics period {blk.period_mm:g} mm "
                              f"origin {blk.origin_mm:g} mm")
        terms = []
        for t in ax.present_terms():
            unit = "um" if t in LINEAR_TERMS else "urad"
            terms.append(f"{t}({unit})")
        out.append(f"axis {a}: travel [{ax.travel_mm[0]:g}, {ax.travel_mm[1]:g}] mm; "
                   f"trend {trend}; " + ("; ".join(blocks) or "no Fourier blocks")
                   + f"; {ax.n_basis()} rows x {len(terms)} terms: "
                   + (" ".join(terms) or "none"))
        if ax.backlash_um or ax.backlash_takeup_mm:
            out.append(f"  backlash {ax.backlash_um:.4f} um, take-up {ax.backlash_takeup_mm:g} mm")
        if ax.reversal_cheb_um is not None:
            r = ax.reversal_um(np.linspace(ax.travel_mm[0], ax.travel_mm[1], 201))
            out.append(f"  reversal block degree {len(ax.reversal_cheb_um) - 1} (format 1.1): "
                       f"total reversal {r.min():.4f} .. {r.max():.4f} um over the travel")
        if ax.thermal_expansion_ppm_per_k or ax.thermal_offset_um_per_k or ax.thermal_tref_c:
            out.append(f"  thermal {ax.thermal_expansion_ppm_per_k:.4f} ppm/K, offset "
                       f"{ax.thermal_offset_um_per_k:.4f} um/K, T_ref {ax.thermal_tref_c:.3f} C")
    if thermal is not None:
        out.append(f"thermal block (format 1.3): {len(thermal.inputs)} inputs, max_gap "
                   f"{thermal.max_gap_s:g} s, fade {thermal.fade_s:g} s")
        for c in thermal.channels:
            out.append(f"  channel {c.output}: limit {c.limit:g}; " + "; ".join(
                f"in{t.input} gain {t.gain:.5f} tau {t.tau_s:g} s" for t in c.terms))
    if five is not None:
        out += five_table_lines(five)
    print("\n".join(out))
    return 0


def _cmd_eval_five(args: argparse.Namespace, data: bytes, five) -> int:
    """``abbe table eval`` of a five-axis table: joint positions X Y Z TILT C."""
    from abbe.formats.five_axis_blob import CHAIN_KIND_AXES, five_reference

    if args.dir is not None or args.temp_c is not None:
        raise AbbeInputError("--dir / --temp-c are for 3-axis tables; a five-axis table is "
                             "evaluated at joint positions only", field="--dir/--temp-c")
    if len(args.pos) % 5:
        raise AbbeInputError(f"{len(args.pos)} numbers given; a five-axis table "
                             f"({five.kind}) takes joint positions in X Y Z TILT C quintuples (format "
                             "1.4: the rotary axes in alphabetical order) "
                             "(mm, mm, mm, deg, deg)", field="pos")
    j = np.array(args.pos, dtype=np.float64).reshape(-1, 5)
    if np.any(np.abs(j[:, 3:]) > 2147.0):
        raise AbbeInputError("angles must lie within +/-2147 deg (the C library's range)",
                             field="pos")
    pos, ang = j[:, :3], j[:, 3:]
    if five.kind in {name for name, _axes in CHAIN_KIND_AXES.values()}:
        # format 1.4 (head-head, head-table, dual rotary table): the chain model's reference
        from abbe.formats.chain_blob import read_chain_blob
        from abbe.model.chain import tool_error_linear

        chain, errs = read_chain_blob(data)
        ref, rot = tool_error_linear(chain, errs, pos, ang)
        names = "".join(sorted(chain.rotaries))
    else:
        ref, rot = five_reference(five, pos, ang)
        names = five.kind[3].upper() + "C"
    cm = None
    if args.clib:
        from abbe.model import clib
        try:
            cm = clib.CFiveModel(data, source=str(args.model))
        except clib.LibraryNotFound as exc:
            raise AbbeInputError(str(exc), field="--clib") from None
    head = (f"joints X Y Z mm {names[0]} {names[1]} deg | ref tool tip dX dY dZ um | orientation "
            "rX rY rZ urad")
    if cm is not None:
        head += " | f32 dX dY dZ um | f32 rX rY rZ urad | max |diff| nm, nrad"
    print(head)
    for i in range(len(j)):
        line = (" ".join(f"{v:.4f}" for v in j[i]) + " | " + " ".join(f"{v:.4f}" for v in ref[i])
                + " | " + " ".join(f"{v:.4f}" for v in rot[i]))
        if cm is not None:
            e, r, _f = cm.error_f32(pos[i:i + 1], ang[i:i + 1])
            line += (" | " + " ".join(f"{v:.4f}" for v in e[0]) + " | "
                     + " ".join(f"{v:.4f}" for v in r[0])
                     + f" | {np.max(np.abs(e[0] - ref[i])) * 1e3:.3f} "
                       f"{np.max(np.abs(r[0] - rot[i])) * 1e3:.3f}")
        print(line)
    return 0


def _cmd_eval(args: argparse.Namespace) -> int:
    from abbe.model.reference import out_of_travel, spatial_error
    data, table, five = _read_any(args.model)
    if five is not None:
        return _cmd_eval_five(args, data, five)
    if len(args.pos) % 3:
        raise AbbeInputError(f"{len(args.pos)} numbers given; positions come in X Y Z triples",
                             field="pos_mm")
    pos = np.array(args.pos, dtype=np.float64).reshape(-1, 3)
    dirs = None
    if args.dir is not None:
        dirs = np.tile(np.array(args.dir, dtype=np.float64), (pos.shape[0], 1))
    temps = None if args.temp_c is None else np.tile(np.array(args.temp_c, dtype=np.float64),
                                                      (pos.shape[0], 1))
    ref = spatial_error(table, pos, dirs, temps)
    oot = out_of_travel(table, pos)
    cm = None
    if args.clib:
        if np.any(np.abs(pos) > 2147.0):
            raise AbbeInputError("with --clib positions must lie within +/-2147 mm (int32 nm)",
                                 field="pos_mm")
        from abbe.model import clib
        try:
            cm = clib.CModel(data, source=str(args.model))
        except clib.LibraryNotFound as exc:
            raise AbbeInputError(str(exc), field="--clib") from None
    head = "pos_mm X Y Z | ref dX dY dZ um"
    if cm is not None:
        head += " | f32 dX dY dZ um | q dX dY dZ um | max |diff| nm (f32, q)"
    print(head)
    for i, p in enumerate(pos):
        line = (" ".join(f"{v:.4f}" for v in p) + " | " + " ".join(f"{v:.4f}" for v in ref[i]))
        if cm is not None:
            ds = None if dirs is None else dirs[i:i + 1]
            tc = None if temps is None else temps[i:i + 1]
            f32, _ = cm.error_f32(p[None, :], ds, tc)
            pnm = np.rint(p * 1e6).astype(np.int64)[None, :]
            dq = None if dirs is None else np.rint(dirs[i:i + 1] * (1 << 30)).astype(np.int64)
            tq = None if temps is None else np.rint(temps[i:i + 1] * 1000).astype(np.int64)
            qv, _ = cm.error_q(pnm, dq, tq)
            qum = qv[0] / 1000.0
            line += (" | " + " ".join(f"{v:.4f}" for v in f32[0])
                     + " | " + " ".join(f"{v:.4f}" for v in qum)
                     + f" | {np.max(np.abs(f32[0] - ref[i])) * 1e3:.3f} "
                       f"{np.max(np.abs(qum - ref[i])) * 1e3:.3f}")
        if oot[i]:
            line += "  (outside travel: end values held)"
        print(line)
    return 0


def _cmd_cgen(args: argparse.Namespace) -> int:
    from abbe.formats.limits import BLOB_MAX_BYTES
    from abbe.formats.text import read_bytes
    from abbe.formats.thermal_blob import THERMAL_MINOR, read_thermal_blob

    Outputs().check_directory(args.out, option="--out")
    raw = read_bytes(args.model, what="table blob", max_bytes=BLOB_MAX_BYTES)
    if raw[:4] == b"ABBE" and int.from_bytes(raw[6:8], "little") == THERMAL_MINOR:
        read_thermal_blob(raw, source=str(args.model))  # format 1.3: errors name the file
        data = raw
    else:
        data, _, _ = _read_any(args.model)
    h, c = write_c(data, args.out, stem=args.stem, option="--out")
    print(h)
    print(c)
    return 0


def _cmd_from_json(args: argparse.Namespace) -> int:
    src = str(args.json)
    with Outputs() as outs:
        out = outs.file(args.out, option="--out")
        d, tf = load_json(args.json, what="table JSON", max_bytes=TABLE_JSON_MAX_BYTES)
        loc = JsonLocator(tf.text)
        table = table_from_json(d, source=src, locator=loc)
        try:
            blob = write_blob(table)
        except AbbeInputError as exc:  # name the JSON file and the line; field says where
            raise exc.located(file=src, line=loc.line(_json_field(exc.field))) from None
        out.write_bytes(blob)
    print(f"{args.out}: {len(blob)} bytes, CRC-32 0x{blob_crc(blob):08X}")
    return 0


def _json_field(blob_field: str | None) -> str | None:
    """The table JSON field an encoder field (``axes.X.coef.dx``) lives in."""
    if not blob_field:
        return None
    parts = blob_field.split(".")
    if len(parts) >= 4 and parts[0] == "axes" and parts[2] == "coef":
        unit = "um" if parts[3] in LINEAR_TERMS else "urad"
        return f"axes.{parts[1]}.terms.{parts[3]}_{unit}"
    return blob_field.replace("[", ".").split(".")[0] if "[" in blob_field else blob_field


def _cmd_to_json(args: argparse.Namespace) -> int:
    from abbe.formats.five_axis_blob import five_table_to_json

    _, table, five = _read_any(args.model)
    doc = table_to_json(table)
    if five is not None:
        # the linear axes' table as for a 3-axis table, plus the rotary section (format
        # 1.2); from-json reads 3-axis tables only (abbe fit writes the five-axis ones)
        doc["rotary"] = five_table_to_json(five)
    text = json.dumps(doc, indent=2, allow_nan=False) + "\n"
    if args.out is None:
        sys.stdout.write(text)
    else:
        atomic_write(args.out, text.encode(), option="--out")
    return 0


def _cmd_thermal(args: argparse.Namespace) -> int:
    from abbe.formats.limits import BLOB_MAX_BYTES
    from abbe.formats.text import read_bytes
    from abbe.formats.thermal_blob import read_thermal_blob, strip_thermal_blob, write_thermal_blob
    from abbe.model.thermal import from_dict

    if (args.thermal_json is None) == (not args.strip):
        raise AbbeInputError("give a thermal.json, or --strip (not both)", field="thermal_json")
    with Outputs() as outs:
        out = outs.file(args.out, option="--out")
        data = read_bytes(args.model, what="table blob", max_bytes=BLOB_MAX_BYTES)
        read_thermal_blob(data, source=str(args.model))
        if args.strip:
            blob = strip_thermal_blob(data)
        else:
            src = str(args.thermal_json)
            d, _ = load_json(args.thermal_json, what="thermal model JSON",
                             max_bytes=TABLE_JSON_MAX_BYTES)
            try:
                model = from_dict(d)
                blob = write_thermal_blob(data, model)
            except AbbeInputError as exc:
                raise exc.located(file=src) from None
        out.write_bytes(blob)
    _, th = read_thermal_blob(blob)
    what = (f"thermal block of {len(th.inputs)} inputs, {len(th.channels)} channels"
            if th is not None else "no thermal block")
    print(f"{args.out}: {len(blob)} bytes, {what}, CRC-32 0x{blob_crc(blob):08X}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    """Add ``abbe table`` and its sub-commands."""
    p = subparsers.add_parser("table", help="inspect, evaluate and convert error tables "
                                            "(three-axis, five-axis 1.2, thermal 1.3)",
                              description=__doc__.splitlines()[0],
                              epilog=examples("abbe table info fit-out/model.bin",
                                              "abbe table eval fit-out/model.bin 250 -200 -150"))
    sub = p.add_subparsers(dest="table_command", metavar="SUBCOMMAND")
    sub.required = True

    q = sub.add_parser("info", help="validate a table and show its shape, features and CRC",
                       epilog=examples("abbe table info fit-out/model.bin"))
    q.add_argument("model", type=Path, help="table blob (model.bin, or model_five.bin: format 1.2)")
    q.set_defaults(func=_cmd_info)

    q = sub.add_parser("eval", help="spatial error (um) at machine positions (mm); five-axis "
                       "tables: tool tip error at joints X Y Z TILT C",
                       epilog=examples("abbe table eval fit-out/model.bin 250 -200 -150 --clib",
                                       "abbe table eval fit-out/model.bin 0 0 0 500 -400 -300 "
                                       "--dir 1 1 1",
                                       "abbe table eval fit5/model_five.bin 120 -40 -180 30 45 "
                                       "--clib"))
    q.add_argument("model", type=Path, help="table blob (model.bin or a five-axis model_five.bin)")
    q.add_argument("pos", nargs="+", type=in_range(-1e5, 1e5, "mm / deg"), metavar="X Y Z",
                   help="machine positions, mm, in X Y Z triples; a five-axis table (format "
                        "1.2): joint positions X Y Z TILT C (mm, deg) in quintuples")
    q.add_argument("--dir", nargs=3, type=in_range(-1.0, 1.0), metavar=("SX", "SY", "SZ"),
                   help="backlash direction state per axis in [-1, 1] (default 0)")
    q.add_argument("--temp-c", nargs=3, type=in_range(-100.0, 200.0, "deg C"),
                   metavar=("TX", "TY", "TZ"),
                   help="axis temperatures, deg C (default: no thermal term)")
    q.add_argument("--clib", action="store_true",
                   help="also evaluate with the C library (f32 and q) and show the difference")
    q.set_defaults(func=_cmd_eval)

    q = sub.add_parser("cgen", help="write abbe_model.c / abbe_model.h",
                       epilog=examples("abbe table cgen fit-out/model.bin -o firmware/"))
    q.add_argument("model", type=Path, help="table blob (model.bin)")
    q.add_argument("-o", "--out", type=Path, required=True, help="output directory")
    q.add_argument("--stem", default="abbe_model", help="file and symbol stem (abbe_model)")
    q.set_defaults(func=_cmd_cgen)

    q = sub.add_parser("from-json", help="convert a JSON table to a blob",
                       epilog=examples("abbe table from-json model.json -o model.bin"))
    q.add_argument("json", type=Path, help="table JSON (model.json)")
    q.add_argument("-o", "--out", type=Path, required=True, help="output blob (model.bin)")
    q.set_defaults(func=_cmd_from_json)

    q = sub.add_parser("thermal", help="put a thermal model (thermal.json) into a table as its "
                       "thermal block (format 1.3)",
                       epilog=examples("abbe table thermal fit-out/model.bin thermal.json -o model_thermal.bin",
                                       "abbe table thermal model_thermal.bin --strip -o model.bin"))
    q.add_argument("model", type=Path, help="table blob (format 1.0, 1.1 or 1.3)")
    q.add_argument("thermal_json", type=Path, nargs="?", help="thermal model (thermal.json)")
    q.add_argument("--strip", action="store_true", help="write the table without its thermal block")
    q.add_argument("-o", "--out", type=Path, required=True, help="output blob")
    q.set_defaults(func=_cmd_thermal)

    q = sub.add_parser("to-json", help="convert a blob to JSON (stdout unless -o)",
                       epilog=examples("abbe table to-json fit-out/model.bin -o model.json"))
    q.add_argument("model", type=Path, help="table blob (model.bin)")
    q.add_argument("-o", "--out", type=Path, help="output JSON file")
    q.set_defaults(func=_cmd_to_json)

    from abbe.cli import table_uncertainty  # the fit's U at any point (issue 37)
    table_uncertainty.register(sub)
