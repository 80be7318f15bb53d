"""abbe.model.reference: Eq. 3 checked independently against exact homogeneous transforms,
end-value hold, backlash and thermal semantics."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from abbe.formats.blob import quantize
from abbe.formats.golden import full_table
from abbe.model.examples import paper_table
from abbe.model.reference import extra_values, out_of_travel, spatial_error, term_values
from abbe.model.table import AXES, TERMS, AxisTable, Table

# --------------------------------------------------------------------------- independent term evaluation


def independent_term(ax: AxisTable, term: str, p: float) -> float:
    """A term value written out from the spec, one position at a time (no basis_matrix)."""
    if term not in ax.coef:
        return 0.0
    lo, hi = ax.travel_mm
    p = min(max(p, lo), hi)
    c = list(ax.coef[term])
    v, r = 0.0, 0
    if ax.trend_degree is not None:
        u = (2 * p - lo - hi) / (hi - lo)
        t_prev, t_cur = 1.0, u                      # Chebyshev recurrence
        for k in range(ax.trend_degree + 1):
            tk = 1.0 if k == 0 else (u if k == 1 else 2 * u * t_cur - t_prev)
            if k >= 2:
                t_prev, t_cur = t_cur, tk
            v += c[r] * tk
            r += 1
    for blk in ax.blocks:
        if blk is None:
            continue
        phi = 2 * np.pi * (p - blk.origin_mm) / blk.period_mm
        for h in range(1, blk.harmonics + 1):
            v += c[r] * np.sin(h * phi) + c[r + 1] * np.cos(h * phi)
            r += 2
    return v


def test_term_values_match_independent_evaluation() -> None:
    t = quantize(full_table(np.random.default_rng(5)))
    rng = np.random.default_rng(1)
    for a in AXES:
        lo, hi = t.axes[a].travel_mm
        p = np.concatenate([[lo, hi, lo - 30, hi + 30], rng.uniform(lo, hi, 20)])
        for term in TERMS:
            got = term_values(t, a, term, p)
            want = [independent_term(t.axes[a], term, x) for x in p]
            np.testing.assert_allclose(got, want, atol=1e-9, rtol=0)


# --------------------------------------------------------------------------- Eq. 3 from transforms


def _error_transform(d_um: np.ndarray, eps_urad: np.ndarray) -> np.ndarray:
    """4x4 error matrix of one axis: rotation by eps (exact), translation d (mm)."""
    m = np.eye(4)
    m[:3, :3] = Rotation.from_rotvec(eps_urad * 1e-6).as_matrix()
    m[:3, 3] = d_um * 1e-3
    return m


def _translation(v_mm: np.ndarray) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = v_mm
    return m


def chain_error(t: Table, pos_mm: np.ndarray, dir_state: np.ndarray | None = None,
                temp_c: np.ndarray | None = None) -> np.ndarray:
    """Tool relative to workpiece from the full (non-linearised) kinematic chain.

    Workpiece side bed -> Y carriage -> X table, tool side bed -> Z ram -> tool
    (notes.md §1). Each axis: ideal translation by its position relative to the
    reference point, then its error matrix; squareness enters as
    d_x(y) - y S_xy, d_x(z) - z S_xz, d_y(z) - z S_yz. The tool point expressed
    in the workpiece frame is

        P = (T_X E_X)^-1 (T_Y E_Y)^-1 (T_Z E_Z) t

    and the error is P minus its ideal value (-x, -y, z) + t, in um.
    """
    out = np.zeros((len(pos_mm), 3))
    ref = np.array(t.reference_mm)
    tool = np.array(list(t.tool_offset_mm) + [1.0])
    s_xy, s_xz, s_yz = (v * 1e-6 for v in t.squareness_urad)
    for i, p in enumerate(pos_mm):
        rel = p - ref
        E = {}
        for j, a in enumerate(AXES):
            d = np.array([independent_term(t.axes[a], k, p[j]) for k in ("dx", "dy", "dz")])
            e = np.array([independent_term(t.axes[a], k, p[j]) for k in ("ex", "ey", "ez")])
            ds = None if dir_state is None else dir_state[i:i + 1, j]
            tc = None if temp_c is None else temp_c[i:i + 1, j]
            d[j] += extra_values(t, a, p[j:j + 1], ds, tc)[0]
            E[a] = (d, e)
        dY, eY = E["Y"]
        dY = dY.copy()
        dY[0] -= rel[1] * s_xy * 1e3                       # mm * rad -> um
        dZ, eZ = E["Z"]
        dZ = dZ.copy()
        dZ[0] -= rel[2] * s_xz * 1e3
        dZ[1] -= rel[2] * s_yz * 1e3
        TX = _translation([rel[0], 0, 0]) @ _error_transform(*E["X"])
        TY = _translation([0, rel[1], 0]) @ _error_transform(dY, eY)
        TZ = _translation([0, 0, rel[2]]) @ _error_transform(dZ, eZ)
        P = np.linalg.inv(TX) @ np.linalg.inv(TY) @ TZ @ tool
        ideal = np.array([-rel[0], -rel[1], rel[2]]) + tool[:3]
        out[i] = (P[:3] - ideal) * 1e3
    return out


def _scaled(t: Table, k: float) -> Table:
    s = Table(axes={}, reference_mm=t.reference_mm, tool_offset_mm=t.tool_offset_mm,
              squareness_urad=tuple(v * k for v in t.squareness_urad))
    for a in AXES:
        ax = t.axes[a]
        s.axes[a] = AxisTable(ax.travel_mm, ax.trend_degree, ax.blocks,
                              {n: c * k for n, c in ax.coef.items()})
    return s


def _positions(t: Table, n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    lo = np.array([t.axes[a].travel_mm[0] for a in AXES])
    hi = np.array([t.axes[a].travel_mm[1] for a in AXES])
    return np.vstack([lo, hi, rng.uniform(lo - 50, hi + 50, size=(n, 3))])


def test_eq3_matches_exact_chain_to_second_order() -> None:
    t = quantize(paper_table())                       # terms ~10 um, ~25 urad, 500 mm lever
    pos = _positions(t, 40, 2)
    lin = spatial_error(t, pos)
    exact = chain_error(t, pos)
    diff = np.abs(lin - exact).max()
    assert np.abs(exact).max() > 5.0                  # the comparison is not trivial
    assert diff < 1e-3, diff                          # only second-order products differ
    # and they are second order: 10x the errors gives ~100x the difference
    t10 = _scaled(t, 10.0)
    diff10 = np.abs(spatial_error(t10, pos) - chain_error(t10, pos)).max()
    assert 50 < diff10 / diff < 200, diff10 / diff


def test_eq3_each_term_enters_with_its_sign() -> None:
    """One constant term at a time: the linearised model and the chain agree, so a
    wrong sign or lever arm anywhere would show as a first-order difference."""
    base = paper_table()
    pos = np.array([[400.0, -50.0, -20.0], [20.0, -390.0, -280.0]])
    for a in AXES:
        for term in TERMS:
            t = Table(axes={b: AxisTable(base.axes[b].travel_mm, 0) for b in AXES},
                      reference_mm=base.reference_mm, tool_offset_mm=(15.0, -25.0, 150.0))
            t.axes[a].coef[term] = np.array([30.0])          # 30 um or 30 urad
            lin, exact = spatial_error(t, pos), chain_error(t, pos)
            assert np.abs(lin).max() > 0.1, (a, term)
            assert np.abs(lin - exact).max() < 1e-3, (a, term)   # eps^2 L ~ 2e-4 um
    for k in range(3):
        sq = [0.0, 0.0, 0.0]
        sq[k] = 40.0
        t = Table(axes={b: AxisTable(base.axes[b].travel_mm) for b in AXES},
                  reference_mm=base.reference_mm, squareness_urad=tuple(sq))
        lin, exact = spatial_error(t, pos), chain_error(t, pos)
        assert np.abs(lin).max() > 1.0
        assert np.abs(lin - exact).max() < 1e-3


def test_eq3_dz_uses_dz_of_z() -> None:
    """The paper's typo (d_y(z) in dZ) is corrected."""
    t = Table(axes={a: AxisTable((-500.0, 500.0), 0) for a in AXES}, reference_mm=(0, 0, 0))
    t.axes["Z"].coef["dz"] = np.array([7.0])
    t.axes["Z"].coef["dy"] = np.array([3.0])
    e = spatial_error(t, np.array([[0.0, 0.0, 100.0]]))[0]
    np.testing.assert_allclose(e, [0.0, 3.0, 7.0])


