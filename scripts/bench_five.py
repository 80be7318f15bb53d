#!/usr/bin/env python3
"""Five-axis benchmark (format 1.2 tables): instructions per call, flash and stack on
the Cortex-M4F and M3, and the 3-axis figures beside them (no regression).

Reads the bench builds of scripts/bench.sh (build-bench-m4f, build-bench-m3: the
bench_five_target image and the bench_size_five_* / bench_size_comp_* link maps) with
scripts/bench_report.py's helpers (QEMU exec trace counts, link-map sizes) and writes
the markdown section "## Five-axis tables" (``section``), which scripts/bench_report.py
appends to bench/results.md. Standalone: ``python3 scripts/bench_five.py --m4f
build-bench-m4f --m3 build-bench-m3 --results bench/results.md`` replaces that section
in place.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_report import (deepest, parse_callgraph, parse_map, qemu_function_counts,  # noqa: E402
                          qemu_trace_counts, short, stack_measured)

TARGETS = {"five_f32": 1500, "five_q": 3000, "flash": 8 * 1024, "stack": 320}
#: The tables the instruction budgets are judged on: the paper machine's linear axes (the
#: 3-axis budgets' table) or none, with the rotary axes. ac_location carries the 'full'
#: 3-axis table, whose linear evaluation alone is above the five-axis budgets.
BUDGET_TABLES = ("ac_full", "bc_motions")
#: bench/results.md's 3-axis figures this section must not regress (issue 23).
THREE_AXIS_BEFORE = {("Cortex-M4F", "f32"): 697, ("Cortex-M3", "q"): 1409,
                     ("Cortex-M4F", "comp_f32"): 6048, ("Cortex-M4F", "comp_q"): 5926,
                     ("Cortex-M3", "comp_q"): 6036}
HEADING = "## 11. Five-axis tables (format 1.2, issue 23)"
MACHINES = {"Cortex-M4F": "mps2-an386", "Cortex-M3": "mps2-an385"}


_WRAPPER = {"five_f32": "run_f32", "five_q": "run_q", "comp5_f32": "run_comp_f32", "comp5_q": "run_comp_q"}


def _wrapper_frames(build: Path) -> dict[str, int]:
    """Frames of bench_five_target.c's wrappers (.su), taken out of the measured stack."""
    out = {}
    for su in build.glob("bench/CMakeFiles/bench_five_target.dir/*.su"):
        for line in su.read_text().splitlines():
            parts = line.split("\t")
            if len(parts) >= 2:
                out[parts[0].rsplit(":", 1)[-1]] = int(parts[1])
    return out


def _verdict(v: float, target: float) -> str:
    return "meets" if v <= target else "MISSES"


