"""Independent reader of the uncertainty fields of `abbe diagnose --json` (diagnose.json),
written from docs/formats.md ("diagnose JSON", the bullet "U (k = 2), issue 37"),
docs/uncertainty.md ("Diagnosis", "The Monte Carlo check") and docs/effects.md alone, not
from the writer.

``read_diagnose_uncertainty(path, mc)`` parses the file strictly (no NaN / Infinity, no
repeated key) and checks, for every named effect, each thermal-drift component and the
gap figures: ``u`` / ``U`` finite, >= 0, U = 2 u (k = 2); ``budget_u`` a non-empty object
of lines (the fit's Type A line and the instruments' inputs), each a finite u >= 0, whose
root sum of squares is the first-order u; the top-level ``uncertainty`` (``k`` = 2,
``method``, ``budgets``, ``assumptions``, ``effects``, ``gap``) holding the same figures as
the effects and the gap; and the Monte Carlo fields: with ``--mc N`` every figure has
``U_first_order``, ``U_mc``, ``mc_agreement`` = U_mc / U_first_order - 1 and ``U_from``
with U the first order's when the two agree within 10 % and the Monte Carlo's otherwise
(a drift's line "drift time constant" taken out of the first order for the comparison and
added to the Monte Carlo's U in quadrature),
``monte_carlo`` has ``draws`` = N, ``seed``, ``figures`` (U, U_mc, agreement each) and
``agree_within_10pct`` of ``of``; without it none of those keys is there. A violation
raises ``FormatError`` naming the place. Nothing is imported from abbe.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from doc_json_readers import (FormatError, _close, _fail, _k2, _list, _num, _obj, _stated,
                              _str, load_strict)

#: docs/formats.md: the keys --mc adds to an effect (absent without it).
MC_KEYS = ("U_first_order", "U_mc", "mc_agreement", "U_from")
#: gap.before / gap.after gain these (um).
GAP_KEYS = ("rms_U_um", "max_U_um", "rms_u_um", "max_u_um")
#: The budget's first line (docs/formats.md: "fit (Type A: noise, lack of fit)").
TYPE_A = "fit (Type A: noise, lack of fit)"
#: docs/formats.md: a drift's budget line for its warm-up time constant, which the Monte
#: Carlo does not draw: compared without it, added to the Monte Carlo's U in quadrature.
TIME_CONSTANT = "drift time constant"
#: the fitted table's own uncertainty along the effect (abbe.diagnose.uncertainty.TABLE_LINE)
TABLE_LINE = "table (fit) uncertainty"
#: Figures in the JSON are rounded; U = 2 u and the root sum of squares hold to this.
_REL = 2e-3
_ABS = 2e-6


def _budget(b: Any, where: str, type_a: str = TYPE_A) -> float:
    """A budget's lines: name -> standard uncertainty; returns their root sum of squares.
    An effect's budget has the line ``TYPE_A``; a gap's a line naming its Type A part."""
    _obj(b, where)
    if not b:
        _fail(where, "a budget has at least the fit's line")
    if not any(type_a in k for k in b):
        _fail(where, f"no line {type_a!r} (docs/formats.md); lines {sorted(b)}")
    return math.sqrt(sum(_num(v, f"{where}[{k!r}]", lo=0.0) ** 2 for k, v in b.items()))


def _without_time_constant(U1: float, budget: dict[str, Any], U: float
                           ) -> tuple[float, float]:
    """(the first-order U, the stated U) without a drift's time-constant line and the
    table's line (2 x their u removed in quadrature; the draws hold both fixed): what the
    Monte Carlo's U is compared with and stated as."""
    line = sum(float(v) ** 2 for k, v in budget.items()
               if k.startswith(TIME_CONSTANT) or k == TABLE_LINE)
    return (math.sqrt(max(U1 ** 2 - 4.0 * line, 0.0)), math.sqrt(max(U ** 2 - 4.0 * line, 0.0)))


