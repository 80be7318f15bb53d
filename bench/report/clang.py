"""Section 9: the clang/LLVM builds beside the GCC ones (instructions, flash, stack)."""

from __future__ import annotations

from report.common import CLANG_USES, ENTRY_POINTS, TARGETS, fmt_counts, verdict
from report.maps import deepest, image_calls, parse_map, su_frames, wrapper_frames
from report.measure import compile_flags, first_line, qemu_function_counts, qemu_trace_counts, stack_measured


def clang_section(args, nm: str, tgt: dict, stdout_by: dict, flash_by: dict, stack_by: dict) -> list[str]:
    """Section 9: the clang/LLVM builds beside the GCC ones (instructions, flash, stack)."""
    md: list[str] = []
    w = md.append
    objdump = "arm-none-eabi-objdump"
    builds = (("Cortex-M4F", args.m4f, args.m4f_clang, "mps2-an386"),
              ("Cortex-M3", args.m3, args.m3_clang, "mps2-an385"))
    w("## 9. clang/LLVM beside GCC (issue 28)")
    w("")
    w("The same sources, flags and measurements built with clang and lld instead of")
    w("arm-none-eabi-gcc (cmake/toolchain-cortex-{m4f,m3}-clang.cmake: -O2, the same per-file -Os,")
    w("-munaligned-access as GCC assumes on ARMv7-M, newlib's headers and libgcc.a of the GNU")
    w("packages). " + first_line(["clang", "--version"]) + ". The targets of the summary are")
    w("GCC's; this section reports what clang reaches. The golden vectors pass with both")
    w("compilers (scripts/test.sh: the GCC Cortex-M steps and the clang step). clang's flags")
    w("(compile_commands.json, as in section 7; the -Os files as with GCC):")
    w("")
    for name, _, build, _ in builds:
        w(f"- {name} (Release), lib/src/*.c: `{compile_flags(build, 'lib/src/terms_q.c')}`")
    w("")
    w("| target | call | GCC instructions | clang instructions | clang / GCC |")
    w("|---|---|---:|---:|---:|")
    clang_counts: dict[str, dict[str, list[int]]] = {}
    clang_stdout: dict[str, str] = {}
    for name, _, build, machine in builds:
        counts, stdout = qemu_trace_counts(machine, build / "bench" / "bench_target.elf", nm)
        clang_counts[name], clang_stdout[name] = counts, stdout
        for key, fn, _ in ENTRY_POINTS:
            if key in counts and key in tgt[name]:
                g, c = max(tgt[name][key]), max(counts[key])
                w(f"| {name} | {fn} | {fmt_counts(tgt[name][key])} | {fmt_counts(counts[key])} | {c / g:.2f} |")
    w("")
    m4f_f32 = max(clang_counts["Cortex-M4F"]["f32"])
    m3_q = max(clang_counts["Cortex-M3"]["q"])
    w(f"clang reaches {m4f_f32} instructions for the M4F's abbe_error_eval_f32 (GCC's target "
      f"<= {TARGETS['m4f_f32']}: {verdict(m4f_f32, TARGETS['m4f_f32'])} with clang) and {m3_q} for the "
      f"M3's abbe_error_eval_q (<= {TARGETS['m3_q']}: {verdict(m3_q, TARGETS['m3_q'])} with clang).")
    w("")
    extra = ""
    if args.m4f_clang_nounroll:
        extra = " clang -fno-unroll-loops (B) |"
    w("| target | use | GCC library flash (B) | clang library flash (B) |" + extra)
    w("|---|---|---:|---:|" + ("---:|" if extra else ""))
    clang_flash: dict[tuple[str, str], int] = {}
    for name, gcc_build, build, _ in builds:
        for use, label in CLANG_USES:
            mp = build / "bench" / f"bench_size_{use}.map"
            if not mp.exists():
                continue
            c = parse_map(mp).lib_flash
            clang_flash[(name, use)] = c
            g = flash_by.get((name, use))
            if g is None:
                g = parse_map(gcc_build / "bench" / f"bench_size_{use}.map").lib_flash
            row = f"| {name} | {label} | {g} | {c} |"
            if extra:
                nu = args.m4f_clang_nounroll / "bench" / f"bench_size_{use}.map"
                row += f" {parse_map(nu).lib_flash if name == 'Cortex-M4F' and nu.exists() else '-'} |"
            w(row)
    w("")
    w("Library flash by source file, compensator images (clang):")
    w("")
    for name, _, build, _ in builds:
        for use in ("comp_f32", "comp_q"):
            mp = build / "bench" / f"bench_size_{use}.map"
            if mp.exists():
                members = parse_map(mp).lib_members
                w(f"- {name}, {use}: " + ", ".join(f"{k} {v}" for k, v in
                                                  sorted(members.items(), key=lambda kv: -kv[1])))
    w("")
    w("Stack: `static` for clang = deepest chain of clang's -fstack-usage frames along the")
    w("calls in the image's disassembly (BL and tail-call B; helper routines count 0, as")
    w("for GCC); `measured` as in section 4 (stack painting, wrapper frame taken out).")
    w("")
    w("| target | entry point | GCC static (B) | clang static (B) | GCC measured (B) | clang measured (B) | clang's deepest chain |")
    w("|---|---|---:|---:|---:|---:|---|")
    for name, gcc_build, build, _ in builds:
        frames = su_frames(build)
        calls = image_calls(build / "bench" / "bench_target.elf", objdump)
        meas_g = stack_measured(stdout_by[name])
        meas_c = stack_measured(clang_stdout[name])
        wrap_g, wrap_c = wrapper_frames(gcc_build), wrapper_frames(build)
        for key, fn, wrapper in ENTRY_POINTS:
            if fn not in frames:
                continue
            depth, chain = deepest(fn, frames, calls)
            g_static = stack_by.get((name, key), "-")
            g_meas = meas_g[key] - wrap_g.get(wrapper, 0) if key in meas_g else "-"
            c_meas = meas_c[key] - wrap_c.get(wrapper, 0) if key in meas_c else "-"
            chain_s = " > ".join(f"{c} ({frames.get(c, 0)})" for c in chain)
            w(f"| {name} | {fn} | {g_static} | {depth} | {g_meas} | {c_meas} | {chain_s} |")
    w("")
    w("Where the instructions go (clang; GCC's are in section 5b), one call:")
    w("")
    fc_by = {}
    for (name, _, build, machine), call in zip(builds, ("f32", "q")):
        fc = qemu_function_counts(machine, build / "bench" / "bench_target.elf", nm, call)
        fc_by[name] = fc
        parts = ", ".join(f"{k} {v}" for k, v in fc.items()
                          if k not in ("bench_mark", "measure_calls", "run_f32", "run_q"))
        w(f"- {name}, abbe_error_eval_{call}: {parts}")
    gfc = qemu_function_counts("mps2-an386", args.m4f / "bench" / "bench_target.elf", nm, "f32")
    gfq = qemu_function_counts("mps2-an385", args.m3 / "bench" / "bench_target.elf", nm, "q")
    cf, cq = fc_by["Cortex-M4F"], fc_by["Cortex-M3"]
    w("")
    w("Why clang differs (each reason seen in the disassembly and the counts above):")
    w("")
    w(f"- abbe_axis_fold_f32 ({gfc.get('abbe_axis_fold_f32', 0)} GCC, {cf.get('abbe_axis_fold_f32', 0)} clang "
      "per call): GCC shrink-wraps it and tail-calls fold6_f32 on the six-term path; clang saves")
    w("  d8-d14 and parks the seven float arguments in callee-saved registers on every path, then")
    w("  moves them back for a normal call. The asm kernels themselves are the same: fold6_f32")
    w(f"  {gfc.get('fold6_f32', 0)} GCC, {cf.get('fold6_f32', 0)} clang. Measured while writing this")
    w("  section: the sparse path out of line (both paths tail calls) takes clang to 657-665")
    w("  instructions, but costs GCC 6 instructions (703, over its target; returned by value:")
    w("  GCC reserves a frame it never uses) or 52 B of flash (returned through a pointer); the")
    w("  library keeps the form GCC's targets were met with.")
    w(f"- terms6_q ({gfq.get('terms6_q', 0)} GCC, {cq.get('terms6_q', 0)} clang on the M3): six int64 "
      "accumulators are 12 of the 13 allocatable")
    w("  registers; both compilers spill some to the stack around each row's six SMLALs, clang")
    w("  more of them. assemble_q and the fixed-point sin/cos likewise (register allocation and")
    w("  scheduling, no different algorithm).")
    w("- Flash: clang -O2 unrolls loops (GCC -O2 does not): the loader's validation loops,")
    w("  crc32 (8 bits per byte) and the Chebyshev and harmonic recurrences."
      + (" The last column is the M4F clang build with -fno-unroll-loops, whose abbe_error_eval_f32 "
         "takes " + fmt_counts(qemu_trace_counts("mps2-an386", args.m4f_clang_nounroll / "bench"
                                                  / "bench_target.elf", nm)[0]["f32"])
         + " instructions instead." if args.m4f_clang_nounroll else ""))
    w("- Alignment: clang assumes strict alignment on bare metal unless told otherwise, and then")
    w("  reads each little-endian table word byte by byte (4 LDRB, 3 ORR); the toolchain files")
    w("  pass -munaligned-access, GCC's default for ARMv7-M (measured while adding them: the M4F's")
    w("  abbe_error_eval_q took 2522 instructions without it).")
    w("- Fused multiply-add: LLVM's Cortex-M4 model marks VFMA as slow and keeps C's multiply-adds")
    w("  as VMUL + VADD whatever -ffp-contract says; the M4F clang toolchain file turns that off")
    w("  (-Xclang -target-feature -Xclang -slowfpvfmx), since the library asks for the fused form")
    w("  (measured while adding it: abbe_error_eval_f32 742 -> 732 instructions).")
    w("")
    return md
