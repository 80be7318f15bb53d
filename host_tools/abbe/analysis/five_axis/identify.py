"""Identify the five-axis errors: observability, nonlinear least squares, intervals, held-out.

1. Observability: the Jacobian of the weighted residuals (columns scaled by
   each parameter's typical size) at the start; its singular values give the
   rank and the condition number. A parameter is *observable* (estimable) when
   no null-space direction of the Jacobian moves it: then every solution of
   the problem gives it the same value. The others are named, never given a
   number; a maximal set of them is fixed at 0 (machine errors first, the
   set-up last) so that the rest has full rank, and the report says which set
   was fixed and with what each is confounded.
2. ``scipy.optimize.least_squares`` on the exact model, each data block
   weighted by its standard deviation (estimated from a first fit, then refit).
3. Covariance ``s^2 (J^T J)^-1`` of the free parameters, 95 % intervals
   (1.96 sigma), correlations.
4. Dispersion of the sphere centres (KinematicsOpt's figure): before (nominal
   kinematics, only the sphere's position fitted) and after; the held-out
   judgement refits with each fold of probing positions left out and predicts it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from abbe.analysis.five_axis.problem import Block, Param, residual_block
from abbe.formats.five_axis import FiveAxisSpec

#: A singular value below this fraction of the largest (scaled Jacobian) is zero.
RANK_TOL = 1e-7
#: A null-space component above this makes a parameter unobservable. Columns are scaled
#: by each unknown's typical size, so a component of 1e-3 moves the unknown by 1e-3 of its
#: size along a confounded direction: the model's second-order cross terms (a zero offset
#: turning about a line that is itself 100 urad off) are of that order, not confounding.
NULL_TOL = 1e-3
#: Which test would see an unobservable error (docs/concepts.md).
SEEN_BY = {
    "zero": "a datum sphere off the axis at a calibrated place on the table ([probing.NAME] "
            "datum_u_um; examples/trunnion5ax_complete), or referencing the axis' home with a "
            "laser + rotary indexer",
    "squareness": "a laser diagonal test or ballbar circles of the linear axes (ISO 230-1 / "
                  "ISO 230-4), fitted by `abbe fit` on a 3-axis file",
    "motion": "an R-test with spheres at two heights (tilt vs radial), the laser + rotary "
              "indexer for the angular motion, more rotary positions per revolution",
    "location": "probing at more angles of the other rotary axis or a second sphere height "
                "(a ballbar: the other axis turning, or the table ball at a second height); "
                "what stays confounded with the spheres' places: a datum sphere "
                "([probing.NAME] datum_u_um)",
    "setup": "a sphere position measured in a known frame (a datum: [probing.NAME] "
             "datum_u_um)",
    "drift": "the diagnosis plan (`abbe program --passes 2`: the grid again backwards, so "
             "campaign time no longer goes with the pose) or one position repeated at the "
             "start, middle and end",
    "wobble": "the table face's axial motion at two radii (ISO 230-7) or spheres at two "
              "heights (tilt against radial + axial motion)",
}


@dataclass
class Observability:
    """Rank, condition number, singular values, the observable flags, the fixed set and
    the confounded groups (null-space directions: parameter names)."""

    rank: int
    n_params: int
    condition: float
    singular: np.ndarray
    observable: np.ndarray
    fixed: list[int]
    groups: list[list[str]]


@dataclass
class FitResult:
    """The identification: parameters, values and intervals (NaN for the unobservable
    and fixed), observability, block sigmas, dispersion and held-out figures."""

    params: list[Param]
    x: np.ndarray
    sd: np.ndarray
    corr: np.ndarray
    obs: Observability
    blocks: list[Block]
    harmonics: int
    dispersion_before_um: float = float("nan")
    dispersion_after_um: float = float("nan")
    heldout_before_um: float = float("nan")
    heldout_after_um: float = float("nan")
    #: the held-out dispersion this model would show if it were right: the centres' noise
    #: (sphere fits) plus the scatter its fold estimates put into the predictions (um);
    #: None without the centres' noise
    heldout_floor_um: float | None = None
    #: the held-out residuals (Q, 3) um of the probing positions, fold by fold (the same
    #: positions in the same order for every model of a plan: a paired comparison)
    heldout_residuals_um: np.ndarray | None = None
    rejected: list[int] = field(default_factory=list)
    nfev: int = 0
    #: the solution as solved (the unobservable that were not fixed keep their arbitrary
    #: values here; ``x`` hides them): what the residuals were computed with
    x_solution: np.ndarray | None = None
    #: what the table holds (:func:`table_solution`): the solution with the angular zeros
    #: the fit fixed at 0 and every other error as the campaign determines it in that
    #: convention (the smallest, scaled, where the plan leaves more undetermined)
    x_table: np.ndarray | None = None
    #: the identification's raw-residual Jacobian (scaled unknowns), the rows' weights and
    #: each block's first row, as the covariance used them (for the Type B propagation)
    jacobian: np.ndarray | None = None
    weights: np.ndarray | None = None
    row_offsets: np.ndarray | None = None
    #: the indices of x_table set by that smallest-norm choice (the plan sees them only in
    #: combinations it cannot separate from errors it cannot see at all)
    min_norm: list[int] = field(default_factory=list)
    #: the standard deviations of the free unknowns in the fit's convention (the
    #: unobservable ones included: how well the campaign determines them there)
    sd_convention: np.ndarray | None = None
    #: True when the table holds the prior's values (below), False when the campaign
    #: contradicted the prior and the table holds the convention's solution alone
    prior: bool = False

    def ci95(self) -> np.ndarray:
        return 1.96 * self.sd


def _jacobian(fun, x: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """Central differences of ``fun`` in scaled coordinates (x = scale * z)."""
    f0 = fun(x)
    J = np.empty((f0.size, x.size))
    for i in range(x.size):
        h = 1e-3 * scale[i]
        xp, xm = x.copy(), x.copy()
        xp[i] += h
        xm[i] -= h
        J[:, i] = (fun(xp) - fun(xm)) / (2 * h) * scale[i]
    return J


_FIX_ORDER = {"location": 1, "squareness": 0, "motion": 2, "wobble": 2, "drift": 2, "setup": 3}


def observability(J: np.ndarray, params: list[Param]) -> Observability:
    """Rank, conditioning and estimability from the scaled Jacobian ``J``."""
    _U, s, Vt = np.linalg.svd(J, full_matrices=J.shape[0] < J.shape[1])
    smax = s[0] if s.size else 1.0
    rank = int(np.sum(s > RANK_TOL * smax))
    null = Vt[rank:].T  # (P, P - rank)
    weight = np.linalg.norm(null, axis=1) if null.size else np.zeros(len(params))
    observable = weight < NULL_TOL
    groups: list[list[str]] = []
    if null.size:
        # Confounded groups: parameters tied through the null space (connected components
        # of the projector onto it), each an "only their combination is seen" set.
        Pn = null @ null.T
        d = np.sqrt(np.clip(np.diag(Pn), 1e-300, None))
        tie = np.abs(Pn) / np.outer(d, d) > 0.05
        seen: set[int] = set()
        for i in np.flatnonzero(~observable):
            if i in seen:
                continue
            comp, stack = set(), [int(i)]
            while stack:
                j = stack.pop()
                if j in comp:
                    continue
                comp.add(j)
                stack += [int(k) for k in np.flatnonzero(tie[j] & ~observable) if k not in comp]
            seen |= comp
            groups.append([params[j].name for j in sorted(comp)])
    cand = sorted(np.flatnonzero(~observable), key=lambda i: (_FIX_ORDER[params[i].kind], i))
    keep = list(range(len(params)))
    fixed: list[int] = []
    for i in cand:
        trial = [k for k in keep if k != i]
        if np.linalg.matrix_rank(J[:, trial], tol=RANK_TOL * smax) == rank:
            keep = trial
            fixed.append(i)
        if len(keep) == rank:
            break
    sk = np.linalg.svd(J[:, keep], compute_uv=False)
    cond = float(sk[0] / sk[-1]) if sk.size and sk[-1] > 0 else float("inf")
    return Observability(rank, len(params), cond, s, observable, sorted(fixed), groups)


class _Problem:
    """The residuals of every block, unweighted (um / urad), their weights and a Jacobian
    computed once: the model is linear to 1e-4 relative (docs/concepts.md), so
    ``least_squares`` iterates with it fixed (refreshed at the solution)."""

    def __init__(self, spec: FiveAxisSpec, params: list[Param], blocks: list[Block]) -> None:
        self.spec, self.params, self.blocks = spec, params, blocks
        self.scale = np.array([p.scale for p in params])
        sizes = [residual_block(spec.geometry, params, np.zeros(len(params)),
                                spec.fit.harmonics, b).size for b in blocks]
        self.offsets = np.r_[0, np.cumsum(sizes)]
        self.J = self.jacobian(np.zeros(len(params)))

    def raw(self, x: np.ndarray) -> np.ndarray:
        g, h = self.spec.geometry, self.spec.fit.harmonics
        return np.concatenate([residual_block(g, self.params, x, h, b) for b in self.blocks])

    def weights(self) -> np.ndarray:
        w = []
        for k, b in enumerate(self.blocks):
            n = self.offsets[k + 1] - self.offsets[k]
            sig = np.asarray(b.sigma, dtype=np.float64)
            w.append(np.tile(1.0 / sig, n // sig.size) if sig.size > 1 else np.full(n, 1.0 / sig))
        return np.concatenate(w)

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        return _jacobian(self.raw, x, self.scale)

    def rows(self, keep: dict[str, np.ndarray]) -> np.ndarray:
        """Global residual rows of the kept observations per block key (others: all)."""
        out = []
        for k, b in enumerate(self.blocks):
            lo, hi = self.offsets[k], self.offsets[k + 1]
            if b.key in keep:
                per = (hi - lo) // len(b.obs)
                r = keep[b.key]
                out.append(lo + (per * r[:, None] + np.arange(per)[None, :]).ravel())
            else:
                out.append(np.arange(lo, hi))
        return np.concatenate(out)

    def solve(self, free: list[int], x0: np.ndarray, rows: np.ndarray | None = None
              ) -> tuple[np.ndarray, int]:
        sel = slice(None) if rows is None else rows
        w = self.weights()[sel]
        sc = self.scale[free]
        Jw = self.J[sel][:, free] * w[:, None]

        def fun(z: np.ndarray) -> np.ndarray:
            x = x0.copy()
            x[free] = z * sc
            return self.raw(x)[sel] * w

        # "lm" needs at least as many residuals as unknowns (a small plan or fold may not).
        method = "lm" if Jw.shape[0] >= Jw.shape[1] else "trf"
        sol = least_squares(fun, x0[free] / sc, jac=lambda z: Jw, method=method,
                            xtol=1e-10, ftol=1e-10)
        x = x0.copy()
        x[free] = sol.x * sc
        return x, int(sol.nfev)


def identify(spec: FiveAxisSpec, blocks: list[Block], params: list[Param]) -> FitResult:
    """The whole identification (module docstring)."""
    g, h = spec.geometry, spec.fit.harmonics
    P = len(params)
    for b in blocks:  # start weights: a first solve estimates them (a datum's is declared)
        if b.kind != "datum":
            b.sigma = 5.0 if b.kind == "indexer" else 1.0
    pb = _Problem(spec, params, blocks)
    x, nfev = np.zeros(P), 0
    bilinear = [i for i, p in enumerate(params) if "mount" in p.name]
    if bilinear:
        # An R-test nest's mounting acts on the displacements, which are zero at the start:
        # a first solve without it, then the observability where its effect shows.
        keep = [i for i in range(P) if i not in bilinear]
        o0 = observability(pb.J[:, keep] * pb.weights()[:, None], [params[i] for i in keep])
        x, nfev = pb.solve([keep[i] for i in range(len(keep)) if i not in o0.fixed], x)
        pb.J = pb.jacobian(x)
    obs = observability(pb.J * pb.weights()[:, None], params)
    free = [i for i in range(P) if i not in obs.fixed]
    x, n1 = pb.solve(free, x)
    nfev += n1
    # Weights: each block's standard deviation from its residuals, then refit.
    for b in blocks:
        if b.kind == "datum":
            continue  # a declared (Type B) uncertainty, not estimated from its residuals
        r = residual_block(g, params, x, h, b)
        if b.kind in ("indexer", "ballbar"):
            n_own = sum(1 for i in free if params[i].block == b.key) + 1
            b.sigma = max(float(np.sqrt(np.sum(r ** 2) / max(r.size - n_own, 1))), 1e-3)
        else:  # per machine axis: a sphere fit of a cap is worse along its axis
            r3 = r.reshape(-1, 3)
            dof = max(len(r3) - len(free) / 3.0, 1.0)
            b.sigma = np.maximum(np.sqrt(np.sum(r3 ** 2, axis=0) / dof), 1e-3)
    pb.J = pb.jacobian(x)
    x, n2 = pb.solve(free, x)
    nfev += n2
    w = pb.weights()
    Jf = pb.J[:, free] * w[:, None]
    r = pb.raw(x) * w
    dof = max(r.size - len(free), 1)
    s2 = float(r @ r) / dof
    cov_z = np.linalg.pinv(Jf.T @ Jf) * s2
    sd = np.full(P, np.nan)
    sdz = np.sqrt(np.clip(np.diag(cov_z), 0.0, None))
    sd[free] = sdz * pb.scale[free]
    corr = np.full((P, P), np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        cz = cov_z / np.outer(sdz, sdz)
    corr[np.ix_(free, free)] = cz
    sd_convention = sd.copy()  # the free unknowns' intervals in the fit's convention
    xo = x.copy()
    hide = ~obs.observable
    xo[hide] = np.nan
    sd[hide] = np.nan
    res = FitResult(params, xo, sd, corr, obs, blocks, h, nfev=nfev, x_solution=x.copy(),
                    jacobian=pb.J, weights=w, row_offsets=pb.offsets)
    res.sd_convention = sd_convention
    xt, res.min_norm = table_solution(params, x, obs, pb.J * w[:, None], pb.scale)
    if any(xt[i] != 0.0 for i in obs.fixed):
        # the smallest-norm choice gave fixed unknowns a value: the free ones follow it
        # through the model itself (one more solve), so the table reproduces the campaign
        # as the fit does, not only to first order
        x0 = x.copy()
        x0[obs.fixed] = xt[obs.fixed]
        xt, n3 = pb.solve(free, x0)
        res.nfev += n3
        # the observable errors are the fit's own numbers (the report's): the re-solve
        # moves them by its tolerance only (2e-5 um on examples/trunnion5ax)
        xt[obs.observable] = x[obs.observable]
        # kept only if it reproduces the campaign as the fit does (a plan so weak that
        # the choice moves far off the linear null space does not): else the convention's
        # solution, which is the fit's own
        r0, rt = pb.raw(x) * w, pb.raw(xt) * w
        if not np.all(np.isfinite(rt)) or float(rt @ rt) > 1.01 * float(r0 @ r0) + 1e-9:
            xt, res.min_norm = x.copy(), []
    # A prior of one typical size (``scale``) on each error the plan sees only in the
    # convention: where the campaign determines it well this moves nothing; where it
    # leaves it noise (one sphere with error motions: EA0C 811 +- 911 urad on
    # examples/trunnion5ax) it holds the smallest values the campaign allows (a MAP
    # estimate, linear: the model is linear to 1e-4 relative here), the observed errors
    # following to within their own intervals.
    prior = [i for i in free if params[i].kind != "setup" and not obs.observable[i]]
    if prior:
        sc = pb.scale[free]
        Jf = pb.J[:, free] * w[:, None]
        r_t = pb.raw(xt) * w
        z0 = xt[free] / sc
        P = np.zeros((len(prior), len(free)))
        for k, i in enumerate(prior):
            P[k, free.index(i)] = 1.0
        sq = np.sqrt(max(s2, 1e-12))
        A = np.vstack([Jf / sq, P])
        b = np.r_[-r_t / sq, -P @ z0]
        dz, *_ = np.linalg.lstsq(A, b, rcond=None)
        xp = xt.copy()
        xp[free] = (z0 + dz) * sc
        r_p = pb.raw(xp) * w
        # kept while the table still reproduces the campaign (its weighted RMS within
        # 1.2 x the fit's): a prior that the data contradict is not taken
        if np.all(np.isfinite(r_p)) and float(r_p @ r_p) <= 1.44 * float(r_t @ r_t):
            xt = xp
            res.prior = True
    res.x_table = xt
    _dispersion(pb, x, free, res)
    return res


def is_angular_zero(p: Param) -> bool:
    """EC0C, EA0A, EB0B: a location error about the axis' own direction."""
    return p.kind == "location" and p.name[1] == p.name[3]


