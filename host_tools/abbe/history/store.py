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
from abbe.history.database import Database, DatabaseReadOnly, classify
from abbe.history.ingest import Campaign
from abbe.history.readback import fetch


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


def add_campaign(db: Database, c: Campaign, meta: Meta) -> int:
    """Store ``c`` in one transaction; its campaign id. Refuses a campaign already stored."""
    digest = c.content_sha256()
    try:
        with db.write() as conn:
            old = conn.execute(sa.select(S.campaigns.c.id).where(
                S.campaigns.c.content_sha256 == digest)).scalar()
            if old is not None:
                raise _duplicate(conn, old, digest)
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
                     "unit": r.unit, "ci_low": r.ci_low, "ci_high": r.ci_high,
                     "expanded_u": r.U, "coverage_k": None if r.U is None else r.k}
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
            dup = _duplicate(conn, old, digest)
        raise dup from exc
    return int(cid)


def _duplicate(conn: Any, cid: int, digest: str) -> AbbeInputError:
    removed = conn.execute(sa.select(S.campaigns.c.removed_at.is_not(None)).where(
        S.campaigns.c.id == cid)).scalar()
    how = (" (removed: `abbe history show MACHINE --removed` shows why; a removed campaign "
           "keeps its content)") if removed else ""
    return AbbeInputError(f"this campaign is already in the database as campaign {cid}{how} "
                          f"(content SHA-256 {digest[:16]}...); nothing added", field="add")


@dataclass
class Point:
    """One value of a series: its campaign and when it was measured (UTC, naive)."""

    campaign_id: int
    measured_at: dt.datetime
    value: float
    ci_low: float | None
    ci_high: float | None
    #: expanded uncertainty (the series' unit) and its coverage factor; None: not stated
    U: float | None = None
    k: float | None = None


@dataclass
class Series:
    """Every value of one quantity of one machine, oldest first."""

    key: str
    unit: str
    points: list[Point]


def machine_names(conn: Any, shown: str | None = None) -> list[str]:
    """Every machine's name, sorted (each checked as read)."""
    return sorted(r["name"] for r in fetch(conn, S.machines, shown=shown))


def machine_id(conn: Any, name: str, create: bool = False) -> int | None:
    """The id of machine ``name`` (created when ``create``; None when unknown)."""
    if create:
        _insert_ignore(conn, S.machines, {"name": name, "created_at": _now()}, "name")
    return conn.execute(sa.select(S.machines.c.id).where(S.machines.c.name == name)).scalar()


def _live(removed: bool) -> list[Any]:
    return [] if removed else [S.campaigns.c.removed_at.is_(None)]


def campaigns_of(conn: Any, mid: int, shown: str | None = None,
                 removed: bool = False) -> list[dict[str, Any]]:
    """The campaigns of a machine, oldest first (measured_at, then id), every field
    checked; removed ones only when ``removed``."""
    return fetch(conn, S.campaigns, S.campaigns.c.machine_id == mid, *_live(removed),
                 order_by=[S.campaigns.c.measured_at, S.campaigns.c.id], shown=shown)


def series_of(conn: Any, mid: int, shown: str | None = None,
              camps: list[dict[str, Any]] | None = None) -> dict[str, Series]:
    """Every series of a machine's campaigns (not removed), keyed by name, points in
    campaign order; every value checked as read."""
    camps = campaigns_of(conn, mid, shown) if camps is None else camps
    order = {c["id"]: i for i, c in enumerate(camps)}
    at = {c["id"]: c["measured_at"] for c in camps}
    ids = sa.select(S.campaigns.c.id).where(S.campaigns.c.machine_id == mid,
                                            S.campaigns.c.removed_at.is_(None))
    rows = fetch(conn, S.results, S.results.c.campaign_id.in_(ids), shown=shown,
                 columns=["campaign_id", "series", "unit", "value", "ci_low", "ci_high",
                          "expanded_u", "coverage_k"])
    rows = [r for r in rows if r["campaign_id"] in order]
    rows.sort(key=lambda r: (r["series"], order[r["campaign_id"]], r["id"]))
    out: dict[str, Series] = {}
    for r in rows:
        s = out.setdefault(r["series"], Series(r["series"], r["unit"], []))
        s.points.append(Point(r["campaign_id"], at[r["campaign_id"]], r["value"], r["ci_low"],
                              r["ci_high"], r["expanded_u"], r["coverage_k"]))
    return out


def require_machine(conn: Any, name: str, shown: str) -> int:
    """The id of a machine that must exist (an error naming the known ones)."""
    mid = machine_id(conn, name)
    if mid is None:
        known = ", ".join(machine_names(conn, shown)) or "none yet"
        raise AbbeInputError(f"no machine {name!r} in the history (known: {known})",
                             file=shown, field="MACHINE")
    return mid


