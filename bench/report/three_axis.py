"""Sections 1 to 4: the 3-axis library's instructions per call on x86-64 (callgrind) and
the Cortex-M (QEMU), its flash and static RAM (link maps) and its stack (call graph and
painted stack). Each function returns its markdown lines and what later sections use."""

from __future__ import annotations

import statistics

from report.common import ENTRY_POINTS, NAMES, TARGETS, fmt_counts, verdict
from report.maps import deepest, parse_callgraph, parse_map, short, wrapper_frames
from report.measure import CALLGRIND_EXTRA, CALLGRIND_N, host_bench, qemu_trace_counts, stack_measured


def host_section(args) -> tuple[list[str], dict]:
    """Section 1: x86-64 instructions per call; returns the lines and the results by mode."""
    md: list[str] = []
    w = md.append
    host, check = host_bench(args.host)
    by = {r.mode: r for r in host}
    w("## 1. x86-64 instructions per call (callgrind)")
    w("")
    w("`inside` = instructions executed inside the function per call")
    w(f"(--toggle-collect, {CALLGRIND_N} calls over the table's golden points);")
    w(f"`loop` = whole-program difference of {CALLGRIND_N + CALLGRIND_EXTRA} and "
      f"{CALLGRIND_N} calls / {CALLGRIND_EXTRA},")
    w("i.e. including the benchmark loop and the call itself "
      f"(an empty call costs {by['empty'].per_iter:.0f} per iteration).")
    w("")
    w("| call | inside | loop |")
    w("|---|---:|---:|")
    names = NAMES
    for r in host:
        w(f"| {names[r.mode]} | {r.per_call:.1f} | {r.per_iter:.1f} |")
    w("")
    w(f"Target x86 f32 <= {TARGETS['x86_f32']}: {by['f32'].per_call:.0f} "
      f"({verdict(by['f32'].per_call, TARGETS['x86_f32'])}) with the kernels this CPU runs; "
      f"the SSE2 kernels every x86-64 runs: {by['f32_base'].per_call:.0f} "
      f"({verdict(by['f32_base'].per_call, TARGETS['x86_f32'])}).")
    w("")
    w(f"Ratios: naive / f32 = {by['naive'].per_call / by['f32'].per_call:.1f}x "
      f"(SSE2: {by['naive'].per_call / by['f32_base'].per_call:.1f}x), "
      f"naive / q = {by['naive'].per_call / by['q'].per_call:.1f}x; "
      f"lean / f32 = {by['lean'].per_call / by['f32'].per_call:.2f}x "
      f"(SSE2: {by['lean'].per_call / by['f32_base'].per_call:.2f}x), "
      f"lean / q = {by['lean'].per_call / by['q'].per_call:.2f}x "
      "(above 1: abbe executes fewer instructions than the lean evaluator).")
    w("")
    w("Naive reference check (`bench_host check`):")
    w("")
    w("```")
    w(check)
    w("```")
    w("")

    return md, by


def target_section(args, nm: str) -> tuple[list[str], dict, dict]:
    """Section 2: Cortex-M instructions per call; returns the lines, the counts and QEMU's
    output (the painted stack) per target."""
    md: list[str] = []
    w = md.append
    names = NAMES
    w("## 2. Cortex-M instructions per call (QEMU exec trace)")
    w("")
    w("One trace line per executed instruction (`-singlestep -d exec,nochain`),")
    w("counted from the first to the second `bench_mark()` minus an empty pair;")
    w("the count includes the argument set-up and the call. 8 points per variant")
    w("(golden points of the table: in and out of travel, both directions).")
    w("These are instructions, not cycles (no wait states, pipeline or FPU latency).")
    w("")
    w("| target | call | instructions |")
    w("|---|---|---:|")
    tgt: dict[str, dict[str, list[int]]] = {}
    stdout_by: dict[str, str] = {}
    naive_t: dict[str, list[int]] = {}
    lean_t: dict[str, list[int]] = {}
    for name, build, machine in (("Cortex-M4F", args.m4f, "mps2-an386"),
                                 ("Cortex-M3", args.m3, "mps2-an385")):
        counts, stdout = qemu_trace_counts(machine, build / "bench" / "bench_target.elf", nm)
        tgt[name] = counts
        stdout_by[name] = stdout
        ncounts, _ = qemu_trace_counts(machine, build / "bench" / "bench_naive_target.elf", nm)
        naive_t[name] = ncounts["naive"]
        lean_img = build / "bench" / "bench_lean_target.elf"
        if lean_img.exists():
            lcounts, _ = qemu_trace_counts(machine, lean_img, nm)
            lean_t[name] = lcounts["lean"]
        for call, v in counts.items():
            if "@" in call:
                continue  # other tables: section 8
            label = {"f32": "abbe_error_eval_f32", "load": "abbe_model_load"}.get(call, names.get(call, call))
            w(f"| {name} | {label} | {fmt_counts(v)} |")
        w(f"| {name} | naive reference (double, newlib libm) | {fmt_counts(naive_t[name])} |")
        if name in lean_t:
            w(f"| {name} | lean reference (float, no guarantees) | {fmt_counts(lean_t[name])} |")
    w("")
    m4f_f32 = max(tgt["Cortex-M4F"]["f32"])
    m3_q = max(tgt["Cortex-M3"]["q"])
    w(f"Target M4F f32 <= {TARGETS['m4f_f32']}: {m4f_f32} ({verdict(m4f_f32, TARGETS['m4f_f32'])}); "
      f"M3 q <= {TARGETS['m3_q']}: {m3_q} ({verdict(m3_q, TARGETS['m3_q'])}). "
      f"Naive / library: M4F {statistics.mean(naive_t['Cortex-M4F']) / statistics.mean(tgt['Cortex-M4F']['f32']):.0f}x (f32), "
      f"M3 {statistics.mean(naive_t['Cortex-M3']) / statistics.mean(tgt['Cortex-M3']['q']):.0f}x (q)."
      + (f" Lean / library: M4F {statistics.mean(lean_t['Cortex-M4F']) / statistics.mean(tgt['Cortex-M4F']['f32']):.2f}x (f32)."
         if "Cortex-M4F" in lean_t else ""))
    w("")

    return md, tgt, stdout_by


