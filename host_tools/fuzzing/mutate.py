"""Mutation operators for text and binary inputs, driven by any random source.

Every operator takes the input bytes and a ``pick(n) -> int in [0, n)`` function, so
the same operators run under hypothesis (``data.draw``: shrinkable, seeded in CI) and
under :mod:`random` (the long run). ``HOSTILE_NUMBERS`` are cells a strict reader must
refuse; :func:`replace_number` puts one where a number was, which makes the input
invalid for sure (used to check "no exit 0 on invalid input").
"""

from __future__ import annotations

import re
from typing import Callable

Pick = Callable[[int], int]

#: Number cells every reader must refuse (each is invalid wherever a number is expected).
HOSTILE_NUMBERS: tuple[str, ...] = (
    "nan", "NaN", "inf", "-Infinity", "1e400", "-1e309", "1e300", "1_0", "0x10", "1,5.3",
    "\u0663\u0664", "\uff11\uff12", "١٢٫٥", "12\u00a0", "--1", "1e", ".", "", "1e99999",
    "9" * 5000, "1" + "0" * 400, "²", "1.2.3", "+-3", "1e5e5", "∞", "true",
)
#: Tokens inserted anywhere (structure breakers, encodings, control characters).
HOSTILE_TOKENS: tuple[str, ...] = HOSTILE_NUMBERS + (
    "\r", "\n", "\r\n", "\x00", "\ufeff", "\u2028", "#", ",", ";", '"', "'", "[", "]", "{", "}",
    "=", "[[" * 200, "{a=" * 100, "x" * 140_000, "\t", " ", "é", "\udcff", "ccw", "cw", "+", "-",
    "[laser.Q]\n", "[ballbar.b]\n", "TGT_DATA[0]=1\n", "CYCLES=\u00b2\n",
)
_NUMBER = re.compile(rb"-?[0-9]+(?:\.[0-9]+)?(?:[eE][-+]?[0-9]+)?")


def _enc(s: str) -> bytes:
    return s.encode("utf-8", errors="surrogatepass")


def flip_bit(data: bytes, pick: Pick) -> bytes:
    if not data:
        return b"\x00"
    i = pick(len(data))
    return data[:i] + bytes([data[i] ^ (1 << pick(8))]) + data[i + 1:]


def insert_token(data: bytes, pick: Pick) -> bytes:
    i = pick(len(data) + 1)
    return data[:i] + _enc(HOSTILE_TOKENS[pick(len(HOSTILE_TOKENS))]) + data[i:]


def delete_span(data: bytes, pick: Pick) -> bytes:
    if not data:
        return data
    i = pick(len(data))
    n = 1 + pick(min(64, len(data) - i))
    return data[:i] + data[i + n:]


def truncate(data: bytes, pick: Pick) -> bytes:
    return data[:pick(len(data) + 1)]


def _lines(data: bytes) -> list[bytes]:
    return data.split(b"\n")


def duplicate_line(data: bytes, pick: Pick) -> bytes:
    ls = _lines(data)
    i = pick(len(ls))
    return b"\n".join(ls[:i + 1] + [ls[i]] + ls[i + 1:])


def delete_line(data: bytes, pick: Pick) -> bytes:
    ls = _lines(data)
    if len(ls) < 2:
        return b""
    i = pick(len(ls))
    return b"\n".join(ls[:i] + ls[i + 1:])


def swap_lines(data: bytes, pick: Pick) -> bytes:
    ls = _lines(data)
    i, j = pick(len(ls)), pick(len(ls))
    ls[i], ls[j] = ls[j], ls[i]
    return b"\n".join(ls)


def replace_number(data: bytes, pick: Pick) -> bytes:
    """One number of the input replaced by a hostile number cell."""
    ms = list(_NUMBER.finditer(data))
    if not ms:
        return insert_token(data, pick)
    m = ms[pick(len(ms))]
    return data[:m.start()] + _enc(HOSTILE_NUMBERS[pick(len(HOSTILE_NUMBERS))]) + data[m.end():]


def scale_number(data: bytes, pick: Pick) -> bytes:
    """One number multiplied by a large power of ten (finite, absurd)."""
    ms = list(_NUMBER.finditer(data))
    if not ms:
        return data
    m = ms[pick(len(ms))]
    return data[:m.start()] + m.group(0) + b"e" + str(pick(320)).encode() + data[m.end():]


def newline_style(data: bytes, pick: Pick) -> bytes:
    """LF -> CRLF or CR-only (valid: readers must accept both)."""
    return data.replace(b"\n", (b"\r\n", b"\r")[pick(2)])


def reencode(data: bytes, pick: Pick) -> bytes:
    """UTF-8 -> UTF-16 (BOM), a UTF-8 BOM, or latin-1 bytes."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        return data
    k = pick(3)
    if k == 0:
        return text.encode("utf-16")
    if k == 1:
        return b"\xef\xbb\xbf" + data
    return text.encode("latin-1", errors="replace") + b"\xe9\xff"


OPERATORS: tuple[Callable[[bytes, Pick], bytes], ...] = (
    flip_bit, insert_token, delete_span, truncate, duplicate_line, delete_line, swap_lines,
    replace_number, scale_number, newline_style, reencode,
)


def mutate(data: bytes, pick: Pick, rounds: int) -> tuple[bytes, list[str]]:
    """``rounds`` operators applied in turn; (result, names of the operators)."""
    names = []
    for _ in range(rounds):
        op = OPERATORS[pick(len(OPERATORS))]
        names.append(op.__name__)
        data = op(data, pick)
    return data, names
