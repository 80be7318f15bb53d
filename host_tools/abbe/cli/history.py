"""``abbe history``: every campaign of a machine in a database; trends, bands, alerts.

    abbe history [--db PATH|URL] add OUTPUT... [--machine M] [--date D] [--operator O] ...
    abbe history [--db PATH|URL] show [MACHINE] [--last N] [--limits FILE]
    abbe history [--db PATH|URL] report MACHINE -o DIR [--limits FILE]
    abbe history [--db PATH|URL] export [MACHINE] -o FILE [--format csv|json]
    abbe history [--db PATH|URL] migrate
    abbe history [--db PATH|URL] remove CAMPAIGN --reason WHY [--by WHO]
    abbe history [--db PATH|URL] amend CAMPAIGN [--machine M] [--date D] ... --reason WHY

docs/history.md. SQLAlchemy, Alembic and psycopg (the ``history`` extra) are imported
inside the commands: every other command works without them.
"""

from __future__ import annotations

import argparse
import datetime as dt
import os
import re
import sys
from pathlib import Path

from abbe.cli.conventions import examples, list_option
from abbe.cli.options import in_range, int_range
from abbe.errors import AbbeInputError

_DB_HELP = ("database: a file path (SQLite) or postgresql://USER@HOST/DB (default "
            "$ABBE_HISTORY_DB, else ~/.local/share/abbe/history.sqlite); keep a password out "
            "of the command line: ~/.pgpass, $ABBE_HISTORY_DB or postgresql:///?service=NAME")
_TZ_HELP = ("the site's time zone (IANA name, e.g. Europe/Berlin): a --date without a zone is "
            "read in it, dates are shown in it (default: $TZ, else the computer's zone)")


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
    p.add_argument("--tz", metavar="ZONE", default=None, help=_TZ_HELP)
    sub = p.add_subparsers(dest="history_command", metavar="SUBCOMMAND")
    sub.required = True

    def db_opt(sp: argparse.ArgumentParser) -> None:
        sp.add_argument("--db", metavar="PATH|URL", default=argparse.SUPPRESS, help=_DB_HELP)
        sp.add_argument("--tz", metavar="ZONE", default=argparse.SUPPRESS, help=_TZ_HELP)

    def who_opt(sp: argparse.ArgumentParser) -> None:
        sp.add_argument("campaign", type=int_range(1, 2**31 - 1), metavar="CAMPAIGN",
                        help="the campaign's id (show MACHINE --campaigns lists them)")
        sp.add_argument("--reason", required=True, help="why (kept in the audit trail)")
        sp.add_argument("--by", default=None, help="who does it (default: the login name)")

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
                                  "(without a zone: the site's zone, --tz; default: now)")
    a.add_argument("--operator", help="who measured")
    list_option(a, "--instrument", metavar="NAME", help="instruments used (name, serial)")
    list_option(a, "--temp-c", metavar="C", type=in_range(-50.0, 150.0, "deg C"),
                help="temperatures noted during the campaign (deg C)")
    a.add_argument("--note", help="a free note (e.g. 'after the crash of 2026-02-11')")
    list_option(a, "--axis", metavar="[FILE=]AXIS",
                help="axis of an abbe iso230-2 JSON (X, Y or Z; FILE=AXIS with several)")
    a.add_argument("--create", action="store_true",
                   help="create the database file's folder when it does not exist (without "
                        "it a missing folder is refused: a typo would start a second history)")
    db_opt(a)
    a.set_defaults(func=run_add)

    s = sub.add_parser("show", help="trend table per quantity of a machine (no MACHINE: the "
                                    "machines)",
                       epilog=examples("abbe history show vmc500 --last 6"))
    s.add_argument("machine", nargs="?", metavar="MACHINE")
    s.add_argument("--last", type=int_range(1, 1000), default=8, metavar="N",
                   help="campaigns shown as columns (1..1000, default 8)")
    s.add_argument("--limits", metavar="FILE", help="limits and alert settings (TOML)")
    s.add_argument("--campaigns", action="store_true",
                   help="list the machine's campaigns with their ids instead of the trends")
    s.add_argument("--removed", action="store_true",
                   help="list the campaigns with the removed ones and the audit trail "
                        "(corrections and removals: who, when, why)")
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

    rm = sub.add_parser(
        "remove", help="remove a campaign from the trends (kept, marked removed, audited)",
        description="Mark a campaign removed: it stays in the database (show --removed lists "
                    "it, with who removed it, when and why) but no longer counts in trends, "
                    "reports and exports. Nothing is deleted.",
        epilog=examples("abbe history remove 17 --reason 'laser not warmed up'"))
    who_opt(rm)
    db_opt(rm)
    rm.set_defaults(func=run_remove)

    am = sub.add_parser(
        "amend", help="correct a campaign's machine, date, operator or note (audited)",
        description="Correct what was said about a campaign when it was added; each changed "
                    "field is noted in the audit trail with its old and new value, who and "
                    "why (show MACHINE --removed shows it).",
        epilog=examples("abbe history amend 17 --machine vmc501 --reason 'wrong machine'",
                        "abbe history amend 17 --date 2026-03-01T09:00 --reason 'typo'"))
    who_opt(am)
    am.add_argument("--machine", help="the right machine (created when new)")
    am.add_argument("--date", help="the right date (as for add; without a zone: --tz)")
    am.add_argument("--operator", help="the right operator")
    am.add_argument("--note", help="the right note")
    db_opt(am)
    am.set_defaults(func=run_amend)

    m = sub.add_parser("migrate", help="upgrade the database schema in place (data kept)",
                       epilog=examples("abbe history --db shop.sqlite migrate"))
    db_opt(m)
    m.set_defaults(func=run_migrate)


