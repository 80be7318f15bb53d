"""``abbe history``: every campaign of a machine in a database; trends, bands, alerts.

    abbe history [--db PATH|URL] add OUTPUT... [--machine M] [--date D] [--operator O] ...
    abbe history [--db PATH|URL] show [MACHINE] [--last N] [--limits FILE]
    abbe history [--db PATH|URL] report MACHINE -o DIR [--limits FILE]
    abbe history [--db PATH|URL] export [MACHINE] -o FILE [--format csv|json]
    abbe history [--db PATH|URL] migrate

docs/history.md. SQLAlchemy, Alembic and psycopg (the ``history`` extra) are imported
inside the commands: every other command works without them.
"""

from __future__ import annotations

import argparse
import datetime as dt
import re
import sys
from pathlib import Path

from abbe.cli.conventions import examples, list_option
from abbe.cli.options import in_range, int_range
from abbe.errors import AbbeInputError

_DB_HELP = ("database: a file path (SQLite) or postgresql://USER@HOST/DB (default "
            "$ABBE_HISTORY_DB, else ~/.local/share/abbe/history.sqlite)")


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "history", help="keep every campaign of a machine in a database (SQLite or "
                        "PostgreSQL): trends, bands, alerts, reports, exports",
        description="A database of campaigns: add the output folder of abbe fit / diagnose / "
                    "demo or the JSON of abbe ballbar / iso230-2, show the trend of every "
                    "quantity, write an HTML report with trend plots, bands and alerts, export "
                    "CSV / JSON. " + _DB_HELP + ".",
        epilog=examples("abbe history add fit-out --date 2026-03-01 --operator ana",
                        "abbe history show vmc500",
                        "abbe history report vmc500 -o history-report",
                        "abbe history --db postgresql://abbe@dbhost/shop export -o all.csv"))
    p.add_argument("--db", metavar="PATH|URL", default=None, help=_DB_HELP)
    sub = p.add_subparsers(dest="history_command", metavar="SUBCOMMAND")
    sub.required = True

    def db_opt(sp: argparse.ArgumentParser) -> None:
        sp.add_argument("--db", metavar="PATH|URL", default=argparse.SUPPRESS, help=_DB_HELP)

    a = sub.add_parser(
        "add", help="add one campaign (its outputs) in one transaction",
        description="Read the outputs of one campaign strictly (recognised by content: the "
                    "folder of abbe fit, diagnose or demo; the JSON of abbe ballbar --json or "
                    "abbe iso230-2 --json) and add them in one transaction. The same campaign "
                    "twice is refused (content SHA-256).",
        epilog=examples("abbe history add fit-out diag-out bb.json x.json --axis x.json=X "
                        "--date 2026-03-01 --operator ana --instrument 'XL-80 #1234'"))
    a.add_argument("outputs", nargs="+", metavar="OUTPUT", help="output folder or JSON file")
    a.add_argument("--machine", help="machine name (required when no fit output names it)")
    a.add_argument("--date", help="when it was measured: YYYY-MM-DD[THH:MM[:SS]][Z|+HH:MM] "
                                  "(default: now, UTC)")
    a.add_argument("--operator", help="who measured")
    list_option(a, "--instrument", metavar="NAME", help="instruments used (name, serial)")
    list_option(a, "--temp-c", metavar="C", type=in_range(-50.0, 150.0, "deg C"),
                help="temperatures noted during the campaign (deg C)")
    a.add_argument("--note", help="a free note (e.g. 'after the crash of 2026-02-11')")
    list_option(a, "--axis", metavar="[FILE=]AXIS",
                help="axis of an abbe iso230-2 JSON (X, Y or Z; FILE=AXIS with several)")
    db_opt(a)
    a.set_defaults(func=run_add)

    s = sub.add_parser("show", help="trend table per quantity of a machine (no MACHINE: the "
                                    "machines)",
                       epilog=examples("abbe history show vmc500 --last 6"))
    s.add_argument("machine", nargs="?", metavar="MACHINE")
    s.add_argument("--last", type=int_range(1, 1000), default=8, metavar="N",
                   help="campaigns shown as columns (1..1000, default 8)")
    s.add_argument("--limits", metavar="FILE", help="limits and alert settings (TOML)")
    db_opt(s)
    s.set_defaults(func=run_show)

    r = sub.add_parser("report", help="HTML report: trend plots, bands, alerts",
                       epilog=examples("abbe history report vmc500 -o history-report "
                                       "--limits limits.toml"))
    r.add_argument("machine", metavar="MACHINE")
    r.add_argument("-o", "--out", required=True, metavar="DIR", help="output folder")
    r.add_argument("--limits", metavar="FILE", help="limits and alert settings (TOML)")
    db_opt(r)
    r.set_defaults(func=run_report)

    e = sub.add_parser("export", help="export campaigns as CSV (one row per value) or JSON",
                       epilog=examples("abbe history export vmc500 -o vmc500.csv",
                                       "abbe history export -o all.json"))
    e.add_argument("machine", nargs="?", metavar="MACHINE", help="one machine (default: all)")
    e.add_argument("-o", "--out", required=True, metavar="FILE", help="output file")
    e.add_argument("--format", choices=("csv", "json"), default=None,
                   help="default: from the file's suffix (.csv, .json)")
    db_opt(e)
    e.set_defaults(func=run_export)

    m = sub.add_parser("migrate", help="upgrade the database schema in place (data kept)",
                       epilog=examples("abbe history --db shop.sqlite migrate"))
    db_opt(m)
    m.set_defaults(func=run_migrate)


