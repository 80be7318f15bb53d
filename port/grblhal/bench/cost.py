#!/usr/bin/env python3
"""Cost of the grblHAL plugin per segment on a Cortex-M4F (_f32) and M3 (_q).

Builds port/grblhal/bench/bench_grblhal.c for both (build-bench-grblhal-m4f/,
-m3/, the project's toolchain files) with the vmc500 table (abbe fit of
examples/vmc500, abbe table cgen), runs it under QEMU with an exec trace and
counts the instructions of each call exactly (bench/report/measure.py's
qemu_trace_counts: one trace line per executed instruction, minus an empty
pair of marks); flash: the plugin core's objects (all of them,
abbe_grblhal_core*.c: port/grblhal/sources.cmake), and from the
link map the library members it pulls in and libgcc's soft-float helpers. Writes
section 10 of bench/results.md (between its markers; replaced on every run)
and, with --json, the figures.

  port/grblhal/bench/cost.py [--json OUT] [--no-write] [--from-json FIGURES] [--thermal]

--thermal: the same with the vmc500 table carrying the thermal block of
examples/spindle_thermal/thermal.json (17 inputs, 5 channels; abbe table thermal), the
clock advancing per segment, and abbe_gh_thermal_sample() measured too; written to its own
section of bench/results.md (10b).
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(REPO / "bench"))
from report.maps import parse_map  # noqa: E402
from report.measure import qemu_trace_counts  # noqa: E402

TARGETS = {"m4f": ("Cortex-M4F", "cortex-m4f", "mps2-an386", "_f32"),
           "m3": ("Cortex-M3", "cortex-m3", "mps2-an385", "_q")}
BEGIN = "<!-- grblhal-plugin: written by port/grblhal/bench/cost.py -->"
END = "<!-- /grblhal-plugin -->"
BEGIN_TH = "<!-- grblhal-plugin-thermal: written by port/grblhal/bench/cost.py --thermal -->"
END_TH = "<!-- /grblhal-plugin-thermal -->"


def sh(cmd: list[str], **kw) -> subprocess.CompletedProcess:
    return subprocess.run(cmd, check=True, text=True, capture_output=True, **kw)


def object_flash(objs: list[Path]) -> int:
    """Flash (.text*, .rodata*) of object files: all of the plugin core (its
    files: port/grblhal/sources.cmake), also the functions this benchmark does
    not call (the upload)."""
    if not objs:
        raise SystemExit("cost.py: no abbe_grblhal_core*.c.obj in the build")
    total = 0
    for obj in objs:
        for line in sh(["arm-none-eabi-size", "-A", str(obj)]).stdout.splitlines():
            parts = line.split()
            if len(parts) >= 2 and parts[0].startswith((".text", ".rodata")):
                total += int(parts[1])
    return total


def blob_c(blob: bytes, out: Path) -> None:
    """abbe_model.c / .h holding ``blob`` as the plugin's built-in table (the names
    abbe table cgen uses; 4-byte aligned, as abbe_model_load needs)."""
    (out / "abbe_model.h").write_text(
        "#ifndef ABBE_BENCH_MODEL_H\n#define ABBE_BENCH_MODEL_H\n#include <stdint.h>\n"
        "extern const uint8_t abbe_model_blob[];\nextern const uint32_t abbe_model_blob_size;\n#endif\n")
    rows = [", ".join(f"0x{b:02x}" for b in blob[i:i + 16]) for i in range(0, len(blob), 16)]
    (out / "abbe_model.c").write_text(
        "/* written by port/grblhal/bench/cost.py --thermal */\n#include \"abbe_model.h\"\n"
        f"__attribute__((aligned(4))) const uint8_t abbe_model_blob[{len(blob)}] = {{\n    "
        + ",\n    ".join(rows) + f"\n}};\nconst uint32_t abbe_model_blob_size = {len(blob)}u;\n")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", type=Path)
    ap.add_argument("--no-write", action="store_true", help="do not touch bench/results.md")
    ap.add_argument("--from-json", type=Path, help="write the section from the figures of an earlier --json")
    ap.add_argument("--thermal", action="store_true", help="the table with a thermal block")
    args = ap.parse_args()
    if args.from_json:
        write_section(json.loads(args.from_json.read_text()), args.thermal)
        return 0
    abbe = REPO / ".venv" / "bin" / "abbe"
    gen = REPO / "build-bench-grblhal-table"
    gen.mkdir(exist_ok=True)
    sh([str(abbe), "fit", str(REPO / "examples/vmc500/machine.toml"), "-o", str(gen / "fit"), "--no-report", "-q"])
    table = gen / "fit" / "model.bin"
    suffix = ""
    if args.thermal:
        suffix = "-th"
        table = gen / "model_thermal.bin"
        sh([str(abbe), "table", "thermal", str(gen / "fit" / "model.bin"),
            str(REPO / "examples/spindle_thermal/thermal.json"), "-o", str(table)])
        gen = REPO / "build-bench-grblhal-table-th"
        gen.mkdir(exist_ok=True)
        blob_c(table.read_bytes(), gen)  # abbe table cgen writes tables of format <= 1.1
    else:
        sh([str(abbe), "table", "cgen", str(table), "-o", str(gen)])
    res: dict = {}
    for key, (label, tc, machine, variant) in TARGETS.items():
        build = REPO / f"build-bench-grblhal{suffix}-{key}"
        sh(["cmake", "-S", str(REPO), "-B", str(build), f"-DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-{tc}.cmake",
            "-DCMAKE_BUILD_TYPE=Release", "-DABBE_BUILD_BENCH=ON", "-DABBE_BUILD_TESTS=OFF",
            f"-DABBE_GRBLHAL_BENCH_TABLE_DIR={gen}",
            f"-DABBE_GRBLHAL_BENCH_THERMAL={'ON' if args.thermal else 'OFF'}"], cwd=REPO)
        sh(["cmake", "--build", str(build), "--target", "bench_grblhal", "-j", "2"])
        image = build / "bench" / "grblhal" / "bench_grblhal.elf"
        counts, out = qemu_trace_counts(machine, image, "arm-none-eabi-nm")
        maps = parse_map(image.with_suffix(".map"))
        core = object_flash(sorted(build.glob("**/abbe_grblhal_core*.c.obj")))
        segs = re.search(r"^SEGMENTS (\d+)$", out, re.M)
        per_seg_circle = max(counts["forward_circle"])
        per_seg_line = max(counts["forward_line"]) + max(counts["line_next"])
        res[key] = {"label": label, "variant": variant, "counts": counts,
                    "forward_max": max(max(counts["forward_circle"]), max(counts["forward_line"])),
                    "per_segment_circle": per_seg_circle, "per_segment_line": per_seg_line,
                    "line_begin": counts["line_begin"][0], "inverse_max": max(counts["inverse"]),
                    "flash_core": core, "flash_lib": maps.lib_flash, "flash_libgcc": maps.gcc_flash,
                    "line_segments": int(segs.group(1)) if segs else None,
                    "table_bytes": table.stat().st_size}
        if args.thermal:
            fl = re.search(r"^THERMAL_FLAGS (\d+)$", out, re.M)
            res[key]["thermal_sample_max"] = max(counts["thermal_sample"])
            res[key]["thermal_flags_after_fade_in"] = int(fl.group(1)) if fl else None
        print(f"{label}: forward (transform) {res[key]['forward_max']} instructions, per line segment "
              f"{per_seg_line}, line begin {res[key]['line_begin']}, inverse {res[key]['inverse_max']}; flash "
              f"core {core} B + library {maps.lib_flash} B + libgcc {maps.gcc_flash} B")
    if args.json:
        args.json.write_text(json.dumps(res, indent=2) + "\n")
    if not args.no_write:
        write_section(res, args.thermal)
    return 0


def write_section(res: dict, thermal: bool = False) -> None:
    if thermal:
        write_thermal_section(res)
        return
    gcc = sh(["arm-none-eabi-gcc", "--version"]).stdout.splitlines()[0]
    qemu = sh(["qemu-system-arm", "--version"]).stdout.splitlines()[0]
    w = [BEGIN, "## 10. The grblHAL plugin per segment (issue 25)", "",
         "port/grblhal/bench/bench_grblhal.c under QEMU (exec trace, exact counts; the worst of the",
         "measured calls), the vmc500 table of `abbe fit` (backlash, thermal; 24 rows), full gain",
         "after a fade-in. Per segment grblHAL's mc_line() gets the next segment end",
         "(`abbe_gh_line_next`, only on lines the plugin splits; arcs come as grblHAL's chords) and",
         "transforms it (`abbe_gh_forward`: direction, one `abbe_comp_step`, motor = p + correction).",
         "Per line once `abbe_gh_line_begin`; per position report `abbe_gh_inverse` (fixed point of",
         "p = m - c(p), 1-2 iterations of one evaluation each, plus one at the last segment end).",
         "Flash: the plugin core's objects (all of them, the upload included), the library members",
         "it links, libgcc's soft-float helpers (M3: the core's float arithmetic; grblHAL links them",
         "anyway). Not included: the grblHAL glue (abbe_grblhal.c, _store.c, _settings.c, _commands.c:",
         "kinematics hooks, storage, settings, commands, report; it needs grblHAL to build).", "",
         "| target | variant | transform per segment (circle) | per line segment (next + transform) | "
         "line begin | inverse | flash core + library + libgcc |",
         "|---|---|---:|---:|---:|---:|---:|"]
    for r in res.values():
        w.append(f"| {r['label']} | {r['variant']} | {r['per_segment_circle']} | {r['per_segment_line']} | "
                 f"{r['line_begin']} | {r['inverse_max']} | {r['flash_core']} + {r['flash_lib']} + "
                 f"{r['flash_libgcc']} B |")
    w += ["", f"Toolchain: {gcc}; {qemu}. Regenerate: `port/grblhal/bench/cost.py`.", END]
    path = REPO / "bench" / "results.md"
    text = path.read_text()
    block = "\n".join(w) + "\n"
    if BEGIN in text and END in text:
        text = text[:text.index(BEGIN)] + block + text[text.index(END) + len(END) + 1:]
    else:
        text = text.rstrip("\n") + "\n\n" + block
    path.write_text(text)


def write_thermal_section(res: dict) -> None:
    gcc = sh(["arm-none-eabi-gcc", "--version"]).stdout.splitlines()[0]
    qemu = sh(["qemu-system-arm", "--version"]).stdout.splitlines()[0]
    w = [BEGIN_TH, "## 10b. The grblHAL plugin per segment with a thermal block (issue 35)", "",
         "As section 10, the vmc500 table carrying the thermal block of",
         "examples/spindle_thermal/thermal.json (17 inputs, 5 channels, 17 terms; the table",
         f"{next(iter(res.values()))['table_bytes']} bytes), the clock advancing 100 ms per measured segment",
         "(each segment end adds the thermal error by elapsed time, abbe_comp_step_thermal_ms_*),",
         "after the thermal part faded in. `abbe_gh_thermal_sample`: one sample of the 17 inputs",
         "(states of every channel advanced, 15 s after the previous sample).", "",
         "| target | variant | transform per segment (circle) | per line segment | line begin | inverse | "
         "one thermal sample | flags after fade-in | flash core + library + libgcc |",
         "|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for r in res.values():
        w.append(f"| {r['label']} | {r['variant']} | {r['per_segment_circle']} | {r['per_segment_line']} | "
                 f"{r['line_begin']} | {r['inverse_max']} | {r['thermal_sample_max']} | "
                 f"0x{r['thermal_flags_after_fade_in']:x} | {r['flash_core']} + {r['flash_lib']} + "
                 f"{r['flash_libgcc']} B |")
    w += ["", f"Toolchain: {gcc}; {qemu}. Regenerate: `port/grblhal/bench/cost.py --thermal`.", END_TH]
    path = REPO / "bench" / "results.md"
    text = path.read_text()
    block = "\n".join(w) + "\n"
    if BEGIN_TH in text and END_TH in text:
        text = text[:text.index(BEGIN_TH)] + block + text[text.index(END_TH) + len(END_TH) + 1:]
    else:
        text = text.rstrip("\n") + "\n\n" + block
    path.write_text(text)


if __name__ == "__main__":
    sys.exit(main())
