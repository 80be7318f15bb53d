"""Least-squares linear maps for targets that hold only a matrix (skew, scale, squareness).

The model error is fitted over the work volume grid (the direction-averaged
error, all axes in state 0) by E_k(p) ~ b_k + sum_i A[k, i] p_i with only the
entries a target can hold free (``mask``), p in machine coordinates (the
controllers apply their matrix about the machine origin; the constant b is a
work-offset shift). Least squares is linear, so the fit of the whole model is the
sum of the fits of its parts: :func:`remainder` gives each part's unheld rest.
Positions mm, errors um; A in um/mm (= 1e-3, i.e. mm/m).
"""

from __future__ import annotations

import numpy as np

from abbe.exports.target import Context
from abbe.exports.terms import model_error

FIT_POINTS = 21  # per axis


def fit_points(ctx: Context) -> np.ndarray:
    return ctx.volume.grid({a: FIT_POINTS for a in "XYZ"})


def fit_matrix(pos: np.ndarray, err: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """A (3, 3) um/mm minimising sum |err - b - A pos|^2 with A[~mask] = 0."""
    A = np.zeros((3, 3))
    for k in range(3):
        cols = [i for i in range(3) if mask[k, i]]
        if not cols:
            continue
        M = np.column_stack([np.ones(pos.shape[0])] + [pos[:, i] for i in cols])
        c, *_ = np.linalg.lstsq(M, err[:, k], rcond=None)
        A[k, cols] = c[1:]
    return A


def model_matrix(ctx: Context, mask: np.ndarray) -> np.ndarray:
    """The least-squares A of the whole model (module docstring)."""
    P = fit_points(ctx)
    return fit_matrix(P, model_error(ctx.table, P), mask)


def remainder(mask: np.ndarray):
    """f(pos, contribution) -> contribution minus its own least-squares linear part
    (constant included): the part a matrix target leaves of one model item."""
    def f(pos: np.ndarray, v: np.ndarray) -> np.ndarray:
        A = fit_matrix(pos, v, mask)
        r = v - pos @ A.T
        return r - r.mean(axis=0)
    return f
