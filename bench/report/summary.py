"""The summary of the targets (issue 16), written last and inserted after the header."""

from __future__ import annotations

from report.common import BEFORE, TARGETS, verdict


def summary_section(args, by: dict, tgt: dict, flash_by: dict, stack_by: dict, f10: dict) -> list[str]:
    """The targets' table: now, before (commit af2baa8) and the target of each measurement."""
    summary: list[str] = []
    sw = summary.append
    f32_flash = max(flash_by.get(("Cortex-M4F", "comp_f32"), 0), 0)
    q_flash_m4f = flash_by.get(("Cortex-M4F", "comp_q"), 0)
    q_flash_m3 = flash_by.get(("Cortex-M3", "comp_q"), 0)
    rows = [
        ("x86-64 abbe_error_eval_f32 (x86-64-v3 kernels)", by["f32"].per_call, BEFORE["x86_f32"], TARGETS["x86_f32"], "instructions"),
        ("x86-64 abbe_error_eval_f32 (SSE2 kernels)", by["f32_base"].per_call, BEFORE["x86_f32"], TARGETS["x86_f32"], "instructions"),
        ("Cortex-M4F abbe_error_eval_f32", max(tgt["Cortex-M4F"]["f32"]), BEFORE["m4f_f32"], TARGETS["m4f_f32"], "instructions"),
        ("Cortex-M3 abbe_error_eval_q", max(tgt["Cortex-M3"]["q"]), BEFORE["m3_q"], TARGETS["m3_q"], "instructions"),
        ("flash, load + compensator, f32 (M4F)", f32_flash, BEFORE["flash_f32"], TARGETS["flash_bytes"], "B"),
        ("flash, load + compensator, q (M4F)", q_flash_m4f, BEFORE["flash_q_m4f"], TARGETS["flash_bytes"], "B"),
        ("flash, load + compensator, q (M3)", q_flash_m3, BEFORE["flash_q_m3"], TARGETS["flash_bytes"], "B"),
        ("stack, abbe_comp_step_q (M4F)", stack_by.get(("Cortex-M4F", "comp_q"), 0), BEFORE["stack_comp_q_m4f"], TARGETS["stack_bytes"], "B"),
        ("stack, abbe_comp_step_q (M3)", stack_by.get(("Cortex-M3", "comp_q"), 0), BEFORE["stack_comp_q_m3"], TARGETS["stack_bytes"], "B"),
    ]
    for label, key, before in (("f32 (M4F)", ("Cortex-M4F", "comp_f32"), BEFORE["flash_f32"]),
                               ("q (M4F)", ("Cortex-M4F", "comp_q"), BEFORE["flash_q_m4f"]),
                               ("q (M3)", ("Cortex-M3", "comp_q"), BEFORE["flash_q_m3"])):
        if key in f10:
            rows.append((f"flash, load + compensator, {label}, 1.0 library (ABBE_WITH_REVERSAL=OFF)",
                         f10[key], before, TARGETS["flash_bytes"], "B"))
    sw("## Summary: the targets (issue 16)")
    sw("")
    sw("`before` = the same measurement of commit af2baa8. Instruction counts are the worst")
    sw("over the measured points (they no longer vary: the run time depends on the table only).")
    sw("`now` is the library that reads format 1.1 (reversal blocks, issue 14; the default);")
    sw("the `1.0 library` rows are the same sources built with -DABBE_WITH_REVERSAL=OFF,")
    sw("a format 1.0 reader with the machine code of the library before 1.1. Section 8 has")
    sw("the blocks' cost per call, flash and stack.")
    sw("")
    sw("| measurement | now | before | target | |")
    sw("|---|---:|---:|---:|---|")
    for label, now, before, target, unit in rows:
        sw(f"| {label} | {now:.0f} | {before} | <= {target} {unit} | {verdict(now, target)} |")
    sw("")
    if args.m4f_clang and args.m3_clang:
        sw("The targets are GCC's; section 9 has the clang/LLVM builds beside them (issue 28).")
        sw("")
    return summary
