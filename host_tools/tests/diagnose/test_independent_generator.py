"""The independent case generator (cases/independent) is itself right: its kinematic
chain linearises to the documented Eq. 3, its take-up laws, servo models and
instruments do what its docstrings say, and its files pass the product's readers.
(It is an evaluation tool: a wrong generator would make the evaluation meaningless.)"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cases.independent import files
from cases.independent.chain import tool_error_um
from cases.independent.measure import CirclePlan, measure_circle
from cases.independent.physics import (
    AXES,
    TERM_NAMES,
    LostMotion,
    Servo,
    SmoothTerm,
    lost_motion_state,
    random_machine,
)
from cases.independent.suite import build, suite


def _polynomial_machine(seed: int):
    """A random machine whose terms are Legendre polynomials of degree <= 5 (exactly
    representable by the model's degree-7 Chebyshev basis)."""
    rng = np.random.default_rng(seed)
    m = random_machine(rng)
    for (a, t), term in m.terms.items():
        term.sine_amp = 0.0
        j = AXES.index(a)
        ref = m.reference[j]
        term.a0 = term.a1 = 0.0
        if t[0] == "d" and t != {"X": "dx", "Y": "dy", "Z": "dz"}[a]:
            lo, hi = term.travel
            g = np.linspace(lo, hi, 801)
            term.a1 = float(np.polyfit(g, term.raw(g), 1)[0])
        term.a0 = float(term.raw(np.array([ref]))[0] - term.a1 * ref)
    return m, rng


def test_chain_linearises_to_eq3_of_the_reference() -> None:
    from abbe.model.reference import spatial_error
    m, rng = _polynomial_machine(3)
    m.effects.squareness_urad = (25.0, -12.0, 8.0)
    m.declared_tool_mm = (10.0, -20.0, 120.0)
    model = files.fit_model(m, rng, m.effects.squareness_urad, noise_um=0.0)
    pos = np.column_stack([rng.uniform(*m.travel[a], 200) for a in AXES])
    e_chain = tool_error_um(m, pos)
    e_ref = spatial_error(model, pos)
    # second-order terms of the exact chain: |eps|^2 L, |eps| |d|: well below 1e-3 um here
    assert np.max(np.abs(e_chain - e_ref)) < 2e-3
    assert np.max(np.abs(e_ref)) > 1.0      # and the comparison is not trivial


@pytest.mark.parametrize("shape", ["linear", "exp", "smooth", "play"])
def test_takeup_laws(shape: str) -> None:
    lm = LostMotion(6.0, shape, 0.2, 0.05)
    L_up = 0.006 if shape == "play" else 0.2
    p = np.concatenate([np.linspace(0, 1, 2001), np.linspace(1, 0, 2001)[1:]])
    s = lost_motion_state(p, lm, -1.0)
    assert s[0] == -1.0 and s[2000] == pytest.approx(1.0, abs=0.06)
    i_half = int(np.argmin(np.abs(p[:2001] - 0.5 * L_up)))
    if shape in ("linear", "smooth", "play"):
        assert s[i_half] == pytest.approx(0.0, abs=0.05)        # half way at half the take-up
    # the reversal to - uses the other (shorter) take-up
    d_down = 0.05 if shape != "play" else 0.006
    k = 2000 + int(round(1.5 * d_down / (1.0 / 2000)))
    assert s[k] < -0.95 if shape != "exp" else s[k] < -0.9


def test_first_order_servo_reaches_the_steady_state_amplitude() -> None:
    rng = np.random.default_rng(0)
    m = random_machine(rng)
    for t in m.terms.values():
        t.leg[:] = 0.0
        t.sine_amp = 0.0
        t.a0 = t.a1 = 0.0
    R, F, tau = 100.0, 3000.0, 0.03
    m.effects.servo = Servo("first_order", (tau * 1e3, 0.0, 0.0))
    c = tuple(0.5 * (lo + hi) for lo, hi in (m.travel[a] for a in AXES))
    plan = CirclePlan("c", "XY", c, R, F, step_deg=1.0, arc_deg=45.0, noise_um=0.0)
    rec = measure_circle(m, plan, 0.0, rng)
    w = F / 60.0 / R
    th = np.radians(rec.angle_deg)
    ok = (rec.angle_deg >= 0) & (rec.angle_deg < 360) & (rec.direction == "ccw")
    # steady state of tau x' = u - x for u = R cos(w t): amplitude g, phase lag phi
    g, phi = 1.0 / np.sqrt(1.0 + (w * tau) ** 2), np.arctan(w * tau)
    exact = (np.hypot(R * g * np.cos(th[ok] - phi), R * np.sin(th[ok])) - R) * 1e3
    A = np.column_stack([np.ones(ok.sum()), np.cos(2 * th[ok]), np.sin(2 * th[ok])])
    coef = np.linalg.lstsq(A, rec.radial_um[ok], rcond=None)[0]
    expect = np.linalg.lstsq(A, exact, rcond=None)[0][1]
    assert np.max(np.abs(rec.radial_um[ok] - exact)) < 0.05   # the start-up transient has died out
    assert coef[1] == pytest.approx(expect, rel=0.03)


def test_every_case_writes_files_the_readers_accept(tmp_path: Path) -> None:
    from abbe.diagnose.checks import ballbar_check, laser_check
    from abbe.diagnose.run import load_model
    from abbe.formats.ess_dat import read_dat
    from abbe.formats.machine import load_machine
    for c in [x for x in suite() if x.name in ("tool_offset", "thermal_lin", "servo_two_feeds",
                                               "pos_ess_like")]:
        b = build(c, tmp_path / c.name)
        if b.dat_file is not None:
            d = read_dat(b.dat_file)
            assert d.up_um.shape == (5, d.targets_mm.size)
            continue
        mach = load_machine(b.machine_file)
        tab = load_model(b.model_file)
        assert set(tab.axes["X"].coef) == set(TERM_NAMES)
        for n in mach.ballbar:
            ck = ballbar_check(mach, n, tab.reference_mm)
            assert ck.n > 100
        for a in mach.laser:
            assert laser_check(mach, a, tab.reference_mm).n_runs >= 4
        if c.name == "thermal_lin":
            assert any(ballbar_check(mach, n, tab.reference_mm).all_temp is not None
                       for n in mach.ballbar)
        if c.name == "servo_two_feeds":
            feeds = {mach.ballbar[n].feed_mm_min for n in mach.ballbar}
            assert len(feeds) >= 2
        if c.name == "tool_offset":
            zs = {mach.ballbar[n].center_mm[2] for n in mach.ballbar if mach.ballbar[n].plane == "XY"}
            assert len(zs) >= 2


def test_smooth_term_is_zero_at_reference_and_has_no_slope_if_straightness() -> None:
    rng = np.random.default_rng(7)
    m = random_machine(rng)
    for (a, t), term in m.terms.items():
        j = AXES.index(a)
        assert abs(float(term(np.array([m.reference[j]]))[0])) < 1e-9
        if t[0] == "d" and t != {"X": "dx", "Y": "dy", "Z": "dz"}[a]:
            g = np.linspace(*term.travel, 801)
            assert abs(np.polyfit(g, term(g), 1)[0]) < 1e-9
    assert isinstance(next(iter(m.terms.values())), SmoothTerm)


def test_generator_is_independent_of_the_simulator() -> None:
    """cases/independent imports neither abbe.sim nor cases.hidden_effects (nor the
    diagnosis outside the suite's entry points): it must not share effect code with
    what it evaluates."""
    import ast
    root = Path(__file__).resolve().parents[2] / "cases" / "independent"
    allowed = {"abbe.model.table", "abbe.formats.blob", "abbe.diagnose.results",
               "abbe.diagnose.run"}
    for f in sorted(root.glob("*.py")):
        tree = ast.parse(f.read_text())
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            for n in names:
                assert not n.startswith(("abbe.sim", "cases.hidden_effects", "cases.synthetic")), (f, n)
                if n.startswith("abbe"):
                    assert n in allowed, (f.name, n)


def test_issue_24_mechanisms(tmp_path) -> None:
    """The extended cases (evaluation only): a drift that rises and falls in time, and a
    short Z whose roll varies by tens of urad, lasered; ``abbe fit`` makes a table of
    every such campaign (issue 24: the roll once made it refuse)."""
    import contextlib
    import io
    import json
    import tomllib

    from abbe.cli.entry import main as cli_main
    from cases.independent.physics import Thermal

    th = Thermal(axis="X", profile="rise_fall", t0_c=20.0, rise_k=3.0, tau_h=1.0)
    T = th.temperature(np.array([0.0, 1800.0, 3600.0, 7200.0, 14400.0]))
    assert T[0] == 20.0 and abs(T[2] - 23.0) < 1e-12 and T[1] < T[2] and T[3] < T[2] and T[4] < T[3]
    cases = [c for c in suite() if c.name.startswith("x_roll_short_z")]
    assert len(cases) == 3
    for c in cases:
        b = build(c, tmp_path / c.name)
        text = b.machine_file.read_text()
        assert "[laser.Z]" in text
        lo, hi = tomllib.loads(text)["axes"]["Z"]["travel_mm"]
        assert hi - lo <= 200.0
        err = io.StringIO()
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(err):
            rc = cli_main(["fit", str(b.machine_file), "-o", str(tmp_path / c.name / "fit"),
                           "--no-report", "--no-clib-check", "-q"])
        assert rc == 0, (c.name, err.getvalue())
        model = json.loads((tmp_path / c.name / "fit" / "model.json").read_text())
        roll = model["axes"]["Z"]["terms"]["ez"]
        assert roll is not None
