"""Bidirectional positioning deviations of one axis, as read from any positioning file.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from abbe.formats.thermal20 import Normalisation


@dataclass
class PositioningData:
    """Bidirectional positioning deviations of one axis.

    targets_mm: (T,) ascending, mm. up_um, down_um: (n_runs, T) deviations
    (measured minus target) of the ``+`` and ``-`` approaches, um. normalisation:
    what was done about 20 deg C (None: the file carries no temperature). notes:
    how the file was read, for the person (a Windows code page, sections skipped).
    """

    source: str
    targets_mm: np.ndarray
    up_um: np.ndarray
    down_um: np.ndarray
    sha256: str = ""
    normalisation: "Normalisation | None" = None
    notes: list[str] = field(default_factory=list)
