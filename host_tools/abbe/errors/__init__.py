"""Errors raised for bad input, carrying where the problem is, and the one strict number parser.

* :class:`AbbeInputError`: bad input (file, line, field, message); the CLI prints
  ``FILE:LINE: field 'F': message`` and exits 2, writing nothing.
* :mod:`abbe.errors.numbers`: the strict number parser every reader uses (ASCII
  decimal only, finite, a range per field): :func:`parse_number`, :func:`parse_int`,
  the column forms :func:`parse_number_column`, :func:`parse_int_column`, and
  :func:`check_number` / :func:`check_int` for values a TOML or JSON parser gave.
"""

from __future__ import annotations


def _printable(s: str) -> str:
    """One printable line: control and separator characters (a newline, U+2028, an escape
    sequence from a hostile file) shown as escapes, never sent raw to the terminal."""
    if s.isprintable():
        return s
    return "".join(ch if ch.isprintable() else ch.encode("unicode_escape").decode("ascii")
                   for ch in s)


class AbbeInputError(Exception):
    """Bad input: names the file, the line, the field and what was expected.

    The CLI prints it as ``FILE:LINE: field 'F': MESSAGE`` and exits with
    status 2 without writing partial output.
    """

    def __init__(self, message: str, *, file: str | None = None, line: int | None = None,
                 field: str | None = None) -> None:
        self.file = file
        self.line = line
        self.field = field
        self.message = message
        super().__init__(str(self))

    def __str__(self) -> str:
        where = ""
        if self.file is not None:
            where = str(self.file)
            if self.line is not None:
                where += f":{self.line}"
            where += ": "
        field = f"field '{self.field}': " if self.field is not None else ""
        return _printable(f"{where}{field}{self.message}")

    def located(self, *, file: str | None = None, line: int | None = None,
                field: str | None = None) -> "AbbeInputError":
        """This error with the missing parts of its location filled in (self, updated)."""
        if self.file is None and file is not None:
            self.file = file
        if self.line is None and line is not None:
            self.line = line
        if self.field is None and field is not None:
            self.field = field
        self.args = (str(self),)
        return self


from abbe.errors.numbers import (  # noqa: E402  (the parser raises AbbeInputError)
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