def _figure(f: dict[str, Any], where: str, mc: bool) -> dict[str, float]:
    """u, U, budget_u and (with --mc) the Monte Carlo fields of one effect or component."""
    for key in ("u", "U", "budget_u"):
        if key not in f:
            _fail(where, f"no {key!r} (docs/formats.md: every effect carries u, U, budget_u)")
    u = _num(f["u"], where + ".u", lo=0.0)
    U = _num(f["U"], where + ".U", lo=0.0)
    _close(U, 2.0 * u, where + ".U = 2 u", rel=_REL, abs_=_ABS)
    rss = _budget(f["budget_u"], where + ".budget_u")
    if not mc:
        extra = [k for k in MC_KEYS if k in f]
        if extra:
            _fail(where, f"{extra} without --mc (docs/formats.md: only with --mc N)")
        _close(U, 2.0 * rss, where + ".U = 2 x RSS(budget_u) (first order)", rel=_REL,
               abs_=_ABS)
        return {"U": U, "u": u}
    for key in MC_KEYS:
        if key not in f:
            _fail(where, f"no {key!r} with --mc (docs/formats.md)")
    u1 = _num(f["U_first_order"], where + ".U_first_order", lo=0.0)
    umc = _num(f["U_mc"], where + ".U_mc", lo=0.0)
    _close(u1, 2.0 * rss, where + ".U_first_order = 2 x RSS(budget_u)", rel=_REL, abs_=_ABS)
    u1x, Ux = _without_time_constant(u1, f["budget_u"], U)
    if u1x > 0:
        _close(_num(f["mc_agreement"], where + ".mc_agreement"), umc / u1x - 1.0,
               where + ".mc_agreement = U_mc / U_first_order - 1", rel=1e-2, abs_=2e-3)
    _stated(u1x, umc, Ux, _str(f["U_from"], where + ".U_from"), where)
    return {"U": U, "u": u, "U_first_order": u1, "U_mc": umc, "U_first_order_mc": u1x}


def read_diagnose_uncertainty(path: Path, mc: int = 0) -> dict[str, Any]:
    """Check diagnose.json's uncertainty fields (``mc``: the --mc N it was written with)."""
    where0 = str(path)
    doc = _obj(load_strict(path), where0)
    for key in ("effects", "gap", "uncertainty"):
        if key not in doc:
            _fail(where0, f"no {key!r}")
    effects = _list(doc["effects"], where0 + ".effects")
    figures: dict[str, dict[str, float]] = {}
    for i, e in enumerate(effects):
        we = f"{where0}.effects[{i}]"
        _obj(e, we)
        key = _str(e.get("key"), we + ".key")
        _num(e.get("value"), we + ".value")
        figures[key] = _figure(e, we, bool(mc))
        for j, c in enumerate(e.get("components", []) or []):
            _figure(_obj(c, f"{we}.components[{j}]"), f"{we}.components[{j}]", bool(mc))
    gap = _obj(doc["gap"], where0 + ".gap")
    for side in ("before", "after"):
        wg = f"{where0}.gap.{side}"
        g = _obj(gap[side], wg)
        for what in ("rms", "max"):
            u = _num(g.get(f"{what}_u_um"), f"{wg}.{what}_u_um", lo=0.0)
            U = _num(g.get(f"{what}_U_um"), f"{wg}.{what}_U_um", lo=0.0)
            _close(U, 2.0 * u, f"{wg}.{what}_U_um = 2 {what}_u_um", rel=_REL, abs_=_ABS)
            _num(g.get(f"{what}_um"), f"{wg}.{what}_um", lo=0.0)
            figures[f"gap {what} {side}"] = {"U": U, "u": u, "value": g[f"{what}_um"]}
    for side in ("held_out_before", "held_out_after"):
        g = gap.get(side)
        if g is not None and any(k in _obj(g, f"{where0}.gap.{side}") for k in GAP_KEYS):
            _fail(f"{where0}.gap.{side}", "U is documented for gap.before / gap.after only")

    un = _obj(doc["uncertainty"], where0 + ".uncertainty")
    for key in ("k", "method", "budgets", "assumptions", "effects", "gap"):
        if key not in un:
            _fail(where0 + ".uncertainty", f"no {key!r} (docs/formats.md)")
    _k2(un["k"], where0 + ".uncertainty.k")
    _str(un["method"], where0 + ".uncertainty.method")
    _obj(un["budgets"], where0 + ".uncertainty.budgets")
    _check_summary(un, figures, where0 + ".uncertainty", mc)
    if mc:
        _check_mc(un.get("monte_carlo"), figures, where0 + ".uncertainty.monte_carlo", mc)
    elif "monte_carlo" in un:
        _fail(where0 + ".uncertainty.monte_carlo", "present without --mc (docs/formats.md)")
    return doc


