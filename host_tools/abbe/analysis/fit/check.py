"""Read a written blob back and compare the C library with the Python reference.

``abbe fit`` calls :func:`check_blob` before it finishes: the blob is decoded
(``abbe.formats.blob.read_blob``), loaded by the C library (``abbe.model.clib.CModel``) and
both numeric variants (``_f32`` and ``_q``) are evaluated at seeded positions
across the travel (10 % beyond it on each side, to exercise the end-value
hold) with random backlash direction states; the float64 reference
(``abbe.model.reference.spatial_error``) on the decoded table is the truth. The fit
fails if any difference exceeds ``BOUND_NM`` (the numerics bound, 2 nm).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from abbe.formats.blob import read_blob
from abbe.model.table import AXES

BOUND_NM = 2.0
BUILD_HINT = ("build it with 'cmake -S . -B build && cmake --build build' in the repository "
              "root (or point ABBE_LIB at libabbe.so), or pass --no-clib-check to skip the check")


class ClibMissing(RuntimeError):
    """The C library is not built: the check cannot run."""


class ClibMismatch(RuntimeError):
    """The C library and the Python reference disagree beyond the bound."""


@dataclass
class CheckResult:
    """Largest |C - reference| over the sample, nm, per variant."""

    n_points: int
    max_diff_f32_nm: float
    max_diff_q_nm: float
    bound_nm: float = BOUND_NM

    def to_json(self) -> dict:
        return {"n_points": self.n_points, "max_diff_f32_nm": round(self.max_diff_f32_nm, 4),
                "max_diff_q_nm": round(self.max_diff_q_nm, 4), "bound_nm": self.bound_nm}


def require_clib() -> None:
    """Raise ClibMissing (with build instructions) if the C library cannot be loaded."""
    from abbe.model import clib

    try:
        clib.load_library()
    except clib.LibraryNotFound as exc:
        raise ClibMissing(f"the C library is needed to check the written table: {exc.what}; "
                          f"{BUILD_HINT}") from None


def sample_inputs(blob: bytes, n: int = 600, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Seeded positions (n, 3) mm across each axis' table travel +/- 10 % and
    direction states (n, 3) in [-1, 1] (0 where the axis has no reversal)."""
    t = read_blob(blob)
    rng = np.random.default_rng(seed)
    pos = np.empty((n, 3))
    ds = np.zeros((n, 3))
    for j, a in enumerate(AXES):
        lo, hi = t.axes[a].travel_mm
        w = hi - lo
        pos[:, j] = rng.uniform(lo - 0.1 * w, hi + 0.1 * w, n)
        if t.axes[a].has_reversal():  # backlash_um or a reversal block (format 1.1)
            ds[:, j] = rng.choice([-1.0, -0.5, 0.0, 0.5, 1.0], n)
    return pos, ds


def check_blob(blob: bytes, n: int = 600, seed: int = 0, bound_nm: float = BOUND_NM
               ) -> CheckResult:
    """Compare C (_f32 and _q) with the Python reference on the decoded blob.

    Raises ClibMissing if the library is not built, ClibMismatch if a difference
    exceeds ``bound_nm``.
    """
    require_clib()
    from abbe.model import clib
    from abbe.model.reference import spatial_error

    table = read_blob(blob)
    cm = clib.CModel(blob, source="model.bin")
    pos, ds = sample_inputs(blob, n, seed)
    # f32: the reference at the float32-rounded inputs the C code actually sees.
    pos32 = pos.astype(np.float32).astype(np.float64)
    ds32 = ds.astype(np.float32).astype(np.float64)
    e32, _ = cm.error_f32(pos32, ds32)
    r32 = spatial_error(table, pos32, ds32)
    d32 = float(np.max(np.abs(e32 - r32))) * 1000.0
    # q: integer nm positions, Q30 direction state.
    pos_nm = np.round(pos * 1e6).astype(np.int64)
    dq = np.round(ds * (1 << 30)).astype(np.int64)
    eq, _ = cm.error_q(pos_nm, dq)
    rq = spatial_error(table, pos_nm / 1e6, dq / float(1 << 30)) * 1000.0
    dq_nm = float(np.max(np.abs(eq - rq)))
    res = CheckResult(n_points=n, max_diff_f32_nm=d32, max_diff_q_nm=dq_nm, bound_nm=bound_nm)
    if d32 > bound_nm or dq_nm > bound_nm:
        raise ClibMismatch(
            f"C library and Python reference differ on the written table: max |f32 - ref| = "
            f"{d32:.3f} nm, max |q - ref| = {dq_nm:.3f} nm, bound {bound_nm} nm")
    return res
