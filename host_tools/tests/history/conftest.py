"""Fixtures of the history tests: real outputs of abbe (made once), and the databases.

``db`` runs a test on SQLite and on PostgreSQL: a throwaway cluster (Debian's
postgresql package) that this file starts once for the whole session in a temporary
folder, on a Unix socket only, as an unprivileged user (``abbe-pg``, created when the
tests run as root, as CI does), stopped by pid at the end. Without the package the
PostgreSQL half is skipped -- except under CI (``$CI`` set), where it fails.
"""

from __future__ import annotations

import glob
import json
import os
import pwd
import shutil
import signal
import subprocess
import tempfile
import time
from pathlib import Path

import pytest

from abbe.cli.entry import main

REPO = Path(__file__).resolve().parents[3]
EXAMPLE = REPO / "examples" / "vmc500"
PG_USER = "abbe-pg"
PG_START_TIMEOUT_S = 60


@pytest.fixture(scope="session")
def outputs(tmp_path_factory) -> Path:
    """OUT/fit (abbe fit), OUT/diagnose (abbe diagnose with the ballbar), OUT/ballbar.json
    (abbe ballbar --json), OUT/iso_x.json (abbe iso230-2 --json) of examples/vmc500."""
    out = tmp_path_factory.mktemp("outputs")
    m = str(EXAMPLE / "machine.toml")
    assert main(["fit", m, "-o", str(out / "fit"), "--no-report", "-q"]) == 0
    assert main(["diagnose", m, "--model", str(out / "fit" / "model.bin"), "--ballbar",
                 "circle1", "-o", str(out / "diagnose"), "--no-plots"]) == 0
    from abbe.analysis.iso230_2 import evaluate
    from abbe.analysis.iso230_4 import evaluate_ballbar
    from abbe.formats.ballbar_csv import read_ballbar_csv
    from abbe.formats.machine import load_machine
    from abbe.formats.positioning import load_positioning
    from abbe.model.geometry import from_machine
    mach = load_machine(m)
    bt = mach.ballbar["circle1"]
    res = evaluate_ballbar(read_ballbar_csv(bt.file, columns=bt.columns), from_machine(bt))
    # the same JSON the commands print (abbe ballbar --json, abbe iso230-2 --json)
    (out / "ballbar.json").write_text(json.dumps(
        {"machine": m, "file": str(bt.file), **res.to_json(), "plot": None}, indent=2))
    x = str(EXAMPLE / "laser" / "x.csv")
    (out / "iso_x.json").write_text(json.dumps({"file": x, **evaluate(load_positioning(x)).to_json()},
                                               indent=2))
    return out


def ballbar_variant(outputs: Path, dest: Path, i: int) -> Path:
    """A ballbar JSON like the real one with G shifted by i x 0.01 um: another campaign."""
    d = json.loads((outputs / "ballbar.json").read_text())
    d["bidirectional"]["G_um"] = round(d["bidirectional"]["G_um"] + 0.01 * i, 4)
    dest.mkdir(parents=True, exist_ok=True)
    p = dest / f"ballbar_{i}.json"
    p.write_text(json.dumps(d, indent=2))
    return p


# ------------------------------------------------------------------ PostgreSQL
def _pg_bin() -> Path | None:
    found = sorted(glob.glob("/usr/lib/postgresql/*/bin/initdb"))
    return Path(found[-1]).parent if found else None


def _as_user(cmd: list[str]) -> list[str]:
    if os.geteuid() != 0:
        return cmd
    return ["runuser", "-u", PG_USER, "--", *cmd]