def table_solution(params: list[Param], x: np.ndarray, obs: Observability, Jw: np.ndarray,
                   scale: np.ndarray) -> tuple[np.ndarray, list[int]]:
    """The machine errors a table should hold (issue 33) and which of them a smallest-norm
    choice set.

    Every solution of the plan is ``x + N z`` (N: the null space of the weighted Jacobian
    ``Jw``, scaled columns). The angular zeros the fit fixed stay 0 (the convention: a
    zero turns the workpiece, which a workpiece datum absorbs). What that convention
    leaves free, a plan with a single sphere radius (for instance) cannot separate at all
    (a shift of C's line against a first-harmonic angular motion with second-harmonic
    radial ones): of those solutions the one with the smallest machine errors and the
    smallest change of the set-up unknowns, each in its typical size (``scale``), is
    taken. With a null space of the zeros alone (the
    usual probing plan) this is exactly the fit's solution in its convention."""
    xt = np.array(x, dtype=np.float64)
    fixed = set(obs.fixed)
    zeros = [i for i in obs.fixed if is_angular_zero(params[i])]
    xt[list(fixed)] = 0.0
    # the null space, one direction per fixed unknown: move it by one (scaled) unit and
    # the free ones as the fit would follow it (least squares on the free columns, which
    # have full rank); kept when that leaves the residuals unmoved (to NULL_TOL: the
    # plan's second-order cross terms lift the directions slightly off zero)
    free = [i for i in range(len(params)) if i not in fixed]
    Jf, Jx = Jw[:, free], Jw[:, obs.fixed]
    follow, *_ = np.linalg.lstsq(Jf, Jx, rcond=None)
    left = np.linalg.norm(Jx - Jf @ follow, axis=0)
    null_cols = [k for k in range(len(obs.fixed))
                 if left[k] <= NULL_TOL * max(float(np.linalg.norm(Jx[:, k])), 1e-300)]
    N = np.zeros((len(params), len(null_cols)))
    for c, k in enumerate(null_cols):
        N[obs.fixed[k], c] = 1.0
        N[free, c] = -follow[:, k]
    N *= scale[:, None]  # raw units (um / urad per scaled unit)
    if N.shape[1] == 0:
        return xt, []
    # keep the zeros at 0: directions of the null space that do not move them
    if zeros:
        _u, s0, V0 = np.linalg.svd(N[zeros], full_matrices=True)
        r0 = int(np.sum(s0 > 1e-9 * (s0[0] if s0.size else 1.0)))
        B = N @ V0[r0:].T
    else:
        B = N
    if B.shape[1] == 0:
        return xt, []
    # start from the fit's solution with the other fixed ones at 0, then along B the
    # smallest machine errors and the smallest change of the set-up's unknowns from the
    # fit's, each in its typical size (a direction that trades a little machine error
    # for millimetres of set-up is no better: its second-order terms are not null)
    machine = [i for i, p in enumerate(params) if p.kind != "setup"]
    setup = [i for i, p in enumerate(params) if p.kind == "setup"]
    A = np.vstack([B[machine] / scale[machine, None], B[setup] / scale[setup, None]])
    b = np.r_[-xt[machine] / scale[machine], np.zeros(len(setup))]
    y, *_ = np.linalg.lstsq(A, b, rcond=None)
    move = B @ y
    move[obs.observable] = 0.0  # the plan's own numbers stay (moved by 1e-6 at most here)
    xt = xt + move
    xt[zeros] = 0.0
    moved = [i for i in machine if abs(move[i]) > 1e-3 * scale[i] and i not in zeros]
    return xt, moved


