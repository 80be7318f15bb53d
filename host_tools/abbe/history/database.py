"""Where the history database is, opening it, its schema revision (Alembic), and what
every database condition means for the user (exit status and message).

* ``--db`` takes a file path (SQLite, one file, no server) or a URL:
  ``postgresql://user@host/db`` (psycopg 3; ``postgresql+psycopg://``, a Unix
  socket as ``postgresql:///db?host=/run/postgresql`` and a service of the
  libpq service file as ``postgresql:///?service=NAME`` work too) or ``sqlite:///PATH``.
* Without ``--db``: ``$ABBE_HISTORY_DB``, else ``$XDG_DATA_HOME/abbe/history.sqlite``
  (``~/.local/share/abbe/history.sqlite``).
* A password is never shown: every message names the database by its path or its
  URL with the password masked (:func:`mask_secrets`).
* A new database is created at the newest revision by ``abbe history add``, under a
  lock (PostgreSQL: an advisory transaction lock; SQLite: the write lock of
  ``BEGIN IMMEDIATE``) and re-checked inside it, so two first writers cannot both
  create the tables. A database at an older revision is refused until ``abbe history
  migrate`` upgrades it (in place, data kept): several people may share it, so
  nobody's command changes the schema behind the others' backs.
* SQLite: a file that is not an abbe history (another program's tables) is refused
  before anything is written (no journal-mode switch, no table); the folder of a new
  file is created only when asked (``create_dirs``); a file this user cannot write is
  opened read-only (readers work; writers are refused, exit 2). WAL journal (set once,
  when abbe creates the file), a 60 s busy timeout, writes in ``BEGIN IMMEDIATE``
  transactions (no lock upgrade deadlock), foreign keys on.
* Every database error is classified (:func:`classify`): bad or read-only database ->
  :class:`AbbeInputError` (exit 2); a server lost or a lock held too long ->
  :class:`DatabaseUnreachable` (exit 1, "retry"; nothing partial was stored).
"""

from __future__ import annotations

import os
import re
import sqlite3
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any
from urllib.parse import quote

from abbe.errors import AbbeInputError
from abbe.history.deps import need

#: Seconds a writer waits for another writer's transaction (SQLite busy timeout).
BUSY_TIMEOUT_S = 60.0
#: Seconds to wait for a PostgreSQL server to answer.
CONNECT_TIMEOUT_S = 10
#: Key of the PostgreSQL advisory lock taken around schema creation and migration
#: (any 64-bit number; this one is b"abbehist" read as an integer).
SCHEMA_LOCK_KEY = 0x6162626568697374
#: The tables abbe's first revision creates: a database holding some of them but no
#: abbe revision stamp is another program's, never written.
ABBE_TABLES = ("machines", "campaigns", "instruments", "temperatures", "inputs", "results",
               "tables", "exports")
_MIGRATIONS = Path(__file__).resolve().parent / "migrations"

_URL_USERINFO = re.compile(r"(?P<head>[A-Za-z][A-Za-z0-9+.\-]*://[^:/@\s]*:)[^@\s]*@")
_PASSWORD_PARAM = re.compile(r"(?i)\b(?P<key>password|passwd|pwd)(?P<eq>\s*=\s*)"
                             r"(?:'[^']*'|\"[^\"]*\"|[^&\s'\"]+)")


def mask_secrets(text: str) -> str:
    """``text`` with every URL password (``scheme://user:SECRET@``) and every
    ``password=SECRET`` (a URL query, a libpq conninfo) replaced by ``***``."""
    text = _URL_USERINFO.sub(lambda m: m.group("head") + "***@", text)
    return _PASSWORD_PARAM.sub(lambda m: m.group("key") + m.group("eq") + "***", text)


def default_location() -> Path:
    """``$XDG_DATA_HOME/abbe/history.sqlite`` (``~/.local/share/abbe/history.sqlite``)."""
    data = os.environ.get("XDG_DATA_HOME") or os.path.join(os.path.expanduser("~"), ".local",
                                                           "share")
    return Path(data) / "abbe" / "history.sqlite"


@dataclass(frozen=True)
class Location:
    """A resolved ``--db``: the SQLAlchemy URL and, for SQLite, the file."""

    url: str
    shown: str  # for messages: the path, or the URL without its password
    sqlite_file: Path | None


