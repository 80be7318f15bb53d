"""The benchmark report: measures the library's builds and writes bench/results.md.

Run by scripts/bench.sh through the thin entry points scripts/bench_report.py (the whole
report), scripts/bench_five.py (section 11 alone) and scripts/bench_thermal.py (section
12); port/grblhal/bench/cost.py (section 10) uses its measuring modules. Only the Python
standard library is used (bench.sh runs it with the system python3); the entry points
put bench/ on sys.path, so the package imports as ``report``.

One module per concern; imports go one way, down this list (nothing imports upward):

- ``document``: the command line and the order of the sections (``main``).
- the sections, each returning its markdown lines (and what later sections use):
  ``three_axis`` (1-4: x86-64 and Cortex-M instructions, flash, stack), ``details``
  (5-7: -Os, where the instructions go, Python throughput, flags), ``reversal`` (8),
  ``clang`` (9), ``summary`` (the targets' table), ``five_axis`` (11), ``thermal`` (12).
- ``common``: the targets, the "before" figures and the labels several sections share.
- ``maps``: link maps, call graphs, stack frames (reads what the builds left on disk).
- ``measure``: callgrind, QEMU exec traces, compile flags, the Python throughput run.
"""
