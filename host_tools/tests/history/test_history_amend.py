"""Correcting the history (issue 42): remove / amend with an audit trail, nothing deleted;
zone-aware dates; the report of a machine with one campaign."""

from __future__ import annotations

import csv
import datetime as dt
import time
from html.parser import HTMLParser

import pytest
import sqlalchemy as sa

from abbe.cli.entry import main
from conftest import ballbar_variant


def _rows(db: str, sql: str) -> list:
    from abbe.history.database import open_database
    base = open_database(db)
    try:
        with base.read() as conn:
            return [tuple(r) for r in conn.execute(sa.text(sql)).all()]
    finally:
        base.close()


def test_remove_and_amend_keep_everything_with_an_audit_trail(db, outputs, tmp_path, capsys):
    for i in range(3):
        assert main(["history", "--db", db, "add", str(ballbar_variant(outputs, tmp_path, i)),
                     "--machine", "m1", "--date", f"2025-0{i + 1}-10T08:00Z",
                     "--operator", "ana"]) == 0
    ids = [r[0] for r in _rows(db, "SELECT id FROM campaigns ORDER BY id")]
    n_results = _rows(db, "SELECT count(*) FROM results")[0][0]
    capsys.readouterr()
    # the second campaign was of another machine, by another operator, an hour later
    assert main(["history", "--db", db, "amend", str(ids[1]), "--machine", "m2", "--operator",
                 "bo", "--date", "2025-02-10T09:00Z", "--note", "re-measured", "--reason",
                 "entered under the wrong machine", "--by", "lead"]) == 0
    assert main(["history", "--db", db, "remove", str(ids[2]), "--reason",
                 "laser not warmed up", "--by", "lead"]) == 0
    # nothing deleted: every campaign and value is still there
    assert len(_rows(db, "SELECT id FROM campaigns")) == 3
    assert _rows(db, "SELECT count(*) FROM results")[0][0] == n_results
    got = _rows(db, "SELECT m.name, c.operator, c.note, c.removed_at IS NOT NULL FROM campaigns "
                    "c JOIN machines m ON m.id = c.machine_id ORDER BY c.id")
    assert got == [("m1", "ana", None, False), ("m2", "bo", "re-measured", False),
                   ("m1", "ana", None, True)]
    assert str(_rows(db, f"SELECT measured_at FROM campaigns WHERE id = {ids[1]}")[0][0]) \
        .startswith("2025-02-10 09:00")
    audit = _rows(db, "SELECT campaign_id, who, action, field, old_value, new_value, reason "
                      "FROM audit ORDER BY id")
    assert [(a[0], a[2], a[3], a[4], a[5]) for a in audit] == [
        (ids[1], "amend", "machine", "m1", "m2"),
        (ids[1], "amend", "measured_at", "2025-02-10 08:00:00", "2025-02-10 09:00:00"),
        (ids[1], "amend", "operator", "ana", "bo"),
        (ids[1], "amend", "note", None, "re-measured"),
        (ids[2], "remove", None, None, None)]
    assert {a[1] for a in audit} == {"lead"}
    assert audit[0][6] == "entered under the wrong machine" and audit[4][6] == "laser not warmed up"
    # the trends, exports and reports no longer count the removed campaign
    capsys.readouterr()
    assert main(["history", "--db", db, "show", "m1"]) == 0
    assert "m1: 1 campaigns" in capsys.readouterr().out
    assert main(["history", "--db", db, "export", "-o", str(tmp_path / "all.csv")]) == 0
    rows = list(csv.DictReader((tmp_path / "all.csv").open()))
    assert sorted({(r["machine"], r["campaign"]) for r in rows}) == [
        ("m1", str(ids[0])), ("m2", str(ids[1]))]
    # ... but shows it on request, with the audit trail
    capsys.readouterr()
    assert main(["history", "--db", db, "show", "m1", "--removed", "--tz", "UTC"]) == 0
    out = capsys.readouterr().out
    assert f"{ids[2]}\t2025-03-10 08:00 UTC" in out and "REMOVED" in out
    assert "by lead: removed; why: laser not warmed up" in out
    # the same outputs again: refused, naming the removed campaign
    assert main(["history", "--db", db, "add", str(ballbar_variant(outputs, tmp_path, 2)),
                 "--machine", "m1"]) == 2
    assert f"campaign {ids[2]} (removed" in capsys.readouterr().err
    # mistakes in the corrections themselves are refused, nothing changed
    n_audit = len(audit)
    for argv, msg in [(["remove", str(ids[2]), "--reason", "again"], "was removed"),
                      (["amend", str(ids[2]), "--note", "x", "--reason", "r"], "was removed"),
                      (["amend", "999", "--note", "x", "--reason", "r"], "no campaign 999"),
                      (["amend", str(ids[0]), "--reason", "r"], "give what to correct"),
                      (["amend", str(ids[0]), "--operator", "ana", "--reason", "r"],
                       "nothing to change"),
                      (["amend", str(ids[0]), "--date", "2099-01-01", "--reason", "r"],
                       "future"),
                      (["remove", str(ids[0]), "--reason", " "], "--reason")]:
        assert main(["history", "--db", db, *argv]) == 2, argv
        assert msg in capsys.readouterr().err, argv
    assert len(_rows(db, "SELECT id FROM audit")) == n_audit


