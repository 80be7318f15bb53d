"""abbe history stores each result's expanded uncertainty U and its coverage factor k
(schema revision 0004), shows it in the trend table, the report and the export, and a
database of revision 0003 still opens after ``abbe history migrate`` (its rows: no U)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest
import sqlalchemy as sa

from abbe.cli.entry import main

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "vmc500"


def _rows(db: str) -> list[dict]:
    from abbe.history.database import open_database
    base = open_database(db)
    try:
        with base.read() as conn:
            return [dict(r._mapping) for r in conn.execute(sa.text(
                "SELECT series, value, expanded_u, coverage_k FROM results ORDER BY id"))]
    finally:
        base.close()


@pytest.fixture(scope="module")
def iso_dir(tmp_path_factory) -> Path:
    """abbe iso230-2's output folder (its JSON states U, k = 2, for E, A, B, R, M)."""
    out = tmp_path_factory.mktemp("iso") / "iso-x"
    assert main(["iso230-2", str(EXAMPLE / "laser" / "x.csv"), "-o", str(out), "--mc", "0"]) == 0
    return out


@pytest.mark.parametrize("db", ["sqlite"], indirect=True)
def test_every_stated_U_is_stored_and_shown(db, outputs, iso_dir, tmp_path, capsys) -> None:
    iso = iso_dir / "iso230_2.json"
    assert main(["history", "--db", db, "add", str(outputs / "fit"), str(outputs / "diagnose"),
                 str(iso), "--axis", f"{iso}=X", "--machine", "vmc500",
                 "--date", "2026-03-01"]) == 0
    rows = {r["series"]: r for r in _rows(db)}
    # the ISO 230-2 JSON: each of E, A, B, R, M with the U it states
    doc = json.loads(iso.read_text())
    for q in ("E", "A", "B", "R", "M"):
        r = rows[f"iso230-2 {q} X bi"]
        assert r["expanded_u"] == pytest.approx(doc["uncertainty"]["results"][q]["U_um"])
        assert r["coverage_k"] == 2.0
    # the diagnosis: each named effect and the gap with its U
    diag = json.loads((outputs / "diagnose" / "diagnose.json").read_text())
    assert diag["effects"]
    for e in diag["effects"]:
        r = rows[f"diagnose {e['key']}"]
        assert r["expanded_u"] == pytest.approx(e["U"]) and r["coverage_k"] == 2.0
    assert rows["diagnose gap rms after"]["expanded_u"] == \
        pytest.approx(diag["gap"]["after"]["rms_U_um"])
    # a result whose producer states no U keeps NULL, never 0
    assert rows["fit term X dx pv"]["expanded_u"] is None
    assert rows["fit term X dx pv"]["coverage_k"] is None
    capsys.readouterr()
    assert main(["history", "--db", db, "show", "vmc500"]) == 0
    out = capsys.readouterr().out
    assert "U last" in out
    sq = next(e for e in diag["effects"] if e["key"] == "squareness_xy")
    line = next(ln for ln in out.splitlines() if ln.startswith("diagnose squareness_xy "))
    assert f"{sq['U']:.3g}" in line.split()
    assert main(["history", "--db", db, "export", "vmc500", "-o", str(tmp_path / "h.csv")]) == 0
    with open(tmp_path / "h.csv", newline="") as f:
        recs = list(csv.DictReader(f))
    e_row = next(r for r in recs if r["series"] == "iso230-2 E X bi")
    assert float(e_row["expanded_u"]) == pytest.approx(doc["uncertainty"]["results"]["E"]["U_um"])
    assert e_row["coverage_k"] == "2.0"
    assert main(["history", "--db", db, "report", "vmc500", "-o", str(tmp_path / "rep")]) == 0
    page = (tmp_path / "rep" / "index.html").read_text()
    assert "U of the last (k = 2)" in page


@pytest.mark.parametrize("db", ["sqlite"], indirect=True)
def test_a_revision_0003_database_opens_after_migrate(db, outputs, capsys) -> None:
    from abbe.history.database import _sqlite_engine, resolve, upgrade
    loc = resolve(db)
    eng = _sqlite_engine(sa, loc, "rwc")
    upgrade(eng, "0003")
    with eng.begin() as conn:  # a campaign stored by the abbe before U was stored
        conn.execute(sa.text("INSERT INTO machines (name, created_at) VALUES "
                             "('vmc500', '2025-01-01 00:00:00')"))
        mid = conn.execute(sa.text("SELECT id FROM machines")).scalar_one()
        conn.execute(sa.text(
            "INSERT INTO campaigns (machine_id, measured_at, added_at, kinds, source, "
            "content_sha256, abbe_version) VALUES (:m, '2025-01-02 00:00:00', "
            "'2025-01-02 00:00:00', 'diagnose', 'x', :h, '0.9.0')"), {"m": mid, "h": "b" * 64})
        cid = conn.execute(sa.text("SELECT id FROM campaigns")).scalar_one()
        conn.execute(sa.text(
            "INSERT INTO results (campaign_id, series, source, quantity, value, unit, ci_low, "
            "ci_high) VALUES (:c, 'diagnose squareness_xy', 'diagnose', 'squareness_xy', 29.1, "
            "'urad', 28.7, 29.5)"), {"c": cid})
        cols = [c["name"] for c in sa.inspect(conn).get_columns("results")]
    assert "expanded_u" not in cols
    eng.dispose()
    capsys.readouterr()
    assert main(["history", "--db", db, "show", "vmc500"]) == 2
    assert "abbe history migrate" in capsys.readouterr().err
    assert main(["history", "--db", db, "migrate"]) == 0
    assert "revision 0004" in capsys.readouterr().out
    assert main(["history", "--db", db, "add", str(outputs / "diagnose"), "--machine", "vmc500",
                 "--date", "2026-03-01"]) == 0
    rows = [r for r in _rows(db) if r["series"] == "diagnose squareness_xy"]
    assert rows[0]["value"] == 29.1 and rows[0]["expanded_u"] is None  # kept, no U invented
    assert rows[1]["expanded_u"] > 0 and rows[1]["coverage_k"] == 2.0
    capsys.readouterr()
    assert main(["history", "--db", db, "show", "vmc500"]) == 0
    line = next(ln for ln in capsys.readouterr().out.splitlines()
                if ln.startswith("diagnose squareness_xy "))
    assert "29.1" in line and f"{rows[1]['expanded_u']:.3g}" in line