def _open(args: argparse.Namespace, **kw: bool):
    from abbe.history.database import open_database
    return open_database(args.db, **kw)


def _guard(work) -> int:
    """Run ``work``; a database server that cannot be reached is exit status 1."""
    from abbe.history.database import DatabaseUnreachable
    try:
        return work()
    except DatabaseUnreachable as exc:
        print(f"abbe history: error: {exc}", file=sys.stderr)
        return 1


_DATE = re.compile(r"\d{4}-\d{2}-\d{2}([T ]\d{2}:\d{2}(:\d{2})?)?(Z|[+-]\d{2}:\d{2})?")


def parse_date(text: str | None) -> dt.datetime:
    """``--date`` as naive UTC; now when not given. Refuses the future (> 1 day) and < 1970."""
    now = dt.datetime.now(dt.timezone.utc)
    if text is None:
        return now.replace(tzinfo=None, microsecond=0)
    if not _DATE.fullmatch(text.strip()):
        raise AbbeInputError(f"expected YYYY-MM-DD[THH:MM[:SS]][Z|+HH:MM], got {text!r}",
                             field="--date")
    try:
        t = dt.datetime.fromisoformat(text.strip().replace("Z", "+00:00"))
    except ValueError as exc:
        raise AbbeInputError(f"not a date: {exc}", field="--date") from None
    if t.tzinfo is not None:
        t = t.astimezone(dt.timezone.utc).replace(tzinfo=None)
    if t.year < 1970 or t > now.replace(tzinfo=None) + dt.timedelta(days=1):
        raise AbbeInputError(f"{text!r} is before 1970 or in the future", field="--date")
    return t


def _axes(values: list[str] | None) -> dict[str, str]:
    out: dict[str, str] = {}
    for v in values or []:
        name, _, axis = v.rpartition("=")
        if axis.upper() not in ("X", "Y", "Z"):
            raise AbbeInputError(f"expected X, Y, Z or FILE=X, got {v!r}", field="--axis")
        if name in out:
            raise AbbeInputError(f"{name or 'the axis'} given twice", field="--axis")
        out[name] = axis.upper()
    return out


def _text(v: str | None, option: str, limit: int = 200) -> str | None:
    if v is None:
        return None
    if not v.strip() or len(v) > limit or not v.isprintable():
        raise AbbeInputError(f"expected printable text of 1..{limit} characters", field=option)
    return v.strip()


