"""Range-checked option values for argparse (``type=in_range(0, 1, "um")``).

Every numeric option of every command states its range; a value outside it, NaN,
Inf, or a number in any other form than the strict parser's
(:mod:`abbe.errors.numbers`) is a usage error (exit 2) naming the option and the
range, e.g. ``argument --min-effect-um: expected a number in [0, 1000] um, got '-1'``.
"""

from __future__ import annotations

import argparse
from typing import Callable

from abbe.errors import AbbeInputError, parse_int, parse_number


def in_range(lo: float, hi: float, unit: str = "", *, lo_open: bool = False,
             hi_open: bool = False) -> Callable[[str], float]:
    """argparse type: a finite number in [lo, hi] (open ends as asked)."""
    def convert(text: str) -> float:
        try:
            v = parse_number(text.strip(), lo=lo, hi=hi, unit=unit)
        except AbbeInputError as exc:
            raise argparse.ArgumentTypeError(exc.message) from None
        if (lo_open and v <= lo) or (hi_open and v >= hi):
            a, b = ("(" if lo_open else "["), (")" if hi_open else "]")
            raise argparse.ArgumentTypeError(
                f"expected a number in {a}{lo:g}, {hi:g}{b}{' ' + unit if unit else ''}, "
                f"got {text!r}")
        return v
    convert.__name__ = "number"
    return convert


def int_range(lo: int, hi: int) -> Callable[[str], int]:
    """argparse type: an integer in [lo, hi]."""
    def convert(text: str) -> int:
        try:
            return parse_int(text.strip(), lo=lo, hi=hi)
        except AbbeInputError as exc:
            raise argparse.ArgumentTypeError(exc.message) from None
    convert.__name__ = "integer"
    return convert


def iso_date(text: str) -> str:
    """argparse type: a calendar date YYYY-MM-DD (a report's test date)."""
    import datetime
    import re
    if not re.fullmatch(r"\d{4}-\d{2}-\d{2}", text):
        raise argparse.ArgumentTypeError(f"expected a date YYYY-MM-DD, got {text!r}")
    try:
        datetime.date.fromisoformat(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a date YYYY-MM-DD, got {text!r} (no such "
                                         "day)") from None
    return text