def _open(args: argparse.Namespace, **kw: bool):
    from abbe.history.database import open_database
    return open_database(args.db, **kw)


def _zone(args: argparse.Namespace):
    from abbe.history.zones import site_zone
    return site_zone(getattr(args, "tz", None))


def _guard(args: argparse.Namespace, work, writing: bool = False) -> int:
    """Run ``work``; every database condition gets its status (docs/history.md, "Exit
    status"): a database that cannot be used now (a server lost or unreachable, a lock
    held too long) is exit 1 with "retry"; a bad, foreign or read-only one is exit 2."""
    import sqlalchemy as sa
    from abbe.history.database import DatabaseUnreachable, classify, resolve
    try:
        try:
            return work()
        except sa.exc.DBAPIError as exc:
            if isinstance(exc, sa.exc.IntegrityError):
                raise  # a constraint abbe itself broke: a bug (exit 70, crash log)
            raise classify(exc, resolve(args.db), writing=writing) from None
    except DatabaseUnreachable as exc:
        print(f"abbe history: error: {exc}", file=sys.stderr)
        return 1


_DATE = re.compile(r"\d{4}-\d{2}-\d{2}([T ]\d{2}:\d{2}(:\d{2})?)?(Z|[+-]\d{2}:\d{2})?")


def parse_date(text: str | None, zone=None, option: str = "--date") -> dt.datetime:
    """``--date`` as naive UTC; now when not given. Without a zone the time is the site's
    (``zone``; None: the computer's zone). Refuses the future (> 1 day) and < 1970."""
    from abbe.history.zones import to_utc
    now = dt.datetime.now(dt.timezone.utc)
    if text is None:
        return now.replace(tzinfo=None, microsecond=0)
    if not _DATE.fullmatch(text.strip()):
        raise AbbeInputError(f"expected YYYY-MM-DD[THH:MM[:SS]][Z|+HH:MM], got {text!r}",
                             field=option)
    try:
        t = dt.datetime.fromisoformat(text.strip().replace("Z", "+00:00"))
    except ValueError as exc:
        raise AbbeInputError(f"not a date: {exc}", field=option) from None
    try:
        t = to_utc(t, zone)
    except (OverflowError, ValueError, OSError) as exc:
        raise AbbeInputError(f"not a date in the site's zone: {exc}", field=option) from None
    if t.year < 1970 or t > now.replace(tzinfo=None) + dt.timedelta(days=1):
        raise AbbeInputError(f"{text!r} is before 1970 or in the future", field=option)
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
    from abbe.history.zones import show as show_time

    zone = _zone(args)
    meta = Meta(measured_at=parse_date(args.date, zone), operator=_text(args.operator, "--operator"),
                instruments=tuple(_text(i, "--instrument") or "" for i in args.instrument or []),
                temperatures_c=tuple(args.temp_c or []), note=_text(args.note, "--note", 2000),
                source=" ".join(str(Path(p).resolve()) for p in args.outputs))
    machine = _text(args.machine, "--machine")
    camp = read_campaign(args.outputs, _axes(args.axis), machine)  # before touching the db

    def work() -> int:
        db = _open(args, create=True, write=True, create_dirs=args.create)
        try:
            cid = add_campaign(db, camp, meta)
        finally:
            db.close()
        print(f"abbe history: added campaign {cid} of {camp.machine} "
              f"({show_time(meta.measured_at, zone)} = {meta.measured_at:%Y-%m-%d %H:%M} UTC; "
              f"{', '.join(camp.kinds)}; {len(camp.results)} values, {len(camp.tables)} tables) "
              f"to {db.location.shown}")
        return 0
    return _guard(args, work, writing=True)


