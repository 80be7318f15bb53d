"""`abbe history export` (CSV and JSON, version 1.1) read by the independent reader of
tests/history_export_reader.py (written from docs/history.md, not from the writer): the
real exports of a database holding fit, diagnose, ISO 230-2 and ballbar campaigns pass
every documented check and hold the same values in both formats; each reader refuses an
export broken the ways the page forbids (so the checks can fail)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from abbe.cli.entry import main
from conftest import EXAMPLE, ballbar_variant
from history_export_reader import (CSV_HEADER, FormatError, read_history_csv,
                                   read_history_json, same_values)


@pytest.fixture(scope="module")
def exports(outputs, tmp_path_factory) -> tuple[Path, Path]:
    tmp = tmp_path_factory.mktemp("hexport")
    db = f"sqlite:///{tmp / 'h.db'}"
    # the real commands' JSON (they state U; the session's iso_x.json / ballbar.json do not)
    iso, bb = tmp / "iso_x.json", tmp / "ballbar.json"
    assert main(["iso230-2", str(EXAMPLE / "laser" / "x.csv"), "--json", str(iso),
                 "--mc", "0"]) == 0
    assert main(["ballbar", str(EXAMPLE / "machine.toml"), "circle1", "--json", str(bb),
                 "--no-plot", "--mc", "0"]) == 0
    assert main(["history", "--db", db, "add", str(outputs / "fit"), str(outputs / "diagnose"),
                 str(iso), str(bb), "--machine", "vmc500",
                 "--date", "2026-03-01", "--operator", "ana", "--axis", f"{iso}=X"]) == 0
    assert main(["history", "--db", db, "add", str(ballbar_variant(outputs, tmp / "v", 3)),
                 "--machine", "vmc500", "--date", "2026-04-01"]) == 0
    assert main(["history", "--db", db, "export", "-o", str(tmp / "h.csv")]) == 0
    assert main(["history", "--db", db, "export", "-o", str(tmp / "h.json")]) == 0
    return tmp / "h.csv", tmp / "h.json"


def test_the_stored_diagnosis_reads_as_documented(outputs) -> None:
    """The diagnose.json this campaign stores (no Monte Carlo) by the independent reader of
    its uncertainty fields (tests/diagnose_json_reader.py, from docs/formats.md)."""
    from diagnose_json_reader import read_diagnose_uncertainty
    d = read_diagnose_uncertainty(outputs / "diagnose" / "diagnose.json", mc=0)
    assert d["effects"] and "monte_carlo" not in d["uncertainty"]


def test_history_exports_read_as_documented(exports) -> None:
    rows = read_history_csv(exports[0])
    doc = read_history_json(exports[1])
    assert same_values(rows, doc) == len(rows) > 50
    camps = doc["machines"][0]["campaigns"]
    assert len(camps) == 2 and camps[0]["operator"] == "ana"
    stated = [r for r in rows if r["expanded_u"] is not None]
    # every producer that states U has it stored (docs/history.md, revision 0004) ...
    for series in ("iso230-2 E X bi", "iso230-2 B Y bi", "diagnose squareness_xy",
                   "diagnose gap rms after", "ballbar G XY F200 bi", "ballbar H XY F200"):
        assert any(r["series"] == series and r["expanded_u"] > 0 for r in stated), series
    # ... and a value whose producer states none keeps an empty cell, never 0
    assert any(r["series"].startswith("fit term ") and r["expanded_u"] is None for r in rows)
    assert all(r["coverage_k"] == 2.0 for r in stated)


def _csv_edit(text: str, col: str, value: str, where=lambda r: True) -> str:
    lines = text.splitlines()
    i = CSV_HEADER.index(col)
    for n, ln in enumerate(lines[1:], start=1):
        cells = ln.split(",")
        if len(cells) == len(CSV_HEADER) and where(dict(zip(CSV_HEADER, cells))):
            cells[i] = value
            lines[n] = ",".join(cells)
            return "\n".join(lines) + "\n"
    raise AssertionError(f"no row to edit for {col}")


_U = lambda r: r["expanded_u"] != ""  # noqa: E731
_CI = lambda r: r["ci_low"] != ""  # noqa: E731


@pytest.mark.parametrize("edit, match", [
    (lambda t: _csv_edit(t, "value", "nan"), "value"),
    (lambda t: _csv_edit(t, "value", "Infinity"), "value"),
    (lambda t: _csv_edit(t, "coverage_k", "", _U), "together"),
    (lambda t: _csv_edit(t, "coverage_k", "1.96", _U), "k must be 2"),
    (lambda t: _csv_edit(t, "expanded_u", "-0.1", _U), "expanded_u"),
    (lambda t: _csv_edit(t, "ci_low", "1e6", _CI), "interval"),
    (lambda t: _csv_edit(t, "measured_at", "2026-03-01 00:00:00"), "UTC"),
    (lambda t: _csv_edit(t, "direction", "sideways"), "direction"),
    (lambda t: t.replace("ci_high,expanded_u", "expanded_u,ci_high", 1), "header"),
])
def test_the_csv_reader_refuses_what_the_page_forbids(exports, tmp_path, edit, match) -> None:
    text = exports[0].read_text(encoding="utf-8")
    bad = tmp_path / "bad.csv"
    bad.write_text(edit(text), encoding="utf-8")
    with pytest.raises(FormatError, match=match):
        read_history_csv(bad)


def _first(doc: dict, pred) -> dict:
    return next(r for c in doc["machines"][0]["campaigns"] for r in c["results"] if pred(r))


@pytest.mark.parametrize("change, match", [
    (lambda d: d.update(version="1.0"), "version"),
    (lambda d: d.update(format="abbe-history 1.1"), "format"),
    (lambda d: _first(d, lambda r: r["expanded_u"]).update(coverage_k=None), "together"),
    (lambda d: _first(d, lambda r: r["expanded_u"]).update(expanded_u=-1.0), "expanded_u"),
    (lambda d: _first(d, lambda r: True).pop("coverage_k"), "missing"),
    (lambda d: _first(d, lambda r: True).update(extra=1), "undocumented"),
    (lambda d: d["machines"][0]["campaigns"][0].update(content_sha256="x" * 64), "SHA-256"),
    (lambda d: d["machines"][0]["campaigns"][0]["tables"][0].update(crc32=1), "CRC-32"),
    (lambda d: d["machines"][0]["campaigns"][0].update(kinds="fit"), "array"),
    (lambda d: d["machines"][0]["campaigns"][0].update(measured_at="2026-03-01"), "UTC"),
    (lambda d: d["machines"][0]["campaigns"][1].update(id=d["machines"][0]["campaigns"][0]["id"]),
     "twice"),
])
def test_the_json_reader_refuses_what_the_page_forbids(exports, tmp_path, change, match) -> None:
    doc = json.loads(exports[1].read_text(encoding="utf-8"))
    change(doc)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(doc), encoding="utf-8")
    with pytest.raises(FormatError, match=match):
        read_history_json(bad)


def test_the_json_reader_refuses_nan(exports, tmp_path) -> None:
    bad = tmp_path / "nan.json"
    text = exports[1].read_text(encoding="utf-8")
    bad.write_text(text.replace('"value": ', '"value": NaN, "x": ', 1), encoding="utf-8")
    with pytest.raises(FormatError, match="NaN"):
        read_history_json(bad)
