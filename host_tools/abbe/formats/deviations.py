"""Bidirectional positioning deviations of one axis, as read from any positioning file.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class PositioningData:
    """Bidirectional positioning deviations of one axis.

    targets_mm: (T,) ascending, mm. up_um, down_um: (n_runs, T) deviations
    (measured minus target) of the ``+`` and ``-`` approaches, um.
    """

    source: str
    targets_mm: np.ndarray
    up_um: np.ndarray
    down_um: np.ndarray
    sha256: str = ""