def _centre_residuals(spec: FiveAxisSpec, params: list[Param], b: Block, x: np.ndarray,
                      rows: np.ndarray | None = None) -> np.ndarray:
    r = residual_block(spec.geometry, params, x, spec.fit.harmonics, b, rows)
    return r.reshape(-1, 3)


def dispersion(r3: np.ndarray) -> float:
    """KinematicsOpt-like dispersion of sphere-centre deviations (M, 3) um: RMS length."""
    return float(np.sqrt(np.mean(np.sum(r3 ** 2, axis=1)))) if r3.size else float("nan")


def _dispersion(pb: _Problem, x: np.ndarray, free: list[int], res: FitResult) -> None:
    spec, params, blocks = pb.spec, pb.params, pb.blocks
    probes = [b for b in blocks if b.kind == "probe"]
    if not probes:
        return
    setup = [i for i in free if params[i].kind == "setup"]
    x_before, _ = pb.solve(setup, np.zeros(len(params)))
    res.dispersion_before_um = dispersion(np.vstack([_centre_residuals(spec, params, b, x_before)
                                                     for b in probes]))
    res.dispersion_after_um = dispersion(np.vstack([_centre_residuals(spec, params, b, x)
                                                    for b in probes]))
    # Held-out: k folds over each probing's positions (interleaved, so every fold spans the travel).
    k = spec.fit.folds
    before, after = [], []
    floor_ss, floor_n, sigma = 0.0, 0, _noise_covariance(pb)
    for fold in range(k):
        train = {b.key: np.flatnonzero(np.arange(len(b.obs)) % k != fold) for b in probes}
        test = {b.key: np.flatnonzero(np.arange(len(b.obs)) % k == fold) for b in probes}
        if any(t.size == 0 for t in test.values()):
            continue
        rows = pb.rows(train)
        xf, _ = pb.solve(free, x, rows)
        xb, _ = pb.solve(setup, np.zeros(len(params)), rows)
        for b in probes:
            after.append(_centre_residuals(spec, params, b, xf, test[b.key]))
            before.append(_centre_residuals(spec, params, b, xb, test[b.key]))
        if sigma is not None:
            floor_ss += _expected_heldout_ss(pb, free, rows, pb.rows(
                {b.key: test[b.key] for b in probes} | {b.key: np.zeros(0, int)
                                                        for b in blocks if b.kind != "probe"}),
                sigma)
            floor_n += sum(t.size for t in test.values())
    if after:
        res.heldout_before_um = dispersion(np.vstack(before))
        res.heldout_after_um = dispersion(np.vstack(after))
        res.heldout_residuals_um = np.vstack(after)
        if sigma is not None and floor_n:
            res.heldout_floor_um = float(np.sqrt(floor_ss / floor_n))