def test_dates_without_a_zone_are_the_sites(db, outputs, tmp_path, capsys, monkeypatch):
    """--date without a zone: the site's zone (--tz, else the computer's, $TZ), with the
    daylight-saving rule of that date; stored in UTC; shown in the site's zone."""
    cases = [(["--tz", "Europe/Berlin"], "2025-01-15T10:00", "2025-01-15 09:00"),  # CET
             (["--tz", "Europe/Berlin"], "2025-07-15T10:00", "2025-07-15 08:00"),  # CEST
             (["--tz", "America/Chicago"], "2025-03-01T20:30", "2025-03-02 02:30"),
             (["--tz", "Europe/Berlin"], "2025-04-01T10:00+02:00", "2025-04-01 08:00"),
             ([], "2025-05-01T10:00Z", "2025-05-01 10:00")]
    for i, (tz, date, utc) in enumerate(cases):
        assert main(["history", "--db", db, *tz, "add",
                     str(ballbar_variant(outputs, tmp_path, i)), "--machine", "m",
                     "--date", date]) == 0
    # the computer's zone when --tz is not given ($TZ)
    monkeypatch.setenv("TZ", "Asia/Tokyo")
    time.tzset()
    try:
        assert main(["history", "--db", db, "add", str(ballbar_variant(outputs, tmp_path, 9)),
                     "--machine", "m", "--date", "2025-06-01T09:00"]) == 0
        capsys.readouterr()
        assert main(["history", "--db", db, "show", "m", "--campaigns"]) == 0
        local_out = capsys.readouterr().out
    finally:
        monkeypatch.delenv("TZ")
        time.tzset()
    stored = [str(r[0])[:16] for r in _rows(db, "SELECT measured_at FROM campaigns ORDER BY id")]
    assert stored == [u for _, _, u in cases] + ["2025-06-01 00:00"]
    assert "2025-06-01 09:00 JST" in local_out
    capsys.readouterr()
    assert main(["history", "--db", db, "--tz", "America/Chicago", "show", "m"]) == 0
    out = capsys.readouterr().out
    assert "dates in America/Chicago" in out and "#2 2025-03-01" in out  # 20:30 CST
    assert main(["history", "--db", db, "report", "m", "-o", str(tmp_path / "rep"),
                 "--tz", "America/Chicago"]) == 0
    page = (tmp_path / "rep" / "index.html").read_text()
    assert "2025-03-01 20:30 CST" in page and "date (America/Chicago)" in page
    assert main(["history", "--db", db, "export", "-o", str(tmp_path / "x.csv")]) == 0
    rows = list(csv.DictReader((tmp_path / "x.csv").open()))
    assert "2025-03-02T02:30:00Z" in {r["measured_at"] for r in rows}  # exports stay UTC
    assert main(["history", "--db", db, "show", "m", "--tz", "Mars/Olympus"]) == 2
    assert "unknown time zone" in capsys.readouterr().err


def test_a_one_campaign_machine_has_its_plots(db, outputs, tmp_path):
    assert main(["history", "--db", db, "add", str(outputs / "fit"), str(outputs / "diagnose"),
                 str(outputs / "ballbar.json"), str(outputs / "iso_x.json"), "--axis", "X",
                 "--date", "2026-01-05"]) == 0
    assert main(["history", "--db", db, "report", "vmc500", "-o", str(tmp_path / "rep")]) == 0
    from abbe.history.database import open_database
    from abbe.history.limits import load_settings
    from abbe.history.store import campaigns_of, require_machine, series_of
    base = open_database(db)
    with base.read() as conn:
        mid = require_machine(conn, "vmc500", "db")
        assert len(campaigns_of(conn, mid)) == 1
        keys = list(series_of(conn, mid))
    base.close()
    settings = load_settings(None)
    with_limit = sorted(k for k in keys if settings.limit_of(k) is not None)
    assert with_limit  # the defaults give ISO 230-2 B, backlash, squareness, ballbar G limits

    class Page(HTMLParser):
        def __init__(self):
            super().__init__()
            self.imgs, self.h3 = [], []
            self._in_h3 = False

        def handle_starttag(self, tag, attrs):
            if tag == "img":
                self.imgs.append(dict(attrs)["src"])
            self._in_h3 = tag == "h3"

        def handle_data(self, data):
            if self._in_h3:
                self.h3.append(data)
                self._in_h3 = False
    page = Page()
    page.feed((tmp_path / "rep" / "index.html").read_text())
    assert sorted(page.h3) == with_limit  # one plot per quantity with a limit
    assert len(page.imgs) == len(with_limit)
    for src in page.imgs:
        assert (tmp_path / "rep" / src).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
