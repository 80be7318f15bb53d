"""Five-axis diagnose on ``[chain]`` machine files (head-head, head-table, dual-rotary
table): a hidden error motion or a changed location error is named from the probing /
R-test residuals with its value, and the held-out gap shrinks; a clean machine gets no
name (docs/concepts.md, "Five-axis machines: the kinematic chain", diagnose)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from abbe.analysis.five_axis.chain_fit import fit_to_json, identify_chain, setups_from_machine
from abbe.cli.entry import main
from abbe.diagnose.chain import diagnose_chain
from abbe.formats.machine import load_machine
from abbe.sim.chain import VirtualChainMachine, random_location_errors, sphere_plan, write_chain_campaign

from cases.chain_suite import CHAINS

FILES = {f.stem.split("-")[0] + "-" + f.stem.split("-")[1]: f
         for f in sorted(CHAINS.glob("*.toml"))}
LONG = (0.0, 0.0, -100.0)


def _campaign(tmp: Path, kind: str, motions: dict, seed: int = 3,
              location: dict | None = None) -> tuple[Path, VirtualChainMachine]:
    """A small plan (5 x 6 angles, two sphere heights, an R-test, a longer stylus on a
    machine with a tool-side axis) of abbe's virtual machine, written as files."""
    ch = load_machine(FILES[kind]).extra["chain"]
    e = random_location_errors(ch, np.random.default_rng(seed))
    e.location.update(location or {})
    for k, v in motions.items():
        e.motions[k] = np.asarray(v, dtype=float)
    vm = VirtualChainMachine(ch, e, (0.04, -0.03, 0.02), probe_noise_um=0.5, rtest_noise_um=0.3,
                             seed=seed)
    tips = ((0.0, 0.0, 0.0), LONG) if ch.tool_side else ((0.0, 0.0, 0.0),)
    return write_chain_campaign(vm, tmp, sphere_plan(ch, 5, 6), tips_mm=tips,
                                heights_mm=(0.0, 100.0)), vm


@pytest.mark.parametrize("kind, motion, key", [
    ("head-table", (("C", "C"), [0.0, 0.0, 15.0, 10.0]), "ECC(C) 2"),   # a 2-per-turn encoder error
    ("table-dual", (("A", "Y"), [0.0, 0.0, 2.0, -1.5]), "EYA(A) 2"),     # a radial motion of A
])
def test_a_hidden_error_motion_is_named(tmp_path: Path, kind: str, motion: tuple, key: str) -> None:
    mf, vm = _campaign(tmp_path, kind, {motion[0]: motion[1]})
    m = load_machine(mf)
    diag = diagnose_chain(m.extra["chain"], setups_from_machine(m))
    assert [n.candidate.key for n in diag.named] == [key], diag.tried
    n = diag.named[0]
    truth = {f"{key.split()[0]} sin2": motion[1][2], f"{key.split()[0]} cos2": motion[1][3]}
    for p, v in n.values.items():
        assert abs(v - truth[p]) <= n.ci95[p], (p, v, truth[p], n.ci95[p])
    assert diag.heldout_after_um < diag.heldout_before_um
    assert diag.gap_before_um > 0.3 and diag.gap_shrink is not None and diag.gap_shrink > 0.5
    assert not n.ambiguous_with
    assert "Named: " + key in diag.text()


def test_a_clean_machine_gets_no_name(tmp_path: Path) -> None:
    mf, _vm = _campaign(tmp_path, "table-dual", {}, seed=5)
    m = load_machine(mf)
    diag = diagnose_chain(m.extra["chain"], setups_from_machine(m))
    assert diag.named == [], diag.tried
    assert diag.heldout_before_um < 1.2 * diag.floor_before_um  # at the floor
    assert "Nothing named" in diag.text()


def test_a_moved_head_axis_line_is_named_against_the_model(tmp_path: Path) -> None:
    """Head-head: the model is `abbe fit`'s chain_fit.json of one campaign; B's line then
    moves 6 um along X (EX0B). `abbe diagnose --model` on a second campaign names EX0B with
    its change and writes diagnose_chain.json."""
    mf1, vm = _campaign(tmp_path / "a", "head-head", {})
    m1 = load_machine(mf1)
    setups = setups_from_machine(m1)
    fit = identify_chain(m1.extra["chain"], setups, explain=False)
    model = tmp_path / "chain_fit.json"
    model.write_text(json.dumps(fit_to_json(fit, setups)), encoding="utf-8")
    moved = {"EX0B": vm.errors.location["EX0B"] + 6.0}
    mf2, _ = _campaign(tmp_path / "b", "head-head", {}, seed=3, location=moved)
    out = tmp_path / "out"
    assert main(["diagnose", str(mf2), "--model", str(model), "-o", str(out)]) == 0
    doc = json.loads((out / "diagnose_chain.json").read_text(encoding="utf-8"))
    assert [n["effect"] for n in doc["named"]] == ["EX0B"], doc["tried"]
    n = doc["named"][0]
    assert abs(n["values"]["EX0B"] - 6.0) <= max(n["ci95"]["EX0B"], 0.5)
    assert doc["gap_after_um"] < doc["gap_before_um"]
    assert "EX0B" in (out / "report.txt").read_text(encoding="utf-8")


def test_a_model_of_another_chain_is_refused(tmp_path: Path) -> None:
    mf, _ = _campaign(tmp_path, "head-table", {})
    bad = tmp_path / "other.json"
    bad.write_text(json.dumps({"chain": "5axiskins", "location": []}), encoding="utf-8")
    assert main(["diagnose", str(mf), "--model", str(bad), "-o", str(tmp_path / "o")]) == 2
