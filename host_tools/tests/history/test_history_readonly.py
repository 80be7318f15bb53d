"""abbe history never trusts its database and never writes where it must not (issues 34
and 42): read-only users read, foreign files stay untouched, bad stored values are
refused with their table, row and field, outputs are atomic."""

from __future__ import annotations

import hashlib
import os
import shutil
import sqlite3
from pathlib import Path

import pytest
import sqlalchemy as sa

from abbe.cli.entry import main
from conftest import ballbar_variant, new_pg_database, pg_admin, raw_sqlite, run_forked


def _count(db: str, table: str) -> int:
    from abbe.history.database import open_database
    base = open_database(db)
    try:
        with base.read() as conn:
            return conn.execute(sa.text(f"SELECT count(*) FROM {table}")).scalar_one()
    finally:
        base.close()


def _sha(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def _fill(db: str, outputs: Path, tmp: Path, n: int = 2) -> None:
    for i in range(n):
        assert main(["history", "--db", db, "add", str(ballbar_variant(outputs, tmp / "v", i)),
                     "--machine", "m1", "--date", f"2025-0{i + 1}-10"]) == 0


def _shared_dir() -> Path:
    """A folder the user nobody can enter (pytest's tmp_path is root's, mode 0700)."""
    import tempfile
    d = Path(tempfile.mkdtemp(prefix="abbe-hist-ro-"))
    os.chmod(d, 0o755)
    return d


# ------------------------------------------------------------------ read-only access
def test_a_read_only_sqlite_file_is_read_and_refused_for_add(outputs, tmp_path):
    """As a user without write permission on the file: show, export and report work
    (the export is not recorded, with a note); add exits 2 naming the database, and
    the file is unchanged."""
    shared = _shared_dir()
    try:
        db = shared / "h.sqlite"
        _fill(str(db), outputs, tmp_path)
        # the interpreter may live where nobody cannot read (/root/.pyenv): import every
        # module the commands need now, running them on a copy, before the fork drops root
        warm = tmp_path / "warm.sqlite"
        shutil.copy(db, warm)
        for cmd in (["show", "m1"], ["export", "-o", str(tmp_path / "w.csv")],
                    ["report", "m1", "-o", str(tmp_path / "wrep")],
                    ["add", str(ballbar_variant(outputs, tmp_path / "w", 9)), "--machine", "m"]):
            assert main(["history", "--db", str(warm), *cmd]) == 0
        os.chmod(db, 0o444)  # root's file; the folder: root's, 0755
        for extra in shared.glob("h.sqlite-*"):
            extra.unlink()  # the writer is gone: no WAL files left
        before = _sha(db)
        work = shared / "work"
        work.mkdir()
        os.chmod(work, 0o777)
        # a folder the reader cannot write: SQLite cannot make the WAL index -> exit 2, said
        rc, out, err = run_forked(["history", "--db", str(db), "show", "m1"], work, True)
        if os.geteuid() == 0:
            assert rc == 2 and "h.sqlite-shm" in err and "folder" in err, err
        os.chmod(shared, 0o1777)  # a shared folder (sticky, as /tmp); the file stays read-only
        rc, out, err = run_forked(["history", "--db", str(db), "show", "m1"], work, True)
        assert rc == 0 and "ballbar G XY F200 bi" in out, err
        rc, out, err = run_forked(["history", "--db", str(db), "export", "m1", "-o",
                                   str(work / "m1.csv")], work, True)
        assert rc == 0, err
        assert "not recorded" in err and "read-only" in err
        assert len((work / "m1.csv").read_text().splitlines()) == 1 + 2 * 7
        rc, out, err = run_forked(["history", "--db", str(db), "report", "m1", "-o",
                                   str(work / "rep")], work, True)
        assert rc == 0 and (work / "rep" / "index.html").exists(), err
        rc, out, err = run_forked(["history", "--db", str(db), "add",
                                   str(ballbar_variant(outputs, work / "v", 9)), "--machine",
                                   "m1"], work, True)
        if os.geteuid() == 0 or not os.access(db, os.W_OK):
            assert rc == 2, err
            assert str(db) in err and "read-only" in err and "nothing was written" in err
        assert _sha(db) == before and _count(str(db), "exports") == 0
    finally:
        shutil.rmtree(shared, ignore_errors=True)


def test_a_select_only_postgresql_role_reads_and_is_refused_for_add(outputs, tmp_path,
                                                                   capsys, request):
    db = new_pg_database(request.getfixturevalue("pg_server"))
    _fill(db, outputs, tmp_path)
    with pg_admin(db) as admin:
        admin.execute("DO $$ BEGIN CREATE ROLE reader LOGIN; EXCEPTION WHEN duplicate_object "
                      "THEN NULL; END $$")
        admin.execute("GRANT SELECT ON ALL TABLES IN SCHEMA public TO reader")
    ro = db.replace("abbe@", "reader@")
    assert main(["history", "--db", ro, "show", "m1"]) == 0
    capsys.readouterr()
    assert main(["history", "--db", ro, "export", "-o", str(tmp_path / "all.json")]) == 0
    assert "not recorded" in capsys.readouterr().err
    assert main(["history", "--db", ro, "report", "m1", "-o", str(tmp_path / "rep")]) == 0
    assert "not recorded" in capsys.readouterr().err
    assert (tmp_path / "all.json").exists() and (tmp_path / "rep" / "index.html").exists()
    n = _count(db, "results")
    assert main(["history", "--db", ro, "add", str(ballbar_variant(outputs, tmp_path, 9)),
                 "--machine", "m1"]) == 2
    err = capsys.readouterr().err
    assert "read-only for this user" in err and "reader@" in err and "nothing was written" in err
    assert _count(db, "results") == n and _count(db, "exports") == 0
    for cmd in (["remove", "1", "--reason", "x"], ["amend", "1", "--note", "n", "--reason", "x"]):
        assert main(["history", "--db", ro, *cmd]) == 2
        assert "read-only" in capsys.readouterr().err


# ------------------------------------------------------------------ foreign files, typos
def test_another_programs_sqlite_file_is_never_written(outputs, tmp_path, capsys):
    other = tmp_path / "crm.sqlite"
    con = sqlite3.connect(other)
    con.execute("CREATE TABLE customers (id INTEGER PRIMARY KEY, name TEXT)")
    con.execute("INSERT INTO customers (name) VALUES ('ACME')")
    con.commit()
    con.close()
    before = _sha(other)
    for cmd in (["show"], ["show", "m"], ["export", "-o", str(tmp_path / "x.csv")],
                ["add", str(ballbar_variant(outputs, tmp_path, 1)), "--machine", "m"],
                ["migrate"], ["remove", "1", "--reason", "x"]):
        assert main(["history", "--db", str(other), *cmd]) == 2, cmd
        err = capsys.readouterr().err
        assert "not an abbe history" in err and "customers" in err, err
    assert _sha(other) == before
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith("crm")) == \
        ["crm.sqlite"]  # no -wal, no -shm, no journal
    con = sqlite3.connect(other)
    assert con.execute("PRAGMA journal_mode").fetchone()[0] == "delete"
    assert [r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")] == \
        ["customers"]
    con.close()
    assert not (tmp_path / "x.csv").exists()


def test_another_programs_postgresql_tables_are_never_written(outputs, tmp_path, capsys,
                                                              request):
    db = new_pg_database(request.getfixturevalue("pg_server"))
    with pg_admin(db) as admin:
        admin.execute("CREATE TABLE machines (id serial PRIMARY KEY, serial_no text)")
    assert main(["history", "--db", db, "add", str(ballbar_variant(outputs, tmp_path, 1)),
                 "--machine", "m"]) == 2
    assert "not an abbe history" in capsys.readouterr().err
    with pg_admin(db) as admin:
        tables = sorted(r[0] for r in admin.execute(
            "SELECT tablename FROM pg_tables WHERE schemaname = 'public'"))
    assert tables == ["machines"]


def test_a_missing_folder_is_created_only_with_create(outputs, tmp_path, capsys):
    db = tmp_path / "new_dir" / "sub" / "h.sqlite"
    bb = str(ballbar_variant(outputs, tmp_path, 1))
    assert main(["history", "--db", str(db), "add", bb, "--machine", "m"]) == 2
    err = capsys.readouterr().err
    assert "does not exist" in err and "--create" in err
    assert not (tmp_path / "new_dir").exists()
    assert main(["history", "--db", str(db), "add", bb, "--machine", "m", "--create"]) == 0
    assert _count(str(db), "campaigns") == 1


# ------------------------------------------------------------------ values read back
SQLITE_BAD = [
    ("results", "value", "9e999", "a finite number"),          # stored as Infinity
    ("results", "value", "'abc'", "a number"),
    ("results", "value", "x'00ff'", "a number"),
    ("results", "ci_low", "-9e999", "a finite number"),
    ("results", "series", "x'00ff'", "text"),
    ("campaigns", "measured_at", "'not a date'", "a date"),
    ("campaigns", "measured_at", "'2025-02-30 00:00:00'", "a date and time"),
    ("campaigns", "operator", "x'00ff'", "text"),
    ("temperatures", "value_c", "'warm'", "a number"),
    ("machines", "name", "NULL", "a value"),
]
PG_BAD = [
    ("results", "value", "'Infinity'::float8", "a finite number"),
    ("results", "value", "'NaN'::float8", "a finite number"),
    ("results", "ci_high", "'-Infinity'::float8", "a finite number"),
    ("campaigns", "measured_at", "'infinity'::timestamp", "a date"),
    ("temperatures", "value_c", "'NaN'::float8", "a finite number"),
]


def _bad_cases():
    return [("sqlite", *c) for c in SQLITE_BAD] + [("postgresql", *c) for c in PG_BAD]


@pytest.mark.parametrize("kind,table,field,sql,expected", _bad_cases(),
                         ids=[f"{k}-{t}.{f}={s}" for k, t, f, s, _ in _bad_cases()])
def test_every_value_read_back_is_checked(kind, table, field, sql, expected, outputs, tmp_path,
                                          capsys, request):
    """A stored value abbe did not write: show, export and report exit 2 naming the
    table, the row and the field; the export file and the report folder that were there
    stay as they were; nothing of the bad value is written."""
    if kind == "sqlite":
        db = str(tmp_path / "h.sqlite")
    else:
        db = new_pg_database(request.getfixturevalue("pg_server"))
    _fill(db, outputs, tmp_path)
    assert main(["history", "--db", db, "add", str(ballbar_variant(outputs, tmp_path, 50)),
                 "--machine", "m1", "--temp-c", "20.5", "--operator", "ana", "--date", "2025-03-10"]) == 0
    # the previous export and report: must survive a failed command byte for byte
    assert main(["history", "--db", db, "export", "-o", str(tmp_path / "x.csv")]) == 0
    assert main(["history", "--db", db, "report", "m1", "-o", str(tmp_path / "rep")]) == 0
    old_csv = _sha(tmp_path / "x.csv")
    old_rep = {p.name: _sha(p) for p in (tmp_path / "rep").iterdir()}
    n_exports = _count(db, "exports")
    stmt = f"UPDATE {table} SET {field} = {sql} WHERE id = (SELECT max(id) FROM {table})"
    if kind == "sqlite":
        con = raw_sqlite(db)
        row = con.execute(f"SELECT max(id) FROM {table}").fetchone()[0]
        if field == "name":  # NOT NULL in the schema: bypass it as a damaged file would
            con.execute("PRAGMA writable_schema = ON")
            con.execute("UPDATE sqlite_master SET sql = replace(sql, 'name VARCHAR(200) NOT "
                        "NULL', 'name VARCHAR(200)') WHERE name = 'machines'")
            con.close()
            con = raw_sqlite(db)
        con.execute(stmt)
        con.close()
    else:
        with pg_admin(db) as admin:
            row = admin.execute(f"SELECT max(id) FROM {table}").fetchone()[0]
            admin.execute(stmt)
    capsys.readouterr()
    cmds = [["show", "m1"], ["export", "-o", str(tmp_path / "x.csv")],
            ["export", "m1", "-o", str(tmp_path / "x.json")],
            ["report", "m1", "-o", str(tmp_path / "rep")]]
    if table == "machines":
        cmds.insert(0, ["show"])
    if table == "temperatures":  # show does not read them (report and export do)
        cmds.pop(0)
    for cmd in cmds:
        rc = main(["history", "--db", db, *cmd])
        err = capsys.readouterr().err
        assert rc == 2, (cmd, err)
        assert f"table {table}, row {row}, field {field}: expected {expected}" in err, err
    assert _sha(tmp_path / "x.csv") == old_csv and not (tmp_path / "x.json").exists()
    assert {p.name: _sha(p) for p in (tmp_path / "rep").iterdir()} == old_rep
    assert _count(db, "exports") == n_exports