def _analyses(conn, mid: int, settings, shown: str, camps):
    from abbe.history.store import series_of
    from abbe.history.trends import analyse
    return [analyse(s, settings) for s in series_of(conn, mid, shown, camps).values()]


def run_show(args: argparse.Namespace) -> int:
    from abbe.history.deps import need
    need("sqlalchemy")
    from abbe.history.limits import load_settings
    from abbe.history.store import audit_of, campaigns_of, machine_id, machine_names, \
        require_machine

    settings = load_settings(args.limits)
    zone = _zone(args)

    def work() -> int:
        db = _open(args)
        shown = db.location.shown
        try:
            with db.read() as conn:
                if args.machine is None:
                    for name in machine_names(conn, shown):
                        n = len(campaigns_of(conn, machine_id(conn, name), shown))
                        print(f"{name}\t{n} campaigns")
                    return 0
                mid = require_machine(conn, args.machine, shown)
                if args.campaigns or args.removed:
                    camps = campaigns_of(conn, mid, shown, removed=args.removed)
                    audit = audit_of(conn, [c["id"] for c in camps], shown) if args.removed \
                        else []
                    text = format_campaigns(args.machine, camps, audit, zone)
                else:
                    camps = campaigns_of(conn, mid, shown)
                    ans = _analyses(conn, mid, settings, shown, camps)
                    text = format_show(args.machine, camps, ans, args.last, zone)
        finally:
            db.close()
        sys.stdout.write(text)
        return 0
    return _guard(args, work)


def format_campaigns(machine: str, camps: list[dict], audit: list[dict], zone=None) -> str:
    """The campaigns with their ids (and, given, the audit trail of corrections/removals)."""
    from abbe.history.zones import show as show_time, zone_name
    lines = [f"{machine}: {len(camps)} campaigns (dates in {zone_name(zone)})",
             "id\tmeasured\toperator\toutputs\tnote"]
    for c in camps:
        state = "" if c["removed_at"] is None else \
            f"\tREMOVED {show_time(c['removed_at'], zone)}"
        lines.append(f"{c['id']}\t{show_time(c['measured_at'], zone)}\t{c['operator'] or '-'}\t"
                     f"{c['kinds']}\t{c['note'] or ''}{state}")
    if audit:
        lines.append("audit trail (corrections and removals):")
        for a in audit:
            what = "removed" if a["action"] == "remove" else \
                f"{a['field']}: {a['old_value']!r} -> {a['new_value']!r}"
            lines.append(f"  campaign {a['campaign_id']}, {show_time(a['at'], zone)}, by "
                         f"{a['who']}: {what}; why: {a['reason']}")
    return "\n".join(lines) + "\n"


