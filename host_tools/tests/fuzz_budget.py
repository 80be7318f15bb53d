"""How many inputs the fuzz and property tests draw.

CI runs the committed numbers, derandomized (the same inputs every run). A long run by
hand multiplies them by ``$ABBE_FUZZ_SCALE`` and, with a scale set, draws fresh inputs
(``--hypothesis-seed=N`` picks them, so a finding can be replayed)::

    ABBE_FUZZ_SCALE=20 pytest tests/formats/test_fuzz_recent_readers.py --hypothesis-seed=7

The raised level is never committed: it would cost CI minutes (scripts/test.sh budget).
"""

from __future__ import annotations

import os

#: Multiplier of every fuzz test's example count (1 in CI).
SCALE = max(1, int(os.environ.get("ABBE_FUZZ_SCALE", "1") or "1"))
#: Derandomized (fixed inputs) at the CI level only.
DERANDOMIZE = SCALE == 1


def examples(n: int) -> int:
    """``n`` (the CI count) times the scale."""
    return n * SCALE