def run_add(args: argparse.Namespace) -> int:
    from abbe.history.deps import need
    need("sqlalchemy")
    from abbe.history.ingest import read_campaign
    from abbe.history.store import Meta, add_campaign

    meta = Meta(measured_at=parse_date(args.date), operator=_text(args.operator, "--operator"),
                instruments=tuple(_text(i, "--instrument") or "" for i in args.instrument or []),
                temperatures_c=tuple(args.temp_c or []), note=_text(args.note, "--note", 2000),
                source=" ".join(str(Path(p).resolve()) for p in args.outputs))
    machine = _text(args.machine, "--machine")
    camp = read_campaign(args.outputs, _axes(args.axis), machine)  # before touching the db

    def work() -> int:
        db = _open(args, create=True)
        try:
            cid = add_campaign(db, camp, meta)
        finally:
            db.close()
        print(f"abbe history: added campaign {cid} of {camp.machine} "
              f"({meta.measured_at:%Y-%m-%d %H:%M} UTC; {', '.join(camp.kinds)}; "
              f"{len(camp.results)} values, {len(camp.tables)} tables) to {db.location.shown}")
        return 0
    return _guard(work)


def _analyses(conn, mid: int, settings):
    from abbe.history.store import series_of
    from abbe.history.trends import analyse
    return [analyse(s, settings) for s in series_of(conn, mid).values()]


def run_show(args: argparse.Namespace) -> int:
    from abbe.history.deps import need
    need("sqlalchemy")
    from abbe.history.limits import load_settings
    from abbe.history.store import campaigns_of, machine_id, machine_names, require_machine

    settings = load_settings(args.limits)

    def work() -> int:
        db = _open(args)
        try:
            with db.read() as conn:
                if args.machine is None:
                    for name in machine_names(conn):
                        n = len(campaigns_of(conn, machine_id(conn, name)))
                        print(f"{name}\t{n} campaigns")
                    return 0
                mid = require_machine(conn, args.machine, db.location.shown)
                camps = campaigns_of(conn, mid)
                ans = _analyses(conn, mid, settings)
        finally:
            db.close()
        sys.stdout.write(format_show(args.machine, camps, ans, args.last))
        return 0
    return _guard(work)


def format_show(machine: str, camps: list[dict], analyses: list, last: int) -> str:
    """The trend table: one row per series, the last ``last`` campaigns as columns."""
    shown = camps[-last:]
    num = {c["id"]: i + 1 for i, c in enumerate(camps)}
    head = ["series", "unit"] + [f"#{num[c['id']]} {c['measured_at']:%Y-%m-%d}" for c in shown] \
        + ["band", "limit", "trend/month", "alerts now"]
    rows = [head]
    for an in sorted(analyses, key=lambda a: a.series.key):
        by = {p.campaign_id: p.value for p in an.series.points}
        rows.append([an.series.key, an.series.unit]
                    + [f"{by[c['id']]:.4g}" if c["id"] in by else "-" for c in shown]
                    + [(f"{an.band[0]:.4g}..{an.band[1]:.4g}" + ("(out)" if an.out_of_band() else ""))
                       if an.band else "-",
                       "-" if an.limit is None else f"{an.limit:g}",
                       f"{an.trend[0] * 30.44:+.3g}" if an.trend else "-",
                       ",".join(a.kind for a in an.current()) or "-"])
    widths = [max(len(r[i]) for r in rows) for i in range(len(head))]
    lines = [f"{machine}: {len(camps)} campaigns (columns: the last {len(shown)}; units per row)"]
    for r in rows:
        lines.append("  ".join(c.ljust(w) if i == 0 else c.rjust(w)
                               for i, (c, w) in enumerate(zip(r, widths))).rstrip())
    return "\n".join(lines) + "\n"


