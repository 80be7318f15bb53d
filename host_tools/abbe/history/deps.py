"""The optional extra ``abbe[history]``: SQLAlchemy, Alembic, psycopg, imported on demand.

Only ``abbe history`` needs them; every other command (and ``import abbe``) works
without. A missing package is an input-style error (exit 2) that says what to install.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from abbe.errors import AbbeInputError

_INSTALL = "install the extra: pip install 'abbe[history]' (SQLAlchemy, Alembic, psycopg)"


class HistoryUnavailable(AbbeInputError):
    """A package of the ``history`` extra is not installed."""


def need(module: str, why: str = "abbe history") -> ModuleType:
    """Import ``module`` or raise :class:`HistoryUnavailable` naming the extra."""
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise HistoryUnavailable(f"{why} needs the Python package {module.split('.')[0]!r} "
                                 f"({exc}); {_INSTALL}", field="--db") from None
