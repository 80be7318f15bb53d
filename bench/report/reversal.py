"""Section 8: format 1.1's reversal blocks, what they cost in instructions, flash and
stack, beside a format 1.0 library (-DABBE_WITH_REVERSAL=OFF builds)."""

from __future__ import annotations

from report.common import CALL_LABELS, TABLES_11
from report.maps import deepest, parse_callgraph, parse_map, wrapper_frames
from report.measure import TABLE_MODES, host_table_bench, qemu_trace_counts, stack_measured


def reversal_section(args, nm: str, by: dict, tgt: dict, stdout_by: dict, flash_by: dict,
                     stack_by: dict) -> dict:
    """Section 8 (format 1.1): instructions on the paper / backlash / reversal tables for
    this library and for the 1.0 library (ABBE_WITH_REVERSAL=OFF builds, if given), flash
    and stack of both. Returns the lines and the numbers the summary uses."""
    lines: list[str] = []
    w = lines.append
    out: dict = {"lines": lines, "flash_10": {}}
    w("## 8. Format 1.1: what the reversal blocks cost (issue 14)")
    w("")
    w("Tables (tests/golden): `paper` as above (no backlash); `backlash` = the paper table")
    w("with a constant backlash on every axis (format 1.0); `reversal` = `backlash` with")
    w("reversal blocks of degree 3, 7 and 0 on X, Y, Z (format 1.1). `1.0 library` = the")
    w("same sources built with `-DABBE_WITH_REVERSAL=OFF` (a format 1.0 reader: the")
    w("library's machine code before format 1.1; it refuses the `reversal` table). The")
    w("blocks' cost is `reversal` - `backlash` with this library. x86-64: callgrind,")
    w("instructions inside the call; Cortex-M: the worst of the measured points, QEMU trace.")
    w("")
    w("| target | call | paper | backlash | reversal | blocks' cost | paper, 1.0 library | "
      "backlash, 1.0 library |")
    w("|---|---|---:|---:|---:|---:|---:|---:|")
    host = {None: {m: by[m].per_call for m, _, _ in TABLE_MODES}}
    for t in TABLES_11:
        host[t] = host_table_bench(args.host, t)
    host10 = {}
    if args.host_10:
        for t in (None, "backlash"):
            host10[t] = host_table_bench(args.host_10, t)

    def cell(v) -> str:
        return "-" if v is None else f"{v:.0f}"
    for mode, _, _ in TABLE_MODES:
        vals = [None if host[t] is None else host[t][mode] for t in (None, *TABLES_11)]
        cost = None if None in vals[1:] else vals[2] - vals[1]
        v10 = [None if not host10.get(t) else host10[t][mode] for t in (None, "backlash")]
        w(f"| x86-64 | {CALL_LABELS[mode]} | " + " | ".join(cell(v) for v in vals) +
          f" | {cell(cost)} | " + " | ".join(cell(v) for v in v10) + " |")
    tgt10: dict[str, dict[str, list[int]]] = {}
    stdout10: dict[str, str] = {}
    for name, build, machine in (("Cortex-M4F", args.m4f_10, "mps2-an386"),
                                 ("Cortex-M3", args.m3_10, "mps2-an385")):
        if build:
            tgt10[name], stdout10[name] = qemu_trace_counts(
                machine, build / "bench" / "bench_target.elf", nm)
    for name in ("Cortex-M4F", "Cortex-M3"):
        for mode in ("f32", "q", "comp_f32", "comp_q"):
            c = tgt[name]
            if mode not in c:
                continue
            vals = [max(c[k]) if k in c else None
                    for k in (mode, f"{mode}@backlash", f"{mode}@reversal")]
            cost = None if None in vals[1:] else vals[2] - vals[1]
            c10 = tgt10.get(name, {})
            v10 = [max(c10[k]) if k in c10 else None for k in (mode, f"{mode}@backlash")]
            w(f"| {name} | {CALL_LABELS[mode]} | " + " | ".join(cell(v) for v in vals) +
              f" | {cell(cost)} | " + " | ".join(cell(v) for v in v10) + " |")
            out[(name, mode)] = (vals, v10)
    w("")
    w("A table without reversal blocks executes no block code: `paper` (no backlash) runs")
    w("the 1.0 paths; the few instructions either way there come from the compiler's")
    w("register allocation in the functions that also hold the blocks' calls. With a")
    w("backlash (`backlash` vs the 1.0 library): `_f32` adds one feature test after the")
    w("extras and passes the axis offsets to them (the blocks are a function of their own,")
    w("called last); `_q` tests each axis' block row count in the extras loop (the block")
    w("replaces B by B + R before the one rounding, so a one-row block is bit for bit a")
    w("change of B). Measured during this work: the `_f32` block code inlined into the")
    w("extras loop instead takes 160 B less flash but costs a table with backlash and no")
    w("blocks +23 (Cortex-M4F) / +48 (x86-64) instructions instead of +11 / +9.")
    w("")

    # flash
    w("Flash of the library (as in section 3), this library and the 1.0 library:")
    w("")
    w("| target | use | this library (B) | 1.0 library (B) | the blocks (B) |")
    w("|---|---|---:|---:|---:|")
    labels = {"load": "abbe_model_load only", "eval_f32": "load + eval_f32",
              "eval_q": "load + eval_q", "comp_f32": "load + compensator (f32)",
              "comp_q": "load + compensator (q)"}
    for name, build in (("Cortex-M4F", args.m4f_10), ("Cortex-M3", args.m3_10)):
        for use in ("load", "eval_f32", "eval_q", "comp_f32", "comp_q"):
            if (name, use) not in flash_by:
                continue
            v10 = None
            if build and (build / "bench" / f"bench_size_{use}.map").exists():
                v10 = parse_map(build / "bench" / f"bench_size_{use}.map").lib_flash
                out["flash_10"][(name, use)] = v10
            now = flash_by[(name, use)]
            w(f"| {name} | {labels[use]} | {now} | {cell(v10)} | "
              f"{'-' if v10 is None else f'{now - v10:+d}'} |")
    w("")

    # stack
    w("Stack (as in section 4): static = deepest call chain; measured = painted, on the")
    w("`reversal` table (minus the wrapper's frame):")
    w("")
    w("| target | entry point | static, this library (B) | static, 1.0 library (B) | "
      "measured, reversal table (B) |")
    w("|---|---|---:|---:|---:|")
    for name, build, build10 in (("Cortex-M4F", args.m4f, args.m4f_10),
                                 ("Cortex-M3", args.m3, args.m3_10)):
        frames10 = calls10 = None
        if build10:
            frames10, calls10 = parse_callgraph(sorted((build10 / "lib").rglob("*.ci")))
        measured = stack_measured(stdout_by[name])
        wrappers = wrapper_frames(build)
        for key, fn, wrapper in (("comp_f32", "abbe_comp_step_f32", "run_comp_f32"),
                                 ("comp_q", "abbe_comp_step_q", "run_comp_q")):
            if (name, key) not in stack_by:
                continue
            s10 = None
            if frames10 is not None and fn in frames10:
                s10 = deepest(fn, frames10, calls10)[0]
            meas = measured.get(f"{key}@reversal")
            meas_s = "-" if meas is None else str(meas - wrappers.get(wrapper, 0))
            w(f"| {name} | {fn} | {stack_by[(name, key)]} | {cell(s10)} | {meas_s} |")
    w("")
    return out