def record_export(conn: Any, mid: int | None, kind: str, path: str, n: int) -> None:
    """Note in ``exports`` that ``path`` was written from the database (in ``conn``'s
    write transaction: the caller commits it with the output)."""
    conn.execute(sa.insert(S.exports).values(machine_id=mid, created_at=_now(), kind=kind,
                                             path=path, n_campaigns=n))


def try_record_export(db: Database, mid: int | None, kind: str, path: str, n: int) -> str | None:
    """Record an export in its own transaction; a note (the reason) instead when this user
    cannot write the database (a read-only file, a SELECT-only role): reading needs no
    write. Any other database error is raised, classified (exit 1 or 2)."""
    why = "the database is read-only for this user"
    if db.read_only:
        return f"not recorded in the database's exports ({why})"
    try:
        with db.write() as conn:
            record_export(conn, mid, kind, path, n)
    except sa.exc.DBAPIError as exc:
        err = classify(exc, db.location)
        if isinstance(err, DatabaseReadOnly):
            return f"not recorded in the database's exports ({why})"
        raise err from None
    return None


# ------------------------------------------------------------------ corrections
#: The fields ``abbe history amend`` corrects (option -> campaigns column).
AMENDABLE = ("machine", "measured_at", "operator", "note")


def _text_of(v: Any) -> str | None:
    if v is None:
        return None
    if isinstance(v, dt.datetime):
        return v.strftime("%Y-%m-%d %H:%M:%S")
    return str(v)


def live_campaign(conn: Any, cid: int, shown: str) -> dict[str, Any]:
    """Campaign ``cid`` (checked), refused when unknown or already removed."""
    rows = fetch(conn, S.campaigns, S.campaigns.c.id == cid, shown=shown)
    if not rows:
        raise AbbeInputError(f"no campaign {cid} in the history (`abbe history show MACHINE "
                             "--campaigns` lists them with their ids)", file=shown,
                             field="CAMPAIGN")
    if rows[0]["removed_at"] is not None:
        raise AbbeInputError(f"campaign {cid} was removed on "
                             f"{rows[0]['removed_at']:%Y-%m-%d %H:%M} UTC (`show MACHINE "
                             "--removed` shows why); nothing changed",
                             file=shown, field="CAMPAIGN")
    return rows[0]


def remove_campaign(db: Database, cid: int, who: str, reason: str) -> dict[str, Any]:
    """Mark campaign ``cid`` removed (kept, hidden from trends) with an audit row."""
    with db.write() as conn:
        c = live_campaign(conn, cid, db.location.shown)
        now = _now()
        conn.execute(sa.update(S.campaigns).where(S.campaigns.c.id == cid).values(removed_at=now))
        conn.execute(sa.insert(S.audit).values(campaign_id=cid, at=now, who=who, action="remove",
                                               field=None, old_value=None, new_value=None,
                                               reason=reason))
    return c


def amend_campaign(db: Database, cid: int, changes: dict[str, Any], who: str,
                   reason: str) -> list[tuple[str, str | None, str | None]]:
    """Correct fields of campaign ``cid`` (``changes``: AMENDABLE -> new value), one audit
    row per changed field; the (field, old, new) that changed."""
    done: list[tuple[str, str | None, str | None]] = []
    with db.write() as conn:
        c = live_campaign(conn, cid, db.location.shown)
        now = _now()
        values: dict[str, Any] = {}
        for key, new in changes.items():
            if key == "machine":
                old_name = conn.execute(sa.select(S.machines.c.name).where(
                    S.machines.c.id == c["machine_id"])).scalar()
                if new == old_name:
                    continue
                values["machine_id"] = machine_id(conn, new, create=True)
                done.append(("machine", old_name, new))
            else:
                if new == c[key]:
                    continue
                values[key] = new
                done.append((key, _text_of(c[key]), _text_of(new)))
        if not done:
            raise AbbeInputError("nothing to change: every given field already has that value",
                                 field="amend")
        conn.execute(sa.update(S.campaigns).where(S.campaigns.c.id == cid).values(**values))
        conn.execute(sa.insert(S.audit), [
            {"campaign_id": cid, "at": now, "who": who, "action": "amend", "field": f,
             "old_value": o, "new_value": n, "reason": reason} for f, o, n in done])
    return done


def audit_of(conn: Any, cids: list[int], shown: str | None = None) -> list[dict[str, Any]]:
    """The audit rows of campaigns ``cids``, oldest first (checked as read)."""
    if not cids:
        return []
    return fetch(conn, S.audit, S.audit.c.campaign_id.in_(cids),
                 order_by=[S.audit.c.at, S.audit.c.id], shown=shown)
