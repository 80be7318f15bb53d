"""Issue 35, round 4: model-structure candidates chosen on the identification hours only
(docs/thermal.md, "Issue 35, fourth round").

Every candidate starts from the default (R3a: the forward selection with the input set
chosen by leave-one-cycle-out cross-validation, :func:`identify_channel` with
``inputs="by_cv"``) and changes one thing, physically motivated:

* **R4a, the speed's heat input as speed^n** (bearing friction grows with speed^1..2):
  the speed candidate is (rpm / 1000)^n, one n for the whole model (the runtime has one
  speed input), chosen from :data:`SPEED_EXPONENTS` by the lowest sum over the
  displacement channels of their leave-one-cycle-out CV RMS divided by their RMS on the
  identification hours (:func:`speed_candidates`).
* **R4b, two time constants per input**: the selection started from the best *pair* of
  lags of one input (tau_fast < tau_slow from the grid, 0 allowed for the fast one: a
  fast and a slow path of the same heat, the bearing and the housing), refined, then the
  forward selection continues; per channel the run with the lower leave-one-cycle-out CV
  RMS of its final terms (R3a or the pair start) is kept, ties to R3a (:func:`pair_start`).
* **R4d, an ambient term from the room sensors**: the selection on the heated inputs
  (at most 3 terms), then one term from the room sensors (the temperatures below the
  coupling gap, any grid tau) if it lowers the CV RMS by the selection's 10 %; per channel
  kept against R3a by the lower CV RMS of the final terms, ties to R3a (:func:`room_term`).
* **R4c, the structure chosen by forward chaining**: per channel, among R3a, R4b and R4d,
  the one with the lowest *forward-chaining* RMS: gains (with the candidate's terms)
  refitted on the first two identification cycles (1250 + 2500 rpm), RMS on the third
  (3750 rpm): the extrapolation to a higher speed the held-out hours ask
  (:func:`forward_chain_rms`).
* **R4e, a structure shared between channels**: each channel takes, among every channel's
  R3a term set (inputs and time constants; gains refitted), the one with the lowest
  leave-one-cycle-out CV RMS. Round 3 computed this rule's held-out figures post hoc, so
  it is reported for completeness and is not eligible for adoption.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from abbe.analysis.thermal.identify import (MAX_VIF, MIN_GAIN_FRACTION, TAU_GRID_S, Candidate,
                                            ChannelFit, _cv_rms, _lstsq, _refine_taus,
                                            _vif_max, _with_offset, cycles_of, heated_inputs,
                                            identify_channel, refine, select_terms)
from abbe.model.thermal import SPEED, MAX_TERMS_PER_CHANNEL, lag_states

#: The speed exponents R4a chooses from (1: today's model; 1.5 and 2 computable without
#: libm: x * sqrt(x), x * x).
SPEED_EXPONENTS: tuple[float, ...] = (1.0, 1.5, 2.0)


def speed_candidates(cands: list[Candidate], n: float) -> list[Candidate]:
    """The candidates with the speed's rise (krpm) raised to ``n`` (krpm^n)."""
    return [replace(c, rise=np.power(np.maximum(c.rise, 0.0), n)) if c.kind == SPEED else c
            for c in cands]


def states_of(t_s: np.ndarray, cands: list[Candidate], terms) -> np.ndarray:
    """The lag states of a channel's terms (one column per term)."""
    return np.column_stack([lag_states(cands[t.input].rise, t_s, t.tau_s) for t in terms])


def loco_rms(t_s: np.ndarray, y: np.ndarray, cands: list[Candidate], terms,
             cyc: np.ndarray) -> float:
    """Leave-one-cycle-out CV RMS (um) of the final terms (gains and offset refitted)."""
    if not terms:
        return float(np.sqrt(np.mean((y[cyc >= 0] - y[cyc >= 0].mean()) ** 2)))
    return _cv_rms(states_of(t_s, cands, terms), y, cyc)


def forward_chain_rms(t_s: np.ndarray, y: np.ndarray, cands: list[Candidate], terms,
                      cyc: np.ndarray) -> float:
    """RMS (um) on the last identification cycle of a fit (gains, offset; the terms'
    inputs and time constants as given) on the cycles before it: extrapolation to the
    next, higher speed."""
    last = int(cyc.max())
    tr, te = (cyc >= 0) & (cyc < last), cyc == last
    cols = _with_offset(states_of(t_s, cands, terms) if terms
                        else np.empty((y.size, 0)))
    g = _lstsq(cols[tr], y[tr])
    r = y[te] - cols[te] @ g
    return float(np.sqrt(np.mean(r ** 2)))


