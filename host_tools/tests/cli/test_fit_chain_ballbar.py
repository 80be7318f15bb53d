"""``abbe fit`` on a [chain] machine file with rotary ballbar tests (issue 39): files the
independent generator's readings are written into (plain text here, not abbe's writer),
the location errors identified back, what ballbar tests alone cannot see named, and bad
ballbar sections and files refused with exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from abbe.cli.entry import main
from cases import chain_generator as gen
from cases import chain_suite
from cases.chain_suite import CHAINS
from doc_json_readers import read_chain_fit

TABLE = np.array([50.0, 20.0, 30.0])


def _write(tmp: Path, file: str, seed: int, probe: bool = False) -> tuple[Path, dict[str, float]]:
    """A machine file (the chain file's text + one ballbar set-up per tool ball) and its
    ballbar CSVs from the independent generator; the truth."""
    src = CHAINS / file
    gch = gen.read_chain(src)
    rng = np.random.default_rng(seed)
    truth = gen.random_location(gch, rng)
    a, b = (n.lower() for n in gch.names)
    text = [src.read_text(encoding="utf-8")]
    for su, tip in chain_suite.ballbar_plan(bool(gch.tool)):
        off, cup = rng.normal(0.0, 0.05, 3), rng.normal(0.0, 0.02, 3)
        for label, path in gen.ballbar_paths(gch):
            for d, e in zip("XYZ", np.eye(3)):
                name = f"{su}_{label}_{d}"
                tool = TABLE + 100.0 * e
                r = gen.ballbar_readings(gch, truth, TABLE, off, tool, tip, cup, path,
                                         float(rng.normal(0.0, 1.5)), 0.3, rng)
                rows = [f"t_s,{a}_deg,{b}_deg,radial_um"]
                rows += [f"{i:.1f},{p[0]:.6f},{p[1]:.6f},{v:.5f}" for i, (p, v) in
                         enumerate(zip(path, r))]
                (tmp / f"{name}.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
                text.append(f'[rotary_ballbar.{name}]\nfile = "{name}.csv"\nsetup = "{su}"\n'
                            f"table_ball_mm = [{TABLE[0]}, {TABLE[1]}, {TABLE[2]}]\n"
                            f"tool_ball_mm = [{tool[0]}, {tool[1]}, {tool[2]}]\n"
                            f"tip_mm = [{tip[0]}, {tip[1]}, {tip[2]}]\n")
    m = tmp / "machine.toml"
    m.write_text("\n".join(text), encoding="utf-8")
    return m, truth


def test_fit_a_dual_rotary_table_from_rotary_ballbar_files(tmp_path: Path, capsys) -> None:
    m, truth = _write(tmp_path, "table-dual-rotary-xyzab.toml", 17)
    assert main(["fit", str(m), "-o", str(tmp_path / "o"), "-q"]) == 0
    doc = json.loads((tmp_path / "o" / "chain_fit.json").read_text())
    seen = [r for r in doc["location"] if r["value"] is not None]
    assert {r["name"] for r in seen} >= {"EC0A", "EA0B", "EC0B"}
    for r in seen:
        floor = 1.0 if r["unit"] == "um" else 5.0
        assert abs(r["value"] - truth[r["name"]]) <= max(r["u95"], floor), r
    rows = {r["name"]: r for r in doc["location"]}
    # a line's place is a ball's place: named, with the probed sphere that would see it
    for n in ("EY0A", "EZ0A", "EX0B", "EZ0B"):
        assert rows[n]["value"] is None and rows[n]["seen_by"].startswith("a sphere probed"), n
        assert any("table_ball" in c or "tool_ball" in c for c in rows[n]["confounded_with"])
    bb = doc["rotary_ballbar"]
    assert len(bb) == 12 and bb["K1_A0_X"]["turning_axis"] == "A"
    assert bb["K1_B0_Z"]["turning_axis"] == "B" and bb["K1_B0_Z"]["length_mm"] == 100.0
    for t in bb.values():  # the chain takes out what the errors did; the noise is left
        assert t["left_rms_um"] < 0.6 < t["measured_pv_um"], t
    assert "observable" in capsys.readouterr().out


def test_bad_rotary_ballbar_sections_and_files_are_refused(tmp_path: Path, capsys) -> None:
    m, _t = _write(tmp_path, "table-dual-rotary-xyzab.toml", 3)
    text = m.read_text()
    out = str(tmp_path / "o")
    cases = [
        (text.replace('tool_ball_mm = [150.0, 20.0, 30.0]', 'tool_ball_mm = [55.0, 20.0, 30.0]',
                      1), "rotary_ballbar.K1_A0_X.tool_ball_mm"),
        (text.replace('setup = "K1"\ntable_ball_mm = [50.0, 20.0, 30.0]\ntool_ball_mm = '
                      '[50.0, 120.0, 30.0]', 'setup = "K1"\ntable_ball_mm = [50.0, 21.0, 30.0]'
                      '\ntool_ball_mm = [50.0, 120.0, 30.0]', 1), "shares one table ball"),
        (text.replace('setup = "K1"', 'setup = "K 1"', 1), "rotary_ballbar.K1_A0_X.setup"),
        (text.replace('setup = "K1"', 'setup = "K1"\nlength_mm = 3', 1),
         "rotary_ballbar.K1_A0_X.length_mm"),
    ]
    for bad, said in cases:
        m.write_text(bad)
        assert main(["fit", str(m), "-o", out, "-q"]) == 2, said
        assert said in capsys.readouterr().err
    m.write_text(text)
    csv = tmp_path / "K1_A0_X.csv"
    good = csv.read_text()
    csv.write_text(good.replace("t_s,a_deg,b_deg", "t_s,a_deg,c_deg"))
    assert main(["fit", str(m), "-o", out, "-q"]) == 2
    assert "expected the header t_s,a_deg,b_deg,radial_um" in capsys.readouterr().err
    lines = good.splitlines()
    lines[3] = lines[3].rsplit(",", 1)[0] + ",inf"
    csv.write_text("\n".join(lines) + "\n")
    assert main(["fit", str(m), "-o", out, "-q"]) == 2
    assert "K1_A0_X.csv:4" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_probing_rtest_and_ballbar_files_together(tmp_path: Path) -> None:
    """A dual-rotary table campaign of abbe's virtual machine (probing at two heights, an
    R-test) with the independent generator's ballbar tests of the same location errors
    added: `abbe fit` uses all three (the ballbar blocks re-weighted by their residual),
    every observable error within max(95 %, 1 um / 5 urad); `abbe diagnose` on the same
    file leaves the ballbar tests out (its checks are centres and R-test readings)."""
    from abbe.formats.machine import load_machine
    from abbe.sim.chain import (VirtualChainMachine, random_location_errors, sphere_plan,
                                write_chain_campaign)
    src = CHAINS / "table-dual-rotary-xyzab.toml"
    ch = load_machine(src).extra["chain"]
    errs = random_location_errors(ch, np.random.default_rng(11))
    vm = VirtualChainMachine(ch, errs, (0.04, -0.02, 0.03), probe_noise_um=0.5,
                             rtest_noise_um=0.3, seed=11)
    m = write_chain_campaign(vm, tmp_path / "c", sphere_plan(ch, 4, 5), heights_mm=(0.0, 100.0))
    # the generator's ballbar tests of the virtual machine's errors (same truth)
    gch = gen.read_chain(src)
    rng = np.random.default_rng(12)
    a, b = (n.lower() for n in gch.names)
    extra = []
    off = rng.normal(0.0, 0.05, 3)  # the table ball's place, one for the set-up
    for label, path in gen.ballbar_paths(gch):
        for d, e in zip("XYZ", np.eye(3)):
            name = f"K1_{label}_{d}"
            r = gen.ballbar_readings(gch, dict(errs.location), TABLE, off,
                                     TABLE + 100.0 * e, np.zeros(3), np.zeros(3), path, 1.0,
                                     0.3, rng)
            (tmp_path / "c" / f"{name}.csv").write_text(
                f"t_s,{a}_deg,{b}_deg,radial_um\n" + "".join(
                    f"{i}.0,{p[0]:.6f},{p[1]:.6f},{v:.5f}\n" for i, (p, v) in
                    enumerate(zip(path, r))), encoding="utf-8")
            extra.append(f'[rotary_ballbar.{name}]\nfile = "{name}.csv"\nsetup = "K1"\n'
                         f"table_ball_mm = [{TABLE[0]}, {TABLE[1]}, {TABLE[2]}]\n"
                         f"tool_ball_mm = [{TABLE[0] + 100 * e[0]}, {TABLE[1] + 100 * e[1]}, "
                         f"{TABLE[2] + 100 * e[2]}]\n")
    m.write_text(m.read_text() + "\n" + "\n".join(extra), encoding="utf-8")
    assert main(["fit", str(m), "-o", str(tmp_path / "o"), "-q"]) == 0
    doc = read_chain_fit(tmp_path / "o" / "chain_fit.json", m)  # the docs' reader
    assert len(doc["rotary_ballbar"]) == 12  # re-weighted to the 0.3 um reading noise
    assert all(v < 0.5 for k, v in doc["sigma_um"].items() if k.startswith("K1_"))
    seen = [r for r in doc["location"] if r["value"] is not None]
    assert len(seen) == 7
    for r in seen:
        floor = 1.0 if r["unit"] == "um" else 5.0
        assert abs(r["value"] - errs.location[r["name"]]) <= max(r["u95"], floor), r
    assert main(["diagnose", str(m), "-o", str(tmp_path / "d")]) == 0
    assert (tmp_path / "d" / "diagnose_chain.json").is_file()