def resolve(db: str | None) -> Location:
    """The database named by ``--db`` / ``$ABBE_HISTORY_DB`` / the default location."""
    text = db if db is not None else os.environ.get("ABBE_HISTORY_DB") or str(default_location())
    if not text.strip():
        raise AbbeInputError("empty database name", field="--db")
    if "://" not in text:
        p = Path(text).expanduser().absolute()
        return Location(f"sqlite:///{p}", str(p), p)
    scheme, rest = text.split("://", 1)
    scheme = scheme.lower()
    if scheme in ("postgresql", "postgres", "postgresql+psycopg"):
        need("psycopg", "a PostgreSQL history database")
        sa = need("sqlalchemy")
        expected = ("expected postgresql://USER@HOST[:PORT]/DB or "
                    "postgresql:///DB?host=SOCKET_DIR[&port=PORT] (PORT a number 1..65535)")
        try:
            url = sa.engine.make_url("postgresql+psycopg://" + rest)
            ports = [url.port] if url.port is not None else []
        except (ValueError, TypeError, sa.exc.ArgumentError) as exc:
            raise AbbeInputError(f"not a database URL ({mask_secrets(str(exc))}): "
                                 f"{mask_secrets(text)}; {expected}", field="--db") from None
        q = url.query.get("port")
        for p in (q if isinstance(q, tuple) else [q] if q is not None else []):
            ports.append(p)
        for p in ports:
            if not str(p).isdigit() or not 1 <= int(p) <= 65535:
                raise AbbeInputError(f"port {str(p)[:20]!r} is not a number 1..65535: "
                                     f"{mask_secrets(text)}; {expected}", field="--db")
        return Location(url.render_as_string(hide_password=False), url.render_as_string(), None)
    if scheme == "sqlite":
        if not rest.startswith("/") or rest == "/":
            raise AbbeInputError(f"expected sqlite:///PATH, got {mask_secrets(text)!r}",
                                 field="--db")
        p = Path(rest[1:]).expanduser().absolute()
        return Location(f"sqlite:///{p}", str(p), p)
    raise AbbeInputError(f"unknown database URL scheme {scheme!r}: expected a file path, "
                         "sqlite:///PATH or postgresql://...", field="--db")


class _BadText(str):
    """A TEXT value of SQLite that is not UTF-8 (kept as bytes for the message)."""

    raw: bytes = b""


def _text_factory(raw: bytes) -> str:
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        bad = _BadText(raw.decode("utf-8", "replace"))
        bad.raw = raw
        return bad


def _sqlite_engine(sa: Any, loc: Location, mode: str = "rw") -> Any:
    """An engine on the SQLite file ``loc`` opened with ``mode`` (``ro``, ``rw``,
    ``rwc``): a reader never creates the file, a writer never switches its journal."""
    assert loc.sqlite_file is not None
    uri = f"file:{quote(str(loc.sqlite_file))}?mode={mode}"

    def connect() -> Any:
        return sqlite3.connect(uri, uri=True, timeout=BUSY_TIMEOUT_S, check_same_thread=False)

    engine = sa.create_engine("sqlite+pysqlite://", creator=connect)

    @sa.event.listens_for(engine, "connect")
    def _on_connect(dbapi_conn: Any, _record: Any) -> None:
        dbapi_conn.isolation_level = None  # we issue BEGIN ourselves
        dbapi_conn.text_factory = _text_factory
        cur = dbapi_conn.cursor()
        cur.execute(f"PRAGMA busy_timeout = {int(BUSY_TIMEOUT_S * 1000)}")
        cur.execute("PRAGMA foreign_keys = ON")
        cur.close()

    @sa.event.listens_for(engine, "begin")
    def _on_begin(conn: Any) -> None:
        mode_ = conn.get_execution_options().get("abbe_write", False)
        conn.exec_driver_sql("BEGIN IMMEDIATE" if mode_ else "BEGIN")

    return engine


class Database:
    """An open history database (an SQLAlchemy engine) at the newest schema revision."""

    def __init__(self, engine: Any, loc: Location, read_only: bool = False) -> None:
        self.engine = engine
        self.location = loc
        #: this user cannot write it (an SQLite file without write permission)
        self.read_only = read_only

    @property
    def dialect(self) -> str:
        return str(self.engine.dialect.name)

    def write(self) -> Any:
        """A connection in a write transaction (``with db.write() as conn``): all or nothing."""
        return self.engine.execution_options(abbe_write=True).begin()

    def read(self) -> Any:
        """A connection in a read transaction that sees one committed state throughout."""
        eng = self.engine
        if eng.dialect.name == "postgresql":
            eng = eng.execution_options(isolation_level="REPEATABLE READ")
        return eng.begin()

    def close(self) -> None:
        self.engine.dispose()