def test_full_table_chain_agreement_scales() -> None:
    """Large terms (200 um, 500 urad, 1 m levers): the difference stays within the
    size of the dropped products (eps^2 L + eps d)."""
    t = quantize(full_table(np.random.default_rng(7)))
    pos = _positions(t, 15, 3)
    ds = np.ones_like(pos)
    tc = np.full_like(pos, 30.0)
    diff = np.abs(spatial_error(t, pos, ds, tc) - chain_error(t, pos, ds, tc)).max()
    bound = (3 * 500e-6) ** 2 * 1.5e6 + 3 * 500e-6 * 800   # um
    assert diff < bound


# --------------------------------------------------------------------------- clamping, backlash, thermal


def _one_axis_table(**kw) -> Table:
    axes = {a: AxisTable((0.0, 100.0)) for a in AXES}
    for k, v in kw.items():
        setattr(axes["X"], k, v)
    for a in AXES:
        axes[a].backlash_takeup_mm = 0.1 if kw.get("backlash_um") else 0.0
    return Table(axes=axes, reference_mm=(50.0, 50.0, 50.0))


def test_end_value_hold_outside_travel() -> None:
    t = quantize(paper_table())
    for a in AXES:
        lo, hi = t.axes[a].travel_mm
        for term in TERMS:
            v = term_values(t, a, term, [lo - 100.0, lo, hi, hi + 250.0])
            assert v[0] == v[1] and v[2] == v[3]
    # fitted terms hold, the Abbe lever arms (unclamped x, y, z) keep growing
    t = Table(axes={a: AxisTable((0.0, 100.0), 0) for a in AXES}, reference_mm=(0, 0, 0))
    t.axes["X"].coef["ez"] = np.array([100.0])            # 100 urad yaw of X
    t.axes["X"].coef["dy"] = np.array([2.0])
    e = spatial_error(t, np.array([[100.0, 0, 0], [300.0, 0, 0]]))
    np.testing.assert_allclose(e[:, 1], [-2.0 + 10.0, -2.0 + 30.0])   # x * e_xz, um
    assert out_of_travel(t, [[100.0, 0, 0], [100.0001, 0, 0], [0, -1e-9, 0]]).tolist() == \
        [False, True, True]


