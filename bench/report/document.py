"""Measure the abbe library and write bench/results.md (run by scripts/bench.sh).

Everything counted here is an instruction count or a byte count, so the
numbers repeat exactly for the same compiler, library and table:

1. x86-64 instructions per call (valgrind --tool=callgrind): the library's
   own cost from --toggle-collect=<function> (total / calls), cross-checked by
   the difference of two whole-program runs of N and N + 1000 calls.
2. Cortex-M4F / Cortex-M3 instructions per call from QEMU's exec trace
   (-singlestep -d exec,nochain: one trace line per executed instruction),
   counted between two calls of bench_mark() minus an empty pair.
3. Flash and static RAM of the library per use, from the link maps of the
   bench_size_* images (input sections that come from libabbe.a).
4. Stack: worst case from GCC's -fcallgraph-info=su call graph (deepest
   chain), and the bytes the call really used on the target (stack painting).
5. Two reference programs for comparison, built the same way: a naive
   double-precision evaluator (bench/naive_ref.c) and a lean float one
   (bench/lean_ref.c: the same model without abbe's guarantees).
6. Points per second from Python (bench/bench_python.py; wall clock).
7. Format 1.1's reversal blocks (issue 14): the calls again on the golden
   tables "backlash" (the paper table with a constant backlash, format 1.0) and
   "reversal" (the same with reversal blocks), and a second set of builds with
   -DABBE_WITH_REVERSAL=OFF (a format 1.0 library, the machine code of the
   library before 1.1): what the blocks cost in instructions, flash and stack,
   and that tables without them cost what they did.
9. clang/LLVM beside GCC (issue 28): the same measurements of the builds with
   cmake/toolchain-cortex-{m4f,m3}-clang.cmake (lld maps; the static stack from
   clang's -fstack-usage frames and the calls in the image's disassembly,
   since clang writes no call graph).

Usage: scripts/bench_report.py --repo DIR --host BUILD --m4f BUILD --m3 BUILD [-o FILE]
(this module's main). Only the Python standard library is used.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from report.clang import clang_section
from report.details import flags_section, python_section, size_section, where_section
from report.five_axis import section as five_section
from report.measure import first_line
from report.reversal import reversal_section
from report.summary import summary_section
from report.three_axis import flash_section, host_section, stack_section, target_section


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repo", type=Path, required=True)
    ap.add_argument("--host", type=Path, required=True)
    ap.add_argument("--m4f", type=Path, required=True)
    ap.add_argument("--m3", type=Path, required=True)
    ap.add_argument("--m4f-os", type=Path, help="Cortex-M4F build at -Os (optional)")
    ap.add_argument("--m3-os", type=Path, help="Cortex-M3 build at -Os (optional)")
    ap.add_argument("--host-1.0", dest="host_10", type=Path,
                    help="host build with -DABBE_WITH_REVERSAL=OFF (optional)")
    ap.add_argument("--m4f-1.0", dest="m4f_10", type=Path,
                    help="Cortex-M4F build with -DABBE_WITH_REVERSAL=OFF (optional)")
    ap.add_argument("--m3-1.0", dest="m3_10", type=Path,
                    help="Cortex-M3 build with -DABBE_WITH_REVERSAL=OFF (optional)")
    ap.add_argument("--m4f-clang", type=Path, help="Cortex-M4F build with clang (optional)")
    ap.add_argument("--m3-clang", type=Path, help="Cortex-M3 build with clang (optional)")
    ap.add_argument("--m4f-clang-nounroll", type=Path,
                    help="Cortex-M4F clang build with -fno-unroll-loops (optional)")
    ap.add_argument("-o", "--out", type=Path)
    args = ap.parse_args()
    nm = "arm-none-eabi-nm"

    md: list[str] = []
    w = md.append
    w("# abbe benchmark results")
    w("")
    w("Written by `scripts/bench.sh` (scripts/bench_report.py); do not edit by hand.")
    w("Instruction and byte counts, not times: they repeat exactly for the same")
    w("compiler, library and table. Table: the `paper` golden table")
    w("(tests/golden: 3 axes x 6 terms, Chebyshev trend degree 1 + 3 harmonics,")
    w("squareness, tool offset); section 8 adds the tables with a backlash and with")
    w("reversal blocks (format 1.1). Library built with CMAKE_BUILD_TYPE=Release")
    w("(host -O3, Cortex-M -O2, see cmake/arm-none-eabi-common.cmake).")
    w("")
    w("Tools: " + "; ".join([
        first_line(["gcc", "--version"]),
        first_line(["arm-none-eabi-gcc", "--version"]),
        first_line(["qemu-system-arm", "--version"]),
        first_line(["valgrind", "--version"]),
    ]))
    w("")

    md_1, by = host_section(args)
    md += md_1
    md_2, tgt, stdout_by = target_section(args, nm)
    md += md_2
    md_3, flash_by = flash_section(args)
    md += md_3
    md_4, stack_by = stack_section(args, stdout_by)
    md += md_4
    if args.m4f_os and args.m3_os:
        md += size_section(args, nm)
    md += where_section(args, nm)
    md += python_section(args)
    md += flags_section(args)

    # 8. format 1.1: the reversal blocks
    rev = reversal_section(args, nm, by, tgt, stdout_by, flash_by, stack_by)
    md += rev["lines"]

    # 9. clang/LLVM
    if args.m4f_clang and args.m3_clang:
        md += clang_section(args, nm, tgt, stdout_by, flash_by, stack_by)

    # summary, inserted after the header
    summary = summary_section(args, by, tgt, flash_by, stack_by, rev["flash_10"])
    md[md.index("## 1. x86-64 instructions per call (callgrind)"):md.index("## 1. x86-64 instructions per call (callgrind)")] = summary

    # five-axis tables (format 1.2): report.five_axis
    md += [""] + five_section(args.m4f, args.m3)
    text = "\n".join(md) + "\n"
    if args.out:
        args.out.write_text(text)
        print(f"bench_report: wrote {args.out}")
    else:
        sys.stdout.write(text)
    return 0
