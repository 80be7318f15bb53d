"""What every export target provides, and the shared option handling.

A target module defines ``NAME``, ``SUMMARY``, ``OPTIONS`` (name -> Option) and
``build(ctx) -> Export``. :class:`Export` carries the files to write and the
target's own reconstruction of the correction it will apply
(``correction(pos_mm, state) -> um``, the amount the target adds to the
commanded position, with the target's own interpolation, grid, quantisation and
omissions), from which :mod:`abbe.exports.residual` computes what is left.

Sign convention (docs/concepts.md): (dX, dY, dZ) is the error of the tool
relative to the workpiece along the machine axes; a correct compensation adds
-(dX, dY, dZ) to the commanded position, so residual = error + correction.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from abbe.errors import AbbeInputError
from abbe.errors.numbers import show_value
from abbe.exports.terms import Item, contribution, items
from abbe.exports.volume import WorkVolume
from abbe.model.table import Table

#: Points per axis of the grid on which the size of an unheld part is measured.
ITEM_GRID_POINTS = 21


#: A name written into a target's file (axis names, profile and component names): ASCII,
#: no spaces, quotes or line ends, so it cannot break the file's syntax.
NAME_PATTERN = r"[A-Za-z0-9_][A-Za-z0-9_.+-]{0,31}"
#: abbe's own bound on the points of any one table (beyond the controllers' limits; it
#: bounds the time and memory of a build).
TABLE_MAX_POINTS = 10_000


@dataclass(frozen=True)
class Option:
    """A target option (``--set NAME=VALUE``): kind "int", "float", "str" or "axes"
    (``X=..,Y=..,Z=..``, each value of kind ``item``). ``lo``/``hi`` bound a number (every
    number has both: the format's hard limits, or abbe's bound); ``choices`` or
    ``pattern`` (a full-match regex) restrict a text."""

    kind: str
    default: Any
    help: str
    lo: float | None = None
    hi: float | None = None
    choices: tuple[str, ...] = ()
    item: str = "str"
    pattern: str = NAME_PATTERN
    lo_open: bool = False

    @property
    def value_kind(self) -> str:
        return self.item if self.kind == "axes" else self.kind

    def describe(self) -> str:
        """``int in [2, 256]``, ``one of a, b``, ``axes X=..,Y=..,Z=.. of int in [0, 15]``."""
        k = self.value_kind
        if self.choices:
            what = f"one of {', '.join(self.choices)}"
        elif k in ("int", "float"):
            what = f"{k} in {'(' if self.lo_open else '['}{self.lo:g}, {self.hi:g}]"
        else:
            what = "a name"
        return f"X=..,Y=..,Z=.. each {what}" if self.kind == "axes" else what

    def show_default(self) -> str:
        if self.kind == "axes":
            return ",".join(f"{a}={v}" for a, v in self.default.items())
        return str(self.default)

    def check(self, text: str, fld: str) -> Any:
        """One value (text, stripped) of this option's value kind, or an AbbeInputError
        (the range, then what the option is)."""
        try:
            return self._check(text, fld)
        except AbbeInputError as exc:
            exc.message = f"{exc.message}: {self.help}"
            exc.args = (str(exc),)
            raise

    def _check(self, text: str, fld: str) -> Any:
        from abbe.errors import parse_int, parse_number

        k = self.value_kind
        if k == "int":
            v: Any = parse_int(text, field=fld, lo=int(self.lo), hi=int(self.hi))  # type: ignore[arg-type]
        elif k == "float":
            v = parse_number(text, field=fld, lo=self.lo, hi=self.hi)  # type: ignore[arg-type]
            if self.lo_open and v <= self.lo:
                raise AbbeInputError(f"expected a number in ({self.lo:g}, {self.hi:g}], got "
                                     f"{text!r}", field=fld)
        elif self.choices:
            if text not in self.choices:
                raise AbbeInputError(f"expected one of {', '.join(self.choices)}, got "
                                     f"{show_value(text)}", field=fld)
            v = text
        else:
            if not re.fullmatch(self.pattern, text):
                raise AbbeInputError(f"expected a name matching {self.pattern} (ASCII letters, "
                                     f"digits, _ . + -), got {show_value(text)}", field=fld)
            v = text
        if self.kind == "axes":
            return text  # as written (the target converts it; the value was checked)
        return v


@dataclass
class Context:
    """Inputs of a build: the table, the work volume, the parsed options."""

    table: Table
    volume: WorkVolume
    options: dict[str, Any]
    model_source: str = ""


@dataclass
class Export:
    """The output of a target build (see the module docstring).

    direction: the target's own direction rule along a path: "none" (no
    direction-dependent correction), "sign" (sign of the axis motion, held at
    rest: LinuxCNC, Fanuc, Heidenhain, Siemens) or ("takeup", mm) (ramped over a
    distance, like the model).
    """

    target: str
    files: dict[str, bytes]
    correction: Callable[[np.ndarray, np.ndarray], np.ndarray]
    expressed: list[str]
    not_held: list[dict[str, Any]] = field(default_factory=list)
    tables: list[dict[str, Any]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    assumptions: list[str] = field(default_factory=list)
    direction: Any = "sign"
    sources: list[str] = field(default_factory=list)


def parse_options(target: str, spec: dict[str, Option], given: list[str]) -> dict[str, Any]:
    """``NAME=VALUE`` strings -> values, defaults for the rest; AbbeInputError (field
    ``--set NAME``) on an unknown name (with a suggestion), a name given twice, a
    malformed value or a value outside the option's range."""
    from abbe.formats.structured import unknown_key

    out = {k: o.default for k, o in spec.items()}
    seen: set[str] = set()
    for raw in given:
        name, eq, val = raw.partition("=")
        name = name.strip(" \t")
        if not eq:
            raise AbbeInputError(f"expected NAME=VALUE, got {show_value(raw)}", field="--set")
        if name not in spec:
            raise AbbeInputError(f"{target}: " + unknown_key(name, sorted(spec) or ["(none)"],
                                                              "option"),
                                 field=f"--set {name[:40]}")
        if name in seen:
            raise AbbeInputError("given twice (it takes one value)", field=f"--set {name}")
        seen.add(name)
        o = spec[name]
        fld = f"--set {name}"
        val = val.strip(" \t")
        if o.kind != "axes":
            out[name] = o.check(val, fld)
            continue
        v = dict(o.default)
        done: set[str] = set()
        for part in val.split(","):
            k, e2, w = part.partition("=")
            k = k.strip(" \t").upper()
            if not e2 or k not in ("X", "Y", "Z"):
                raise AbbeInputError(f"expected X=..,Y=..,Z=.. (any of them), got "
                                     f"{show_value(val)}", field=fld)
            if k in done:
                raise AbbeInputError(f"axis {k} given twice", field=fld)
            done.add(k)
            v[k] = o.check(w.strip(" \t"), f"{fld} {k}")
        out[name] = v
    return out


