"""The LinuxCNC kinds test's campaign (port/linuxcnc/tests/kinds_campaign.py): the
independent generator's true machine must be kinds_sim.py's, and the files it writes
must be a campaign `abbe fit` reads (the LinuxCNC run itself is port/linuxcnc/tests/run.sh)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from abbe.formats.machine import load_machine

TESTS = Path(__file__).resolve().parents[3] / "port" / "linuxcnc" / "tests"
sys.path.insert(0, str(TESTS))

import kinds_campaign as camp  # noqa: E402
import kinds_sim as ks  # noqa: E402

from cases import chain_generator as gen  # noqa: E402


@pytest.mark.parametrize("name", sorted(ks.CASES))
def test_the_generator_measures_kinds_sims_true_machine(tmp_path: Path, name: str) -> None:
    mf = camp.write_campaign(name, tmp_path)
    machine = load_machine(mf)
    plans = machine.extra["chain_plans"]
    tool_side = bool(machine.extra["chain"].tool_side)
    assert sorted(plans.probing) == (["S1", "S2", "S3"] if tool_side else ["S1", "S2"])
    assert sorted(plans.rtest) == ["R1"]
    case = ks.CASES[name]
    gch = gen.read_chain(mf)
    assert camp.check_truth(case, gch, camp.true_location(case, gch)) <= camp.TRUTH_TOL_MM


@pytest.mark.parametrize("name", ["max5", "xyzab-tdr"])
def test_the_truth_check_fails_without_the_zero_sign_change(name: str, tmp_path: Path) -> None:
    """kinds_sim writes a workpiece-side -1 axis' zero about the turned direction: handing
    it to the generator unchanged is another machine, and check_truth says so."""
    (tmp_path / "m.toml").write_text(camp.chain_toml(name))
    case = ks.CASES[name]
    gch = gen.read_chain(tmp_path / "m.toml")
    with pytest.raises(AssertionError, match="not kinds_sim's"):
        camp.check_truth(case, gch, dict(case.errors))
    loc = camp.true_location(case, gch)
    assert any(np.sign(loc[n]) != np.sign(v) for n, v in case.errors.items())
