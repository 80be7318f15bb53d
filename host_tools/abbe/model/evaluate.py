"""The spatial error of any model at machine positions: reference, C library or callable.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def model_error_um(model: Any, pos_mm: np.ndarray, dir_state: np.ndarray | None = None,
                   temp_c: np.ndarray | None = None) -> np.ndarray:
    """Spatial error (N, 3) um of a model at positions (N, 3) mm.

    ``model``: an ``abbe.model.table.Table`` (float64 reference, ``abbe.model.reference``), an
    ``abbe.model.clib.CModel`` (C library ``error_f32``), or a callable
    ``f(pos_mm, dir_state, temp_c) -> (N, 3) um``.
    """
    from abbe.model.table import Table

    if isinstance(model, Table):
        from abbe.model.reference import spatial_error
        return spatial_error(model, pos_mm, dir_state, temp_c)
    if hasattr(model, "error_f32"):
        err, _flags = model.error_f32(pos_mm, dir_state, temp_c)
        return np.asarray(err, dtype=np.float64)
    if callable(model):
        return np.asarray(model(pos_mm, dir_state, temp_c), dtype=np.float64).reshape(-1, 3)
    raise TypeError(f"cannot evaluate a model of type {type(model).__name__}")
