"""Issue 36, thirteenth round: the held-out arbiter asks for a share of the in-sample decrease
**the split can see** (docs/effects.md §3, rule 2; candidate_eval.heldout_need).

The ballbar's held-out split is alternate 45 deg sectors, each fold with its own centre and
radius. The centre times the sectors' square wave (period 90 deg) is cos(theta) sin(4 theta)
= (sin 3 theta + sin 5 theta) / 2, and the like for sin(theta): a fold's centre takes half of
any 3-theta harmonic. A tool offset through a model whose angular terms are cubic in the
position has a signature that is mostly 3-theta on the circles (the second generator, seed
1690691555, ``tool_offset_3``: 3-theta |z| 0.0037 against 0.0012 at 2-theta), so the folds
see a fraction of what the whole circle sees (there an in-sample decrease of 126 noise units
over the circles, 35 within the folds) and the rest of the residual's harmonics (4, 5-theta
of the model's error) sets the folds' values apart (43 and 124 mm for 157.7): a held-out
gain of 10.5, 8 % of 126 (need 12.6), though 30 % of what the folds could see."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from abbe.diagnose.candidate_eval import _judge
from abbe.diagnose.candidates import Cand
from abbe.diagnose.effects import by_key
from abbe.diagnose.heldout import heldout_rss
from abbe.diagnose.problem import lstsq_rss, project_out, qr_basis
from abbe.diagnose.results import DiagnoseOptions

N_C = 360                                     # samples per circle (1 deg)
TH = np.radians(np.arange(N_C) + 0.5)
SECTOR = (np.floor(np.degrees(TH) / 45.0).astype(int) % 2)


def _engine(y: np.ndarray, n_circ: int) -> SimpleNamespace:
    one = np.stack([np.cos(TH), np.sin(TH), np.ones(N_C)], axis=1)
    nuis = np.zeros((n_circ * N_C, 3 * n_circ))
    for k in range(n_circ):
        nuis[k * N_C:(k + 1) * N_C, 3 * k:3 * k + 3] = one
    lab = np.tile(SECTOR, n_circ)
    prob = SimpleNamespace(N=n_circ * N_C, nuis=nuis,
                           split=lambda level: (lab, "angle sectors (alternate 45 deg, both directions)"),
                           split_in_time=lambda: None)
    return SimpleNamespace(prob=prob, r0=y, opts=DiagnoseOptions())


def _judged(pattern: np.ndarray, amp: float, other: np.ndarray, seed: int) -> tuple[bool, dict]:
    """Three circles, the candidate's column ``pattern`` (um per unit) on each, the residual
    amp x pattern + ``other`` (a harmonic the candidate does not have) + white noise of 1."""
    n_circ = 3
    rng = np.random.default_rng(seed)
    col = np.tile(pattern, n_circ)[:, None]
    y = amp * col[:, 0] + np.tile(other, n_circ) + rng.normal(0.0, 1.0, n_circ * N_C)
    eng = _engine(y, n_circ)
    W = np.ones(eng.prob.N)
    Q = qr_basis(eng.prob.nuis)
    Z = project_out(Q, col)
    r = project_out(Q, y[:, None])[:, 0]
    coef, fit = lstsq_rss(Z, r)
    cand = Cand(spec=by_key()["tool_offset"], cols=col, param_idx=[2])
    ho = heldout_rss(eng, [], cand, W, 1.0)
    st = {"ok": True, "evidence": {"log_evidence": 50.0, "sigma_model_um": 0.0}, "heldout": ho,
          "k_eff": 1, "drss": fit, "coef": coef, "observable_rms_um": 1.0,
          "contrib_rms_um": 1.0}
    ok, why = _judge(st, eng.opts)
    st["why"] = why
    return ok, st


def test_a_three_theta_signature_is_judged_on_what_the_sectors_see() -> None:
    """A 3-theta signature with a 5-theta residual beside it (the model's error): the folds'
    centres take half of the 3-theta and the 5-theta most of the rest within a fold; the
    held-out gain is below 10 % of the whole decrease but above 10 % of what the folds can
    see: named (on the code before: "does not hold on held-out data")."""
    ok, st = _judged(0.35 * np.cos(3 * TH), 1.0, 0.3 * np.cos(5 * TH + 2.5), seed=3)
    ho = st["heldout"]
    assert ho["gain"] < 0.1 * st["drss"], (ho, st["drss"])          # the old rule rejects it
    assert ok, st["why"]                                             # named now
    assert ho["drss_split"] < 0.2 * st["drss"], (ho, st["drss"])     # the folds see a part
    assert ho["gain"] > max(2.0, 0.1 * ho["drss_split"])


def test_an_oval_is_seen_whole_by_the_sectors() -> None:
    """A 2-theta signature (an oval: a scale, a squareness) is orthogonal to a fold's centre
    and radius: the split sees the whole decrease and the arbiter's need is the same as
    before."""
    ok, st = _judged(0.35 * np.cos(2 * TH), 1.0, np.zeros(N_C), seed=4)
    ho = st["heldout"]
    assert abs(ho["drss_split"] - st["drss"]) < 0.1 * st["drss"], (ho, st["drss"])
    assert ok, st["why"]


def test_a_pattern_on_one_fold_only_is_still_rejected() -> None:
    """A 3-theta pattern present on one fold's sectors only (not an effect of the machine,
    which would act on every sector): its in-sample decrease is real, but fitted on one fold
    it does not predict the other: the need on what the split sees does not let it through."""
    pattern = 0.35 * np.cos(3 * TH)
    ok, st = _judged(pattern, 0.0, 1.5 * pattern * (SECTOR == 1), seed=3)
    assert st["drss"] > 20.0, st["drss"]
    assert not ok, (st["heldout"], st["drss"])