def run_report(args: argparse.Namespace) -> int:
    from abbe.history.deps import need
    need("sqlalchemy")
    from abbe.formats.output import Outputs
    from abbe.history.limits import load_settings
    from abbe.history.report import render
    from abbe.history.store import campaigns_of, record_export, require_machine

    settings = load_settings(args.limits)
    Outputs().check_directory(args.out, option="--out")

    def work() -> int:
        db = _open(args)
        try:
            with db.read() as conn:
                mid = require_machine(conn, args.machine, db.location.shown)
                camps = campaigns_of(conn, mid)
                ans = _analyses(conn, mid, settings)
                details = _details(conn, [c["id"] for c in camps])
            with Outputs() as outs:
                staging = outs.directory(args.out, option="--out")
                summary = render(staging, args.machine, camps, ans, details, settings,
                                 db.location.shown)
            record_export(db, mid, "report", str(Path(args.out).resolve()), len(camps))
        finally:
            db.close()
        print(f"abbe history: wrote {Path(args.out) / 'index.html'} ({len(camps)} campaigns, "
              f"{len(summary['plots'])} plots, {summary['alerts_now']} alerts at the last "
              f"campaign)")
        return 0
    return _guard(work)


def _details(conn, ids: list[int]) -> dict[int, dict]:
    import sqlalchemy as sa
    from abbe.history import schema as S
    out: dict[int, dict] = {i: {"instruments": [], "temperatures": []} for i in ids}
    if not ids:
        return out
    for cid, name in conn.execute(sa.select(S.instruments.c.campaign_id, S.instruments.c.name)
                                  .where(S.instruments.c.campaign_id.in_(ids))):
        out[cid]["instruments"].append(name)
    for cid, src, v in conn.execute(sa.select(S.temperatures.c.campaign_id,
                                              S.temperatures.c.source, S.temperatures.c.value_c)
                                    .where(S.temperatures.c.campaign_id.in_(ids))):
        out[cid]["temperatures"].append((src, v))
    return out


def run_export(args: argparse.Namespace) -> int:
    from abbe.history.deps import need
    need("sqlalchemy")
    from abbe.formats.output import Outputs
    from abbe.history.export import collect, to_csv, to_json
    from abbe.history.store import machine_id, machine_names, record_export, require_machine

    fmt = args.format or Path(args.out).suffix.lower().lstrip(".")
    if fmt not in ("csv", "json"):
        raise AbbeInputError("give --format csv|json or a file name ending in .csv / .json",
                             file=args.out, field="--format")
    Outputs().check_file(args.out, option="--out")

    def work() -> int:
        db = _open(args)
        try:
            with db.read() as conn:
                if args.machine is not None:
                    mids = [require_machine(conn, args.machine, db.location.shown)]
                else:
                    mids = [machine_id(conn, n) for n in machine_names(conn)]
                doc = collect(conn, mids)
            text = to_csv(doc) if fmt == "csv" else to_json(doc)
            with Outputs() as outs:
                outs.file(args.out, option="--out").write_text(text, encoding="utf-8")
            n = sum(len(m["campaigns"]) for m in doc["machines"])
            record_export(db, mids[0] if len(mids) == 1 else None, fmt,
                          str(Path(args.out).resolve()), n)
        finally:
            db.close()
        print(f"abbe history: wrote {args.out} ({fmt}, {len(doc['machines'])} machines, "
              f"{n} campaigns)")
        return 0
    return _guard(work)


def run_migrate(args: argparse.Namespace) -> int:
    from abbe.history.database import current_revision, head_revision, open_database, resolve
    from abbe.history.deps import need
    need("sqlalchemy")

    def work() -> int:
        loc = resolve(args.db)
        db = open_database(args.db, migrate=True)
        try:
            with db.read() as conn:
                rev = current_revision(conn)
        finally:
            db.close()
        print(f"abbe history: {loc.shown} is at schema revision {rev} (newest {head_revision()})")
        return 0
    return _guard(work)
