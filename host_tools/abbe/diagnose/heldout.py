"""Held-out judgement of ``abbe diagnose``: the arbiter of the selection and the gap.

Fit on one fold, judge the other (nuisance refitted there), and back (docs/effects.md
§3): laser / positioning data early runs against late runs (a drift must
extrapolate in time), ballbar alternate 45 deg sectors with both directions; the
secondary split (CCW / CW, alternate targets) when a fold cannot identify the
effects. A thermal drift is judged on the split in time of every check that has one
(early / late runs, the CCW trace / the CW trace run after it: Problem.split_in_time). Units: RSS in noise units (whitened), gaps in um.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from abbe.diagnose.candidates import Cand, Engine, Selected, apply_selection, selection_residual
from abbe.diagnose.problem import gap_stats, is_identifiable, project_out, qr_basis, remove_nuisance
from abbe.diagnose.results import GapStats

def heldout_rss(eng: Engine, sel: list[Selected], cand: Cand | None, W: np.ndarray,
             s2: float, free: np.ndarray | None = None) -> dict[str, Any]:
    """Held-out RSS (whitened, / s2) without and with ``cand``: fit the effects (and the
    nuisance) on one fold, judge the other (nuisance refitted there), and back.
    ``free``: columns (um rows) fitted in both, like the named effects: a drift is judged
    with its axis' scale free (docs/effects.md §3, drift and scale), on held-out data as in
    its evidence ratio. ``drss_split``: the candidate's in-sample RSS decrease within the
    fitted folds (each with its own nuisance), what the split can see of it (the arbiter's
    share is of that: candidate_eval.heldout_need)."""
    prob = eng.prob
    r_sel = selection_residual(eng, sel) * W
    Nw = prob.nuis * W[:, None]
    X_sel = [s.cand.cols for s in sel] + ([free] if free is not None and free.shape[1] else [])
    # the rows the candidate acts on (its support): its held-out gain is judged against
    # the residual there, not diluted by checks it does not touch
    support = np.ones(prob.N, dtype=bool) if cand is None else \
        np.any(np.abs(cand.cols) > 1e-12 * max(float(np.max(np.abs(cand.cols), initial=0.0)), 1e-300),
               axis=1) | (np.abs(cand.offset) > 0 if cand.offset is not None else False)
    # a drift is judged on the split in time (fit the early runs / the CCW trace, judge
    # the late runs / the CW trace, and back): a change in time must extrapolate in time.
    # On a split by angle sectors a drift column is one more shape within each trace and
    # can take a static misfit (of a large squareness, say) that no later run repeats.
    timed = prob.split_in_time() if cand is not None and cand.spec.kind == "thermal" else None
    for sp in ([timed] if timed is not None else [prob.split(0), prob.split(1)]):
        if sp is None:
            continue
        lab, name = sp
        res = {}
        ok = True
        for with_c in (False, True):
            r = r_sel
            if with_c and cand is not None and cand.offset is not None:
                r = r_sel - cand.offset * W
            cols = X_sel + ([cand.cols] if (with_c and cand is not None) else [])
            X = np.hstack(cols) * W[:, None] if cols else np.zeros((prob.N, 0))
            tot = tot_s = tot_in = 0.0
            n_s = 0
            for f in (0, 1):
                A, B = lab == f, lab != f
                if A.sum() == 0 or B.sum() == 0:
                    ok = False
                    break
                nA = Nw[A][:, np.any(Nw[A] != 0, axis=0)]
                QA = qr_basis(nA)
                XA = project_out(QA, X[A])
                if not is_identifiable(XA):
                    ok = False
                    break
                rA = project_out(QA, r[A][:, None])[:, 0]
                beta, *_ = np.linalg.lstsq(XA, rA, rcond=None) if X.shape[1] else (np.zeros(0),)
                # the fitted fold's own residual: the in-sample decrease the split sees
                eA = rA - (XA @ beta if X.shape[1] else 0.0)
                tot_in += float(eA @ eA)
                eB = r[B] - (X[B] @ beta if X.shape[1] else 0.0)
                nB = Nw[B][:, np.any(Nw[B] != 0, axis=0)]
                eB = project_out(qr_basis(nB), eB[:, None])[:, 0]
                tot += float(eB @ eB)
                eS = eB[support[B]]
                tot_s += float(eS @ eS)
                n_s += int(eS.size)
            if not ok:
                break
            res["with" if with_c else "without"] = tot / s2
            res["support_with" if with_c else "support_without"] = tot_s / s2
            res["in_with" if with_c else "in_without"] = tot_in / s2
        if ok:
            return {"split": name, "rss_without": res["without"], "rss_with": res["with"],
                    "gain": res["without"] - res["with"],
                    "drss_split": res["in_without"] - res["in_with"],
                    "rss_without_support": res["support_without"], "n_support": n_s}
    return {"split": None, "gain": float("nan")}

def heldout_removal(eng: Engine, sel: list[Selected], W: np.ndarray,
                     notes: list[str]) -> list[Selected]:
    """Drop, one at a time, a named effect whose removal leaves the held-out residual
    unchanged (held-out RSS gain of keeping it < 2 per parameter, noise units)."""
    while len(sel) > 1:
        weakest, w_gain = None, math.inf
        for i, s in enumerate(sel):
            others = sel[:i] + sel[i + 1:]
            ho = heldout_rss(eng, others, s.cand, W, 1.0)
            if ho["split"] is None:
                continue
            need = 2.0 * s.stats.get("k_eff", s.cand.cols.shape[1])
            if ho["gain"] < need and ho["gain"] - need < w_gain:
                weakest, w_gain = i, ho["gain"] - need
        if weakest is None:
            break
        s = sel[weakest]
        notes.append(f"{s.cand.spec.key} dropped: removing it leaves the held-out residual "
                     "unchanged once " + ", ".join(o.cand.spec.key for o in sel if o is not s)
                     + " are in the model")
        sel = sel[:weakest] + sel[weakest + 1:]
    return sel



def heldout_gap(eng: Engine, sel: list[Selected], W: np.ndarray, clean0: np.ndarray
                 ) -> tuple[GapStats | None, GapStats | None, str | None]:
    """Gap on held-out data: effect parameters fitted on one fold (linearised, with the
    fold's nuisance), the updated model predicted through the library on the other fold
    (nuisance refitted there); both ways, pooled."""
    prob = eng.prob
    for level in (0, 1):
        sp = prob.split(level)
        if sp is None:
            continue
        lab, name = sp
        before = np.full(prob.N, np.nan)
        after = np.full(prob.N, np.nan)
        ok = True
        for f in (0, 1):
            A, B = lab == f, lab != f
            if A.sum() == 0 or B.sum() == 0:
                ok = False
                break
            before_B = remove_nuisance(prob, eng.r0, B)
            before[B] = before_B[B]
            if not sel:
                after[B] = before_B[B]
                continue
            X = np.hstack([s.cand.cols for s in sel]) * W[:, None]
            nA = (prob.nuis * W[:, None])[A]
            nA = nA[:, np.any(nA != 0, axis=0)]
            QA = qr_basis(nA)
            XA = project_out(QA, X[A])
            if not is_identifiable(XA):
                ok = False
                break
            beta, *_ = np.linalg.lstsq(XA, project_out(QA, (selection_residual(eng, sel) * W)[A][:, None])[:, 0],
                                       rcond=None)
            vals, k = [], 0
            for s in sel:
                n = s.cand.cols.shape[1]
                vals.append(beta[k:k + n])
                k += n
            t, p = apply_selection(eng, sel, vals)
            r = prob.y - prob.predict(eng.ev, t, p)
            after_B = remove_nuisance(prob, r, B)
            after[B] = after_B[B]
        if ok:
            return gap_stats(prob, before), gap_stats(prob, after), name
    return None, None, None
