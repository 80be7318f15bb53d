"""The five-axis model: the linearisation derived symbolically (sympy) and checked against
the exact homogeneous transforms; its error bound over a travel; the TCP round trip."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from abbe.model.five_axis import (LOCATION_ERRORS, MOTION_COMPONENTS, FiveAxisErrors,
                                  TrunnionGeometry, axis_twist, linearisation_bound,
                                  lowest_harmonic, nominal_joints, table_transform,
                                  tool_error_exact, tool_error_linear)

GEOMS = [TrunnionGeometry("xyzac-trt", (100.0, 50.0, -300.0), (0.0, 20.0, -80.0), 120.0,
                          {"A": (-110.0, 110.0), "C": (-360.0, 360.0)}),
         TrunnionGeometry("xyzbc-trt", (-40.0, 10.0, -250.0), (15.0, 0.0, -60.0), 90.0,
                          {"B": (-110.0, 110.0), "C": (0.0, 360.0)})]


def _random_errors(g: TrunnionGeometry, rng: np.random.Generator, size: float = 30.0,
                   motions: bool = True) -> FiveAxisErrors:
    loc = {n: float(rng.normal(0, size)) for ax in g.rotaries for n in LOCATION_ERRORS[ax]}
    mot = {}
    if motions:
        for ax in g.rotaries:
            for c in MOTION_COMPONENTS:
                v = rng.normal(0, 2.0, 6)
                v[: 2 * (lowest_harmonic(ax, c) - 1)] = 0.0
                mot[(ax, c)] = v
    return FiveAxisErrors(loc, mot, tuple(rng.normal(0, 10.0, 3)))


def _sym_rot(axis: str, t):
    c, s = sp.cos(t), sp.sin(t)
    if axis == "A":
        return sp.Matrix([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "B":
        return sp.Matrix([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return sp.Matrix([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _sym_small(v):
    return _sym_rot("A", v[0]) * _sym_rot("B", v[1]) * _sym_rot("C", v[2])


@pytest.mark.parametrize("axis", ["A", "B", "C"])
def test_axis_twist_is_the_derivative_of_the_exact_transform(axis: str) -> None:
    """d/de of Tr(P) D(e) E(e) Rot(t + e E0) D(e)^-1 Tr(-P) u at e = 0 equals
    (I - R) delta + (phi - R phi + E0 k + r) x (R u) + t, symbolically."""
    e, th, E0 = sp.symbols("e theta E0", real=True)
    dl = sp.Matrix(sp.symbols("d0:3", real=True))
    ph = sp.Matrix(sp.symbols("p0:3", real=True))
    tm = sp.Matrix(sp.symbols("t0:3", real=True))
    rm = sp.Matrix(sp.symbols("r0:3", real=True))
    u = sp.Matrix(sp.symbols("u0:3", real=True))  # the point relative to the pivot
    R = _sym_rot(axis, th)
    Re = _sym_rot(axis, th + e * E0)
    # child -> carrying frame, relative to the pivot: D E Rot D^-1 applied to u
    Dinv_u = _sym_small(e * ph).T * (u - e * dl)
    moved = e * dl + _sym_small(e * ph) * (e * tm + _sym_small(e * rm) * (Re * Dinv_u))
    deriv = sp.diff(moved, e).subs(e, 0)
    k = sp.Matrix({"A": [1, 0, 0], "B": [0, 1, 0], "C": [0, 0, 1]}[axis])
    w = ph - R * ph + E0 * k + rm
    formula = (sp.eye(3) - R) * dl + w.cross(R * u) + tm
    assert sp.simplify(deriv - formula) == sp.zeros(3, 1)
    # and the rotation of the child frame: d/de of D E Rot(t+eE0) D^-1 R^T = [w]x
    Rm = _sym_small(e * ph) * _sym_small(e * rm) * Re * _sym_small(e * ph).T
    dR = sp.simplify(sp.diff(Rm, e).subs(e, 0) * R.T)
    assert sp.simplify(sp.Matrix([dR[2, 1], dR[0, 2], dR[1, 0]]) - w) == sp.zeros(3, 1)
    assert sp.simplify(dR + dR.T) == sp.zeros(3, 3)


@pytest.mark.parametrize("g", GEOMS, ids=lambda g: g.kind)
def test_axis_twist_code_matches_the_symbolic_formula(g: TrunnionGeometry) -> None:
    rng = np.random.default_rng(2)
    errs = _random_errors(g, rng)
    for ax in g.rotaries:
        ang = rng.uniform(-180, 180, 20)
        pts = rng.uniform(-200, 200, (20, 3))
        d, w = axis_twist(g, errs, ax, ang, pts)
        # numeric derivative of the exact transform along the error direction
        h = 1e-4
        small = FiveAxisErrors({k: v * h for k, v in errs.location.items()},
                               {k: v * h for k, v in errs.motions.items()})
        Tn = table_transform(g, None, np.zeros((1, 2)))  # identity check of the helper
        assert np.allclose(Tn[0], np.eye(4))
        from abbe.model.five_axis import axis_transform
        Ta = axis_transform(g, small, ax, ang)
        T0 = axis_transform(g, None, ax, ang)
        # pts are positions after the nominal rotation: map back to the child frame
        child = np.einsum("nji,nj->ni", T0[:, :3, :3], pts - T0[:, :3, 3])
        moved = np.einsum("nij,nj->ni", Ta[:, :3, :3], child) + Ta[:, :3, 3]
        num = (moved - pts) * 1e3 / h
        assert np.allclose(num, d, atol=1e-3 * (1 + np.abs(d).max()))


@pytest.mark.parametrize("g", GEOMS, ids=lambda g: g.kind)
def test_linear_model_matches_exact_to_second_order(g: TrunnionGeometry) -> None:
    """Halving every error quarters |exact - linear|: the difference is second order."""
    rng = np.random.default_rng(5)
    errs = _random_errors(g, rng, size=100.0)
    ang = np.column_stack([rng.uniform(*g.travel_deg[g.tilt], 200),
                           rng.uniform(*g.travel_deg["C"], 200)])
    q = nominal_joints(g, rng.uniform(-150, 150, (200, 3)) + np.asarray(g.rot_point_mm), ang)
    diffs = []
    for f in (1.0, 0.5):
        e = FiveAxisErrors({k: v * f for k, v in errs.location.items()},
                           {k: v * f for k, v in errs.motions.items()},
                           tuple(v * f for v in errs.squareness))
        pe, re = tool_error_exact(g, e, q, ang)
        pl, rl = tool_error_linear(g, e, q, ang)
        assert np.abs(pe).max() > 10.0  # the errors are not trivially small
        diffs.append((np.abs(pe - pl).max(), np.abs(re - rl).max()))
    assert diffs[0][0] < 0.05 and diffs[0][1] < 0.05
    assert 3.0 < diffs[0][0] / diffs[1][0] < 5.0


@pytest.mark.parametrize("g", GEOMS, ids=lambda g: g.kind)
def test_linearisation_bound_over_the_travel(g: TrunnionGeometry) -> None:
    """Location errors of 100 um / 100 urad, motions 2 um / 2 urad: the linear model is
    within 0.2 um and 0.1 urad of the exact one over the travel (docs/concepts.md)."""
    errs = FiveAxisErrors({n: (100.0 if i < 2 else 100.0) * (-1) ** i
                           for ax in g.rotaries for i, n in enumerate(LOCATION_ERRORS[ax])},
                          {}, (50.0, -50.0, 50.0))
    b = linearisation_bound(g, errs, np.array([[-100.0, -100.0, -350.0], [200.0, 200.0, -150.0]]))
    assert b.n_points == 9 * 9 * 8
    assert b.position_um < 0.2 and b.orientation_urad < 0.1
    assert b.position_um > 0.0


@pytest.mark.parametrize("g", GEOMS, ids=lambda g: g.kind)
def test_nominal_kinematics_keep_the_point_on_the_workpiece(g: TrunnionGeometry) -> None:
    rng = np.random.default_rng(1)
    w = rng.uniform(-100, 100, (30, 3))
    ang = rng.uniform(-90, 90, (30, 2))
    q = nominal_joints(g, w, ang)
    T = table_transform(g, None, ang)
    back = np.einsum("nji,nj->ni", T[:, :3, :3], q - T[:, :3, 3])
    assert np.allclose(back, w, atol=1e-9)
    # The pivots are fixed points of their own axis.
    for ax in g.rotaries:
        from abbe.model.five_axis import axis_transform
        P = g.pivot(ax)
        Ta = axis_transform(g, None, ax, np.array([37.0]))[0]
        assert np.allclose(Ta[:3, :3] @ P + Ta[:3, 3], P)