def _alembic_config(conn: Any) -> Any:
    config = need("alembic.config").Config()
    config.set_main_option("script_location", str(_MIGRATIONS))
    config.attributes["connection"] = conn
    return config


def head_revision() -> str:
    """The newest revision of the migrations shipped with abbe."""
    script = need("alembic.script").ScriptDirectory.from_config(_alembic_config(None))
    return str(script.get_current_head())


def current_revision(conn: Any) -> str | None:
    """The revision a database is at (None: no abbe schema yet)."""
    mc = need("alembic.runtime.migration").MigrationContext.configure(conn)
    return mc.get_current_revision()


def _lock_schema(conn: Any) -> None:
    """Serialise schema creation and migration between processes, inside ``conn``'s
    transaction (released at its end). SQLite: the transaction is ``BEGIN IMMEDIATE``,
    which already holds the database's write lock."""
    if conn.dialect.name == "postgresql":
        conn.exec_driver_sql(f"SELECT pg_advisory_xact_lock({SCHEMA_LOCK_KEY})")


def upgrade(engine: Any, revision: str = "head") -> None:
    """Run the migrations up to ``revision`` in one transaction, under the schema lock."""
    command = need("alembic.command")
    with engine.execution_options(abbe_write=True).begin() as conn:
        _lock_schema(conn)
        command.upgrade(_alembic_config(conn), revision)


class DatabaseUnreachable(Exception):
    """The database cannot be used now (a server refused, lost, or a lock held too long):
    exit status 1, the message says to retry; nothing partial was stored."""


class DatabaseReadOnly(AbbeInputError):
    """The database is read-only for this user (exit status 2 for a command that writes)."""


_SQLITE_BUSY = ("database is locked", "database table is locked", "database is busy")
_SQLITE_READONLY = ("readonly database", "read-only", "attempt to write a readonly")
_SQLITE_BAD = ("file is not a database", "malformed", "no such table", "no such column",
               "unable to open database file")


def classify(exc: BaseException, loc: Location, *, writing: bool = False) -> Exception:
    """The user-facing error for a database error ``exc`` (module docstring): an
    :class:`AbbeInputError` (exit 2) or a :class:`DatabaseUnreachable` (exit 1)."""
    sa = need("sqlalchemy")
    orig = getattr(exc, "orig", None) or exc
    lines = mask_secrets(str(orig)).strip().splitlines()
    text = lines[0] if lines else type(orig).__name__
    stored = " nothing was stored (the transaction was rolled back);" if writing else ""
    name = loc.shown
    if loc.sqlite_file is not None:
        low = text.lower()
        if any(s in low for s in _SQLITE_READONLY):
            return DatabaseReadOnly(f"the database is read-only for this user ({text});"
                                    f"{stored or ' nothing was written'}", file=name,
                                    field="--db")
        if any(s in low for s in _SQLITE_BUSY):
            return DatabaseUnreachable(
                f"the history database {name} stayed locked by another writer for more than "
                f"{BUSY_TIMEOUT_S:g} s ({text});{stored} retry when the other writer is done")
        if any(s in low for s in _SQLITE_BAD):
            return AbbeInputError(f"cannot use the database: {text} (damaged, or not an abbe "
                                  "history)", file=name, field="--db")
        return DatabaseUnreachable(f"cannot use the history database {name}: {text};{stored} "
                                   "retry (a full disk or an I/O error: check the file's disk)")
    state = str(getattr(orig, "sqlstate", "") or "")
    if state == "25006" or state == "42501":  # read-only transaction, insufficient privilege
        return DatabaseReadOnly(f"the database is read-only for this user ({text});"
                                f"{stored or ' nothing was written'}", file=name, field="--db")
    if state.startswith("22"):  # data exception: a stored value abbe cannot read
        return AbbeInputError(f"the database holds a value abbe cannot read: {text}",
                              file=name, field="--db")
    if state.startswith("42") or state.startswith("3D") or state.startswith("28"):
        return AbbeInputError(f"cannot use the database: {text}", file=name, field="--db")
    if isinstance(exc, sa.exc.ProgrammingError) and not state:
        # psycopg: an invalid connection option (e.g. a port that is not a number)
        return AbbeInputError(f"cannot use the database URL: {text}", file=name, field="--db")
    low = text.lower()
    if any(k in low for k in ("does not exist", "authentication failed", "no password supplied",
                              "permission denied", "pg_hba.conf")):
        # the server answered: the database, the role or its password is wrong (no retry helps)
        return AbbeInputError(f"the server refused: {text} (check the database name, the role "
                              "and its password: ~/.pgpass or a service file)", file=name,
                              field="--db")
    if state in ("40001", "40P01"):
        return DatabaseUnreachable(f"the history database {name} refused the transaction "
                                   f"({text});{stored} retry")
    return DatabaseUnreachable(f"lost or cannot reach the history database {name}: {text};"
                               f"{stored} retry when the server is reachable")


