"""Errors raised for bad input, carrying where the problem is."""

from __future__ import annotations

import math


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
        return f"{where}{field}{self.message}"


def parse_finite(text: str, *, file: str | None, line: int | None, field: str | None) -> float:
    """A finite number from a text cell, or an AbbeInputError naming where."""
    try:
        v = float(text)
    except ValueError:
        raise AbbeInputError(f"expected a number, got {text!r}", file=file, line=line,
                             field=field) from None
    if not math.isfinite(v):
        raise AbbeInputError(f"expected a finite number, got {text!r}", file=file, line=line,
                             field=field)
    return v
