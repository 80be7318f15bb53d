"""The kinematic chain model: the trunnions are two instances of it with the same bits,
every kind's linearisation is second-order close to its exact form, a tool-side rotary
axis moves the tool tip (hand-computed cases), the direction sign, and the model against
the independent generator (cases/chain_generator.py, written without abbe's code)."""

from __future__ import annotations


import numpy as np
import pytest

from abbe.formats.machine import load_machine
from abbe.model import five_axis as F
from abbe.model.chain import (ChainAxis, KinematicChain, nominal_joints, tool_error_exact,
                              tool_error_linear, trunnion_chain, workpiece_transform)
from abbe.model.five_axis import FiveAxisErrors, TrunnionGeometry, linear_axis_errors, rotvec
from abbe.sim.chain import VirtualChainMachine, random_location_errors
from abbe.sim.five_axis import random_errors

from cases import chain_generator as gen
from cases.chain_suite import CHAINS

CHAIN_FILES = sorted(CHAINS.glob("*.toml"))
TRUNNIONS = [TrunnionGeometry("xyzac-trt", (100.0, 50.0, -300.0), (0.0, 20.0, -80.0), 120.0,
                              {"A": (-110.0, 110.0), "C": (-360.0, 360.0)}),
             TrunnionGeometry("xyzbc-trt", (-40.0, 10.0, -250.0), (15.0, 0.0, -60.0), 90.0,
                              {"B": (-110.0, 110.0), "C": (0.0, 360.0)})]
LIN = (-500.0, 500.0)


def _chains() -> list[KinematicChain]:
    return [load_machine(f).extra["chain"] for f in CHAIN_FILES]


def test_the_three_new_kinds_are_there() -> None:
    assert sorted(c.kind for c in _chains()) == ["head-head", "head-table", "table-table"]