def connect_error(exc: Exception, loc: Location) -> Exception:
    """A database that cannot be opened, named without its password (:func:`classify`)."""
    out = classify(exc, loc)
    if isinstance(out, DatabaseUnreachable):
        return DatabaseUnreachable(f"cannot open the history database {loc.shown}: "
                                   f"{str(out).split(': ', 1)[-1]}")
    return out


def _sqlite_tables(f: Path) -> set[str]:
    """The tables of the SQLite file ``f``, read without writing anything to it."""
    try:
        con = sqlite3.connect(f"file:{quote(str(f))}?mode=ro", uri=True, timeout=BUSY_TIMEOUT_S)
        try:
            return {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        finally:
            con.close()
    except sqlite3.Error as exc:
        if "readonly" in str(exc) and not os.access(f.parent, os.W_OK | os.X_OK):
            raise AbbeInputError(
                f"cannot read it: its write-ahead log needs {f.name}-shm beside it and this "
                f"user cannot create files in {f.parent} (give the readers write permission on "
                "the folder, the file itself may stay read-only)", file=str(f),
                field="--db") from None
        raise AbbeInputError(f"cannot read it as an SQLite database: {exc}", file=str(f),
                             field="--db") from None


def _foreign(tables: set[str], f: str) -> AbbeInputError | None:
    """The refusal of a database that holds another program's tables (None: abbe's or empty)."""
    ours = {"alembic_version", *ABBE_TABLES}
    if not tables:
        return None
    if "alembic_version" in tables and {"machines", "campaigns"} <= tables:
        return None
    other = sorted(tables - ours) or sorted(tables)
    return AbbeInputError("not an abbe history: it holds other tables ("
                          + ", ".join(other[:6]) + (", ..." if len(other) > 6 else "")
                          + "), another program's database? Nothing was written to it",
                          file=f, field="--db")


def _writable(f: Path) -> bool:
    return os.access(f, os.W_OK) and os.access(f.parent, os.W_OK | os.X_OK)


def open_database(db: str | None, *, create: bool = False, migrate: bool = False,
                  write: bool = False, create_dirs: bool = False) -> Database:
    """Open the database ``--db``: create it (``create``; its folder too only with
    ``create_dirs``), upgrade it (``migrate``) or refuse it when missing, foreign or at
    another revision than this abbe's; ``write``: refuse a read-only one now (exit 2),
    before anything is written."""
    sa = need("sqlalchemy")
    need("alembic")
    loc = resolve(db)
    read_only = False
    new_file = False
    if loc.sqlite_file is not None:
        f = loc.sqlite_file
        if f.is_dir():
            raise AbbeInputError("is a folder, expected a database file", file=str(f),
                                 field="--db")
        if not f.exists():
            if not create:
                raise AbbeInputError("no history database here (`abbe history add` creates "
                                     "it)", file=str(f), field="--db")
            if not f.parent.is_dir():
                if not create_dirs:
                    raise AbbeInputError(f"its folder {f.parent} does not exist (a typo? "
                                         "`--create` creates it); nothing was written",
                                         file=str(f), field="--db")
                try:
                    f.parent.mkdir(parents=True, exist_ok=True)
                except OSError as exc:
                    raise AbbeInputError(f"cannot create its folder: {exc.strerror}",
                                         file=str(f), field="--db") from None
            if not os.access(f.parent, os.W_OK | os.X_OK):
                raise DatabaseReadOnly(f"cannot create it: its folder {f.parent} is not "
                                       "writable for this user", file=str(f), field="--db")
            new_file = True
        else:
            if f.stat().st_size and f.open("rb").read(16) != b"SQLite format 3\x00":
                raise AbbeInputError("not an SQLite database", file=str(f), field="--db")
            bad = _foreign(_sqlite_tables(f), str(f))
            if bad is not None:
                raise bad
            read_only = not _writable(f)
            if read_only and (write or create or migrate):
                raise DatabaseReadOnly("the database is read-only for this user (no write "
                                       "permission on the file or its folder); nothing was "
                                       "written", file=str(f), field="--db")
        engine = _sqlite_engine(sa, loc, "rwc" if new_file else "ro" if read_only else "rw")
    else:
        engine = sa.create_engine(loc.url, connect_args={"connect_timeout": CONNECT_TIMEOUT_S})
    try:
        with engine.connect() as conn:
            # The tables first, then the revision: each statement sees what is committed
            # when it runs (READ COMMITTED), and a first writer commits its tables and its
            # revision together, so tables seen before mean a revision seen after; in the
            # other order a writer committing in between looked like a foreign database.
            tables = (set(sa.inspect(conn).get_table_names()) if loc.sqlite_file is None
                      else set())
            rev = current_revision(conn)
            if rev is None and loc.sqlite_file is None:
                bad = _foreign(tables & set(ABBE_TABLES), loc.shown)
                if bad is not None:
                    raise bad
            conn.rollback()
        head = head_revision()
        if rev is None:
            if not (create or migrate):
                raise AbbeInputError("the database holds no abbe history (`abbe history add` "
                                     "creates it)", file=loc.shown, field="--db")
            _create(sa, engine, loc)
        elif rev != head:
            if rev not in _known_revisions():
                raise AbbeInputError(f"the database is at schema revision {rev}, unknown to "
                                     f"this abbe (newest {head}): a newer abbe wrote it",
                                     file=loc.shown, field="--db")
            if not migrate:
                raise AbbeInputError(f"the database is at schema revision {rev}, this abbe "
                                     f"needs {head}: run `abbe history migrate --db ...` "
                                     "(upgrades in place, keeps every campaign)",
                                     file=loc.shown, field="--db")
            upgrade(engine)
        if write and loc.sqlite_file is None:
            _check_pg_writable(sa, engine, loc)
    except (sa.exc.SQLAlchemyError, sqlite3.Error) as exc:
        engine.dispose()
        raise connect_error(exc, loc) from None
    except BaseException:
        engine.dispose()
        if new_file:  # a file this call created and could not make an abbe history
            _remove_if_empty(loc.sqlite_file)
        raise
    return Database(engine, loc, read_only=read_only)


def _create(sa: Any, engine: Any, loc: Location) -> None:
    """Create abbe's tables: under the schema lock, re-checking the revision inside it
    (the loser of a race of two first writers finds the tables made and goes on)."""
    command = need("alembic.command")
    with engine.execution_options(abbe_write=True).begin() as conn:
        _lock_schema(conn)
        rev = current_revision(conn)
        if rev is None:
            if loc.sqlite_file is not None:
                bad = _foreign(set(sa.inspect(conn).get_table_names()), loc.shown)
                if bad is not None:
                    raise bad
            command.upgrade(_alembic_config(conn), "head")
    if loc.sqlite_file is not None:  # abbe's own file now: write-ahead log, set once
        _set_wal(engine)


def _set_wal(engine: Any) -> None:
    """Switch abbe's new SQLite file to WAL. The switch needs the file to itself and
    SQLite does not wait for it (no busy handler): retried up to the busy timeout while
    other first writers are at work."""
    deadline = time.monotonic() + BUSY_TIMEOUT_S
    while True:
        raw = engine.raw_connection()
        try:
            cur = raw.driver_connection
            if str(cur.execute("PRAGMA journal_mode").fetchone()[0]).lower() == "wal":
                return
            cur.execute("PRAGMA journal_mode = WAL")
            return
        except sqlite3.OperationalError as exc:
            if not any(b in str(exc) for b in _SQLITE_BUSY) or time.monotonic() > deadline:
                raise
        finally:
            raw.close()
        time.sleep(0.05)


def _check_pg_writable(sa: Any, engine: Any, loc: Location) -> None:
    """Refuse (exit 2) a PostgreSQL database this role cannot write, before any write."""
    with engine.connect() as conn:
        ro = conn.exec_driver_sql("SHOW transaction_read_only").scalar() == "on"
        missing = [t for t in ("machines", "campaigns", "results", "audit") if not conn.execute(
            sa.text("SELECT has_table_privilege(:t, 'INSERT')"), {"t": t}).scalar()]
        conn.rollback()
    if ro or missing:
        why = "read-only transactions" if ro else "no INSERT privilege on " + ", ".join(missing)
        raise DatabaseReadOnly(f"the database is read-only for this user ({why}); nothing was "
                               "written", file=loc.shown, field="--db")


def _remove_if_empty(f: Path | None) -> None:
    if f is not None and f.exists() and f.stat().st_size == 0:
        f.unlink()


def _known_revisions() -> set[str]:
    script = need("alembic.script").ScriptDirectory.from_config(_alembic_config(None))
    return {r.revision for r in script.walk_revisions()}
