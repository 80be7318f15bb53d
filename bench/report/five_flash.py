"""Five-axis flash per kind and per function (issue 39 item 4), for section 11.

Reads the five-axis size images (bench_size_five_f32 / _q: load + evaluation + the
compensator's five-axis cycle) of the bench builds and of the per-kind builds that
scripts/bench_five_kinds.sh makes next to them (<build>-kinds<k>: the library built with
-DABBE_FIVE_KINDS=<k>). Library flash comes from the link maps (report.maps.parse_map, as
the rest of the section); the per-function breakdown from arm-none-eabi-nm on the image,
restricted to the symbols libabbe.a defines, each marked shared when the 3-axis load +
compensator image (bench_size_comp_*) links it too.
"""

from __future__ import annotations

import subprocess
from pathlib import Path

from report.maps import parse_map

NM = "arm-none-eabi-nm"
#: per-kind builds: directory suffix, the kinds, what a firmware with them is
KIND_BUILDS = (("", "1-5", "every kind (default)"), ("-kinds12", "1, 2", "trunnions (xyzac-trt, xyzbc-trt)"),
               ("-kinds1", "1", "xyzac-trt"), ("-kinds2", "2", "xyzbc-trt"), ("-kinds3", "3", "head-head (5axiskins)"),
               ("-kinds4", "4", "head-table (maxkins)"), ("-kinds5", "5", "dual rotary table (xyzab-tdr)"))
IMAGES = (("Cortex-M4F", "m4f", "five_f32"), ("Cortex-M4F", "m4f", "five_q"), ("Cortex-M3", "m3", "five_q"))


def _symbols(path: Path, defined_only: bool = False) -> dict[str, int]:
    """name -> size (B) of the sized symbols nm lists for an ELF or archive."""
    cmd = [NM, "-S", "--size-sort"] + (["--defined-only"] if defined_only else []) + [str(path)]
    out = subprocess.run(cmd, capture_output=True, text=True, check=False).stdout
    sizes: dict[str, int] = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 4:
            sizes[parts[3]] = sizes.get(parts[3], 0) + int(parts[1], 16)
    return sizes


def _lib_functions(build: Path, use: str, ref: Path) -> tuple[dict[str, int], set[str]] | None:
    """The library's symbols in the five-axis image (name -> size) and the names the 3-axis
    load + compensator image of the same variant (in the every-kind build ref) also links."""
    elf = build / "bench" / f"bench_size_{use}.elf"
    lib = build / "lib" / "libabbe.a"
    if not elf.exists() or not lib.exists():
        return None
    lib_names = set(_symbols(lib, defined_only=True))
    image = {k: v for k, v in _symbols(elf).items() if k in lib_names}
    three = ref / "bench" / f"bench_size_comp_{use.split('_')[1]}.elf"
    shared = set(_symbols(three)) & lib_names if three.exists() else set()
    return image, shared


def flash_lines(m4f: Path, m3: Path, budget: int) -> list[str]:
    """Markdown: flash per kind image, then per function where the budget is missed."""
    builds = {"m4f": m4f, "m3": m3}
    out = ["Flash per kind (issue 39 item 4: a machine's firmware carries its own kind only;",
           "`-DABBE_FIVE_KINDS=<k>`, the loader refusing the other kinds with ABBE_E_KIND; per-kind",
           "builds by scripts/bench_five_kinds.sh), library flash of load + evaluation +",
           "compensator (B, over the budget in brackets):", "",
           "| kinds built | machines | f32 (M4F) | q (M4F) | q (M3) |", "|---|---|---:|---:|---:|"]
    smallest: dict[tuple[str, str], tuple[int, Path]] = {}
    for suffix, kinds, what in KIND_BUILDS:
        cells = []
        for _, tgt, use in IMAGES:
            mp = Path(f"{builds[tgt]}{suffix}") / "bench" / f"bench_size_{use}.map"
            if not mp.exists():
                cells.append("not built")
                continue
            size = parse_map(mp).lib_flash
            over = size - budget
            cells.append(f"{size} ({'+' if over > 0 else ''}{over})")
            key = (tgt, use)
            if key not in smallest or size < smallest[key][0]:
                smallest[key] = (size, Path(f"{builds[tgt]}{suffix}"))
        out.append(f"| {kinds} | {what} | " + " | ".join(cells) + " |")
    out += ["", f"What stands in the way of {budget} B, per byte: the library's functions and",
            "tables in the every-kind image and in the smallest per-kind image (arm-none-eabi-nm",
            "sizes; 'shared': the 3-axis load + compensator image links the same function;",
            "the rest of the map's figure is alignment and literal padding):", ""]
    for name, tgt, use in IMAGES:
        small = smallest.get((tgt, use), (0, None))[1]
        for label, build in (("every kind", builds[tgt]), ("smallest kind image", small)):
            if build is None:
                continue
            mp = build / "bench" / f"bench_size_{use}.map"
            got = _lib_functions(build, use, builds[tgt])
            if got is None or not mp.exists():
                continue
            image, shared = got
            total = parse_map(mp).lib_flash
            five = sorted(((v, k) for k, v in image.items() if k not in shared), reverse=True)
            both = sorted(((v, k) for k, v in image.items() if k in shared), reverse=True)
            s_five, s_both = sum(v for v, _ in five), sum(v for v, _ in both)
            out.append(f"- {name} `{use}`, {label} ({build.name}): {total} B, {total - budget:+d} against "
                       f"{budget}; five-axis only {s_five} B: " + ", ".join(f"{k} {v}" for v, k in five)
                       + f"; shared with the 3-axis image {s_both} B: " + ", ".join(f"{k} {v}" for v, k in both)
                       + f"; padding {total - s_five - s_both} B")
    loaders = []
    for name, tgt, _ in IMAGES[1:]:
        three = _symbols(builds[tgt] / "bench" / "bench_size_comp_q.elf")
        loaders.append(f"{name} {three.get('abbe_model_load', 0)} B")
    out += ["", "abbe_five_model_load holds the 3-axis loader's checks and build inlined (five_load.c is",
            "model_load.c compiled a second time); the 3-axis image's abbe_model_load: " + ", ".join(loaders) + "."]
    return out