def _noise_covariance(pb: _Problem) -> np.ndarray | None:
    """The residual rows' noise covariance (dense, um^2 / urad^2): the sphere centres' from
    their fits (3 x 3 per position), the other blocks' their fitted sigma squared; None when
    a probing has no centre covariance."""
    n = int(pb.offsets[-1])
    S = np.zeros((n, n))
    for k, b in enumerate(pb.blocks):
        lo, hi = int(pb.offsets[k]), int(pb.offsets[k + 1])
        if b.kind == "probe":
            if b.centre_cov_um2 is None:
                return None
            for m, c in enumerate(b.centre_cov_um2):
                S[lo + 3 * m:lo + 3 * m + 3, lo + 3 * m:lo + 3 * m + 3] = c
        else:
            sig = np.asarray(b.sigma, dtype=np.float64)
            d = np.tile(sig, (hi - lo) // sig.size) if sig.size > 1 else np.full(hi - lo, sig)
            S[lo:hi, lo:hi] = np.diag(d ** 2)
    return S


def _expected_heldout_ss(pb: _Problem, free: list[int], train: np.ndarray, test: np.ndarray,
                         S: np.ndarray) -> float:
    """Expected sum of squared held-out residuals (um^2) on rows ``test`` of a right model
    fitted (weighted, linearised) on rows ``train`` under the noise covariance ``S``: the
    test rows' own noise plus what the estimate's scatter puts into their prediction,
    tr(S_test) + tr(J_test C J_test^T), C = K S_train K^T, K the weighted LSQ solution map."""
    w = pb.weights()[train]
    Jw = pb.J[train][:, free] * w[:, None]
    K = np.linalg.pinv(Jw.T @ Jw) @ Jw.T * w[None, :]
    C = K @ S[np.ix_(train, train)] @ K.T
    Jt = pb.J[test][:, free]
    return float(np.trace(S[np.ix_(test, test)]) + np.sum((Jt @ C) * Jt))
