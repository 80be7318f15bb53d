"""`abbe history add` reads the outputs of any kinematic chain (issue 39): `abbe fit` and
`abbe diagnose` on a [chain] machine file; the values stored are read back from the
database against the command's own JSON, a second campaign makes a trend."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import sqlalchemy as sa

from abbe.cli.entry import main
from abbe.formats.machine import load_machine
from abbe.sim.chain import (VirtualChainMachine, random_location_errors, sphere_plan,
                            write_chain_campaign)
from cases.chain_suite import CHAINS


def _stored(db: str) -> dict[str, tuple[float, float | None, float | None]]:
    from abbe.history.database import open_database
    base = open_database(db)
    try:
        with base.read() as conn:
            rows = conn.execute(sa.text("SELECT series, value, ci_low, ci_high FROM results")).all()
    finally:
        base.close()
    return {s: (v, lo, hi) for s, v, lo, hi in rows}


def _campaign(tmp: Path, seed: int, drift_um: float = 0.0) -> Path:
    ch = load_machine(CHAINS / "head-table-maxkins.toml").extra["chain"]
    e = random_location_errors(ch, np.random.default_rng(seed))
    e.location["EX0B"] = e.location.get("EX0B", 0.0) + drift_um
    vm = VirtualChainMachine(ch, e, (0.04, -0.02, 0.03), probe_noise_um=0.5,
                             rtest_noise_um=0.3, seed=seed)
    return write_chain_campaign(vm, tmp, sphere_plan(ch, 4, 5),
                                tips_mm=((0.0, 0.0, 0.0), (0.0, 0.0, -100.0)),
                                heights_mm=(0.0, 100.0))


def test_chain_fit_and_diagnose_folders_are_stored_and_trended(tmp_path, capsys) -> None:
    db = str(tmp_path / "h.sqlite")
    m = _campaign(tmp_path / "c1", 5)
    fit = tmp_path / "fit"
    assert main(["fit", str(m), "-o", str(fit), "-q"]) == 0
    doc = json.loads((fit / "chain_fit.json").read_text())
    assert doc["format"] == "abbe-chain-fit 1.0" and doc["machine"]
    assert main(["history", "--db", db, "add", str(fit), "--date", "2026-03-01"]) == 0
    vals = _stored(db)
    seen = [r for r in doc["location"] if r["status"] == "identified"]
    assert len(seen) >= 8
    for r in seen:
        v, lo, hi = vals[f"chain {r['name']}"]
        assert v == r["value"] and hi - lo == pytest.approx(2 * r["u95"])
    for r in doc["location"]:  # what the plan cannot see is not stored (never as 0)
        if r["status"] != "identified":
            assert f"chain {r['name']}" not in vals
    diag = tmp_path / "diag"
    assert main(["diagnose", str(m), "-o", str(diag), "--model",
                 str(fit / "chain_fit.json")]) == 0
    d = json.loads((diag / "diagnose_chain.json").read_text())
    db2 = str(tmp_path / "h2.sqlite")
    assert main(["history", "--db", db2, "add", str(diag), "--date", "2026-03-01"]) == 0
    vals = _stored(db2)
    assert vals["chain diagnose heldout after"][0] == d["heldout_after_um"]
    assert vals["chain diagnose gap before"][0] == d["gap_before_um"]
    # a later campaign: B's line moved 8 um along X; the trend table shows both values
    m2 = _campaign(tmp_path / "c2", 5, drift_um=8.0)
    fit2 = tmp_path / "fit2"
    assert main(["fit", str(m2), "-o", str(fit2), "-q"]) == 0
    doc2 = json.loads((fit2 / "chain_fit.json").read_text())
    assert main(["history", "--db", db, "add", str(fit2), "--date", "2026-04-01"]) == 0
    capsys.readouterr()
    assert main(["history", "--db", db, "show", doc["machine"]]) == 0
    shown = capsys.readouterr().out
    row = next(line for line in shown.splitlines() if "chain EX0B" in line)
    first = next(r["value"] for r in doc["location"] if r["name"] == "EX0B")
    second = next(r["value"] for r in doc2["location"] if r["name"] == "EX0B")
    assert second - first == pytest.approx(8.0, abs=1.0)
    assert f"{first:.2f}"[:4] in row and f"{second:.2f}"[:4] in row


def test_a_chain_fit_json_without_its_format_tag_and_a_bad_value(tmp_path, capsys) -> None:
    m = _campaign(tmp_path / "c", 6)
    fit = tmp_path / "fit"
    assert main(["fit", str(m), "-o", str(fit), "-q"]) == 0
    f = fit / "chain_fit.json"
    doc = json.loads(f.read_text())
    old = {k: v for k, v in doc.items() if k not in ("format", "machine", "provenance")}
    f.write_text(json.dumps(old, indent=2))
    db = str(tmp_path / "h.sqlite")
    assert main(["history", "--db", db, "add", str(fit), "--machine", "m1", "--date",
                 "2026-03-01"]) == 0
    assert "chain EA0B" in _stored(db)
    i = next(i for i, r in enumerate(old["location"]) if r["status"] == "identified")
    old["location"][i]["u95"] = -1.0
    f.write_text(json.dumps(old, indent=2))
    assert main(["history", "--db", str(tmp_path / "h2.sqlite"), "add", str(fit), "--machine",
                 "m1", "--date", "2026-03-01"]) == 2
    assert f"location[{i}].u95" in capsys.readouterr().err
