"""Real data the project does not carry (its licence does not allow it), found beside the checkout.

``../shared/data`` next to the repository (``$ABBE_SHARED_DATA`` overrides it).
A test that reads it is marked ``@needs_real_data(path)``: without the file it
is SKIPPED with a reason starting "real data absent" (scripts/test.sh lists
pytest's skips in its summary); under CI (``CI=true``), where ../shared is
beside the clone, a missing file FAILS the test instead (conftest.py), so a
CI run never passes by skipping them.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SHARED_DATA = Path(os.environ.get("ABBE_SHARED_DATA") or REPO.parent / "shared" / "data")

#: ESS target's ISO 230-2 X record (Renishaw .dat): not carried, no licence to.
ESS_DAT = SHARED_DATA / "ess-target" / "x_iso230_2.dat"


def needs_real_data(path: Path) -> pytest.MarkDecorator:
    """Mark a test (or ``pytestmark``) that reads the real-data file ``path``."""
    return pytest.mark.real_data(path=Path(path))


def check_real_data(item: pytest.Item) -> None:
    """Skip ``item`` (or fail it under CI=true) if a real-data file it is marked with is absent."""
    for mark in item.iter_markers(name="real_data"):
        path = Path(mark.kwargs["path"])
        if path.is_file():
            continue
        if os.environ.get("CI") == "true":
            pytest.fail(f"real data missing under CI=true: {path} (CI has ../shared beside the clone; "
                        f"set ABBE_SHARED_DATA if it lies elsewhere)", pytrace=False)
        pytest.skip(f"real data absent: {path.parent} (not carried by the project: licence; "
                    f"put shared/data beside the repository or set ABBE_SHARED_DATA)")
