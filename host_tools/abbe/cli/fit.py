"""``abbe fit MACHINE.toml -o OUT/``: fit the error model from 6D laser lines.

Writes OUT/model.bin (the table blob), OUT/abbe_model.c and .h (generated C),
OUT/model.json (coefficients with units, fit metrics, provenance) and
OUT/report/ (one PNG per term + index.html). Outputs are built in a temporary
directory next to OUT and swapped in by one rename only when everything
succeeded (:class:`abbe.formats.output.Outputs`), so bad input never leaves
partial output and a failure keeps the old result intact. Before finishing, the blob is read back
and evaluated by the C library against the Python reference (2 nm bound);
``--no-clib-check`` skips that (for tests without a built library).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from abbe.analysis.fit.options import MODELS
from abbe.cli.conventions import examples
from abbe.cli.options import int_range
from abbe.errors import AbbeInputError
from abbe.formats.output import Outputs


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "fit", help="fit the error table: a three-axis machine from 6D laser lines, a "
                    "five-axis trunnion from probing / R-test / indexer / ballbar",
        description="Fit the 18 error terms from the machine file's laser lines and write "
                    "the table (blob, generated C), model.json and an HTML/PNG report. "
                    "On a five-axis table-table machine (a machine file with a [rotary] "
                    "section: xyzac-trt or xyzbc-trt) it identifies the rotary axes' "
                    "location errors (and error motions, [rotary.fit] harmonics) from the "
                    "plan's sphere probing, R-test, indexer and rotary ballbar files, names "
                    "what the plan cannot observe and the convention the table holds it in, "
                    "and writes five_axis.json, model_five.bin (table format 1.2 for the C "
                    "library; abbe table info / eval read it) and report.txt / report/ "
                    "(docs/concepts.md, 'Five-axis machines'). --model, --folds, "
                    "--max-degree, --max-harmonics and --no-clib-check are for laser fits; "
                    "the five-axis fit takes its options from [rotary.fit].",
        epilog=examples("abbe fit examples/vmc500/machine.toml -o fit-out",
                        "abbe fit examples/trunnion5ax/machine.toml -o fit5  # five-axis"))
    p.add_argument("machine", help="machine file (TOML)")
    p.add_argument("-o", "--out", required=True, help="output directory")
    p.add_argument("--model", choices=MODELS, default=None,
                   help="auto (default): period search + cross-validated orders; "
                        "paper-fourier3 / paper-poly7: the paper's fixed models")
    p.add_argument("--folds", type=int_range(2, 50), default=None, metavar="K",
                   help="outer cross-validation folds for held-out metrics (2..50, default 5)")
    p.add_argument("--max-degree", type=int_range(0, 7), default=None, metavar="D",
                   help="highest Chebyshev trend degree (0..7, default 7)")
    p.add_argument("--max-harmonics", type=int_range(0, 8), default=None, metavar="H",
                   help="most harmonics in Fourier block 0 (0..8, default 8)")
    p.add_argument("--no-report", action="store_true", help="skip the PNG/HTML report")
    p.add_argument("--no-clib-check", action="store_true",
                   help="do not check the table with the C library (tests without the library)")
    p.add_argument("--mc", type=int_range(0, 100_000), default=0, metavar="N",
                   help="five-axis fit: N Monte Carlo draws checking every U (GUM S1; the "
                        "exact model solved per draw; its U is stated where the first order "
                        "is more than 10 %% off); default 0. A three-axis table's check: "
                        "abbe table uncertainty --mc")
    p.add_argument("--bench", action="store_true", help="print the time of each stage")
    p.add_argument("-q", "--quiet", action="store_true",
                   help="do not print the metrics table (paper Table 4 layout)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from abbe.cli.fit_chain import is_chain_machine, run_chain
    from abbe.cli.fit_five_axis import is_five_axis, run_five_axis
    if is_five_axis(args.machine) and not is_chain_machine(args.machine):
        return run_five_axis(args)  # a [rotary] machine: the five-axis identification
    if is_chain_machine(args.machine):  # a [chain] machine: any five-axis kind
        return run_chain(args)
    if args.mc:
        raise AbbeInputError("--mc is the five-axis fits' Monte Carlo check; for a "
                             "three-axis table run abbe table uncertainty --mc", field="--mc",
                             file=args.machine)
    # the with block turns a write error inside the staging (disk full, permission)
    # into an input error naming OUT, and removes the staging on any failure
    with Outputs() as outs:
        staging = outs.directory(args.out, option="--out")
        rc, done = _run(args, staging)
        if rc != 0:
            outs.abort()
            return rc
    _print_summary(args, *done)
    return 0


def _run(args: argparse.Namespace, staging: Path) -> tuple[int, tuple]:
    """The fit into ``staging``: (exit status, what the summary prints)."""
    t0 = time.perf_counter()
    times: dict[str, float] = {}

    def lap(name: str) -> None:
        times[name] = time.perf_counter() - t0 - sum(times.values())

    from abbe.analysis.fit.check import ClibMismatch, ClibMissing, check_blob, require_clib
    from abbe.analysis.fit.pipeline import fit_machine, options_from_machine
    from abbe.formats.machine import load_machine

    if not args.no_clib_check:
        try:
            require_clib()
        except ClibMissing as exc:
            print(f"abbe fit: error: {exc}", file=sys.stderr)
            return 3, ()
    machine = load_machine(args.machine)
    opts = options_from_machine(machine, model=args.model, folds=args.folds,
                                max_degree=args.max_degree, max_harmonics=args.max_harmonics)
    lap("read+imports")
    res = fit_machine(machine, opts)
    lap("fit")
    check = None
    if not args.no_clib_check:
        try:
            check = check_blob(res.blob)
        except ClibMismatch as exc:
            print(f"abbe fit: error: {exc}", file=sys.stderr)
            return 4, ()
        res.model_json["clib_check"] = check.to_json()
    else:
        res.model_json["clib_check"] = None
    lap("clib check")
    write_outputs(res, staging, report=not args.no_report, times=times, t0=t0)
    return 0, (res, check, times, t0)


def _print_summary(args: argparse.Namespace, res, check, times: dict, t0: float) -> None:
    total = time.perf_counter() - t0
    if not args.quiet:
        from abbe.analysis.fit.report import metrics_text
        print(metrics_text(res))
    summary = ", ".join(f"{a}: {_axis_summary(res, a)}" for a in res.axes)
    print(f"abbe fit: wrote {args.out} ({summary})")
    if check is not None:
        print(f"abbe fit: C library agrees with the reference: max |f32 - ref| "
              f"{check.max_diff_f32_nm:.3f} nm, max |q - ref| {check.max_diff_q_nm:.3f} nm "
              f"(bound {check.bound_nm} nm, {check.n_points} points)")
    if args.bench:
        for k, v in times.items():
            print(f"bench: {k:<14} {v * 1000:8.1f} ms")
        print(f"bench: {'total':<14} {total * 1000:8.1f} ms")


def _axis_summary(res, a: str) -> str:
    blk = res.axes[a].table.blocks[0]
    d = res.axes[a].table.trend_degree
    return f"degree {d}" + (f" + {blk.harmonics} harm. P={blk.period_mm:.1f} mm" if blk else "")


def write_outputs(res, out: Path, report: bool = True, times: dict | None = None,
                  t0: float = 0.0) -> None:
    """Write every output into the folder ``out`` (a staging folder of :class:`Outputs`)."""
    from abbe.analysis.fit.report import write_report
    from abbe.formats.c_source import write_c

    out = Path(out)
    (out / "model.bin").write_bytes(res.blob)
    write_c(res.blob, out)
    (out / "model.json").write_text(json.dumps(res.model_json, indent=2, allow_nan=False) + "\n",
                                    encoding="utf-8")
    if times is not None:
        times["write table+json"] = time.perf_counter() - t0 - sum(times.values())
    if report:
        write_report(res, out / "report")
        if times is not None:
            times["report"] = time.perf_counter() - t0 - sum(times.values())