def _U_last(an, shown: list[dict]) -> str:
    """U (k = 2) of the series' value in the last campaign shown, '-' when not stated."""
    last = [p for p in an.series.points if p.campaign_id == shown[-1]["id"]] if shown else []
    if not last or last[-1].U is None:
        return "-"
    k = last[-1].k
    return f"{last[-1].U:.3g}" + ("" if k in (None, 2.0) else f" (k={k:g})")


def format_show(machine: str, camps: list[dict], analyses: list, last: int, zone=None) -> str:
    """The trend table: one row per series, the last ``last`` campaigns as columns."""
    from abbe.history.zones import to_site, zone_name
    shown = camps[-last:]
    num = {c["id"]: i + 1 for i, c in enumerate(camps)}
    head = ["series", "unit"] + [f"#{num[c['id']]} {to_site(c['measured_at'], zone):%Y-%m-%d}"
                                 for c in shown] \
        + ["U last", "band", "limit", "trend/month", "alerts now"]
    rows = [head]
    for an in sorted(analyses, key=lambda a: a.series.key):
        by = {p.campaign_id: p.value for p in an.series.points}
        rows.append([an.series.key, an.series.unit]
                    + [f"{by[c['id']]:.4g}" if c["id"] in by else "-" for c in shown]
                    + [_U_last(an, shown)]
                    + [(f"{an.band[0]:.4g}..{an.band[1]:.4g}" + ("(out)" if an.out_of_band() else ""))
                       if an.band else "-",
                       "-" if an.limit is None else f"{an.limit:g}",
                       f"{an.trend[0] * 30.44:+.3g}" if an.trend else "-",
                       ",".join(a.kind for a in an.current()) or "-"])
    widths = [max(len(r[i]) for r in rows) for i in range(len(head))]
    lines = [f"{machine}: {len(camps)} campaigns (columns: the last {len(shown)}; units per row; "
             f"dates in {zone_name(zone)})"]
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
    from abbe.history.store import campaigns_of, require_machine, try_record_export

    settings = load_settings(args.limits)
    zone = _zone(args)
    Outputs().check_directory(args.out, option="--out")

    def work() -> int:
        db = _open(args)
        shown = db.location.shown
        try:
            with db.read() as conn:  # everything read and checked before anything is written
                mid = require_machine(conn, args.machine, shown)
                camps = campaigns_of(conn, mid, shown)
                if not camps:
                    raise AbbeInputError(f"machine {args.machine!r} has no campaign (all "
                                         "removed?)", file=shown, field="MACHINE")
                ans = _analyses(conn, mid, settings, shown, camps)
                details = _details(conn, [c["id"] for c in camps], shown)
            with Outputs() as outs:
                staging = outs.directory(args.out, option="--out")
                summary = render(staging, args.machine, camps, ans, details, settings,
                                 shown, zone)
                # recorded last, inside the writer: a failure leaves no report behind
                note = try_record_export(db, mid, "report", str(Path(args.out).resolve()),
                                         len(camps))
        finally:
            db.close()
        print(f"abbe history: wrote {Path(args.out) / 'index.html'} ({len(camps)} campaigns, "
              f"{len(summary['plots'])} plots, {summary['alerts_now']} alerts at the last "
              f"campaign)")
        if note:
            print(f"abbe history: note: {note}", file=sys.stderr)
        return 0
    return _guard(args, work)


def _details(conn, ids: list[int], shown: str) -> dict[int, dict]:
    from abbe.history import schema as S
    from abbe.history.readback import fetch
    out: dict[int, dict] = {i: {"instruments": [], "temperatures": []} for i in ids}
    if not ids:
        return out
    for r in fetch(conn, S.instruments, S.instruments.c.campaign_id.in_(ids), shown=shown):
        out[r["campaign_id"]]["instruments"].append(r["name"])
    for r in fetch(conn, S.temperatures, S.temperatures.c.campaign_id.in_(ids), shown=shown):
        out[r["campaign_id"]]["temperatures"].append((r["source"], r["value_c"]))
    return out