def section(m4f: Path, m3: Path) -> list[str]:
    """The markdown lines of the five-axis section."""
    nm = "arm-none-eabi-nm"
    out = [HEADING, "",
           "Written by scripts/bench_five.py from the builds of scripts/bench.sh. Per five-axis",
           "golden table (tests/golden/golden_five.*: `ac_full` A/C with every location error, all",
           "six motions of A (4 harmonics) and C (6), five-axis squareness and the paper machine's",
           "linear axes; `bc_motions` B/C, 8 harmonics on both, no linear errors; `ac_location`",
           "location errors only with the 'full' 3-axis table's linear axes), 8 points each:",
           "instructions per call from QEMU's exec trace (min / median / max), and the stack the",
           "call really used (painted stack, the benchmark wrapper's own frame taken out).", "",
           "| target | call | table | instructions (min / median / max) | stack measured (B) | target |",
           "|---|---|---|---:|---:|---|"]
    worst: dict[tuple[str, str], int] = {}
    stack_worst: dict[tuple[str, str], int] = {}
    three: dict[tuple[str, str], int] = {}
    for name, build in (("Cortex-M4F", m4f), ("Cortex-M3", m3)):
        image = build / "bench" / "bench_five_target.elf"
        counts, stdout = qemu_trace_counts(MACHINES[name], image, nm)
        stacks = stack_measured(stdout)
        wrappers = _wrapper_frames(build)
        for key, v in counts.items():
            call, table = key.split("@")
            target = {"five_f32": f"<= {TARGETS['five_f32']}", "five_q": f"<= {TARGETS['five_q']}"}.get(call, "")
            st = stacks.get(key, 0) - wrappers.get(_WRAPPER[call], 0)
            out.append(f"| {name} | {call} | {table} | {min(v)} / {int(statistics.median(v))} / {max(v)} | "
                       f"{st} | {target} |")
            # the budget's tables: the paper machine's linear axes (or none) with the rotary axes;
            # ac_location's linear axes are the 'full' 3-axis table (reported apart, below)
            budget_key = (name, call) if table in BUDGET_TABLES else (name, call + "@" + table)
            worst[budget_key] = max(worst.get(budget_key, 0), max(v))
            stack_worst[(name, call)] = max(stack_worst.get((name, call), 0), st)
        c3, _ = qemu_trace_counts(MACHINES[name], build / "bench" / "bench_target.elf", nm)
        for call in ("f32", "q", "comp_f32", "comp_q"):
            if call in c3:
                three[(name, call)] = max(c3[call])
    out += ["", "Static stack (call graph of -fstack-usage / -fcallgraph-info, as section 4):", "",
            "| target | entry point | static (B) | deepest chain (frame bytes) |", "|---|---|---:|---|"]
    static: dict[tuple[str, str], int] = {}
    for name, build in (("Cortex-M4F", m4f), ("Cortex-M3", m3)):
        frames, calls = parse_callgraph(sorted((build / "lib").rglob("*.ci")))
        for fn in ("abbe_five_model_load", "abbe_five_error_eval_f32", "abbe_five_error_eval_q",
                   "abbe_comp_step5_f32", "abbe_comp_step5_q", "abbe_comp_step_q"):
            if fn not in frames:
                continue
            depth, chain = deepest(fn, frames, calls)
            static[(name, fn)] = depth
            out.append(f"| {name} | {fn} | {depth} | " + " > ".join(f"{short(c)} ({frames.get(c, 0)})" for c in chain)
                       + " |")
    out += ["", "| target | use | library flash (B) | libgcc flash (B) | target |", "|---|---|---:|---:|---|"]
    flash: dict[tuple[str, str], int] = {}
    for name, build in (("Cortex-M4F", m4f), ("Cortex-M3", m3)):
        for use in ("five_f32", "five_q", "comp_f32", "comp_q"):
            mp = build / "bench" / f"bench_size_{use}.map"
            if not mp.exists():
                continue
            s = parse_map(mp)
            flash[(name, use)] = s.lib_flash
            label = {"five_f32": "five-axis load + eval + compensator (f32)",
                     "five_q": "five-axis load + eval + compensator (q)",
                     "comp_f32": "3-axis load + compensator (f32)",
                     "comp_q": "3-axis load + compensator (q)"}[use]
            tgt = f"<= {TARGETS['flash']}" if use.startswith("five") else "no regression"
            out.append(f"| {name} | {label} | {s.lib_flash} | {s.gcc_flash} | {tgt} |")
    out += ["", "Budgets (issue 23) and the 3-axis figures (must not regress):", "",
            "| measurement | now | budget / before | |", "|---|---:|---:|---|"]
    rows = [
        ("Cortex-M4F abbe_five_error_eval_f32, worst of ac_full, bc_motions", worst.get(("Cortex-M4F", "five_f32")),
         TARGETS["five_f32"]),
        ("Cortex-M3 abbe_five_error_eval_q, worst of ac_full, bc_motions", worst.get(("Cortex-M3", "five_q")),
         TARGETS["five_q"]),
        ("Cortex-M4F abbe_five_error_eval_f32, ac_location ('full' 3-axis table: see below)",
         worst.get(("Cortex-M4F", "five_f32@ac_location")), TARGETS["five_f32"]),
        ("Cortex-M3 abbe_five_error_eval_q, ac_location ('full' 3-axis table: see below)",
         worst.get(("Cortex-M3", "five_q@ac_location")), TARGETS["five_q"]),
        ("flash, five-axis load + eval + compensator, f32 (M4F)", flash.get(("Cortex-M4F", "five_f32")),
         TARGETS["flash"]),
        ("flash, five-axis load + eval + compensator, q (M4F)", flash.get(("Cortex-M4F", "five_q")),
         TARGETS["flash"]),
        ("flash, five-axis load + eval + compensator, q (M3)", flash.get(("Cortex-M3", "five_q")), TARGETS["flash"]),
        ("stack (static), abbe_comp_step5_f32 (M4F)", static.get(("Cortex-M4F", "abbe_comp_step5_f32")),
         TARGETS["stack"]),
        ("stack (static), abbe_comp_step5_q (M4F)", static.get(("Cortex-M4F", "abbe_comp_step5_q")), TARGETS["stack"]),
        ("stack (static), abbe_comp_step5_q (M3)", static.get(("Cortex-M3", "abbe_comp_step5_q")), TARGETS["stack"]),
        ("stack (measured), abbe_comp_step5_q (M3)", stack_worst.get(("Cortex-M3", "comp5_q")), TARGETS["stack"]),
        ("3-axis: stack (static), abbe_comp_step_q (M3)", static.get(("Cortex-M3", "abbe_comp_step_q")), 236),
        ("3-axis: Cortex-M4F abbe_error_eval_f32 (paper table, worst)", three.get(("Cortex-M4F", "f32")),
         THREE_AXIS_BEFORE[("Cortex-M4F", "f32")]),
        ("3-axis: Cortex-M3 abbe_error_eval_q (paper table, worst)", three.get(("Cortex-M3", "q")),
         THREE_AXIS_BEFORE[("Cortex-M3", "q")]),
        ("3-axis: flash, load + compensator, f32 (M4F)", flash.get(("Cortex-M4F", "comp_f32")),
         THREE_AXIS_BEFORE[("Cortex-M4F", "comp_f32")]),
        ("3-axis: flash, load + compensator, q (M4F)", flash.get(("Cortex-M4F", "comp_q")),
         THREE_AXIS_BEFORE[("Cortex-M4F", "comp_q")]),
        ("3-axis: flash, load + compensator, q (M3)", flash.get(("Cortex-M3", "comp_q")),
         THREE_AXIS_BEFORE[("Cortex-M3", "comp_q")]),
    ]
    for label, now, budget in rows:
        out.append(f"| {label} | {now if now is not None else 'n/a'} | {budget} | "
                   f"{_verdict(now, budget) if now is not None else 'not measured'} |")
    out += ["", "Where the instructions go (first point, instructions per function):", ""]
    for name, build, plan in (("Cortex-M4F", m4f, "five_f32@ac_full"), ("Cortex-M3", m3, "five_q@ac_full"),
                              ("Cortex-M4F", m4f, "five_f32@ac_location"), ("Cortex-M3", m3, "five_q@ac_location")):
        fc = qemu_function_counts(MACHINES[name], build / "bench" / "bench_five_target.elf", nm, plan)
        call, table = plan.split("@")
        out.append(f"- {name} `{call}` on `{table}`: " + ", ".join(f"{short(k)} {v}" for k, v in fc.items()
                                                                   if not k.startswith("run_")))
    out += ["", FLOOR, ""]
    return out


