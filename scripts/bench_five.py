#!/usr/bin/env python3
"""Five-axis benchmark (section 11 of bench/results.md) on its own: bench/report/five_axis.py.

    python3 scripts/bench_five.py --m4f build-bench-m4f --m3 build-bench-m3 [--results bench/results.md]

prints the section (with --results: replaces it there in place).
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from report.five_axis import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
