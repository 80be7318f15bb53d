"""Example tables shaped like fitted machine errors (seeded, reproducible).

:func:`paper_table` is the machine of the seed paper (Zhang & Chen 2021): travel
X [0, 500], Y [-400, 0], Z [-300, 0] mm, reference point (163.626, -212.772,
-290.704) mm, every one of the 18 terms a degree-1 trend plus a 3-harmonic
Fourier block over the travel. The coefficients are synthetic (smooth, decaying
harmonics, magnitudes typical of a mid-size VMC), not the paper's data, which
is not published.

``python -m abbe.cli.example_table OUTDIR`` writes OUTDIR/model.json and OUTDIR/model.bin
(the repository's examples/paper_table/ is made this way).
"""

from __future__ import annotations

import numpy as np

from abbe.model.table import AXES, AxisTable, FourierBlock, Table, basis_matrix

PAPER_TRAVEL_MM: dict[str, tuple[float, float]] = {
    "X": (0.0, 500.0), "Y": (-400.0, 0.0), "Z": (-300.0, 0.0)}
PAPER_REFERENCE_MM = (163.626, -212.772, -290.704)
# Peak |term| over the travel for the paper-like machine: um (linear), urad (angular).
PAPER_AMPLITUDE: dict[str, dict[str, float]] = {
    "X": {"dx": 8.0, "dy": 4.0, "dz": 5.0, "ex": 12.0, "ey": 25.0, "ez": 18.0},
    "Y": {"dx": 3.5, "dy": 9.0, "dz": 4.5, "ex": 20.0, "ey": 10.0, "ez": 15.0},
    "Z": {"dx": 3.0, "dy": 4.0, "dz": 6.0, "ex": 14.0, "ey": 16.0, "ez": 8.0},
}


def synthetic_axis(rng: np.random.Generator, travel_mm: tuple[float, float], ref_mm: float,
                   amplitude: dict[str, float], trend_degree: int | None,
                   blocks: tuple[FourierBlock | None, FourierBlock | None],
                   short_amplitude: dict[str, float] | None = None) -> AxisTable:
    """An axis whose terms look like fitted errors.

    Trend coefficients decay geometrically with the degree, block-0 harmonics
    as k^-1.5, block-1 (short period) harmonics as k^-2 with random phases.
    Each term is made zero at ``ref_mm`` (through T0, or by subtracting a
    constant spread over the cos rows when there is no trend) and scaled so
    its peak over the travel is ``amplitude[term]`` (um / urad). Block-1 rows
    are scaled separately to peak near ``short_amplitude[term]``.
    """
    ax = AxisTable(travel_mm=travel_mm, trend_degree=trend_degree, blocks=blocks)
    nb = ax.n_basis()
    p = np.linspace(travel_mm[0], travel_mm[1], 4001)
    # dense enough for short periods
    for blk in blocks:
        if blk is not None:
            n = int(12 * blk.harmonics * (travel_mm[1] - travel_mm[0]) / blk.period_mm) + 1
            if n > p.size:
                p = np.linspace(travel_mm[0], travel_mm[1], n)
    basis = basis_matrix(ax, p)
    at_ref = basis_matrix(ax, np.array([ref_mm]))[0]
    n_trend = ax.n_trend()
    b0 = 2 * blocks[0].harmonics if blocks[0] is not None else 0
    for t, amp in amplitude.items():
        long = np.zeros(nb)
        if n_trend:
            long[:n_trend] = rng.normal(size=n_trend) * 0.55 ** np.arange(n_trend)
        if b0:
            k = np.arange(1, blocks[0].harmonics + 1)
            a = rng.normal(size=k.size) * k ** -1.5
            ph = rng.uniform(0, 2 * np.pi, size=k.size)
            long[n_trend:n_trend + b0:2] = a * np.cos(ph)
            long[n_trend + 1:n_trend + b0:2] = a * np.sin(ph)
        short = np.zeros(nb)
        if blocks[1] is not None:
            k = np.arange(1, blocks[1].harmonics + 1)
            a = k ** -2.0 * rng.uniform(0.5, 1.0, size=k.size)
            ph = rng.uniform(0, 2 * np.pi, size=k.size)
            short[n_trend + b0::2] = a * np.cos(ph)
            short[n_trend + b0 + 1::2] = a * np.sin(ph)
            sa = (short_amplitude or {}).get(t, 0.0)
            peak = np.max(np.abs(basis @ short))
            short *= sa / peak if peak > 0 else 0.0
        long_v = basis @ long
        long *= amp / max(np.max(np.abs(long_v)), 1e-12)
        c = long + short
        c = _zero_at(c, at_ref, n_trend, ax)
        # rescale the total so the peak is the requested amplitude
        peak = np.max(np.abs(basis @ c))
        if peak > 0:
            c *= amp / peak if amp > 0 else 0.0
        ax.coef[t] = c
    return ax


def _zero_at(c: np.ndarray, at_ref: np.ndarray, n_trend: int, ax: AxisTable) -> np.ndarray:
    """Make the term zero at the reference point (the fit does the same)."""
    c = c.copy()
    v = float(at_ref @ c)
    if n_trend:
        c[0] -= v  # T0 == 1
    else:
        # no constant row: remove the value along the basis vector at the reference
        # (least-norm correction), which keeps the shape smooth.
        c -= v * at_ref / float(at_ref @ at_ref)
    return c


def paper_table(seed: int = 2021) -> Table:
    """The paper's machine with synthetic, realistic coefficients (float table)."""
    rng = np.random.default_rng(seed)
    axes = {}
    for j, a in enumerate(AXES):
        lo, hi = PAPER_TRAVEL_MM[a]
        blk = FourierBlock(period_mm=hi - lo, origin_mm=lo, harmonics=3)
        axes[a] = synthetic_axis(rng, (lo, hi), PAPER_REFERENCE_MM[j], PAPER_AMPLITUDE[a],
                                 trend_degree=1, blocks=(blk, None))
    return Table(axes=axes, reference_mm=PAPER_REFERENCE_MM, tool_offset_mm=(0.0, 0.0, 150.0),
                 squareness_urad=(25.0, -12.0, 8.0))
