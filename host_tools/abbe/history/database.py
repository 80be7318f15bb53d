"""Where the history database is, opening it, and its schema revision (Alembic).

* ``--db`` takes a file path (SQLite, one file, no server) or a URL:
  ``postgresql://user@host/db`` (psycopg 3; ``postgresql+psycopg://`` and a Unix
  socket as ``postgresql:///db?host=/run/postgresql`` work too) or ``sqlite:///PATH``.
* Without ``--db``: ``$ABBE_HISTORY_DB``, else ``$XDG_DATA_HOME/abbe/history.sqlite``
  (``~/.local/share/abbe/history.sqlite``).
* A new database is created at the newest revision by ``abbe history add``; a
  database at an older revision is refused until ``abbe history migrate`` upgrades
  it (in place, data kept): several people may share it, so nobody's command
  changes the schema behind the others' backs.
* SQLite: WAL journal (readers see the last committed campaign while a writer
  adds one), a 60 s busy timeout (two writers queue, neither fails), writes in
  ``BEGIN IMMEDIATE`` transactions (no lock upgrade deadlock), foreign keys on.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from abbe.errors import AbbeInputError
from abbe.history.deps import need

#: Seconds a writer waits for another writer's transaction (SQLite busy timeout).
BUSY_TIMEOUT_S = 60.0
#: Seconds to wait for a PostgreSQL server to answer.
CONNECT_TIMEOUT_S = 10
_MIGRATIONS = Path(__file__).resolve().parent / "migrations"


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
        url = sa.engine.make_url("postgresql+psycopg://" + rest)
        return Location(url.render_as_string(hide_password=False), url.render_as_string(), None)
    if scheme == "sqlite":
        if not rest.startswith("/") or rest == "/":
            raise AbbeInputError(f"expected sqlite:///PATH, got {text!r}", field="--db")
        p = Path(rest[1:]).expanduser().absolute()
        return Location(f"sqlite:///{p}", str(p), p)
    raise AbbeInputError(f"unknown database URL scheme {scheme!r}: expected a file path, "
                         "sqlite:///PATH or postgresql://...", field="--db")


def _sqlite_engine(sa: Any, loc: Location) -> Any:
    engine = sa.create_engine(loc.url, connect_args={"timeout": BUSY_TIMEOUT_S})

    @sa.event.listens_for(engine, "connect")
    def _on_connect(dbapi_conn: Any, _record: Any) -> None:
        dbapi_conn.isolation_level = None  # we issue BEGIN ourselves
        cur = dbapi_conn.cursor()
        cur.execute(f"PRAGMA busy_timeout = {int(BUSY_TIMEOUT_S * 1000)}")
        cur.execute("PRAGMA journal_mode = WAL")
        cur.execute("PRAGMA foreign_keys = ON")
        cur.close()

    @sa.event.listens_for(engine, "begin")
    def _on_begin(conn: Any) -> None:
        mode = conn.get_execution_options().get("abbe_write", False)
        conn.exec_driver_sql("BEGIN IMMEDIATE" if mode else "BEGIN")

    return engine


class Database:
    """An open history database (an SQLAlchemy engine) at the newest schema revision."""

    def __init__(self, engine: Any, loc: Location) -> None:
        self.engine = engine
        self.location = loc

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


def upgrade(engine: Any, revision: str = "head") -> None:
    """Run the migrations up to ``revision`` in one transaction."""
    command = need("alembic.command")
    with engine.execution_options(abbe_write=True).begin() as conn:
        command.upgrade(_alembic_config(conn), revision)


class DatabaseUnreachable(Exception):
    """The database server refused or could not be reached (exit status 1)."""


def connect_error(exc: Exception, loc: Location) -> Exception:
    """A database that cannot be opened (SQLite: an input error, exit 2) or reached
    (a server: :class:`DatabaseUnreachable`, exit 1), naming it without its password."""
    msg = str(getattr(exc, "orig", None) or exc).strip().splitlines()
    text = f"cannot open the history database {loc.shown}: {msg[0] if msg else exc}"
    if loc.sqlite_file is None:
        return DatabaseUnreachable(text)
    return AbbeInputError(text, file=loc.shown, field="--db")


def open_database(db: str | None, *, create: bool = False, migrate: bool = False) -> Database:
    """Open the database ``--db``: create it (``create``), upgrade it (``migrate``) or
    refuse it when missing or at another revision than this abbe's."""
    sa = need("sqlalchemy")
    need("alembic")
    loc = resolve(db)
    if loc.sqlite_file is not None:
        f = loc.sqlite_file
        if f.is_dir():
            raise AbbeInputError("is a folder, expected a database file", file=str(f),
                                 field="--db")
        if not f.exists():
            if not create:
                raise AbbeInputError("no history database here (`abbe history add` creates "
                                     "it)", file=str(f), field="--db")
            try:
                f.parent.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise AbbeInputError(f"cannot create its folder: {exc.strerror}", file=str(f),
                                     field="--db") from None
        elif f.stat().st_size and f.open("rb").read(16) != b"SQLite format 3\x00":
            raise AbbeInputError("not an SQLite database", file=str(f), field="--db")
        engine = _sqlite_engine(sa, loc)
    else:
        engine = sa.create_engine(loc.url, connect_args={"connect_timeout": CONNECT_TIMEOUT_S})
    try:
        with engine.connect() as conn:
            rev = current_revision(conn)
            conn.rollback()
        head = head_revision()
        if rev is None:
            if not (create or migrate):
                raise AbbeInputError("the database holds no abbe history (`abbe history add` "
                                     "creates it)", file=loc.shown, field="--db")
            upgrade(engine)
        elif rev != head:
            known = rev in _known_revisions()
            if not known:
                raise AbbeInputError(f"the database is at schema revision {rev}, unknown to "
                                     f"this abbe (newest {head}): a newer abbe wrote it",
                                     file=loc.shown, field="--db")
            if not migrate:
                raise AbbeInputError(f"the database is at schema revision {rev}, this abbe "
                                     f"needs {head}: run `abbe history migrate --db ...` "
                                     "(upgrades in place, keeps every campaign)",
                                     file=loc.shown, field="--db")
            upgrade(engine)
    except sa.exc.SQLAlchemyError as exc:
        engine.dispose()
        raise connect_error(exc, loc) from None
    except BaseException:
        engine.dispose()
        raise
    return Database(engine, loc)


def _known_revisions() -> set[str]:
    script = need("alembic.script").ScriptDirectory.from_config(_alembic_config(None))
    return {r.revision for r in script.walk_revisions()}
