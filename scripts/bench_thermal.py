#!/usr/bin/env python3
"""Thermal block benchmark (section 12 of bench/results.md): bench/report/thermal.py.

    python3 scripts/bench_thermal.py --m4f build-bench-m4f --m3 build-bench-m3 \\
        [--results bench/results.md]

prints the markdown section (and with --results replaces or appends it there).
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from report.thermal import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
