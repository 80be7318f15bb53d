"""Time zones of ``abbe history``: dates are stored in UTC, given and shown in the site's zone.

The site's zone is ``--tz ZONE`` (an IANA name such as ``Europe/Berlin``), else the
zone of the computer abbe runs on (``$TZ``, else the system's). A ``--date`` without a
zone (``2026-03-01T09:00``) is a time in the site's zone, converted to UTC with the
daylight-saving rule of that date; one with ``Z`` or ``+HH:MM`` is taken as given.
Tables and reports show dates in the site's zone and name it; exports keep UTC
(``...Z``), as every file abbe writes for programs.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

from abbe.errors import AbbeInputError

UTC = dt.timezone.utc


def site_zone(name: str | None) -> Any:
    """The zone ``--tz`` names (None: the computer's local zone, applied per date)."""
    if name is None:
        return None
    from zoneinfo import ZoneInfo, ZoneInfoNotFoundError
    try:
        if not name.strip() or name.startswith(("/", ".")) or ".." in name:
            raise ValueError(name)
        return ZoneInfo(name)
    except (ZoneInfoNotFoundError, ValueError):
        raise AbbeInputError(f"unknown time zone {name!r}: expected an IANA name such as "
                             "Europe/Berlin, America/Chicago or UTC", field="--tz") from None


def to_utc(local: dt.datetime, zone: Any) -> dt.datetime:
    """A time of the site (naive, or aware) -> naive UTC."""
    if local.tzinfo is None:
        local = local.replace(tzinfo=zone) if zone is not None else local.astimezone()
    return local.astimezone(UTC).replace(tzinfo=None)


def to_site(utc_naive: dt.datetime, zone: Any) -> dt.datetime:
    """A stored time (naive UTC) -> aware, in the site's zone."""
    aware = utc_naive.replace(tzinfo=UTC)
    return aware.astimezone(zone) if zone is not None else aware.astimezone()


def show(utc_naive: dt.datetime, zone: Any, fmt: str = "%Y-%m-%d %H:%M") -> str:
    """A stored time as the site reads it, with its zone's abbreviation."""
    t = to_site(utc_naive, zone)
    return f"{t.strftime(fmt)} {t.strftime('%Z') or t.strftime('%z')}"


def zone_name(zone: Any) -> str:
    """The site's zone as shown in headers (its IANA key, or the local abbreviation)."""
    if zone is not None:
        return str(getattr(zone, "key", zone))
    now = dt.datetime.now().astimezone()
    return f"local, {now.strftime('%Z') or now.strftime('%z')}"
