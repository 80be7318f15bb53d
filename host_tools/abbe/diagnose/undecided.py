"""What the table holds when the data cannot decide between explanations (issue 36).

An undecided effect (describe._undecided: another candidate reproduces its signature on
every check within the estimated noise, log likelihood ratio below log 19) has several
explanations that predict the same on the checked paths: scale_x = +k or scale_y = -k on one XY circle. Any mixture w A + (1 - w) B
reproduces the checks too (the signatures are linear in the values). The table gets the
**equal share**, (A + B) / n: the combination the checks constrain, with no weight on
what they cannot see; whichever explanation is true, the table's error off the checked
paths is at most half of it, not all of it as with the first name alone. The report says
what stays unknown (which explanation, i.e. the share between them) and the test that
decides it. When an alternative cannot go where the named effect goes (one into the
table, the other only into the prediction model, or a cyclic one whose period was
searched for the ambiguity only), the named effect keeps the whole and the report says so.

Units: those of each effect (see docs/effects.md §2).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from abbe.diagnose.candidates import Cand, Engine, Selected, apply_selection
from abbe.diagnose.effects import PredParams
from abbe.diagnose.results import EffectResult, round_to
from abbe.model.table import Table


def misfit_log_lr(misfit: float, norm: float, s2: float, model_rel_sigma: float) -> float:
    """The log likelihood ratio of a named effect A over an alternative B fitted to A's
    signature (docs/effects.md section 3, "Undecided is an answer"): half the part of A's
    whitened fitted signature B cannot reproduce (``misfit``, RSS in noise units) over its
    variance along that one direction, the noise ``s2`` plus the model's own error of the
    signature, (``model_rel_sigma`` x |s_A|)^2 with ``norm`` = |s_A|^2 (whitened): the
    model predicts a signature's shape to a relative accuracy, not exactly, so a misfit
    of a small share of a large signature is not many noise units of evidence. The same
    form as a tool offset's model-angle term (evidence.log_evidence: sigma_w^2 +
    sigma_m^2). Tends to (1 - R^2) / (2 model_rel_sigma^2) for a large signature and to
    misfit / (2 s2) for a small one."""
    var = max(s2, 1e-300) + model_rel_sigma ** 2 * max(norm, 0.0)
    return max(misfit, 0.0) / (2.0 * var)


def heldout_in_time(prob: Any, cols: np.ndarray) -> bool:
    """True when a candidate acts on a check whose held-out split is in time (a repeated-run
    laser or positioning line: fit on the early runs, judge the late ones): a drift is a
    change in time, and only such a split has checked its extrapolation in time. A drift
    seen only within circle traces (split by angle sectors) has not (docs/effects.md §3,
    the size rule and "A alone, or A + B")."""
    if cols.size == 0:
        return False
    scale = max(float(np.max(np.abs(cols))), 1e-300)
    acts = np.any(np.abs(cols) > 1e-12 * scale, axis=1)
    for i, c in enumerate(prob.checks):
        keys = list(c.folds)
        if keys and keys[0].startswith("runs") and np.any(acts[prob.slice(i)]):
            return True
    return False


def _in_table(eng: Engine, c: Cand) -> bool:
    spec = c.spec
    return bool(spec.compensable) and not (spec.kind == "thermal" and not eng.drift_on_table)


def share_undecided(eng: Engine, sel: list[Selected], values: list[np.ndarray],
                    effects: list[EffectResult], pool: list[Cand]
                    ) -> tuple[Table, PredParams] | None:
    """The updated table and prediction parameters with every undecided effect replaced by
    the equal share of its explanations, or None when no effect is undecided (or none can
    be shared). Each undecided entry gets ``table_holds`` (key -> value written) and
    ``unknown`` (what the checks leave open)."""
    by_key = {c.spec.key: c for c in pool}
    plan: list[tuple[Cand, np.ndarray]] = []
    shared = False
    for s, v in zip(sel, values):
        e = next((x for x in effects if x.key == s.cand.spec.key and x.undecided), None)
        alts = [] if e is None else [a for a in e.undecided["alternatives"][1:]]  # type: ignore[index]
        cands = [by_key.get(a["key"]) for a in alts]
        if e is not None and e.undecided.get("companion"):  # type: ignore[union-attr]
            alts = []    # "A alone, or A + B": the table holds A alone (describe.companion_undecided)
        ok = bool(alts) and all(c is not None and c.spec.kind != "cyclic" and c.cols.shape[1]
                                and _in_table(eng, c) == _in_table(eng, s.cand) for c in cands)
        if e is None or not alts:
            plan.append((s.cand, np.asarray(v, dtype=float)))
            continue
        if not ok:
            e.undecided["table_holds"] = {s.cand.spec.key: round_to(e.value)}  # type: ignore[index]
            e.undecided["unknown"] = (  # type: ignore[index]
                "which explanation holds; the table holds " + s.cand.spec.key + " alone (an "
                "alternative cannot go where it goes: into the table / the prediction model)")
            plan.append((s.cand, np.asarray(v, dtype=float)))
            continue
        n = len(alts) + 1
        plan.append((s.cand, np.asarray(v, dtype=float) / n))
        holds = {s.cand.spec.key: round_to(e.value / n)}
        for a, c in zip(alts, cands):
            coef = np.atleast_1d(np.asarray(a["value"], dtype=float))
            if coef.size != len(c.param_idx):    # type: ignore[union-attr]
                return None
            plan.append((c, coef / n))  # type: ignore[arg-type]
            holds[a["key"]] = [round_to(x) for x in coef / n] if coef.size > 1 \
                else round_to(float(coef[0]) / n)
        e.undecided["table_holds"] = holds  # type: ignore[index]
        e.undecided["constrained"] = (  # type: ignore[index]
            "the combination the checks see (the fitted signature): every explanation "
            "reproduces it, and so does the equal share of them, which the table holds")
        e.undecided["unknown"] = (  # type: ignore[index]
            "the share between " + " and ".join(holds) + ": the checks cannot tell which "
            "holds; the table's error off the checked paths is at most half of either")
        shared = True
    if not shared:
        return None
    fake = [Selected(c, {}) for c, _ in plan]
    return apply_selection(eng, fake, [v for _, v in plan])