def run_export(args: argparse.Namespace) -> int:
    from abbe.history.deps import need
    need("sqlalchemy")
    from abbe.formats.output import Outputs
    from abbe.history.export import collect, to_csv, to_json
    from abbe.history.store import machine_id, machine_names, require_machine, try_record_export

    fmt = args.format or Path(args.out).suffix.lower().lstrip(".")
    if fmt not in ("csv", "json"):
        raise AbbeInputError("give --format csv|json or a file name ending in .csv / .json",
                             file=args.out, field="--format")
    Outputs().check_file(args.out, option="--out")

    def work() -> int:
        db = _open(args)
        shown = db.location.shown
        try:
            with db.read() as conn:  # every value read and checked before the file is written
                if args.machine is not None:
                    mids = [require_machine(conn, args.machine, shown)]
                else:
                    mids = [machine_id(conn, n) for n in machine_names(conn, shown)]
                doc = collect(conn, mids, shown)
            text = to_csv(doc) if fmt == "csv" else to_json(doc)
            n = sum(len(m["campaigns"]) for m in doc["machines"])
            with Outputs() as outs:
                outs.file(args.out, option="--out").write_text(text, encoding="utf-8")
                # recorded last, inside the writer: a failure leaves the old file as it was
                note = try_record_export(db, mids[0] if len(mids) == 1 else None, fmt,
                                         str(Path(args.out).resolve()), n)
        finally:
            db.close()
        print(f"abbe history: wrote {args.out} ({fmt}, {len(doc['machines'])} machines, "
              f"{n} campaigns)")
        if note:
            print(f"abbe history: note: {note}", file=sys.stderr)
        return 0
    return _guard(args, work)


def run_migrate(args: argparse.Namespace) -> int:
    from abbe.history.database import current_revision, head_revision, open_database, resolve
    from abbe.history.deps import need
    need("sqlalchemy")

    def work() -> int:
        loc = resolve(args.db)
        db = open_database(args.db, migrate=True, write=True)
        try:
            with db.read() as conn:
                rev = current_revision(conn)
        finally:
            db.close()
        print(f"abbe history: {loc.shown} is at schema revision {rev} (newest {head_revision()})")
        return 0
    return _guard(args, work, writing=True)


def _who(args: argparse.Namespace) -> str:
    if args.by is not None:
        return _text(args.by, "--by") or ""
    import getpass
    try:
        return getpass.getuser()
    except (KeyError, OSError):
        return f"uid {os.getuid()}"


def run_remove(args: argparse.Namespace) -> int:
    from abbe.history.deps import need
    need("sqlalchemy")
    from abbe.history.store import remove_campaign
    reason = _text(args.reason, "--reason", 2000) or ""
    who = _who(args)

    def work() -> int:
        db = _open(args, write=True)
        try:
            c = remove_campaign(db, args.campaign, who, reason)
        finally:
            db.close()
        print(f"abbe history: campaign {c['id']} ({c['measured_at']:%Y-%m-%d %H:%M} UTC) marked "
              f"removed by {who}; kept in {db.location.shown} (show MACHINE --removed)")
        return 0
    return _guard(args, work, writing=True)


def run_amend(args: argparse.Namespace) -> int:
    from abbe.history.deps import need
    need("sqlalchemy")
    from abbe.history.store import amend_campaign
    reason = _text(args.reason, "--reason", 2000) or ""
    who = _who(args)
    changes: dict = {}
    if args.machine is not None:
        changes["machine"] = _text(args.machine, "--machine")
    if args.date is not None:
        changes["measured_at"] = parse_date(args.date, _zone(args))
    if args.operator is not None:
        changes["operator"] = _text(args.operator, "--operator")
    if args.note is not None:
        changes["note"] = _text(args.note, "--note", 2000)
    if not changes:
        raise AbbeInputError("give what to correct: --machine, --date, --operator or --note",
                             field="amend")

    def work() -> int:
        db = _open(args, write=True)
        try:
            done = amend_campaign(db, args.campaign, changes, who, reason)
        finally:
            db.close()
        for f, o, n in done:
            print(f"abbe history: campaign {args.campaign}: {f} {o!r} -> {n!r} (by {who})")
        return 0
    return _guard(args, work, writing=True)