@pytest.fixture(scope="session")
def pg_server():
    """A PostgreSQL cluster for the session: (socket folder, port). One per session."""
    bin_dir = _pg_bin()
    if bin_dir is None:
        if os.environ.get("CI"):
            pytest.fail("PostgreSQL (initdb) not installed: scripts/setup.sh installs it")
        pytest.skip("PostgreSQL not installed (apt-get install postgresql)")
    if os.geteuid() == 0:
        try:
            pwd.getpwnam(PG_USER)
        except KeyError:
            subprocess.run(["useradd", "--system", "--no-create-home", "--shell", "/usr/sbin/nologin",
                            "--comment", "abbe PostgreSQL tests", PG_USER], check=True)
    root = Path(tempfile.mkdtemp(prefix="abbe-pg-"))
    if os.geteuid() == 0:
        shutil.chown(root, PG_USER)
    data = root / "data"
    port = "5432"
    subprocess.run(_as_user([str(bin_dir / "initdb"), "-D", str(data), "-U", "abbe",
                             "--auth=trust", "--no-sync", "-E", "UTF8", "--locale=C"]),
                   check=True, stdout=subprocess.DEVNULL, timeout=120)
    opts = f"-k {root} -c listen_addresses='' -p {port} -c fsync=off -c max_connections=50"
    subprocess.run(_as_user([str(bin_dir / "pg_ctl"), "-D", str(data), "-l", str(root / "log"),
                             "-o", opts, "-w", "-t", str(PG_START_TIMEOUT_S), "start"]),
                   check=True, stdout=subprocess.DEVNULL, timeout=PG_START_TIMEOUT_S + 10)
    pid = int((data / "postmaster.pid").read_text().split()[0])
    try:
        yield root, port
    finally:
        try:  # fast shutdown by pid; then make sure it is gone, bounded in time
            os.kill(pid, signal.SIGINT)
            for _ in range(100):
                os.kill(pid, 0)
                time.sleep(0.1)
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        shutil.rmtree(root, ignore_errors=True)


_counter = [0]


@pytest.fixture(params=["sqlite", "postgresql"])
def db(request, tmp_path) -> str:
    """The --db of one test: a new SQLite file, or a new database on the session's server."""
    if request.param == "sqlite":
        return str(tmp_path / "history.sqlite")
    root, port = request.getfixturevalue("pg_server")
    import psycopg
    _counter[0] += 1
    name = f"t{os.getpid()}_{_counter[0]}"
    with psycopg.connect(host=str(root), port=port, user="abbe", dbname="postgres",
                         autocommit=True) as conn:
        conn.execute(f"CREATE DATABASE {name}")
    return f"postgresql://abbe@/{name}?host={root}&port={port}"


def new_pg_database(pg_server) -> str:
    """A new, empty database on the session's server: its --db URL (user abbe)."""
    root, port = pg_server
    import psycopg
    _counter[0] += 1
    name = f"t{os.getpid()}_{_counter[0]}"
    with psycopg.connect(host=str(root), port=port, user="abbe", dbname="postgres",
                         autocommit=True) as conn:
        conn.execute(f"CREATE DATABASE {name}")
    return f"postgresql://abbe@/{name}?host={root}&port={port}"


def pg_admin(url: str):
    """A psycopg connection (autocommit, superuser abbe) to the database of ``url``."""
    import psycopg
    from urllib.parse import parse_qs, urlsplit
    u = urlsplit(url)
    q = parse_qs(u.query)
    return psycopg.connect(host=q["host"][0], port=q["port"][0], user="abbe",
                           dbname=u.path.lstrip("/"), autocommit=True)


def raw_sqlite(path: str):
    """A plain sqlite3 connection to a history file (no abbe, no SQLAlchemy)."""
    import sqlite3
    return sqlite3.connect(path, isolation_level=None)


def run_forked(argv: list[str], out_dir: Path, as_nobody: bool = False,
               env: dict | None = None, timeout_s: float = 300) -> tuple[int, str, str]:
    """``abbe`` ARGV in a forked child (optionally as the user nobody, so that file
    permissions apply although the tests run as root): (status, stdout, stderr)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    os.chmod(out_dir, 0o777)
    tag = os.urandom(4).hex()
    fo, fe = out_dir / f"out_{tag}", out_dir / f"err_{tag}"
    pid = os.fork()
    if pid == 0:  # the child: never returns into pytest
        rc = 70
        try:
            fdo = os.open(fo, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
            fde = os.open(fe, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
            os.dup2(fdo, 1)
            os.dup2(fde, 2)
            import sys
            sys.stdout = os.fdopen(1, "w", closefd=False)
            sys.stderr = os.fdopen(2, "w", closefd=False)
            if as_nobody and os.geteuid() == 0:
                os.setgroups([])
                os.setgid(65534)
                os.setuid(65534)
                os.environ["HOME"] = str(out_dir)
                os.environ["MPLCONFIGDIR"] = str(out_dir)
                os.environ["ABBE_CRASH_DIR"] = str(out_dir / "crash")
            os.environ.update(env or {})
            rc = main(argv)
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            os._exit(rc)
    deadline = time.monotonic() + timeout_s
    while True:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        if time.monotonic() > deadline:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            raise AssertionError(f"abbe {argv} did not finish within {timeout_s} s")
        time.sleep(0.05)
    return os.waitstatus_to_exitcode(status), fo.read_text(), fe.read_text()
