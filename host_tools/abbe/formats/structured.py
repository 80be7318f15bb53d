"""Bounded TOML and JSON loading: every problem an AbbeInputError with file and line.

* :func:`load_toml`: the bounded text reader, then ``tomllib`` with its errors
  located; nesting deeper than :data:`abbe.formats.limits.MAX_NESTING` and
  integers longer than 4300 digits are input errors (not RecursionError /
  ValueError); a float beyond the double range (``1e400``) reaches the schema as
  ``inf``, which :func:`abbe.errors.check_number` refuses.
* :func:`load_json`: strict JSON in UTF-8 (one BOM allowed): ``NaN``,
  ``Infinity``, numbers longer than :data:`abbe.errors.MAX_NUMBER_CHARS` or
  outside the double range, duplicated keys and deep nesting are refused; a
  :class:`JsonLocator` gives the line of a dotted field for messages.
* :func:`unknown_key` : the message for a key not in the schema, with a suggestion.
"""

from __future__ import annotations

import difflib
import json
import math
import re
import tomllib
from pathlib import Path
from typing import Any, Iterable

from abbe.errors import MAX_NUMBER_CHARS, AbbeInputError
from abbe.formats.limits import MAX_NESTING
from abbe.formats.text import TextFile, decode_text, read_text


def unknown_key(key: str, options: Iterable[str], what: str = "key") -> str:
    """``unknown key (did you mean 'x'?); expected one of a, b, c``."""
    opts = list(options)
    close = difflib.get_close_matches(key, opts, n=1, cutoff=0.6)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    if not key.isascii() and not hint:
        ascii_key = "".join(ch if ch.isascii() else "?" for ch in key)
        close = difflib.get_close_matches(ascii_key, opts, n=1, cutoff=0.5)
        hint = f" (did you mean {close[0]!r}? it holds non-ASCII letters)" if close else \
            " (it holds non-ASCII letters)"
    return f"unknown {what}{hint}; expected one of {', '.join(opts)}"


def _depth_line(text: str, *, toml: bool) -> int | None:
    """Line where brackets/braces nest deeper than MAX_NESTING (strings and comments
    skipped), or None."""
    depth, line, i, n = 0, 1, 0, len(text)
    while i < n:
        ch = text[i]
        if ch == "\n":
            line += 1
        elif toml and ch == "#":
            j = text.find("\n", i)
            i = n if j < 0 else j
            continue
        elif ch in "\"'" and (toml or ch == '"'):
            triple = toml and text.startswith(ch * 3, i)
            end = ch * 3 if triple else ch
            j = i + len(end)
            while j < n:
                if text[j] == "\\" and ch == '"':
                    j += 2
                    continue
                if text.startswith(end, j):
                    break
                if text[j] == "\n":
                    line += 1
                    if not triple:
                        break
                j += 1
            i = j + len(end)
            continue
        elif ch in "[{":
            depth += 1
            if depth > MAX_NESTING:
                return line
        elif ch in "]}":
            depth = max(depth - 1, 0)
        i += 1
    return None


def _long_int_line(text: str) -> int | None:
    m = re.search(r"[0-9_]{4000,}", text)
    return text.count("\n", 0, m.start()) + 1 if m else None


def load_toml(path: str | Path, *, what: str, max_bytes: int) -> tuple[dict[str, Any], TextFile]:
    """Parse a bounded TOML file; (data, text file)."""
    tf = read_text(path, what=what, max_bytes=max_bytes)
    name = tf.name
    deep = _depth_line(tf.text, toml=True)
    if deep is not None:
        raise AbbeInputError(f"nested deeper than {MAX_NESTING} levels", file=name, line=deep)
    for _no, _line in tf.lines():  # the line-length bound
        pass
    try:
        data = tomllib.loads(tf.text)
    except tomllib.TOMLDecodeError as exc:
        m = re.search(r"line (\d+)", str(exc))
        msg = re.sub(r"\s*\(at line \d+, column \d+\)", "", str(exc))
        raise AbbeInputError(f"TOML syntax error: {msg}", file=name,
                             line=int(m.group(1)) if m else None) from None
    except RecursionError:
        raise AbbeInputError(f"nested too deeply (at most {MAX_NESTING} levels)",
                             file=name) from None
    except ValueError as exc:  # e.g. an integer beyond Python's 4300-digit conversion limit
        raise AbbeInputError(f"number too long: {exc}", file=name,
                             line=_long_int_line(tf.text)) from None
    return data, tf


# --------------------------------------------------------------------------- JSON