def _finish(name: str, t_s: np.ndarray, y: np.ndarray, cands: list[Candidate],
            chosen: list[tuple[int, float]], mask: np.ndarray, cyc: np.ndarray,
            input_set: str) -> ChannelFit:
    """A ChannelFit from selected (input, tau) terms: refined jointly, CV of the final terms."""
    terms, fit_rms, rho, n_eff, offset = refine(t_s, y, cands, chosen, mask)
    cv = loco_rms(t_s, y, cands, terms, cyc)
    return ChannelFit(name, terms, cv, [], rho, n_eff, fit_rms, offset, [], cv, 0.0, input_set)


def pair_start(name: str, t_s: np.ndarray, y: np.ndarray, cands: list[Candidate],
               mask: np.ndarray, cycle_s: float, allowed: set[int] | None = None,
               grid: tuple[float, ...] = TAU_GRID_S) -> ChannelFit | None:
    """R4b's run: the best pair of lags of one input (leave-one-cycle-out CV, VIF guard),
    refined, then the forward selection from it; None if no pair passes the guard."""
    cyc = cycles_of(t_s, mask, cycle_s)
    usable = [i for i in range(len(cands)) if allowed is None or i in allowed]
    best: tuple[float, tuple[int, float], tuple[int, float]] | None = None
    for i in usable:
        st = {tau: lag_states(cands[i].rise, t_s, tau) for tau in grid}
        for a, ta in enumerate(grid):
            for tb in grid[a + 1:]:
                cols = np.column_stack([st[ta], st[tb]])
                if _vif_max(cols[mask]) > MAX_VIF:
                    continue
                r = _cv_rms(cols, y, cyc)
                if best is None or r < best[0]:
                    best = (r, (i, ta), (i, tb))
    if best is None:
        return None
    pair = _refine_taus(t_s, y, cands, [best[1], best[2]], mask)
    if _vif_max(states_of(t_s, cands, [_T(i, tau) for i, tau in pair])[mask]) > MAX_VIF:
        pair = [best[1], best[2]]
    chosen, _ = select_terms(t_s, y, cands, cyc, start=pair, allowed=allowed)
    return _finish(name, t_s, y, cands, chosen, mask, cyc, "pair")


class _T:
    """A bare (input, tau) term for :func:`states_of`."""

    def __init__(self, i: int, tau: float) -> None:
        self.input, self.tau_s = i, tau


def room_term(name: str, t_s: np.ndarray, y: np.ndarray, cands: list[Candidate],
              mask: np.ndarray, cycle_s: float, heated_run: ChannelFit | None = None
              ) -> ChannelFit:
    """R4d's run: the forward selection on the heated inputs (at most 3 terms), then at
    most one term of a room sensor (every temperature not heated) by the same rule.
    ``heated_run``: a fit whose ``heated_path`` is that selection's path on the same
    samples (the default's, ``inputs="by_cv"``): its first 3 steps are reused (the
    forward selection's first k steps do not depend on its term limit)."""
    cyc = cycles_of(t_s, mask, cycle_s)
    heated = heated_inputs(t_s, cands, mask)
    room = {i for i in range(len(cands)) if i not in heated}
    n3 = MAX_TERMS_PER_CHANNEL - 1
    if heated_run is not None and heated_run.heated_path is not None:
        hp = heated_run.heated_path
        chosen = list(hp[min(len(hp), n3) - 1]) if hp else []
        trace = list((heated_run.heated_steps or [])[:len(hp[:n3])])
    else:
        chosen, trace = select_terms(t_s, y, cands, cyc, allowed=heated, max_terms=n3)
    chosen, more = select_terms(t_s, y, cands, cyc, start=chosen, allowed=room,
                                max_terms=len(chosen) + 1, min_gain=MIN_GAIN_FRACTION)
    if not chosen:
        off = float(np.mean(y[mask]))
        rms0 = float(np.sqrt(np.mean((y[mask] - off) ** 2)))
        return ChannelFit(name, [], rms0, trace + more, offset_um=off, selection_cv_um=rms0,
                          input_set="heated+room")
    fit = _finish(name, t_s, y, cands, chosen, mask, cyc, "heated+room")
    fit.steps = trace + more
    return fit


def with_room_term(name: str, t_s: np.ndarray, y: np.ndarray, cands: list[Candidate],
                   mask: np.ndarray, cycle_s: float, default: ChannelFit) -> ChannelFit:
    """R4d, adopted as the default by round 4's rule (docs/thermal.md, "Issue 35, fourth
    round"): the default run or the heated inputs plus one room-sensor term
    (:func:`room_term`), whichever has the lower leave-one-cycle-out CV RMS of its final
    terms on the identification hours (ties: the default)."""
    return by_loco(t_s, y, cands, mask, cycle_s, default,
                   room_term(name, t_s, y, cands, mask, cycle_s, heated_run=default))


