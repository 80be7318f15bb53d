"""The strict JSON document an abbe output is read as, the campaign it fills, and the
small located readers every output's reader shares (``abbe history add``, docs/history.md).
Values: um, urad, ppm/K as each output states them."""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from abbe.errors import AbbeInputError, check_number
from abbe.formats.limits import TABLE_JSON_MAX_BYTES
from abbe.formats.structured import JsonLocator, json_from_bytes
from abbe.formats.text import read_bytes

#: Largest magnitude accepted for any stored value (um, urad, ppm/K, ...).
VALUE_LIMIT = 1e7
AXES = ("X", "Y", "Z")
ANGULAR_TERMS = ("ex", "ey", "ez")


@dataclass
class Result:
    """One stored value: ``series`` is what a trend follows across campaigns."""

    series: str
    source: str
    quantity: str
    value: float
    unit: str
    axis: str | None = None
    direction: str | None = None
    plane: str | None = None
    feed_mm_min: float | None = None
    ci_low: float | None = None
    ci_high: float | None = None
    #: expanded uncertainty U (the result's unit) and its coverage factor k, when stated
    U: float | None = None
    k: float | None = None


@dataclass
class Campaign:
    """Everything ``abbe history add`` stores for one campaign (before the database)."""

    machine: str | None = None
    kinds: list[str] = field(default_factory=list)
    results: list[Result] = field(default_factory=list)
    tables: list[tuple[str, bytes, int]] = field(default_factory=list)  # source, blob, crc
    inputs: list[tuple[str, str, str]] = field(default_factory=list)  # role, file, sha256
    temperatures: list[tuple[str, float]] = field(default_factory=list)  # source, deg C
    parts: list[tuple[str, str]] = field(default_factory=list)  # (kind, sha256) -> the hash

    def content_sha256(self) -> str:
        """SHA-256 of what was read (kinds and file hashes, order-free): the campaign's id."""
        h = hashlib.sha256()
        for kind, digest in sorted(self.parts):
            h.update(f"{kind}:{digest}\n".encode())
        return h.hexdigest()


class _Doc:
    """A strict JSON document and its locator, for located errors."""

    def __init__(self, path: Path, raw: bytes, what: str) -> None:
        self.path = path
        self.raw = raw
        self.sha256 = hashlib.sha256(raw).hexdigest()
        self.data, tf = json_from_bytes(raw, name=str(path), what=what)
        self._loc: JsonLocator | None = None
        self._text = tf.text

    def err(self, field_: str, msg: str) -> AbbeInputError:
        if self._loc is None:
            self._loc = JsonLocator(self._text)
        return AbbeInputError(msg, file=str(self.path), line=self._loc.line(field_), field=field_)

    def get(self, dotted: str, kind: type | tuple[type, ...] = dict, optional: bool = False) -> Any:
        node: Any = self.data
        for part in dotted.split("."):
            if not isinstance(node, dict) or part not in node:
                if optional:
                    return None
                raise self.err(dotted, f"missing (expected {_kind_name(kind)})")
            node = node[part]
        if node is None and optional:
            return None
        if not isinstance(node, kind) or isinstance(node, bool) and kind is not bool:
            raise self.err(dotted, f"expected {_kind_name(kind)}, got {type(node).__name__}")
        return node

    def num(self, dotted: str, optional: bool = False, lo: float = -VALUE_LIMIT,
            hi: float = VALUE_LIMIT) -> float | None:
        v = self.get(dotted, (int, float), optional=optional)
        if v is None:
            return None
        try:
            return check_number(v, file=str(self.path), field=dotted, lo=lo, hi=hi)
        except AbbeInputError as exc:
            raise self.err(dotted, exc.message) from None


def _kind_name(kind: type | tuple[type, ...]) -> str:
    names = {dict: "an object", list: "a list", str: "a string", int: "a number",
             float: "a number", bool: "true or false"}
    ks = kind if isinstance(kind, tuple) else (kind,)
    return " or ".join(sorted({names.get(k, k.__name__) for k in ks}))


def _read(path: Path, what: str, max_bytes: int = TABLE_JSON_MAX_BYTES) -> _Doc:
    return _Doc(path, read_bytes(path, what=what, max_bytes=max_bytes), what)


def _begin(c: Campaign, doc: _Doc, kind: str, names_machine: bool = True) -> None:
    """Count ``doc`` in the campaign; ``names_machine``: its "machine" field is the
    machine's name (an export's is the machine file it read, not a name)."""
    c.kinds.append(kind)
    c.parts.append((kind, doc.sha256))
    c.inputs.append((f"{kind}:{doc.path.name}", str(doc.path), doc.sha256))
    name = doc.get("machine", str, optional=True) if names_machine else None
    if name:
        _set_machine(c, name, doc, "machine")


def _list(doc: _Doc, key: str) -> list[Any]:
    v = doc.get(key, list)
    if len(v) > 10_000:
        raise doc.err(key, f"{len(v)} entries: more than an abbe output writes")
    return v


def _entry_num(doc: _Doc, entry: Any, key: str, where: str, lo: float = -VALUE_LIMIT,
               optional: bool = False) -> float | None:
    if not isinstance(entry, dict):
        raise doc.err(where, "expected an object")
    v = entry.get(key)
    if v is None and optional:
        return None
    if v is None:
        raise doc.err(f"{where}.{key}", "missing (expected a number)")
    try:
        return check_number(v, file=str(doc.path), field=f"{where}.{key}", lo=lo,
                            hi=VALUE_LIMIT)
    except AbbeInputError as exc:
        raise doc.err(f"{where}.{key}", exc.message) from None


def _entry_str(doc: _Doc, entry: Any, key: str, where: str) -> str:
    v = entry.get(key) if isinstance(entry, dict) else None
    if not isinstance(v, str) or not v or len(v) > 100:
        raise doc.err(f"{where}.{key}", "expected a name (1-100 characters)")
    return v


def _unit(doc: _Doc, u: Any, where: str) -> str:
    if u not in ("um", "urad", "ppm", "mm", "deg", "K"):
        raise doc.err(where, f"unknown unit {u!r}")
    return str(u)


def _hash_named_file(c: Campaign, name: Any, role: str, beside: Path) -> None:
    """Record the SHA-256 of a measurement file an output names, when it is still there."""
    if not isinstance(name, str) or not name:
        return
    p = Path(name)
    if not p.is_absolute():
        p = beside.parent / p
    try:
        if p.is_file() and p.stat().st_size <= 256 << 20:
            h = hashlib.sha256()
            with open(p, "rb") as fh:
                for chunk in iter(lambda: fh.read(1 << 20), b""):
                    h.update(chunk)
            c.inputs.append((role, name, h.hexdigest()))
    except OSError:
        pass  # the output is what is stored; its measurement file is a courtesy


def _set_machine(c: Campaign, name: str, doc: _Doc, where: str) -> None:
    if c.machine is not None and c.machine != name:
        raise doc.err(where, f"machine {name!r}, but this campaign is of {c.machine!r}")
    c.machine = name
