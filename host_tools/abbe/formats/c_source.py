"""Generated C of a table blob (``abbe_model.c`` / ``.h``, docs/table-format.md).

``python -m abbe.formats.c_source --c MODEL.bin -o DIR`` writes them from a blob.
"""

from __future__ import annotations

import re
import struct
from pathlib import Path

from abbe.errors import AbbeInputError
from abbe.formats.blob import FORMAT_MAJOR, blob_crc, read_blob, read_blob_file
from abbe.formats.output import atomic_write_many
from abbe.model.table import AXES, FEATURE_REVERSAL, LINEAR_TERMS, Table, feature_names


def _c_listing(table: Table, crc: int, size: int, minor: int) -> list[str]:
    """Human-readable comment lines listing every coefficient."""
    lines = [f"table format {FORMAT_MAJOR}.{minor}, {size} bytes, CRC-32 0x{crc:08X}",
             "features: " + (", ".join(feature_names(table.features())) or "none"),
             "reference_mm: " + ", ".join(f"{v:.6f}" for v in table.reference_mm)]
    if any(table.tool_offset_mm):
        lines.append("tool_offset_mm: " + ", ".join(f"{v:.6f}" for v in table.tool_offset_mm))
    if any(table.squareness_urad):
        lines.append("squareness_urad: S_xy %.6f, S_xz %.6f, S_yz %.6f" % table.squareness_urad)
    for a in AXES:
        ax = table.axes[a]
        lines.append("")
        desc = [f"axis {a}: travel_mm [{ax.travel_mm[0]:.6f}, {ax.travel_mm[1]:.6f}]",
                "trend " + ("none" if ax.trend_degree is None else f"degree {ax.trend_degree}")]
        for b, blk in enumerate(ax.blocks):
            if blk is not None:
                desc.append(f"block {b}: {blk.harmonics} harmonics, period_mm "
                            f"{blk.period_mm:.6f}, origin_mm {blk.origin_mm:.6f}")
        lines.append("; ".join(desc))
        if ax.backlash_um or ax.backlash_takeup_mm:
            lines.append(f"  backlash_um {ax.backlash_um:.6f}, takeup_mm "
                         f"{ax.backlash_takeup_mm:.6f}")
        if ax.reversal_cheb_um is not None:
            # the total reversal is backlash_um + sum_k R_k T_k(u), u the trend's argument
            lines.append(f"  reversal block (degree {len(ax.reversal_cheb_um) - 1}, added to "
                         "backlash_um), um: " + ", ".join(
                             f"R{k} {v:.6f}" for k, v in enumerate(ax.reversal_cheb_um)))
        if ax.thermal_expansion_ppm_per_k or ax.thermal_offset_um_per_k or ax.thermal_tref_c:
            lines.append(f"  thermal_expansion_ppm_per_k {ax.thermal_expansion_ppm_per_k:.6f}, "
                         f"thermal_offset_um_per_k {ax.thermal_offset_um_per_k:.6f}, "
                         f"tref_c {ax.thermal_tref_c:.3f}")
        terms = ax.present_terms()
        if not terms:
            lines.append("  no terms")
            continue
        head = "  " + "row".ljust(10) + "".join(
            (f"{t}_um" if t in LINEAR_TERMS else f"{t}_urad").rjust(16) for t in terms)
        lines.append(head)
        for r, name in enumerate(ax.row_names()):
            lines.append("  " + name.ljust(10) + "".join(
                f"{float(ax.coef[t][r]):16.6f}" for t in terms))
    return lines


def _thermal_lines(model) -> list[str]:
    """The listing of a format 1.3 table's thermal block (as the table holds it)."""
    lines = [f"thermal block (format 1.3; load with abbe_thermal_load(), abbe/thermal.h): "
             f"{len(model.inputs)} inputs, {len(model.channels)} channels, "
             f"max_gap_s {model.max_gap_s:g}, fade_s {model.fade_s:g}"]
    for k, i in enumerate(model.inputs):
        unit = "rpm" if i.kind == "speed" else "degC"
        line = (f"  in{k} {i.kind}: reference {i.reference:g} {unit}, valid "
                f"[{i.valid_min:g}, {i.valid_max:g}], max_step {i.max_step:g}")
        if i.stuck_s:
            line += f", stuck after {i.stuck_s:g} s within {i.stuck_resolution:g}"
        lines.append(line)
    for c in model.channels:
        unit = "urad" if c.output in ("a", "b") else "um"
        per = {True: "krpm", False: "K"}
        lines.append(f"  channel {c.output} ({unit}, limit {c.limit:g}): " + "; ".join(
            f"in{t.input} {t.gain:.6f} {unit}/{per[model.inputs[t.input].kind == 'speed']} "
            f"tau {t.tau_s:g} s" for t in c.terms))
    return lines


