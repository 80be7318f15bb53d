"""Which of two entangled explanations a forward step adds first (issue 36, seventh round).

The forward selection (:mod:`abbe.diagnose.selection`) adds, among the candidates that
qualify, the one with the largest BIC decrease. The BIC knows neither the catalogue's
priors nor the model's own uncertainty along a signature, which the decision (the
evidence ratio, :mod:`abbe.diagnose.evidence`) counts. For candidates that explain
different parts of the residual the order does not matter: each is judged again beside
the other at the next step. For two **entangled** candidates it decides the answer: when
one reproduces most of the other's fitted signature (R^2 >= ``ambiguity_r2``, the
ambiguity level of docs/effects.md section 3), whichever goes first takes the shared
part, and the second is then redundant: it has to earn its place with the pair margin of
the held-out arbiter. A tool offset of three free components, whose evidence is inflated
by the model's angular uncertainty (sigma_m), then took a squareness with a slightly
larger RSS decrease but a far smaller evidence (the team's independent suite,
`tool_offset+squareness_xy`: 270.6 mm for 131.0 and no squareness).

The rule: among the qualifying candidates entangled with the BIC's choice, the one with
the largest log evidence ratio goes first -- {A} against {B} judged by the same number
that decides whether either is named; {A + B} against the better single is then the
next forward step (log K of the second beside the first >= log 19, and the held-out
arbiter). Candidates not entangled keep the BIC's order.

Units: whitened residuals (noise units); R^2 dimensionless.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from abbe.diagnose.candidates import Cand
from abbe.diagnose.problem import lstsq_rss, project_out


def _signature(cand: Cand, st: dict[str, Any], W: np.ndarray, Qb: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray]:
    """The candidate's whitened columns and fitted signature, base projected out."""
    Z = project_out(Qb, cand.cols * W[:, None])
    return Z, Z @ np.asarray(st["coef"], dtype=float)


def entanglement(a: tuple[Cand, dict[str, Any]], b: tuple[Cand, dict[str, Any]],
                 W: np.ndarray, Qb: np.ndarray) -> float:
    """The larger share (R^2) of one candidate's fitted signature that the other's columns
    reproduce (each fitted freely), both with the base (nuisance and named effects)
    projected out; 0 when either has no signature."""
    Za, sa = _signature(a[0], a[1], W, Qb)
    Zb, sb = _signature(b[0], b[1], W, Qb)
    best = 0.0
    for Z, s in ((Zb, sa), (Za, sb)):
        n = float(s @ s)
        if n <= 0 or Z.shape[1] == 0:
            return 0.0
        _, fit = lstsq_rss(Z, s)
        best = max(best, fit / n)
    return best


def first_of_entangled(good: list[tuple[Cand, dict[str, Any]]], W: np.ndarray,
                       Qb: np.ndarray, r2_min: float) -> tuple[tuple[Cand, dict[str, Any]], str]:
    """The candidate a forward step adds: the BIC's choice, unless a qualifying candidate
    entangled with it (R^2 >= ``r2_min``) has a larger log evidence ratio; then the
    entangled one with the largest. Returns it and a note ("" when the BIC's choice
    stands)."""
    first = min(good, key=lambda cs: cs[1]["dbic"])
    rivals = [cs for cs in good if cs is not first
              and cs[1]["log_evidence"] > first[1]["log_evidence"]]
    ent = [(cs, entanglement(first, cs, W, Qb)) for cs in rivals]
    ent = [(cs, r2) for cs, r2 in ent if r2 >= r2_min]
    if not ent:
        return first, ""
    (best, r2) = max(ent, key=lambda x: x[0][1]["log_evidence"])
    note = (f"{best[0].spec.key} before {first[0].spec.key}: entangled (R^2 {r2:.3f}), "
            f"log evidence ratio {best[1]['log_evidence']:.1f} against "
            f"{first[1]['log_evidence']:.1f} (the BIC decrease ranked "
            f"{first[0].spec.key} first)")
    return best, note