@dataclass(frozen=True)
class Unheld:
    """Why (part of) a model item is not held by a target.

    components: the error components it is not held in ("XYZ" = all);
    remainder: optional ``f(pos (N, 3), contribution (N, 3)) -> (N, 3)`` giving the
    part left over when the target holds a share of the item (e.g. its linear
    part); None = the whole contribution in ``components``.
    """

    reason: str
    components: str = "XYZ"
    remainder: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None


def item_size(table: Table, volume: WorkVolume, item: Item,
              how: Unheld | None = None) -> dict[str, Any]:
    """max and RMS of |unheld part| (vector norm, um) of ``item`` over a coarse volume
    grid (ITEM_GRID_POINTS per axis), and the component where it is largest."""
    c = {a: ITEM_GRID_POINTS for a in "XYZ"}
    pos = volume.grid(c)
    v = contribution(table, item, pos)
    if how is not None:
        if how.remainder is not None:
            v = how.remainder(pos, v)
        mask = np.array([a in how.components for a in "XYZ"])
        v = v * mask[None, :]
    n = np.linalg.norm(v, axis=1)
    comp = "XYZ"[int(np.argmax(np.max(np.abs(v), axis=0)))]
    return {"max_um": round(float(np.max(n)), 4), "rms_um": round(float(np.sqrt(np.mean(n ** 2))), 4),
            "largest_in": f"d{comp}"}


def not_held(ctx: Context, cannot: Callable[[Item], Unheld | None],
             floor_um: float = 1e-4) -> list[dict[str, Any]]:
    """The parts of the model the target cannot hold, each with its size.

    ``cannot(item)`` returns an :class:`Unheld` or None if the item is held. Parts
    smaller than ``floor_um`` everywhere are left out. Thermal sizes are per kelvin
    of deviation from T_ref.
    """
    out = []
    for it in items(ctx.table):
        how = cannot(it)
        if how is None:
            continue
        size = item_size(ctx.table, ctx.volume, it, how)
        if size["max_um"] < floor_um:
            continue
        d = {"item": it.label, "kind": it.kind, "reason": how.reason,
             "components": how.components, **size}
        if it.kind == "thermal":
            d["per_kelvin"] = True
        out.append(d)
    return out


def fmt(v: float, decimals: int) -> str:
    """Fixed-point text without a negative zero."""
    s = f"{v:.{decimals}f}"
    return s[1:] if s.startswith("-") and float(s) == 0.0 else s


def quantize(v: np.ndarray, decimals: int) -> np.ndarray:
    """The values as they read back from :func:`fmt` text."""
    return np.array([float(fmt(float(x), decimals)) for x in np.asarray(v).reshape(-1)])