def _entries(v: Any, where: str) -> list[tuple[str, dict[str, Any]]]:
    """The per-figure entries of uncertainty.effects / monte_carlo.figures: an object
    name -> figure (or a list of figures each naming itself)."""
    if isinstance(v, dict):
        return [(k, _obj(x, f"{where}[{k!r}]")) for k, x in v.items()]
    out = []
    for i, x in enumerate(_list(v, where)):
        _obj(x, f"{where}[{i}]")
        name = x.get("key", x.get("name", x.get("figure")))
        out.append((_str(name, f"{where}[{i}].name"), x))
    return out


def _summary_entry(x: Any, where: str, mc: int) -> dict[str, Any]:
    """One figure of uncertainty.effects / .gap: value, u, U, budget_u; with --mc also
    U_first_order, U_mc, mc_agreement, mc_interval95 and U_from (the 10 % rule)."""
    keys = {"value", "u", "U", "budget_u"} | (set(MC_KEYS) | {"mc_interval95"} if mc else set())
    x = _obj(x, where, keys)
    _num(x["value"], where + ".value")
    u = _num(x["u"], where + ".u", lo=0.0)
    U = _num(x["U"], where + ".U", lo=0.0)
    _close(U, 2.0 * u, where + ".U = 2 u", rel=_REL, abs_=_ABS)
    if mc:
        iv = _list(x["mc_interval95"], where + ".mc_interval95")
        if len(iv) != 2:
            _fail(where + ".mc_interval95", f"expected [low, high], got {iv!r}")
        lo, hi = (_num(v, where + ".mc_interval95") for v in iv)
        if not lo <= hi:
            _fail(where + ".mc_interval95", f"[{lo}, {hi}] is not an interval")
        u1 = _num(x["U_first_order"], where + ".U_first_order", lo=0.0)
        umc = _num(x["U_mc"], where + ".U_mc", lo=0.0)
        u1x, Ux = _without_time_constant(u1, _obj(x["budget_u"], where + ".budget_u"), U)
        if u1x > 0:
            _close(_num(x["mc_agreement"], where + ".mc_agreement"), umc / u1x - 1.0,
                   where + ".mc_agreement = U_mc / U_first_order - 1", rel=1e-2, abs_=2e-3)
        _stated(u1x, umc, Ux, _str(x["U_from"], where + ".U_from"), where)
    return x