#: Why the five-axis budgets are missed, and the arithmetic floor (issue 23 asks for it).
FLOOR = """The arithmetic floor of `ac_full` (the budget's case: the paper machine's linear
axes plus A and C with all six motions, 4 and 6 harmonics). The 3-axis evaluation
is 697 (M4F f32) / 1409 (M3 q). On top: the motions' 2 x 6 x (4 + 6) = 120
multiply-adds with their 120 coefficient loads (about 250 f32; about 500 q, one
SMLAL pair each), two sin/cos and the harmonics' rotations (about 100 / 300), and
about 60 multiplies for the levers, rotations and cross products (about 150 / 400
with q's 64-bit products): about 1,200 f32 and 2,600 q, within the budgets. What the
measured breakdown above adds to that: f32 evaluates the linear axes twice (the
3-axis kernels fold the terms into Eq. 3 and never expose the angular sums the
orientation needs, so `abbe_axis_terms_f32` runs a second pass: about 1,000 of
fold6_f32's 1,788), and both variants run the motions and the rotary
geometry through generic loops over vectors (motions, twist, rotate: about
700 f32 / 1,000 q above the floor). A kernel variant returning the angular sums
with the folded position, and straight-line rotary code, are what the budgets need;
not done in this session.
Flash: the five-axis loader (five_load.c, about 3.4 KB: model_load.c's checks compiled
a second time with the rotary ones, so the 3-axis image stays byte for byte what it
was; sharing one copy cost the 3-axis image 88 B, measured) and the linear terms'
code twice, folded (position) and as values (orientation); the single-pass kernel
above would also remove the second. Stack: the compensator cycle's evaluation
copies its inputs (the five-axis input embeds neither abbe_input_*_t nor
abbe_error_*_t: an API that embedded them would save the copies) and the q
rotary part keeps int64 vectors."""


def replace_section(results: Path, lines: list[str]) -> None:
    """Replace (or append) the five-axis section of results.md."""
    text = results.read_text(encoding="utf-8").splitlines()
    if HEADING in text:
        i = text.index(HEADING)
        j = next((k for k in range(i + 1, len(text)) if text[k].startswith("## ")), len(text))
        text = text[:i] + lines + text[j:]
    else:
        text = text + [""] + lines
    results.write_text("\n".join(text).rstrip() + "\n", encoding="utf-8")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--m4f", type=Path, required=True)
    ap.add_argument("--m3", type=Path, required=True)
    ap.add_argument("--results", type=Path, help="replace the section in this results.md (else print)")
    args = ap.parse_args()
    lines = section(args.m4f, args.m3)
    if args.results:
        replace_section(args.results, lines)
    else:
        print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
