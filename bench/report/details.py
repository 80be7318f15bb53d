"""Sections 5 to 7: the library built for size (-Os), where the instructions and bytes
go, points per second from Python, and the compiler flags of each build."""

from __future__ import annotations

from report.common import NAMES, fmt_counts
from report.maps import deepest, parse_callgraph, parse_map
from report.measure import (callgrind_function_counts, compile_flags, python_throughput, qemu_function_counts,
                            qemu_trace_counts)


def size_section(args, nm: str) -> list[str]:
    """Section 5 (with the -Os builds only): instructions, flash and stack at -Os."""
    md: list[str] = []
    w = md.append
    names = NAMES
    if args.m4f_os and args.m3_os:
        w("## 5. The same library built for size (-Os, CMAKE_BUILD_TYPE=MinSizeRel)")
        w("")
        w("| target | call | instructions | library flash, load + call (B) | static stack (B) |")
        w("|---|---|---:|---:|---:|")
        for name, build, machine in (("Cortex-M4F", args.m4f_os, "mps2-an386"),
                                     ("Cortex-M3", args.m3_os, "mps2-an385")):
            counts, _ = qemu_trace_counts(machine, build / "bench" / "bench_target.elf", nm)
            frames, calls = parse_callgraph(sorted((build / "lib").rglob("*.ci")))
            for key, fn, use in (("f32", "abbe_error_eval_f32", "eval_f32"),
                                 ("q", "abbe_error_eval_q", "eval_q"),
                                 ("comp_f32", "abbe_comp_step_f32", "comp_f32"),
                                 ("comp_q", "abbe_comp_step_q", "comp_q")):
                if key not in counts:
                    continue
                flash = parse_map(build / "bench" / f"bench_size_{use}.map").lib_flash
                label = "abbe_error_eval_f32" if key == "f32" else names[key]
                w(f"| {name} | {label} | {fmt_counts(counts[key])} | {flash} | "
                  f"{deepest(fn, frames, calls)[0]} |")
        w("")

    return md


def where_section(args, nm: str) -> list[str]:
    """Section 5b: instructions per function during one call, and how the targets were met."""
    md: list[str] = []
    w = md.append
    w("## 5b. Where the instructions and bytes go")
    w("")
    w("Instructions per function during one call (Cortex-M: the first measured point, from the")
    w("QEMU trace; x86-64: callgrind self cost per call). The kernels are the per-axis dot")
    w("products with their basis (Chebyshev recurrence, one sin/cos per block, the rotations to")
    w("the higher harmonics); the core is the argument reduction, the clamps and flags, the")
    w("NaN checks and Eq. 3. The paper table has 8 basis rows x 6 terms per axis: 144")
    w("coefficients, each one load and one multiply-add (two instructions without FMA).")
    w("")
    for tname, build, machine, call in (("Cortex-M4F", args.m4f, "mps2-an386", "f32"),
                                       ("Cortex-M3", args.m3, "mps2-an385", "q")):
        fc = qemu_function_counts(machine, build / "bench" / "bench_target.elf", nm, call)
        parts = ", ".join(f"{k} {v}" for k, v in fc.items() if k not in ("bench_mark", "run_f32", "run_q"))
        w(f"- {tname}, abbe_error_eval_{call}: {parts}")
    host_exe = args.host / "bench" / "bench_host"
    for label, mode in (("x86-64-v3 kernels", "f32"), ("SSE2 kernels", "f32_base")):
        fc = callgrind_function_counts(host_exe, mode)
        parts = ", ".join(f"{k} {v:.0f}" for k, v in sorted(fc.items(), key=lambda kv: -kv[1]))
        w(f"- x86-64, abbe_error_eval_f32 ({label}): {parts}")
    w("")
    w("On x86-64 the core is one function (the kernels inlined: the ABI clobbers every vector")
    w("register at a call). Flash of the images is listed by source file in section 3.")
    w("How the last two targets were met (each step measured, the rest of the guarantees kept):")
    w("")
    w("- q flash (format 1.1 library): the fixed-point sin/cos is one out-of-line function")
    w("  shared by the six-term and the sparse kernel (before: inlined in each), returning")
    w("  its pair as one uint64 (r0:r1) and built -Os, so its frame is 20 B and")
    w("  abbe_comp_step_q stays within 256 B; the sparse kernel is its own -Os file. The")
    w("  six-term kernel also got faster (fewer registers live around the inline sin/cos).")
    w("- x86-64 f32: the three axes' phases are one vector computation on x86-64-v3 (64-bit")
    w("  lanes, the model keeps the per-axis frequencies in lanes); block 1's sin/cos reads its")
    w("  constants through a second opaque pointer (GCC had loaded them once for both blocks")
    w("  and spilled them); a linear trend costs one test (the recurrence for degree >= 2")
    w("  behind it); the harmonic jump table has no range check; GCC flags as in section 7.")
    w("  The SSE2 kernels (every x86-64; what a CPU without AVX2 and FMA runs) benefit from")
    w("  all but the vector phases and stay above 400: the x86-64-v3 path executes 51 fused")
    w("  multiply-adds per call on this table (36 of them the 144 coefficients, four lanes")
    w("  each; the others sin/cos, rotations, conversions and Eq. 3), which SSE2 executes as")
    w("  51 multiplies and 51 adds, and it has neither variable shifts, 32-bit multiplies")
    w("  nor blends for the argument reduction (scalar there): 379 + 51 > 400 before any")
    w("  of those. The target is met by the kernels that Intel CPUs since Haswell (2013) and")
    w("  AMD ones since Excavator (2015) run; abbe_model_load() picks them by CPUID.")
    w("")

    return md