def _old_tool_error_exact(g: TrunnionGeometry, errs: FiveAxisErrors, q: np.ndarray,
                          ang: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The trunnion model's exact error as it was before the chain (commit 271b02c)."""
    tilt, table = g.rotaries
    Ta = F.axis_transform(g, errs, tilt, ang[:, 0]) @ F.axis_transform(g, errs, table, ang[:, 1])
    Tn = F.axis_transform(g, None, tilt, ang[:, 0]) @ F.axis_transform(g, None, table, ang[:, 1])
    M = Ta @ np.linalg.inv(Tn)
    dl, rl = linear_axis_errors(g, errs, q)
    moved = np.einsum("nij,nj->ni", M[:, :3, :3], q) + M[:, :3, 3]
    Rrel = F.small_rotation(rl * 1e-6) @ np.transpose(M[:, :3, :3], (0, 2, 1))
    return (q + dl * 1e-3 - moved) * 1e3, rotvec(Rrel) * 1e6


@pytest.mark.parametrize("g", TRUNNIONS, ids=lambda g: g.kind)
def test_trunnions_are_chain_instances_bit_for_bit(g: TrunnionGeometry) -> None:
    rng = np.random.default_rng(5)
    e = random_errors(g, rng, motion_um=2.0, motion_urad=5.0)
    e.squareness = (3.0, -4.0, 5.0)
    ch = trunnion_chain(g)
    assert ch.kind == "table-table" and ch.workpiece_side == ("C", g.tilt)
    ang = np.column_stack([rng.uniform(-100, 100, 40), rng.uniform(0, 360, 40)])
    w = rng.uniform(-100, 100, (40, 3))
    tilt = g.tilt
    T_old = F.axis_transform(g, e, tilt, ang[:, 0]) @ F.axis_transform(g, e, "C", ang[:, 1])
    assert np.array_equal(workpiece_transform(ch, e, ang), T_old)
    assert np.array_equal(F.table_transform(g, e, ang), T_old)
    q = F.nominal_joints(g, w, ang)
    Tn = F.axis_transform(g, None, tilt, ang[:, 0]) @ F.axis_transform(g, None, "C", ang[:, 1])
    assert np.array_equal(q, np.einsum("nij,nj->ni", Tn[:, :3, :3], w) + Tn[:, :3, 3])
    old = _old_tool_error_exact(g, e, q, ang)
    new = F.tool_error_exact(g, e, q, ang)
    assert all(np.array_equal(a, b) for a, b in zip(old, new))
    lin_old = F.tool_error_linear(g, e, q, ang)
    lin_new = tool_error_linear(ch, e, q, ang)
    assert max(float(np.abs(a - b).max()) for a, b in zip(lin_old, lin_new)) < 1e-9


@pytest.mark.parametrize("i", range(3))
def test_linearisation_is_second_order_for_every_kind(i: int) -> None:
    ch = _chains()[i]
    rng = np.random.default_rng(11 + i)
    e = random_location_errors(ch, rng, 100.0, 100.0)
    ang = np.column_stack([rng.uniform(-80, 80, 300), rng.uniform(-80, 80, 300)])
    w = rng.uniform(-150, 150, (300, 3))
    q = nominal_joints(ch, w, ang, (0.0, 0.0, -50.0))
    pe, re = tool_error_exact(ch, e, q, ang, (0.0, 0.0, -50.0))
    pl, rl = tool_error_linear(ch, e, q, ang, (0.0, 0.0, -50.0))
    big = max(float(np.abs(pe - pl).max()), 1e-12)
    assert float(np.abs(pe).max()) > 50.0  # the errors are seen at all
    assert big < 0.5 and float(np.abs(re - rl).max()) < 0.2
    half = FiveAxisErrors({k: v / 2 for k, v in e.location.items()})
    pe2, _ = tool_error_exact(ch, half, q, ang, (0.0, 0.0, -50.0))
    pl2, _ = tool_error_linear(ch, half, q, ang, (0.0, 0.0, -50.0))
    ratio = big / float(np.abs(pe2 - pl2).max())
    assert 3.0 < ratio < 5.0  # halving the errors quarters the difference


def _head_head() -> KinematicChain:
    return KinematicChain("hh", (ChainAxis("X", 1, (0, 0, 0), LIN), ChainAxis("Y", 1, (0, 0, 0), LIN),
                                 ChainAxis("Z", 1, (0, 0, 0), LIN),
                                 ChainAxis("C", 1, (0.0, 0.0, 200.0), (-360.0, 360.0)),
                                 ChainAxis("B", 1, (0.0, 0.0, 200.0), (-120.0, 120.0))))


def test_a_tool_side_axis_carries_the_tool_tip() -> None:
    """B's line 10 um off along +X: at B = 90 deg the tip turns about the shifted line,
    (I - R_y(90)) (10, 0, 0) = (10, 0, 10) um; at B = 0 nothing moves."""
    ch = _head_head()
    e = FiveAxisErrors({"EX0B": 10.0})
    ang = np.array([[0.0, 0.0], [90.0, 0.0]])  # (B, C)
    q = nominal_joints(ch, np.zeros((2, 3)), ang)
    assert np.allclose(q[1], [200.0, 0.0, -200.0])  # the tip swung 200 mm to -X
    pos, rot = tool_error_exact(ch, e, q, ang)
    assert np.allclose(pos[0], 0.0, atol=1e-9)
    assert np.allclose(pos[1], [10.0, 0.0, 10.0], atol=1e-6)
    assert np.allclose(rot, 0.0, atol=1e-9)
    # a longer stylus turns with the head too: EB0B = 100 urad moves its tip by 100 urad
    # times its distance from the pivot (200 + 50 mm) = 25 um along -X at B = 0
    pos, rot = tool_error_exact(ch, FiveAxisErrors({"EB0B": 100.0}), q[:1], ang[:1],
                                (0.0, 0.0, -50.0))
    assert np.allclose(pos[0], [-25.0, 0.0, 0.0], atol=2e-3)  # 1.25e-3 um: second order
    assert np.allclose(rot[0], [0.0, 100.0, 0.0], atol=1e-6)


def test_head_head_c_zero_and_b_tilt_about_z_are_one_error() -> None:
    """EC0C turns B's line about Z through C's pivot: for the tool tip that is EC0B."""
    ch = _head_head()
    rng = np.random.default_rng(2)
    ang = np.column_stack([rng.uniform(-100, 100, 50), rng.uniform(0, 360, 50)])
    q = rng.uniform(-100, 100, (50, 3))
    a, _ = tool_error_exact(ch, FiveAxisErrors({"EC0C": 80.0}), q, ang, (0.0, 0.0, -30.0))
    b, _ = tool_error_exact(ch, FiveAxisErrors({"EC0B": 80.0}), q, ang, (0.0, 0.0, -30.0))
    assert float(np.abs(a).max()) > 5.0 and np.allclose(a, b, atol=1e-6)


def test_direction_sign_turns_the_axis_the_other_way() -> None:
    plus = _head_head()
    minus = KinematicChain("hm", plus.axes[:4] + (ChainAxis("B", -1, (0.0, 0.0, 200.0),
                                                            (-120.0, 120.0)),))
    w = np.array([[10.0, 20.0, 30.0]])
    a = nominal_joints(plus, w, np.array([[-30.0, 40.0]]))
    b = nominal_joints(minus, w, np.array([[30.0, 40.0]]))
    assert np.allclose(a, b, atol=1e-12) and not np.allclose(a, w)


@pytest.mark.parametrize("i", range(3))
def test_model_agrees_with_the_independent_generator(i: int) -> None:
    """Probe centres and R-test readings from abbe's virtual machine and from the
    independent generator (Rodrigues rotations about the actual lines) agree to 0.002 um
    (their difference is the second order of tilts: 100 urad^2 x 200 mm)."""
    f = CHAIN_FILES[i]
    ch = load_machine(f).extra["chain"]
    gch = gen.read_chain(f)
    rng = np.random.default_rng(21 + i)
    truth = gen.random_location(gch, rng)
    ang = gen.grid(gch)
    off = np.array([0.03, -0.02, 0.01])
    vm = VirtualChainMachine(ch, FiveAxisErrors(dict(truth)), tuple(off))
    for tip in ((0.0, 0.0, 0.0), (0.0, 0.0, -100.0)):
        s = np.array([50.0, 20.0, 30.0])
        a = vm.probe_centres(tuple(s), ang, tip)
        b = gen.probe_centres(gch, truth, s, off, np.array(tip), ang, 0.0, rng)
        assert float(np.abs(a - b).max()) * 1e3 < 0.002
        ideal = VirtualChainMachine(ch, FiveAxisErrors()).probe_centres(tuple(s), ang, tip)
        assert float(np.abs(a - ideal).max()) * 1e3 > 5.0  # the errors are seen at all
        ra = vm.rtest(tuple(s), ang, tip)
        rb = gen.rtest_readings(gch, truth, s, off, np.array(tip), ang, 0.0, rng)
        assert float(np.abs(ra).max()) > 5.0
        assert float(np.abs(ra - rb).max()) < 0.002


def test_5axiskins_forward_kinematics_is_its_chain() -> None:
    """LinuxCNC 5axiskins (its source): tip = joints + (0, 0, L) + L (sin B cos C,
    sin B sin C, -cos B), L = pivot-length: the head-head chain file's nominal tip."""
    from abbe.model.chain import tool_tip

    ch = load_machine(CHAINS / "head-head-5axiskins.toml").extra["chain"]
    L = ch.axis("B").pivot_mm[2]
    rng = np.random.default_rng(4)
    q = rng.uniform(-200, 200, (30, 3))
    b, c = rng.uniform(-120, 120, 30), rng.uniform(-360, 360, 30)
    br, cr = np.deg2rad(b), np.deg2rad(c)
    lcnc = q + np.column_stack([L * np.sin(br) * np.cos(cr), L * np.sin(br) * np.sin(cr),
                                L - L * np.cos(br)])
    assert np.allclose(tool_tip(ch, None, q, np.column_stack([b, c])), lcnc, atol=1e-9)


def test_maxkins_forward_kinematics_is_its_chain() -> None:
    """LinuxCNC maxkins (its source): world = Rz(C) (jx, jy) + (L sin B, 0, L - L cos B)
    with jz added to z: the head-table chain file's workpiece point, where maxkins is
    exact (C = 0 with any B; any C with L sin B = 0, the max5 sample's pivot-length 0)."""
    from abbe.model.chain import tool_tip

    ch = load_machine(CHAINS / "head-table-maxkins.toml").extra["chain"]
    L = ch.axis("B").pivot_mm[2]
    rng = np.random.default_rng(5)
    q = rng.uniform(-200, 200, (30, 3))
    for b, c in ((rng.uniform(-90, 90, 30), np.zeros(30)), (np.zeros(30), rng.uniform(-360, 360, 30))):
        br, cr = np.deg2rad(b), np.deg2rad(c)
        xy = np.column_stack([np.cos(cr) * q[:, 0] - np.sin(cr) * q[:, 1],
                              np.sin(cr) * q[:, 0] + np.cos(cr) * q[:, 1]])
        world = np.column_stack([xy[:, 0] + L * np.sin(br), xy[:, 1],
                                 q[:, 2] - L * np.cos(br) + L])
        ang = np.column_stack([b, c])
        tip = tool_tip(ch, None, q, ang)
        T = workpiece_transform(ch, None, ang)
        w = np.einsum("nji,nj->ni", T[:, :3, :3], tip - T[:, :3, 3])
        assert np.allclose(w, world, atol=1e-9)
