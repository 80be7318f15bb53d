"""Errors raised for bad input, carrying where the problem is, and the one strict number parser.

* :class:`AbbeInputError`: bad input (file, line, field, message); the CLI prints
  ``FILE:LINE: field 'F': message`` and exits 2, writing nothing.
* :mod:`abbe.errors.numbers`: the strict number parser every reader uses (ASCII
  decimal only, finite, a range per field): :func:`parse_number`, :func:`parse_int`,
  the column forms :func:`parse_number_column`, :func:`parse_int_column`, and
  :func:`check_number` / :func:`check_int` for values a TOML or JSON parser gave.
"""

from __future__ import annotations

from abbe.errors.input_error import AbbeInputError
from abbe.errors.numbers import (
    MAX_NUMBER_CHARS,
    check_int,
    check_number,
    parse_int,
    parse_int_column,
    parse_number,
    parse_number_column,
)

__all__ = ["AbbeInputError", "MAX_NUMBER_CHARS", "check_int", "check_number", "parse_int",
           "parse_int_column", "parse_number", "parse_number_column"]