def flash_section(args) -> tuple[list[str], dict]:
    """Section 3: flash and static RAM; returns the lines and the library flash per (target, use)."""
    md: list[str] = []
    w = md.append
    w("## 3. Flash and static RAM of the library")
    w("")
    w("From the link maps of minimal images (bench/bench_size.c, --gc-sections):")
    w("`.text` + `.rodata` input sections taken from libabbe.a, and separately the")
    w("libgcc routines they pull in. Static RAM = `.data` + `.bss` from libabbe.a.")
    w("")
    w("| target | use | library flash (B) | libgcc flash (B) | libgcc routines | library RAM (B) |")
    w("|---|---|---:|---:|---|---:|")
    flash_worst = 0
    flash_eval_worst = 0
    flash_by: dict[tuple[str, str], int] = {}
    ram_worst = 0
    member_rows = []
    for name, build in (("Cortex-M4F", args.m4f), ("Cortex-M3", args.m3)):
        for use in ("load", "eval_f32", "eval_q", "comp_f32", "comp_q"):
            mp = build / "bench" / f"bench_size_{use}.map"
            if not mp.exists():
                continue
            s = parse_map(mp)
            flash_by[(name, use)] = s.lib_flash
            if use != "load":
                flash_worst = max(flash_worst, s.lib_flash)
            if use.startswith("eval"):
                flash_eval_worst = max(flash_eval_worst, s.lib_flash)
            ram_worst = max(ram_worst, s.lib_ram)
            gcc = ", ".join(sorted(m[:-2] if m.endswith(".o") else m
                                   for m in s.gcc_members)) or "none"
            label = {"load": "abbe_model_load only", "eval_f32": "load + eval_f32",
                     "eval_q": "load + eval_q", "comp_f32": "load + compensator (f32)",
                     "comp_q": "load + compensator (q)"}[use]
            w(f"| {name} | {label} | {s.lib_flash} | {s.gcc_flash} | {gcc} | {s.lib_ram} |")
            if use in ("comp_f32", "comp_q"):
                member_rows.append((name, use, s.lib_members))
    w("")
    w(f"Target flash per variant <= {TARGETS['flash_bytes']} B: load + eval worst "
      f"{flash_eval_worst} B ({verdict(flash_eval_worst, TARGETS['flash_bytes'])}), with the "
      f"compensator worst {flash_worst} B ({verdict(flash_worst, TARGETS['flash_bytes'])}). "
      f"Static RAM of the library: {ram_worst} B (must be 0: {'yes' if ram_worst == 0 else 'NO'}).")
    w("")
    w("Library flash by source file, compensator images:")
    w("")
    for name, use, members in member_rows:
        parts = ", ".join(f"{k} {v}" for k, v in sorted(members.items(), key=lambda kv: -kv[1]))
        w(f"- {name}, {use}: {parts}")
    w("")

    return md, flash_by


def stack_section(args, stdout_by: dict) -> tuple[list[str], dict]:
    """Section 4: stack; returns the lines and the static stack per (target, entry point)."""
    md: list[str] = []
    w = md.append
    w("## 4. Stack")
    w("")
    w("`static` = deepest chain in GCC's call graph (-fstack-usage,")
    w("-fcallgraph-info=su) of the library objects; compiler helper routines")
    w("(libgcc, memset/memcpy) are not in that graph and count as 0 there.")
    w("`measured` = bytes really written below SP during the call on the target")
    w("(stack painted, QEMU run), minus the frame of the benchmark wrapper.")
    w("")
    w("| target | entry point | static (B) | measured (B) | deepest chain (frame bytes) |")
    w("|---|---|---:|---:|---|")
    stack_worst = 0
    stack_by: dict[tuple[str, str], int] = {}
    for name, build in (("Cortex-M4F", args.m4f), ("Cortex-M3", args.m3)):
        cis = sorted((build / "lib").rglob("*.ci"))
        frames, calls = parse_callgraph(cis)
        measured = stack_measured(stdout_by[name])
        wrappers = wrapper_frames(build)
        for key, fn, wrapper in ENTRY_POINTS:
            if fn not in frames:
                continue
            depth, chain = deepest(fn, frames, calls)
            stack_by[(name, key)] = depth
            if key != "load":
                stack_worst = max(stack_worst, depth)
            meas = measured.get(key)
            meas_s = "-" if meas is None else str(meas - wrappers.get(wrapper, 0))
            chain_s = " > ".join(f"{short(c)} ({frames.get(c, 0)})" for c in chain)
            w(f"| {name} | {fn} | {depth} | {meas_s} | {chain_s} |")
    w("")
    comp_q_stack = max(stack_by.get(("Cortex-M4F", "comp_q"), 0), stack_by.get(("Cortex-M3", "comp_q"), 0))
    w(f"Target stack of abbe_comp_step_q <= {TARGETS['stack_bytes']} B: worst static {comp_q_stack} B "
      f"({verdict(comp_q_stack, TARGETS['stack_bytes'])}). Worst of all entry points above: {stack_worst} B.")
    w("")

    return md, stack_by
