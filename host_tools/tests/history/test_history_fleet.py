"""abbe history for a fleet (issue 42): first writers on a fresh database, every database
condition's status and message, passwords never written."""

from __future__ import annotations

import json
import multiprocessing
import os
import sqlite3
import stat
import sys
from pathlib import Path

import pytest
import sqlalchemy as sa

from abbe.cli.entry import main
from conftest import ballbar_variant, new_pg_database, pg_admin, raw_sqlite

RACE_ROUNDS = 20
RACE_WRITERS = 4
RESULTS_PER_BALLBAR_CAMPAIGN = 7


def _count(db: str, table: str) -> int:
    from abbe.history.database import open_database
    base = open_database(db)
    try:
        with base.read() as conn:
            return conn.execute(sa.text(f"SELECT count(*) FROM {table}")).scalar_one()
    finally:
        base.close()


def _first_writer(db: str, path: Path, go, q) -> None:
    go.wait(30)  # every writer released at the same moment onto the fresh database
    q.put(main(["history", "--db", db, "add", str(path), "--machine", "fleet",
                "--date", "2025-01-01"]))


@pytest.mark.parametrize("kind", ["sqlite", "postgresql"])
def test_first_writers_on_a_fresh_database_lose_nothing(kind, outputs, tmp_path, request):
    """RACE_WRITERS processes released together onto a new database (no tables yet),
    RACE_ROUNDS times: every campaign stored, every writer exit 0."""
    server = request.getfixturevalue("pg_server") if kind == "postgresql" else None
    ctx = multiprocessing.get_context("fork")
    lost, failed = 0, []
    for r in range(RACE_ROUNDS):
        db = (str(tmp_path / f"r{r}" / "h.sqlite") if kind == "sqlite"
              else new_pg_database(server))
        if kind == "sqlite":
            (tmp_path / f"r{r}").mkdir()
        files = [ballbar_variant(outputs, tmp_path / f"v{r}", r * 100 + k)
                 for k in range(RACE_WRITERS)]
        q, go = ctx.Queue(), ctx.Event()
        ps = [ctx.Process(target=_first_writer, args=(db, f, go, q)) for f in files]
        for p in ps:
            p.start()
        go.set()
        for p in ps:
            p.join(300)
        rcs = sorted(q.get(timeout=10) for _ in ps)
        stored = _count(db, "campaigns")
        lost += RACE_WRITERS - stored
        if rcs != [0] * RACE_WRITERS:
            failed.append((r, rcs))
        assert _count(db, "results") == stored * RESULTS_PER_BALLBAR_CAMPAIGN
        assert _count(db, "machines") == 1
    summary = {"database": kind, "rounds": RACE_ROUNDS, "writers": RACE_WRITERS,
               "campaigns_lost": lost, "failed_writers": failed}
    print("\nfirst-writer race:", json.dumps(summary))
    assert failed == [] and lost == 0


# ------------------------------------------------------------------ database conditions
def test_a_server_lost_mid_add_is_exit_1_retry_and_nothing_stored(outputs, tmp_path, capsys,
                                                                  request):
    """The PostgreSQL backend is killed while the results go in: exit 1, "retry", no row."""
    db = new_pg_database(request.getfixturevalue("pg_server"))
    assert main(["history", "--db", db, "add", str(ballbar_variant(outputs, tmp_path, 1)),
                 "--machine", "m"]) == 0
    before = {t: _count(db, t) for t in ("machines", "campaigns", "results", "inputs")}
    killed = []

    def kill_backend(conn, cursor, statement, params, context, executemany):
        if statement.lstrip().upper().startswith("INSERT INTO RESULTS") and not killed:
            pid = conn.connection.dbapi_connection.info.backend_pid
            with pg_admin(db) as admin:
                admin.execute("SELECT pg_terminate_backend(%s)", (pid,))
            killed.append(pid)

    sa.event.listen(sa.engine.Engine, "before_cursor_execute", kill_backend)
    try:
        capsys.readouterr()
        rc = main(["history", "--db", db, "add", str(outputs / "fit"), str(outputs / "diagnose")])
    finally:
        sa.event.remove(sa.engine.Engine, "before_cursor_execute", kill_backend)
    err = capsys.readouterr().err
    assert killed and rc == 1, err
    assert "retry" in err and "nothing was stored" in err and "internal error" not in err
    assert {t: _count(db, t) for t in before} == before


def test_an_sqlite_lock_held_too_long_is_exit_1_retry(outputs, tmp_path, capsys, monkeypatch):
    """Another writer holds the write lock past the busy timeout: exit 1, "locked", "retry"."""
    import abbe.history.database as D
    db = str(tmp_path / "h.sqlite")
    assert main(["history", "--db", db, "add", str(ballbar_variant(outputs, tmp_path, 1)),
                 "--machine", "m"]) == 0
    monkeypatch.setattr(D, "BUSY_TIMEOUT_S", 0.5)
    other = raw_sqlite(db)
    other.execute("BEGIN IMMEDIATE")  # another writer's transaction, never finished in time
    try:
        capsys.readouterr()
        rc = main(["history", "--db", db, "add", str(ballbar_variant(outputs, tmp_path, 2)),
                   "--machine", "m"])
    finally:
        other.execute("ROLLBACK")
        other.close()
    err = capsys.readouterr().err
    assert rc == 1, err
    assert "locked by another writer" in err and "retry" in err and "nothing was stored" in err
    assert _count(db, "campaigns") == 1


@pytest.mark.parametrize("bad", [
    "postgresql://abbe:pw@localhost:abc/db", "postgresql://abbe@/db?host=/tmp&port=5x",
    "postgresql://abbe@localhost:99999/db", "sqlite://relative.sqlite", "mysql://u@h/db"])