def by_loco(t_s: np.ndarray, y: np.ndarray, cands: list[Candidate], mask: np.ndarray,
            cycle_s: float, default: ChannelFit, other: ChannelFit | None) -> ChannelFit:
    """The default or the other run, by the lower CV RMS of the final terms (ties: the
    default)."""
    if other is None or not other.terms:
        return default
    cyc = cycles_of(t_s, mask, cycle_s)
    d = loco_rms(t_s, y, cands, default.terms, cyc)
    o = loco_rms(t_s, y, cands, other.terms, cyc)
    return other if o < d else default


def by_forward_chain(t_s: np.ndarray, y: np.ndarray, cands: list[Candidate],
                     mask: np.ndarray, cycle_s: float, runs: list[ChannelFit]) -> ChannelFit:
    """R4c: among ``runs`` (the default first), the lowest forward-chaining RMS (ties: the
    earlier run)."""
    cyc = cycles_of(t_s, mask, cycle_s)
    scores = [forward_chain_rms(t_s, y, cands, r.terms, cyc) for r in runs]
    return runs[int(np.argmin(scores))]


def default_fit(name: str, t_s: np.ndarray, y: np.ndarray, cands: list[Candidate],
                mask: np.ndarray, cycle_s: float) -> ChannelFit:
    """R3a, the default (``inputs="by_cv"``)."""
    return identify_channel(name, t_s, y, cands, mask, cycle_s, inputs="by_cv")


# Issue 35, round 5 (docs/thermal.md, "Issue 35, fifth round"): a paired channel of the
# ISO 230-3 nest predicted as its partner's model plus a model of the pair's difference.

def _fold_fit(cols: np.ndarray, y: np.ndarray, tr: np.ndarray) -> np.ndarray:
    """Prediction over the record of a least squares fit (with the sensor's zero offset) of
    y on cols over the samples ``tr``."""
    a = _with_offset(cols)
    return a @ _lstsq(a[tr], y[tr])


def partner_difference_rms(t_s: np.ndarray, y: np.ndarray, cands: list[Candidate],
                           partner_terms, y_partner: np.ndarray, diff_terms,
                           y_diff: np.ndarray, sign: float, cyc: np.ndarray,
                           scheme: str = "loco") -> float:
    """Cross-validated RMS (um) of y predicted as the partner channel's model plus ``sign``
    times the model of the pair's difference (y_diff = upper - lower, um; sign +1 for the
    upper channel, -1 for the lower). Each model keeps its inputs and time constants; its
    gains and offset are refitted on the training cycles of its own signal (the partner's
    displacement, the difference), as the runtime would run them: two separate models.
    ``scheme``: "loco" (leave one cycle out) or "forward" (fit on the cycles before the
    last, score the last: :func:`forward_chain_rms`)."""
    sp = states_of(t_s, cands, partner_terms) if partner_terms else np.empty((y.size, 0))
    sd = states_of(t_s, cands, diff_terms) if diff_terms else np.empty((y.size, 0))
    if scheme == "loco":
        folds = [((cyc >= 0) & (cyc != c), cyc == c) for c in np.unique(cyc[cyc >= 0])]
    elif scheme == "forward":
        last = int(cyc.max())
        folds = [((cyc >= 0) & (cyc < last), cyc == last)]
    else:
        raise ValueError(f"scheme: expected 'loco' or 'forward', got {scheme!r}")
    sq, n = 0.0, 0
    for tr, te in folds:
        pred = _fold_fit(sp, y_partner, tr) + sign * _fold_fit(sd, y_diff, tr)
        r = (y - pred)[te]
        sq += float(r @ r)
        n += int(te.sum())
    return float(np.sqrt(sq / n))


def prefers_partner(t_s: np.ndarray, y: np.ndarray, cands: list[Candidate], direct_terms,
                    partner_terms, y_partner: np.ndarray, diff_terms, y_diff: np.ndarray,
                    sign: float, cyc: np.ndarray) -> tuple[bool, dict[str, float]]:
    """R5a's per-channel choice (docs/thermal.md, "Issue 35, fifth round"): partner plus
    difference only if it has a lower leave-one-cycle-out RMS AND a lower forward-chaining
    RMS than the channel's own model on the identification hours (ties: the direct model).
    Returns (choice, the four figures, um)."""
    f = {"loco_direct": loco_rms(t_s, y, cands, direct_terms, cyc),
         "forward_direct": forward_chain_rms(t_s, y, cands, direct_terms, cyc),
         "loco_partner": partner_difference_rms(t_s, y, cands, partner_terms, y_partner,
                                                diff_terms, y_diff, sign, cyc, "loco"),
         "forward_partner": partner_difference_rms(t_s, y, cands, partner_terms, y_partner,
                                                   diff_terms, y_diff, sign, cyc, "forward")}
    return (f["loco_partner"] < f["loco_direct"]
            and f["forward_partner"] < f["forward_direct"]), f