def _check_summary(un: dict[str, Any], figures: dict[str, dict[str, float]], where: str,
                   mc: int) -> None:
    """uncertainty.effects and .gap: value, u, U, budget_u per figure, the same U as the
    effect or gap entry it sums up."""
    eff = [k for k in figures if not k.startswith("gap ")]
    got = _entries(un["effects"], where + ".effects")
    names = {n for n, _ in got}
    if set(eff) - names:
        _fail(where + ".effects", f"missing the effects {sorted(set(eff) - names)}")
    for n, x in got:
        _summary_entry(x, f"{where}.effects[{n!r}]", mc)
        if n in figures:
            _close(_num(x["U"], f"{where}.effects[{n!r}].U", lo=0.0), figures[n]["U"],
                   f"{where}.effects[{n!r}].U = the effect's U", rel=_REL, abs_=_ABS)
    # gap: before / after, each rms_um / max_um (the gap entry's figures)
    g = _obj(un["gap"], where + ".gap", {"before", "after"})
    for side in ("before", "after"):
        _obj(g[side], f"{where}.gap.{side}", {"rms_um", "max_um"})
        for what in ("rms", "max"):
            wx = f"{where}.gap.{side}.{what}_um"
            x = _summary_entry(g[side][f"{what}_um"], wx, mc)
            fig = figures[f"gap {what} {side}"]
            _close(_num(x["value"], wx + ".value"), fig["value"], wx + ".value = the gap's",
                   rel=1e-3, abs_=1e-4)
            _close(_num(x["U"], wx + ".U", lo=0.0), fig["U"], wx + ".U = the gap's", rel=_REL,
                   abs_=_ABS)
            _close(_num(x["u"], wx + ".u", lo=0.0), fig["u"], wx + ".u = the gap's", rel=_REL,
                   abs_=_ABS)
            rss = _budget(x["budget_u"], wx + ".budget_u", type_a="Type A")
            fig["U_first_order"] = 2.0 * rss
            if not mc:  # without a Monte Carlo the first order is stated
                _close(fig["U"], 2.0 * rss, wx + ".U = 2 x RSS(budget_u) (first order)",
                       rel=_REL, abs_=_ABS)


def _check_mc(m: Any, figures: dict[str, dict[str, float]], where: str, mc: int) -> None:
    m = _obj(m, where)
    for key in ("draws", "seed", "figures", "agree_within_10pct", "of"):
        if key not in m:
            _fail(where, f"no {key!r} (docs/formats.md)")
    if m["draws"] != mc:
        _fail(where + ".draws", f"{m['draws']!r}, --mc was {mc}")
    figs = _entries(m["figures"], where + ".figures")
    agree = 0
    for n, x in figs:
        # the figure it checks: an effect's key, or the gap's "before.rms_um"
        side, _, what = n.partition(".")
        ref = figures.get(n) or figures.get(f"gap {what.removesuffix('_um')} {side}")
        if ref is None:
            _fail(f"{where}.figures[{n!r}]", f"names no figure of the document ({sorted(figures)})")
        for key in ("U", "U_mc", "agreement"):
            if key not in x:
                _fail(f"{where}.figures[{n!r}]", f"no {key!r} (U, U_mc, agreement per figure)")
        U = _num(x["U"], f"{where}.figures[{n!r}].U", lo=0.0)
        Umc = _num(x["U_mc"], f"{where}.figures[{n!r}].U_mc", lo=0.0)
        a = _num(x["agreement"], f"{where}.figures[{n!r}].agreement")
        Ux = ref.get("U_first_order_mc", U)   # without a drift's time-constant line
        if Ux > 0:
            _close(a, Umc / Ux - 1.0, f"{where}.figures[{n!r}].agreement = U_mc / U - 1",
                   rel=1e-2, abs_=2e-3)
        # U here is the first order's (the rule then states U or U_mc)
        _close(U, ref["U_first_order"], f"{where}.figures[{n!r}].U = the first-order U",
               rel=_REL, abs_=_ABS)
        if "U_mc" in ref:
            _close(Umc, ref["U_mc"], f"{where}.figures[{n!r}].U_mc = the effect's", rel=_REL,
                   abs_=_ABS)
        else:  # a gap figure: its stated U follows the 10 % rule too
            _stated(U, Umc, ref["U"], "first order" if abs(Umc / U - 1) <= 0.1 else
                    "Monte Carlo", f"{where}.figures[{n!r}]")
        agree += abs(a) <= 0.10
    if m["of"] != len(figs):
        _fail(where + ".of", f"{m['of']!r}, there are {len(figs)} figures")
    if m["agree_within_10pct"] != agree:
        _fail(where + ".agree_within_10pct", f"{m['agree_within_10pct']!r}, the figures' "
                                             f"agreements give {agree}")
    if len(figs) < len(figures):
        _fail(where + ".figures", f"{len(figs)} figures, the document states U for "
                                  f"{len(figures)}")


__all__ = ["FormatError", "read_diagnose_uncertainty"]