def python_section(args) -> list[str]:
    """Section 6: points per second through ctypes (wall clock)."""
    md: list[str] = []
    w = md.append
    py = python_throughput(args.repo, args.host)
    w("## 6. Points per second from Python (ctypes)")
    w("")
    w("bench/bench_python.py on the `paper` table, 20 000 random points in the travel, best of")
    w("several runs: wall-clock times, which vary with the machine and its load (unlike the")
    w("counts above). `point by point` is the loop host_tools/abbe/clib.py ran before the")
    w("batch entry points (one ctypes call per point); `batch` is CModel.error_f32 / error_q")
    w("now (abbe_error_eval_batch_f32 / _q, one call).")
    w("")
    if py is None:
        w("(not measured: build/lib/libabbe.so or .venv missing)")
    elif "error" in py:
        w(f"(failed: {py['error']})")
    else:
        w("| variant | point by point (points/s) | batch (points/s) | speed-up |")
        w("|---|---:|---:|---:|")
        for k in ("f32", "q"):
            pb, b = py[f"{k}_point_by_point"], py[f"{k}_batch"]
            w(f"| {k} | {pb:,.0f} | {b:,.0f} | {b / pb:.0f}x |")
    w("")

    return md


def flags_section(args) -> list[str]:
    """Section 7: the compiler flags per target and why some files differ."""
    md: list[str] = []
    w = md.append
    w("## 7. Compiler flags per target")
    w("")
    w("From each build's compile_commands.json (library sources; include paths, definitions")
    w("and the warning set `-Wall -Wextra -Wpedantic -Wconversion ... -Werror` left out;")
    w("`-fstack-usage -fcallgraph-info=su` are the benchmark builds' stack analysis only):")
    w("")
    w("| target | sources | flags |")
    w("|---|---|---|")
    w(f"| x86-64 (host, Release) | lib/src/*.c | `{compile_flags(args.host, 'lib/src/eval_q.c')}` |")
    w(f"| x86-64-v3 kernels | lib/src/eval_f32_avx2.c | `{compile_flags(args.host, 'lib/src/eval_f32_avx2.c')}` |")
    w(f"| x86-64 SSE2 kernels | lib/src/eval_f32_sse2.c | `{compile_flags(args.host, 'lib/src/eval_f32_sse2.c')}` |")
    w(f"| Cortex-M4F (Release) | lib/src/*.c | `{compile_flags(args.m4f, 'lib/src/eval_f32.c')}` |")
    w(f"| Cortex-M3 (Release) | lib/src/*.c | `{compile_flags(args.m3, 'lib/src/terms_q.c')}` |")
    w(f"| Cortex-M4F (Release) | lib/src/comp.c | `{compile_flags(args.m4f, 'lib/src/comp.c')}` |")
    w(f"| Cortex-M3 (Release) | lib/src/comp.c | `{compile_flags(args.m3, 'lib/src/comp.c')}` |")
    w(f"| Cortex-M4F (Release) | lib/src/eval_q.c | `{compile_flags(args.m4f, 'lib/src/eval_q.c')}` |")
    w(f"| Cortex-M3 (Release) | lib/src/eval_q.c | `{compile_flags(args.m3, 'lib/src/eval_q.c')}` |")
    w(f"| Cortex-M3 (Release) | lib/src/sincos_q.c, terms_sparse_q.c | `{compile_flags(args.m3, 'lib/src/sincos_q.c')}` |")
    w("")
    w("comp.c (the compensator's state machine: ramps, limits, staleness; no arithmetic of")
    w("the model) and eval_q.c (the fixed-point Eq. 3 assembly: straight-line multiply-adds)")
    w("are built for size on the Cortex-M (the last -O wins): on comp.c -Os takes 132 B")
    w("(Cortex-M4F) / 116 B (Cortex-M3) off the load + compensator images for +16 / +17")
    w("instructions per compensator cycle, on eval_q.c 98 / 138 B for -9 / 0 instructions")
    w("per call; the rows of sections 2 and 8 include both. The fixed-point sin/cos")
    w("(sincos_q.c, out of line, shared by the six-term and the sparse kernel) and the sparse")
    w("kernel (terms_sparse_q.c) are -Os too: at -O2 GCC loads sin/cos's nine constants")
    w("into registers up front and its frame is 56 B instead of 20, which would put")
    w("abbe_comp_step_q over its 256 B of stack.")
    w("")
    w("x86-64 (GCC only): the f32 core files are built with `-fno-tree-pre -fno-ivopts`. The")
    w("core is one function with every vector register in use; partial redundancy elimination")
    w("and the induction-variable rewrite each add register copies, spills and jumps there")
    w("(measured on this table: x86-64-v3 408 -> 379 instructions inside the kernel, SSE2")
    w("573 -> 539).")
    w("")
    w("x86-64: the f32 core exists twice, SSE2 (every x86-64) and x86-64-v3 (AVX2, FMA);")
    w("abbe_model_load() picks by CPUID (`__builtin_cpu_supports`). Cortex-M4F: the row kernel")
    w("uses one `vldm` per row, the harmonics and sin/cos are inline assembly blocks (plain C")
    w("fallback, the same operations in the same order); the CMake option")
    w("`-DABBE_PORTABLE_C=ON` builds the plain C kernels everywhere.")
    w("")

    return md