@pytest.mark.parametrize("axis,sign", [("X", -1.0), ("Y", -1.0), ("Z", 1.0)])
def test_backlash_on_own_positioning_term(axis: str, sign: float) -> None:
    axes = {a: AxisTable((0.0, 100.0), backlash_takeup_mm=0.1) for a in AXES}
    axes[axis].backlash_um = 8.0
    t = Table(axes=axes, reference_mm=(50.0, 50.0, 50.0))
    j = AXES.index(axis)
    pos = np.array([[20.0, 30.0, 40.0]] * 4 + [[500.0, -500.0, 900.0]])
    ds = np.zeros((5, 3))
    ds[:, j] = [1.0, -1.0, 0.5, 0.0, 1.0]
    e = spatial_error(t, pos, ds)
    want = np.zeros((5, 3))
    want[:, j] = sign * ds[:, j] * 8.0 / 2          # s B / 2 on d_j(j), Eq. 3 sign
    np.testing.assert_allclose(e, want, atol=1e-12)
    # reversal: (+ approach) - (- approach) of the positioning term is B
    assert sign * (e[0, j] - e[1, j]) == pytest.approx(8.0)
    # no direction state: no backlash
    np.testing.assert_array_equal(spatial_error(t, pos), np.zeros((5, 3)))


def test_thermal_on_own_positioning_term() -> None:
    axes = {a: AxisTable((-100.0, 100.0)) for a in AXES}
    axes["Y"].thermal_expansion_ppm_per_k = 12.0
    axes["Y"].thermal_offset_um_per_k = 0.5
    axes["Y"].thermal_tref_c = 20.0
    axes["Y"].coef["dy"] = np.array([3.0])
    axes["Y"].trend_degree = 0
    t = Table(axes=axes, reference_mm=(0.0, 10.0, 0.0))
    pos = np.array([[0.0, 110.0, 0.0], [0.0, 1010.0, 0.0], [0.0, 110.0, 0.0]])
    temp = np.array([[99.0, 30.0, 99.0], [20.0, 30.0, 20.0], [20.0, 20.0, 20.0]])
    e = spatial_error(t, pos, temp_c=temp)
    # d_y(y) = 3 + 12e-6/K * 10 K * (y - 10 mm) * 1000 um/mm + 0.5 um/K * 10 K; dY = -d_y(y)
    np.testing.assert_allclose(e[:, 1], [-(3 + 12.0 + 5.0), -(3 + 120.0 + 5.0), -3.0])
    np.testing.assert_allclose(e[:, [0, 2]], 0.0)     # other axes' temperatures unused
    np.testing.assert_allclose(spatial_error(t, pos)[:, 1], -3.0)   # no temperature given
