"""Benchmark of ``abbe fit`` on a full 3-axis data set.

51 targets x 5 bidirectional runs x 6 channels x 3 axes (seeded synthetic data,
cases.synthetic_laser), automatic selection, all outputs (blob, C, JSON, report) and,
if the C library is built, the C-vs-reference check. Prints the wall time of
each stage (in-process, after imports) and of the whole command in a fresh
interpreter (including Python start-up and imports).

    python host_tools/bench/bench_fit.py [--repeat N] [--no-clib-check]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

# cases/ (the synthetic case generators) lives beside the package, not in it.
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3, help="runs of each measurement (best kept)")
    ap.add_argument("--no-clib-check", action="store_true")
    args = ap.parse_args()

    from abbe.model import clib
    from cases.synthetic_laser import make_dataset

    check = [] if (clib.available() and not args.no_clib_check) else ["--no-clib-check"]
    with tempfile.TemporaryDirectory(prefix="abbe-bench-") as tmp:
        syn = make_dataset(Path(tmp) / "data", seed=2021, n_targets=51, n_runs=5)
        print(f"data: {syn.machine.parent} (51 targets x 5 runs x 6 channels x 3 axes)")
        print("C check:", "on" if not check else "off (library not built or --no-clib-check)")
        best_in, best_cold = float("inf"), float("inf")
        for i in range(args.repeat):
            out = Path(tmp) / f"out{i}"
            cmd = [sys.executable, "-m", "abbe.cli.entry", "fit", str(syn.machine), "-o", str(out),
                   "--bench", *check]
            t0 = time.perf_counter()
            res = subprocess.run(cmd, capture_output=True, text=True)
            cold = time.perf_counter() - t0
            if res.returncode != 0:
                print(res.stdout, res.stderr, sep="\n")
                return res.returncode
            total = [ln for ln in res.stdout.splitlines() if ln.startswith("bench: total")]
            inproc = float(total[0].split()[-2]) / 1000.0
            best_in, best_cold = min(best_in, inproc), min(best_cold, cold)
            if i == 0:
                print("\n".join(ln for ln in res.stdout.splitlines() if ln.startswith("bench:")))
        print(f"best of {args.repeat}: abbe fit {best_in:.2f} s in-process "
              f"(after imports), {best_cold:.2f} s as a fresh command (target <= 2 s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