def test_a_bad_url_is_exit_2(bad, capsys):
    assert main(["history", "--db", bad, "show"]) == 2
    err = capsys.readouterr().err
    assert "--db" in err and "internal error" not in err and ":pw@" not in err


def test_nan_and_duplicate_keys_name_the_file_and_the_line(outputs, tmp_path, capsys):
    lines = (outputs / "ballbar.json").read_text().splitlines()
    at = next(i for i, ln in enumerate(lines) if '"H_um"' in ln)
    nan = lines.copy()
    nan[at] = nan[at].split(":")[0] + ": NaN,"
    (tmp_path / "nan.json").write_text("\n".join(nan))
    dup = lines.copy()
    dup.insert(at + 1, lines[at])  # the same key twice in one object
    (tmp_path / "dup.json").write_text("\n".join(dup))
    for name in ("nan.json", "dup.json"):
        assert main(["history", "--db", str(tmp_path / "h.sqlite"), "add",
                     str(tmp_path / name), "--machine", "m"]) == 2
        err = capsys.readouterr().err
        line = at + 1 if name == "nan.json" else at + 2
        assert f"{name}:{line}:" in err, err
    assert not (tmp_path / "h.sqlite").exists()


# ------------------------------------------------------------------ passwords
PASSWORD = "Pw-9zQ-never-in-a-log"


def test_a_password_is_never_written(outputs, tmp_path, capsys, monkeypatch, request):
    """Every message, crash log and output of the commands given a URL with a password
    is grepped for it: none holds it; crash logs are mode 0600."""
    root, port = request.getfixturevalue("pg_server")
    plain = new_pg_database((root, port))
    url = plain.replace("abbe@", f"abbe:{PASSWORD}@")
    crash = tmp_path / "crash"
    monkeypatch.setenv("ABBE_CRASH_DIR", str(crash))
    texts: list[str] = []
    statuses = {}

    def run(name, argv):
        capsys.readouterr()
        statuses[name] = main(argv)
        o = capsys.readouterr()
        texts.extend([o.out, o.err])
        sys.__stderr__.write(f"{name}: {statuses[name]}: {o.err.strip()[:400]}\n")

    run("add", ["history", "--db", url, "add", str(ballbar_variant(outputs, tmp_path, 1)),
                "--machine", "m"])
    run("add again (duplicate)", ["history", "--db", url, "add",
                                  str(ballbar_variant(outputs, tmp_path, 1)), "--machine", "m"])
    run("show", ["history", "--db", url, "show", "m"])
    run("show unknown machine", ["history", "--db", url, "show", "nope"])
    run("export", ["history", "--db", url, "export", "-o", str(tmp_path / "x.json")])
    run("report", ["history", "--db", url, "report", "m", "-o", str(tmp_path / "rep")])
    run("migrate", ["history", "--db", url, "migrate"])
    run("unreachable", ["history", "--db", f"postgresql://abbe:{PASSWORD}@/x?host={tmp_path}"
                        "&port=1", "show"])
    run("bad port", ["history", "--db", f"postgresql://abbe:{PASSWORD}@h:p0rt/x", "show"])
    run("no database", ["history", "--db", url.replace(plain.split("/")[3].split("?")[0],
                                                       "nodb"), "show"])
    monkeypatch.setenv("ABBE_HISTORY_DB", url)  # the URL out of the command line
    run("env", ["history", "show", "m"])
    monkeypatch.delenv("ABBE_HISTORY_DB")
    # a bug inside a command: exit 70, a crash log with the command line and traceback

    def boom(*a, **k):
        raise RuntimeError(f"simulated bug while using {url} (password={PASSWORD})")
    monkeypatch.setattr("abbe.history.store.add_campaign", boom)
    run("crash", ["history", "--db", url, "add", str(ballbar_variant(outputs, tmp_path, 2)),
                  "--machine", "m"])
    assert statuses == {"add": 0, "add again (duplicate)": 2, "show": 0,
                        "show unknown machine": 2, "export": 0, "report": 0, "migrate": 0,
                        "unreachable": 1, "bad port": 2, "no database": 2, "env": 0,
                        "crash": 70}, statuses
    logs = sorted(crash.glob("abbe-crash-*.log"))
    assert len(logs) == 1
    assert stat.S_IMODE(logs[0].stat().st_mode) == 0o600
    log = logs[0].read_text()
    assert "simulated bug" in log and "abbe:***@" in log and "password=***" in log
    written = [p for p in tmp_path.rglob("*") if p.is_file()]
    found = [p for p in written if PASSWORD.encode() in p.read_bytes()]
    found += [f"message {i}" for i, t in enumerate(texts) if PASSWORD in t]
    server_log = Path(root) / "log"
    if PASSWORD in server_log.read_text(errors="replace"):
        found.append(str(server_log))
    print(f"\npassword grep: {len(texts)} messages, {len(written)} files "
          f"({len(logs)} crash log), the server log: {len(found)} holding the password")
    assert found == []


def test_a_service_file_keeps_the_password_out_of_the_command_line(tmp_path, capsys,
                                                                   monkeypatch, request, outputs):
    root, port = request.getfixturevalue("pg_server")
    db = new_pg_database((root, port))
    name = db.split("/")[3].split("?")[0]
    (tmp_path / "pg_service.conf").write_text(
        f"[abbe-shop]\nhost={root}\nport={port}\ndbname={name}\nuser=abbe\n")
    monkeypatch.setenv("PGSERVICEFILE", str(tmp_path / "pg_service.conf"))
    assert main(["history", "--db", "postgresql:///?service=abbe-shop", "add",
                 str(ballbar_variant(outputs, tmp_path, 1)), "--machine", "m"]) == 0
    assert _count(db, "campaigns") == 1