def _pairs(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    d: dict[str, Any] = {}
    for k, v in pairs:
        if k in d:
            raise _JsonProblem(f"duplicated key {k!r}")
        d[k] = v
    return d


class _JsonProblem(ValueError):
    def __init__(self, msg: str, text: str | None = None) -> None:
        super().__init__(msg)
        self.text = text


def _json_float(text: str) -> float:
    if len(text) > MAX_NUMBER_CHARS:
        raise _JsonProblem(f"number of {len(text)} characters (at most {MAX_NUMBER_CHARS})", text)
    v = float(text)
    if not math.isfinite(v):
        raise _JsonProblem(f"number {text[:30]!r} is outside the double range", text)
    return v


def _json_int(text: str) -> int:
    if len(text) > MAX_NUMBER_CHARS:
        raise _JsonProblem(f"integer of {len(text)} digits (at most {MAX_NUMBER_CHARS})", text)
    return int(text)


def _json_constant(name: str) -> Any:
    raise _JsonProblem(f"{name} is not a JSON number (strict JSON: no NaN or Infinity)")


_JSON_TOKEN = re.compile(r'"(?:[^"\\]|\\.)*"|[{}\[\]:,]|\n|-?Infinity|NaN')


def _json_problem_line(text: str, what: str) -> int | None:
    """Line of the first bare NaN / Infinity (``what`` = "constant") or of the first key
    repeated in one object (``what`` = "duplicate"), strings skipped."""
    line = 1
    keys: list[set[str] | None] = []  # per open container: its keys (None: a list)
    last: str | None = None
    for m in _JSON_TOKEN.finditer(text):
        t = m.group(0)
        if t == "\n":
            line += 1
        elif t[0] == '"':
            last = t
            line += t.count("\n")
        elif t in ("NaN", "Infinity", "-Infinity"):
            if what == "constant":
                return line
        elif t == "{":
            keys.append(set())
        elif t == "[":
            keys.append(None)
        elif t in "}]":
            if keys:
                keys.pop()
        elif t == ":" and keys and keys[-1] is not None and last is not None:
            try:
                k = json.loads(last)
            except ValueError:
                k = last
            if k in keys[-1] and what == "duplicate":
                return line
            keys[-1].add(k)
            last = None
    return None


def parse_json_text(tf: TextFile) -> Any:
    """Strict JSON from a decoded text file (module docstring)."""
    deep = _depth_line(tf.text, toml=False)
    if deep is not None:
        raise AbbeInputError(f"nested deeper than {MAX_NESTING} levels", file=tf.name, line=deep)
    try:
        return json.loads(tf.text, object_pairs_hook=_pairs, parse_float=_json_float,
                          parse_int=_json_int, parse_constant=_json_constant)
    except json.JSONDecodeError as exc:
        raise AbbeInputError(f"invalid JSON: {exc.msg} (column {exc.colno})", file=tf.name,
                             line=exc.lineno) from None
    except _JsonProblem as exc:
        at = tf.text.find(exc.text) if exc.text else -1
        line = tf.text.count("\n", 0, at) + 1 if at >= 0 else _json_problem_line(
            tf.text, "duplicate" if str(exc).startswith("duplicated key") else "constant")
        raise AbbeInputError(f"invalid JSON: {exc}", file=tf.name, line=line) from None
    except RecursionError:
        raise AbbeInputError(f"nested too deeply (at most {MAX_NESTING} levels)",
                             file=tf.name) from None


def load_json(path: str | Path, *, what: str, max_bytes: int) -> tuple[Any, TextFile]:
    """Strict, bounded JSON file; (value, text file)."""
    tf = read_text(path, what=what, max_bytes=max_bytes)
    return parse_json_text(tf), tf


def json_from_bytes(raw: bytes, *, name: str, what: str) -> tuple[Any, TextFile]:
    """Strict JSON from bytes already read (bounded by the caller)."""
    tf = decode_text(raw, name=name, what=what)
    return parse_json_text(tf), tf


class JsonLocator:
    """Dotted path (``axes.X.backlash_um``, ``a.b[2]``) -> line of a JSON text (best effort)."""

    _TOKEN = re.compile(r'"(?:[^"\\]|\\.)*"|[{}\[\],:]|\n')

    def __init__(self, text: str) -> None:
        self.lines: dict[str, int] = {}
        stack: list[list[Any]] = []  # [kind, path, key or index]
        line = 1
        last_str: str | None = None
        expect_key = False
        for m in self._TOKEN.finditer(text):
            t = m.group(0)
            if t == "\n":
                line += 1
                continue
            line_here = line + 0
            if t[0] == '"':
                if stack and stack[-1][0] == "{" and expect_key:
                    try:
                        last_str = json.loads(t)
                    except ValueError:
                        last_str = t.strip('"')
                continue
            if t == ":" and stack and last_str is not None:
                frame = stack[-1]
                frame[2] = last_str
                self.lines.setdefault(self._path(stack), line_here)
                expect_key = False
                last_str = None
            elif t in "{[":
                if stack and stack[-1][0] == "[":
                    self.lines.setdefault(self._path(stack), line_here)
                stack.append([t, None, None if t == "{" else 0])
                expect_key = t == "{"
            elif t in "}]":
                if stack:
                    stack.pop()
                expect_key = False
            elif t == ",":
                if stack and stack[-1][0] == "[":
                    stack[-1][2] += 1
                    self.lines.setdefault(self._path(stack), line_here)
                expect_key = bool(stack and stack[-1][0] == "{")

    @staticmethod
    def _path(stack: list[list[Any]]) -> str:
        out = ""
        for kind, _, k in stack:
            if k is None:
                break
            out += f"[{k}]" if kind == "[" else (("." if out else "") + str(k))
        return out

    def line(self, dotted: str | None) -> int | None:
        """Line of ``dotted`` or of its nearest enclosing field."""
        p = dotted or ""
        while p:
            if p in self.lines:
                return self.lines[p]
            cut = max(p.rfind("."), p.rfind("["))
            if cut <= 0:
                break
            p = p[:cut]
        return self.lines.get(p)