def write_c(blob: bytes, out_dir: Path, stem: str = "abbe_model",
            option: str = "--out") -> tuple[Path, Path]:
    """Write ``STEM.h`` and ``STEM.c`` (docs/table-format.md "Generated C").

    The blob is validated first. The .c file holds the bytes and a comment
    listing every coefficient in um / urad; no timestamp. The symbols are
    ``abbe_model_blob`` / ``abbe_model_blob_size`` for the default stem, else
    ``STEM_blob`` / ``STEM_blob_size``. Both files are written to a temporary
    name and moved into place only when both are complete.
    """
    from abbe.formats.five_axis_blob import five_table_lines, is_five_axis_blob, read_five_blob
    from abbe.formats.thermal_blob import THERMAL_MINOR, read_thermal_blob

    five = read_five_blob(blob) if is_five_axis_blob(blob) else None
    thermal = None
    minor, = struct.unpack_from("<H", blob, 6) if len(blob) >= 8 else (0,)
    if five is None and bytes(blob[:4]) == b"ABBE" and minor == THERMAL_MINOR:
        table, thermal = read_thermal_blob(blob)  # every check of abbe_thermal_load
    else:
        table = read_blob(blob) if five is None else five.errors.linear
    total, = struct.unpack_from("<I", blob, 8)
    # the table's minor: 1.0 tables still build with 1.0 libraries; a 1.3 table needs the
    # minor of its geometric part (1.1 with reversal blocks) and a library with abbe/thermal.h
    base_minor = minor if thermal is None else (1 if table.features() & FEATURE_REVERSAL else 0)
    blob = bytes(blob[:total])
    crc = blob_crc(blob)
    ident = stem
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]{0,63}", stem):
        raise AbbeInputError(f"stem {stem!r} is not a C identifier (letters, digits, '_'; "
                             "at most 64)", field="--stem")
    guard = "ABBE_GENERATED_" + ident.upper() + "_H"  # not ABBE_MODEL_H: abbe/model.h has it
    sym = f"{ident}_blob"
    out_dir = Path(out_dir)
    h_text = "\n".join([
        f"/* {stem}.h: abbe error table (generated by abbe, do not edit). */",
        f"#ifndef {guard}",
        f"#define {guard}",
        "",
        "#include <stdint.h>",
        "",
        '#include "abbe/version.h"',
        f"#if ABBE_TABLE_FORMAT_MAJOR != {FORMAT_MAJOR} || ABBE_TABLE_FORMAT_MINOR < {base_minor}",
        f'#error "{stem}.c was generated for table format {FORMAT_MAJOR}.{minor}: '
        'regenerate it with a matching abbe"',
        "#endif",
        *([] if thermal is None else [
            '#include "abbe/thermal.h" /* a library without it cannot read the thermal block */',
            f"#if !defined(ABBE_THERMAL_FORMAT_MINOR) || ABBE_THERMAL_FORMAT_MINOR != {THERMAL_MINOR}",
            f'#error "{stem}.c was generated for table format {FORMAT_MAJOR}.{minor} (thermal block): '
            'regenerate it with a matching abbe"',
            "#endif",
            f"/* a table of format {FORMAT_MAJOR}.{minor}: load it with abbe_thermal_load() */"]),
        "",
        f"#define {ident.upper()}_BLOB_CRC32 0x{crc:08X}u /* abbe_model_crc() of this table */",
        "",
        f"extern const uint8_t {sym}[];",
        f"extern const uint32_t {sym}_size;",
        "",
        f"#endif /* {guard} */",
        "",
    ])
    listing = _c_listing(table, crc, total, minor)
    if thermal is not None:
        listing += [""] + _thermal_lines(thermal)
    if five is not None:  # a five-axis table: abbe_five_model_load() reads it
        listing += ["", "rotary section (format 1.2; load with abbe_five_model_load(), "
                    "abbe/five_axis.h):"] + five_table_lines(five)
    c_lines = [f"/* {stem}.c: abbe error table (generated by abbe, do not edit).", " *"]
    c_lines += [(" * " + ln).rstrip() for ln in listing]
    c_lines += [" */", f'#include "{stem}.h"', "",
                "/* abbe_model_load() needs the table 4-byte aligned (ABBE_E_ALIGN). */",
                "#if defined(__GNUC__) || defined(__clang__)",
                "__attribute__((aligned(4)))",
                "#elif defined(__ICCARM__)",
                "#pragma data_alignment = 4",
                "#elif defined(__CC_ARM)",
                "__align(4)",
                "#else",
                "#error \"align abbe_model_blob to 4 bytes for this compiler\"",
                "#endif",
                f"const uint8_t {sym}[{total}] = {{"]
    for i in range(0, total, 16):
        chunk = blob[i:i + 16]
        c_lines.append("    " + ", ".join(f"0x{b:02X}" for b in chunk) + ",")
    c_lines += ["};", f"const uint32_t {sym}_size = {total}u;", ""]
    c_text = "\n".join(c_lines)
    h_path, c_path = out_dir / f"{stem}.h", out_dir / f"{stem}.c"
    atomic_write_many({h_path: h_text.encode(), c_path: c_text.encode()}, option=option)
    return h_path, c_path


def main(argv: list[str] | None = None) -> int:
    """``python -m abbe.formats.c_source --c MODEL.bin -o DIR``: write the generated C."""
    import argparse
    import sys
    ap = argparse.ArgumentParser(prog="python -m abbe.formats.c_source",
                                 description="write generated C for a table blob")
    ap.add_argument("--c", type=Path, required=True, metavar="MODEL.bin", help="table blob")
    ap.add_argument("-o", "--out", type=Path, default=Path("."), help="output directory")
    ap.add_argument("--stem", default="abbe_model", help="file and symbol stem")
    args = ap.parse_args(argv)
    try:
        from abbe.formats.limits import BLOB_MAX_BYTES
        from abbe.formats.text import read_bytes
        data = read_bytes(args.c, what="table blob", max_bytes=BLOB_MAX_BYTES)
        if data[:4] == b"ABBE" and data[6:8] == b"\x03\x00":  # 1.3: write_c validates it
            from abbe.formats.thermal_blob import read_thermal_blob
            read_thermal_blob(data, source=str(args.c))
        else:
            data, _ = read_blob_file(args.c)
        for path in write_c(data, args.out, args.stem):
            print(path)
    except AbbeInputError as exc:
        print(f"python -m abbe.formats.c_source: error: {exc}", file=sys.stderr)
        return 2
    return 0

if __name__ == "__main__":
    raise SystemExit(main())
