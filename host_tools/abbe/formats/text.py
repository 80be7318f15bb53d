"""The bounded file reader every reader uses: size limit, regular files only, text decoding
with BOM and newline handling, line-length limit; every problem an AbbeInputError.

* :func:`read_bytes` (blobs): a regular file of at most ``max_bytes``; a path with a
  NUL byte, a missing file, a directory, a device or FIFO (``/dev/zero``), a symlink
  loop, a permission problem: each a one-line input error naming the path.
* :func:`read_text`: :func:`read_bytes`, then decoding (UTF-8 by default; one
  leading BOM removed; UTF-16/32 text, a NUL byte or an undecodable byte refused
  with its line), giving a :class:`TextFile` whose :meth:`TextFile.lines` yields
  ``(line_no, line)`` with LF, CRLF and CR-only line ends alike and refuses a
  line longer than ``max_line_chars``.

Adopt it as ``tf = read_text(path, what="laser CSV", max_bytes=LIMIT)`` then
``for no, line in tf.lines(): ...`` (line numbers 1-based).
"""

from __future__ import annotations

import codecs
import errno
import hashlib
import io
import os
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator

from abbe.errors import AbbeInputError
from abbe.formats.limits import MAX_LINE_CHARS

#: Encodings a declared instrument file may use (``encoding = ...`` in a columns section).
ENCODINGS: tuple[str, ...] = ("utf-8", "utf-16", "latin-1", "cp1252")

_OPEN_ERRORS = {
    errno.ENOENT: "no such file",
    errno.ELOOP: "too many levels of symbolic links (a symlink loop?)",
    errno.EISDIR: "is a directory, expected a file",
    errno.EACCES: "permission denied",
    errno.EPERM: "permission denied",
    errno.ENOTDIR: "a component of the path is not a directory",
    errno.ENAMETOOLONG: "file name too long",
}


def _size_text(n: int) -> str:
    if n >= 1 << 20:
        return f"{n / (1 << 20):.1f} MiB"
    if n >= 1 << 10:
        return f"{n / (1 << 10):.1f} KiB"
    return f"{n} bytes"


def read_bytes(path: str | Path, *, what: str, max_bytes: int) -> bytes:
    """The content of a regular file of at most ``max_bytes`` bytes, or an AbbeInputError."""
    name = os.fsdecode(path) if isinstance(path, (bytes, os.PathLike)) else str(path)
    if "\0" in name:
        raise AbbeInputError(f"cannot read {what}: the path contains a NUL byte",
                             file=name.replace("\0", "\\0"))
    try:
        fd = os.open(name, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as exc:
        why = _OPEN_ERRORS.get(exc.errno or 0, exc.strerror or str(exc))
        raise AbbeInputError(f"cannot read {what}: {why}", file=name) from None
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise AbbeInputError(f"cannot read {what}: is a directory, expected a file", file=name)
        if not stat.S_ISREG(st.st_mode):
            raise AbbeInputError(f"cannot read {what}: not a regular file (a device, FIFO or "
                                 "socket)", file=name)
        too_big = AbbeInputError(
            f"{what} larger than the limit of {_size_text(max_bytes)} (docs/formats.md, "
            "\"Limits\")", file=name)
        if st.st_size > max_bytes:
            raise too_big
        os.set_blocking(fd, True)
        chunks: list[bytes] = []
        total = 0
        while True:
            try:
                b = os.read(fd, min(1 << 20, max_bytes + 1 - total))
            except OSError as exc:
                raise AbbeInputError(f"cannot read {what}: {exc.strerror}", file=name) from None
            if not b:
                break
            chunks.append(b)
            total += len(b)
            if total > max_bytes:
                raise too_big
        return b"".join(chunks)
    finally:
        os.close(fd)


def _line_of_offset(raw: bytes, offset: int) -> int:
    pre = raw[:offset]
    return pre.count(b"\n") + pre.count(b"\r") - pre.count(b"\r\n") + 1


@dataclass
class TextFile:
    """A decoded text file. ``text`` without a BOM; ``sha256`` of the bytes on disk."""

    name: str
    text: str
    sha256: str
    size: int
    max_line_chars: int = MAX_LINE_CHARS

    def lines(self) -> Iterator[tuple[int, str]]:
        """``(line_no, line)`` from 1, line ends (LF, CRLF, CR) removed; a line longer
        than ``max_line_chars`` is an AbbeInputError."""
        limit = self.max_line_chars
        for no, line in enumerate(io.StringIO(self.text, newline=None), start=1):
            if line.endswith("\n"):
                line = line[:-1]
            if len(line) > limit:
                raise AbbeInputError(f"line of {len(line)} characters: the limit is {limit} "
                                     "(docs/formats.md, \"Limits\")", file=self.name, line=no)
            yield no, line


def decode_text(raw: bytes, *, name: str, what: str, encoding: str = "utf-8",
                max_line_chars: int = MAX_LINE_CHARS) -> TextFile:
    """Decode ``raw`` (see :func:`read_text`)."""
    digest = hashlib.sha256(raw).hexdigest()
    enc = encoding.lower().replace("_", "-")
    if enc not in ENCODINGS:
        raise AbbeInputError(f"unknown encoding {encoding!r}; expected one of "
                             f"{', '.join(ENCODINGS)}", file=name, field="encoding")
    if enc == "utf-8":
        if raw.startswith((codecs.BOM_UTF32_LE, codecs.BOM_UTF32_BE)):
            raise AbbeInputError(f"{what} is UTF-32 text: save it as UTF-8", file=name, line=1)
        if raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
            raise AbbeInputError(f"{what} is UTF-16 text: save it as UTF-8 (or declare "
                                 "encoding = \"utf-16\" for an instrument file)", file=name, line=1)
        if raw.startswith(codecs.BOM_UTF8):
            raw = raw[len(codecs.BOM_UTF8):]
    if enc == "utf-16" and not raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        raise AbbeInputError("UTF-16 text must start with a byte-order mark", file=name, line=1)
    try:
        text = raw.decode(enc)
    except UnicodeDecodeError as exc:
        line = _line_of_offset(raw, exc.start) if enc == "utf-8" else None
        raise AbbeInputError(f"not {encoding.upper()} text: byte 0x{raw[exc.start]:02X} cannot be "
                             "decoded", file=name, line=line) from None
    text = text.removeprefix("\ufeff")
    nul = text.find("\0")
    if nul >= 0:
        line = text.count("\n", 0, nul) + text.count("\r", 0, nul) - text.count("\r\n", 0, nul) + 1
        raise AbbeInputError(f"NUL byte: {what} must be text (binary data, or UTF-16 text "
                             "without a byte-order mark?)", file=name, line=line)
    return TextFile(name=name, text=text, sha256=digest, size=len(raw),
                    max_line_chars=max_line_chars)


def read_text(path: str | Path, *, what: str, max_bytes: int, encoding: str = "utf-8",
              max_line_chars: int = MAX_LINE_CHARS) -> TextFile:
    """A bounded, decoded text file (:func:`read_bytes` + :func:`decode_text`)."""
    name = str(path)
    raw = read_bytes(path, what=what, max_bytes=max_bytes)
    return decode_text(raw, name=name, what=what, encoding=encoding,
                       max_line_chars=max_line_chars)
