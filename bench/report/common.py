"""The numbers the sections judge against and the labels more than one section uses."""

from __future__ import annotations

import statistics

# Targets from the issue: reported, not asserted.
TARGETS = {
    "x86_f32": 400,
    "m4f_f32": 700,
    "m3_q": 1500,
    "flash_bytes": 6 * 1024,
    "stack_bytes": 256,
}

# The same measurements of the library before this round of work (commit
# af2baa8, bench/results.md of that commit): the "before" column.
BEFORE = {
    "x86_f32": 1404, "m4f_f32": 1461, "m3_q": 2380,
    "flash_f32": 6176, "flash_q_m4f": 7084, "flash_q_m3": 7140,
    "stack_comp_q_m4f": 544, "stack_comp_q_m3": 560,
}


def fmt_counts(v: list[int]) -> str:
    lo, hi = min(v), max(v)
    return f"{lo}" if lo == hi else f"{lo} to {hi} (mean {statistics.mean(v):.0f})"


def verdict(value: float, target: float) -> str:
    return "meets" if value <= target else "MISSES"


TABLES_11 = ("backlash", "reversal")
CALL_LABELS = {"f32": "abbe_error_eval_f32", "f32_base": "abbe_error_eval_f32 (SSE2 kernels)",
               "q": "abbe_error_eval_q", "comp_f32": "abbe_comp_step_f32",
               "comp_q": "abbe_comp_step_q"}


# The measured entry points: PLAN key in bench_target.c, function, its wrapper there.
ENTRY_POINTS = (("load", "abbe_model_load", "run_load"), ("f32", "abbe_error_eval_f32", "run_f32"),
                ("q", "abbe_error_eval_q", "run_q"), ("comp_f32", "abbe_comp_step_f32", "run_comp_f32"),
                ("comp_q", "abbe_comp_step_q", "run_comp_q"))
CLANG_USES = (("load", "abbe_model_load only"), ("eval_f32", "load + eval_f32"),
              ("eval_q", "load + eval_q"), ("comp_f32", "load + compensator (f32)"),
              ("comp_q", "load + compensator (q)"))


# abbe_* call labels of sections 1, 2 and 5 (bench_host / bench_target modes).
NAMES = {"f32": "abbe_error_eval_f32 (kernels this CPU runs, see below)",
         "f32_base": "abbe_error_eval_f32, x86-64 baseline (SSE2) kernels",
         "lean": "lean reference (float, no guarantees; bench/lean_ref.c)",
         "q": "abbe_error_eval_q",
         "comp_f32": "abbe_comp_step_f32 (compensator cycle)",
         "comp_q": "abbe_comp_step_q (compensator cycle)",
         "naive": "naive reference (double, libm sin/cos)", "empty": "empty call"}
