"""A campaign into the database in one transaction; machines, campaigns and series out.

Adding is all or nothing: the machine row (created on first use, safely when two
writers create it at once), the campaign, its instruments, temperatures, inputs,
results and tables go in one transaction; any error rolls every row back. The
campaign's content SHA-256 is unique: the same outputs added twice (by one person
or two at once) are refused with the number of the campaign that has them.
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass
from typing import Any

import sqlalchemy as sa

from abbe import __version__
from abbe.errors import AbbeInputError
from abbe.history import schema as S
from abbe.history.database import Database
from abbe.history.ingest import Campaign


@dataclass
class Meta:
    """What the person adding a campaign says about it."""

    measured_at: dt.datetime
    operator: str | None = None
    instruments: tuple[str, ...] = ()
    temperatures_c: tuple[float, ...] = ()
    note: str | None = None
    source: str = ""


def _now() -> dt.datetime:
    return dt.datetime.now(dt.timezone.utc).replace(tzinfo=None, microsecond=0)


def _insert_ignore(conn: Any, table: sa.Table, values: dict[str, Any], key: str) -> Any:
    """INSERT ... ON CONFLICT (key) DO NOTHING in this database's dialect."""
    name = conn.dialect.name
    if name == "postgresql":
        from sqlalchemy.dialects.postgresql import insert
    elif name == "sqlite":
        from sqlalchemy.dialects.sqlite import insert
    else:  # pragma: no cover -- only SQLite and PostgreSQL are supported
        raise AbbeInputError(f"unsupported database {name!r}", field="--db")
    return conn.execute(insert(table).values(**values).on_conflict_do_nothing(index_elements=[key]))


def machine_id(conn: Any, name: str, create: bool = False) -> int | None:
    """The id of machine ``name`` (created when ``create``; None when unknown)."""
    if create:
        _insert_ignore(conn, S.machines, {"name": name, "created_at": _now()}, "name")
    return conn.execute(sa.select(S.machines.c.id).where(S.machines.c.name == name)).scalar()


def add_campaign(db: Database, c: Campaign, meta: Meta) -> int:
    """Store ``c`` in one transaction; its campaign id. Refuses a campaign already stored."""
    digest = c.content_sha256()
    try:
        with db.write() as conn:
            old = conn.execute(sa.select(S.campaigns.c.id).where(
                S.campaigns.c.content_sha256 == digest)).scalar()
            if old is not None:
                raise _duplicate(old, digest)
            mid = machine_id(conn, c.machine or "", create=True)
            cid = conn.execute(sa.insert(S.campaigns).values(
                machine_id=mid, measured_at=meta.measured_at, added_at=_now(),
                operator=meta.operator, kinds=",".join(c.kinds), source=meta.source,
                content_sha256=digest, abbe_version=__version__, note=meta.note,
            ).returning(S.campaigns.c.id)).scalar_one()
            rows = [{"campaign_id": cid, "name": n} for n in meta.instruments]
            if rows:
                conn.execute(sa.insert(S.instruments), rows)
            temps = [("operator", t) for t in meta.temperatures_c] + list(c.temperatures)
            if temps:
                conn.execute(sa.insert(S.temperatures), [
                    {"campaign_id": cid, "source": s, "value_c": v} for s, v in temps])
            if c.inputs:
                conn.execute(sa.insert(S.inputs), [
                    {"campaign_id": cid, "role": r, "file": f, "sha256": h} for r, f, h in c.inputs])
            if c.results:
                conn.execute(sa.insert(S.results), [
                    {"campaign_id": cid, "series": r.series, "source": r.source,
                     "quantity": r.quantity, "axis": r.axis, "direction": r.direction,
                     "plane": r.plane, "feed_mm_min": r.feed_mm_min, "value": r.value,
                     "unit": r.unit, "ci_low": r.ci_low, "ci_high": r.ci_high}
                    for r in c.results])
            if c.tables:
                conn.execute(sa.insert(S.tables), [
                    {"campaign_id": cid, "source": s, "blob": b, "crc32": crc,
                     "size_bytes": len(b)} for s, b, crc in c.tables])
    except sa.exc.IntegrityError as exc:
        # another writer stored the same campaign between our check and our insert
        with db.read() as conn:
            old = conn.execute(sa.select(S.campaigns.c.id).where(
                S.campaigns.c.content_sha256 == digest)).scalar()
        if old is None:
            raise
        raise _duplicate(old, digest) from exc
    return int(cid)


def _duplicate(cid: int, digest: str) -> AbbeInputError:
    return AbbeInputError(f"this campaign is already in the database as campaign {cid} "
                          f"(content SHA-256 {digest[:16]}...); nothing added", field="add")


@dataclass
class Point:
    """One value of a series: its campaign and when it was measured."""

    campaign_id: int
    measured_at: dt.datetime
    value: float
    ci_low: float | None
    ci_high: float | None


@dataclass
class Series:
    """Every value of one quantity of one machine, oldest first."""

    key: str
    unit: str
    points: list[Point]


def machine_names(conn: Any) -> list[str]:
    return list(conn.execute(sa.select(S.machines.c.name).order_by(S.machines.c.name)).scalars())


def campaigns_of(conn: Any, mid: int) -> list[dict[str, Any]]:
    """The campaigns of a machine, oldest first (measured_at, then id)."""
    rows = conn.execute(sa.select(S.campaigns).where(S.campaigns.c.machine_id == mid)
                        .order_by(S.campaigns.c.measured_at, S.campaigns.c.id)).mappings()
    return [dict(r) for r in rows]


def series_of(conn: Any, mid: int) -> dict[str, Series]:
    """Every series of a machine, keyed by name, points in campaign order."""
    q = (sa.select(S.results.c.series, S.results.c.unit, S.results.c.value, S.results.c.ci_low,
                   S.results.c.ci_high, S.campaigns.c.id, S.campaigns.c.measured_at)
         .join(S.campaigns, S.campaigns.c.id == S.results.c.campaign_id)
         .where(S.campaigns.c.machine_id == mid)
         .order_by(S.results.c.series, S.campaigns.c.measured_at, S.campaigns.c.id))
    out: dict[str, Series] = {}
    for key, unit, v, lo, hi, cid, at in conn.execute(q):
        s = out.setdefault(key, Series(key, unit, []))
        s.points.append(Point(cid, at, v, lo, hi))
    return out


def require_machine(conn: Any, name: str, shown: str) -> int:
    """The id of a machine that must exist (an error naming the known ones)."""
    mid = machine_id(conn, name)
    if mid is None:
        known = ", ".join(machine_names(conn)) or "none yet"
        raise AbbeInputError(f"no machine {name!r} in the history (known: {known})",
                             file=shown, field="MACHINE")
    return mid


def record_export(db: Database, mid: int | None, kind: str, path: str, n: int) -> None:
    """Note in ``exports`` that ``path`` was written from the database."""
    with db.write() as conn:
        conn.execute(sa.insert(S.exports).values(machine_id=mid, created_at=_now(), kind=kind,
                                                 path=path, n_campaigns=n))
