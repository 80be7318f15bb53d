"""The error every reader raises for bad input: :class:`AbbeInputError` (file, line, field,
message). Its own module so that the number parser (:mod:`abbe.errors.numbers`) and the
package that re-exports both (:mod:`abbe.errors`) import it one way, without a circle."""

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
