"""What every export target provides, and the shared option handling.

A target module defines ``NAME``, ``SUMMARY``, ``OPTIONS`` (name -> Option) and
``build(ctx) -> Export``. :class:`Export` carries the files to write and the
target's own reconstruction of the correction it will apply
(``correction(pos_mm, state) -> um``, the amount the target adds to the
commanded position, with the target's own interpolation, grid, quantisation and
omissions), from which :mod:`abbe.formats.export.residual` computes what is left.

Sign convention (docs/concepts.md): (dX, dY, dZ) is the error of the tool
relative to the workpiece along the machine axes; a correct compensation adds
-(dX, dY, dZ) to the commanded position, so residual = error + correction.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from abbe.errors import AbbeInputError
from abbe.formats.export.terms import Item, contribution, items
from abbe.formats.export.volume import WorkVolume
from abbe.model.table import Table

#: Points per axis of the grid on which the size of an unheld part is measured.
ITEM_GRID_POINTS = 21


@dataclass(frozen=True)
class Option:
    """A target option (``--set NAME=VALUE``): kind "int", "float", "str" or "axes"
    (``X=..,Y=..,Z=..``); ``lo``/``hi`` bound numbers (hard limits of the format)."""

    kind: str
    default: Any
    help: str
    lo: float | None = None
    hi: float | None = None
    choices: tuple[str, ...] = ()


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
    """``NAME=VALUE`` strings -> values, defaults for the rest; AbbeInputError on an
    unknown name, a malformed value or a value outside the target's limits."""
    out = {k: o.default for k, o in spec.items()}
    for raw in given:
        name, eq, val = raw.partition("=")
        name = name.strip()
        if not eq:
            raise AbbeInputError(f"expected NAME=VALUE, got {raw!r}", field="--set")
        if name not in spec:
            known = ", ".join(sorted(spec)) or "none"
            raise AbbeInputError(f"{target} has no option {name!r} (options: {known})",
                                 field=f"--set {name}")
        o = spec[name]
        val = val.strip()
        try:
            if o.kind == "int":
                v: Any = int(val)
            elif o.kind == "float":
                v = float(val)
                if not np.isfinite(v):
                    raise ValueError
            elif o.kind == "axes":
                v = dict(o.default)
                for part in val.split(","):
                    k, e2, w = part.partition("=")
                    if not e2 or k.strip().upper() not in ("X", "Y", "Z"):
                        raise ValueError
                    v[k.strip().upper()] = w.strip()
            else:
                v = val
        except ValueError:
            raise AbbeInputError(f"expected {o.kind}, got {val!r}", field=f"--set {name}") from None
        if o.choices and v not in o.choices:
            raise AbbeInputError(f"expected one of {', '.join(o.choices)}, got {val!r}",
                                 field=f"--set {name}")
        if o.lo is not None and v < o.lo:
            raise AbbeInputError(f"{v} is below {o.lo:g}: {o.help}", field=f"--set {name}")
        if o.hi is not None and v > o.hi:
            raise AbbeInputError(f"{v} is above the limit {o.hi:g}: {o.help}",
                                 field=f"--set {name}")
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
