#!/usr/bin/env python3
"""Measure the abbe library and write bench/results.md (run by scripts/bench.sh).

The code is the package bench/report/ (one module per section; its __init__ says which
and in what order they import): this is its entry point, report.document's main.
Usage: bench_report.py --repo DIR --host BUILD --m4f BUILD --m3 BUILD [-o FILE]
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
from report.document import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
