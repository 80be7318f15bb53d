"""The discrepancy workflow on any kinematic chain (head-head, head-table, dual-rotary
table): which location error or error motion the model of a ``[chain]`` machine misses.

The checks are the machine file's probing and R-test set-ups (sphere centres in machine
positions, R-test readings; :func:`abbe.analysis.five_axis.chain_fit.setups_from_machine`).
The *base model* is either a model given (``abbe fit``'s chain_fit.json: its location
errors and error motions held, only the set-ups' unknowns refitted) or, without one, the
location-only identification of the same plan (the trunnions' five-axis diagnose does
the same). Each candidate of the catalogue is added to the base in turn:

* ``EXC(C) k`` ...: an error motion of a rotary axis, one ISO 230-7 component at one
  harmonic k (its sin and cos coefficients, um / urad), k from the lowest ISO 230-7
  allows (:func:`abbe.model.five_axis.lowest_harmonic`) up to :data:`MAX_HARMONIC` and
  below half the number of distinct angles the plan has of that axis;
* ``EX0C`` ...: with a model given, one location error changed since the model (a crash,
  a re-assembly), um / urad.

Everything is linearised once at the base model (the chain model is linear in its errors
to 0.1 um at 100 um / 100 urad, docs/concepts.md): the weighted Jacobian J of the
predictions, central differences. A candidate is named when (a) the plan sees its
parameters beyond what the base's unknowns take (the part of its columns outside the
base's column space has full rank), (b) its parameters are significant together
(chi-square against their covariance above the 1 % Bonferroni level of the catalogue)
and (c) it predicts held-out probing positions better: folds of positions left out
(every probing set-up's position m in fold m mod k), the rest fitted, the left-out
centres predicted; their RMS 3-D error must fall by :data:`MIN_GAIN`. The best such
candidate (largest held-out gain) is added and the search repeats (at most
:data:`MAX_EFFECTS`). A named candidate whose signature another reproduces to
:data:`AMBIGUITY_R2` is reported ambiguous with it.

The *gap* is the held-out RMS above what a right model shows on this plan: the floor
``sqrt(mean over held-out rows of sigma^2 (1 + h))`` (sigma the centres' noise, h the
row's leverage through the fold's fit), taken out in quadrature.

Units: um, urad.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.stats import chi2

from abbe.analysis.five_axis.chain_fit import (RANK_TOL, ChainSetup, _jacobian, _residual,
                                               _unknowns, identify_chain, reweight)
from abbe.model.chain import KinematicChain
from abbe.model.five_axis import LOCATION_ERRORS, MOTION_COMPONENTS, lowest_harmonic, motion_name

#: Held-out RMS must fall by this fraction (the trunnions' five-axis diagnose's guard).
MIN_GAIN = 0.05
#: Another candidate reproducing this share of a named one's signature makes it ambiguous.
AMBIGUITY_R2 = 0.9
MAX_EFFECTS = 2
#: Highest harmonic of an error motion tried.
MAX_HARMONIC = 3
#: False alarms over the whole catalogue per round (Bonferroni).
FALSE_ALARM = 0.01

_COMPONENT_WORDS = {"X": "along X", "Y": "along Y", "Z": "along Z", "A": "about X",
                    "B": "about Y", "C": "about Z"}


@dataclass(frozen=True)
class Candidate:
    """A catalogue entry: ``key`` (``EXC(C) 2``, ``EX0B``), what it is, its unknowns'
    names (as :func:`abbe.analysis.five_axis.chain_fit._unknowns` has them) and unit."""

    key: str
    what: str
    params: tuple[str, ...]
    unit: str


def _kind_of(axis: str, comp: str) -> str:
    own = {"A": "X", "B": "Y", "C": "Z"}[axis]
    if comp in "XYZ":
        return "axial" if comp == own else "radial"
    return "angular positioning" if comp == axis else "tilt"


def catalogue(chain: KinematicChain, setups: list[ChainSetup], location: bool) -> list[Candidate]:
    """The candidates for this chain and plan (see module)."""
    out: list[Candidate] = []
    r1, r2 = chain.rotaries
    for col, ax in enumerate((r1, r2)):
        n_ang = max((len(np.unique(np.round(np.asarray(s.angles_deg)[:, col], 6)))
                     for s in setups), default=0)
        top = min(MAX_HARMONIC, max((n_ang - 1) // 2, 0))
        for comp in MOTION_COMPONENTS:
            unit = "um" if comp in "XYZ" else "urad"
            for k in range(lowest_harmonic(ax, comp), top + 1):
                name = motion_name(ax, comp)
                out.append(Candidate(
                    f"{name} {k}", f"{_kind_of(ax, comp)} error motion of {ax} "
                    f"{_COMPONENT_WORDS[comp]}, {k} cycle(s) per turn ({unit})",
                    (f"{name} sin{k}", f"{name} cos{k}"), unit))
    if location:
        for ax in (r1, r2):
            for i, n in enumerate(LOCATION_ERRORS[ax]):
                unit = "um" if i < 2 else "urad"
                out.append(Candidate(n, f"location error {n} of {ax} changed since the "
                                        f"model ({unit})", (n,), unit))
    return out


@dataclass
class Named:
    """A named candidate: values and 95 % intervals, amplitude (root sum of squares of
    its coefficients, or the value), the held-out RMS before and after adding it (um),
    chi-square, and the candidates it is ambiguous with (key, R^2)."""

    candidate: Candidate
    values: dict[str, float]
    ci95: dict[str, float]
    amplitude: float
    heldout_before_um: float
    heldout_after_um: float
    chi2: float
    ambiguous_with: list[tuple[str, float]] = field(default_factory=list)


@dataclass
class ChainDiagnosis:
    """The result: base (``model`` or ``location-only fit``), held-out RMS and floor of the
    base and of the final model (um), the named candidates, every candidate tried."""

    chain: KinematicChain
    base: str
    heldout_before_um: float
    floor_before_um: float
    heldout_after_um: float
    floor_after_um: float
    named: list[Named] = field(default_factory=list)
    tried: list[dict[str, Any]] = field(default_factory=list)
    n_candidates: int = 0

    @property
    def gap_before_um(self) -> float:
        return float(np.sqrt(max(self.heldout_before_um ** 2 - self.floor_before_um ** 2, 0.0)))

    @property
    def gap_after_um(self) -> float:
        return float(np.sqrt(max(self.heldout_after_um ** 2 - self.floor_after_um ** 2, 0.0)))

    @property
    def gap_shrink(self) -> float | None:
        """1 - gap after / gap before (None when the base is already at its floor)."""
        b = self.gap_before_um
        return None if not b > 0 else 1.0 - self.gap_after_um / b

    def to_json(self) -> dict[str, Any]:
        return {"chain": self.chain.name, "kind": self.chain.kind, "base": self.base,
                "candidates": self.n_candidates,
                "heldout_before_um": self.heldout_before_um,
                "heldout_after_um": self.heldout_after_um,
                "heldout_floor_before_um": self.floor_before_um,
                "heldout_floor_after_um": self.floor_after_um,
                "gap_before_um": self.gap_before_um, "gap_after_um": self.gap_after_um,
                "gap_shrink": self.gap_shrink,
                "named": [{"effect": n.candidate.key, "what": n.candidate.what,
                           "unit": n.candidate.unit, "values": n.values, "ci95": n.ci95,
                           "amplitude": n.amplitude, "chi2": n.chi2,
                           "heldout_before_um": n.heldout_before_um,
                           "heldout_after_um": n.heldout_after_um,
                           "ambiguous_with": [{"effect": k, "r2": r} for k, r in
                                              n.ambiguous_with]} for n in self.named],
                "tried": self.tried}

    def text(self) -> str:
        c = self.chain
        out = [f"Five-axis discrepancy ({c.name}, {c.kind}): base {self.base}; held-out "
               f"sphere-centre RMS {self.heldout_before_um:.3f} um (a right model shows "
               f"{self.floor_before_um:.3f} um on this plan); {self.n_candidates} candidates"]
        if not self.named:
            out.append("Nothing named: no candidate is seen by the plan, significant and "
                       f"lowers the held-out RMS by {MIN_GAIN:.0%}")
        for n in self.named:
            vals = ", ".join(f"{k} {v:.3f} +- {n.ci95[k]:.3f}" for k, v in n.values.items())
            head = "Ambiguous" if n.ambiguous_with else "Named"
            out.append(f"{head}: {n.candidate.key}: {n.candidate.what}: amplitude "
                       f"{n.amplitude:.3f} {n.candidate.unit} ({vals}); held out "
                       f"{n.heldout_before_um:.3f} -> {n.heldout_after_um:.3f} um")
            for k, r in n.ambiguous_with:
                out.append(f"  as well explained by {k} (R^2 {r:.2f}): the plan cannot tell "
                           "them apart")
        s = self.gap_shrink
        out.append(f"Gap (held-out RMS above the floor): {self.gap_before_um:.3f} -> "
                   f"{self.gap_after_um:.3f} um" + (f", shrink {s:.0%}" if s is not None
                                                    else " (at the floor)"))
        return "\n".join(out) + "\n"


class _Linear:
    """The plan linearised at the base model: weighted residual r0 and Jacobian J (scaled
    unknowns), the rows' sigma (um) and which rows are probing positions (position id)."""

    def __init__(self, chain: KinematicChain, setups: list[ChainSetup], x0: np.ndarray,
                 harmonics: int, folds: int, noise_um: list[float]) -> None:
        unk = _unknowns(chain, setups, harmonics)
        self.names = [u[0] for u in unk]
        self.index = {n: i for i, n in enumerate(self.names)}
        self.scale = np.array([u[1] for u in unk])
        self.r0 = _residual(chain, setups, x0, harmonics)
        self.J = _jacobian(chain, setups, x0, self.scale, central=True, harmonics=harmonics)
        sig, fold, pos, noise = [], [], [], []
        p = 0
        for s, nz in zip(setups, noise_um):
            m = len(s.obs)
            sig.append(np.full(3 * m, s.sigma_um))
            noise.append(np.full(3 * m, nz))
            if s.kind == "probe":
                fold.append(np.repeat(np.arange(m) % folds, 3))
                pos.append(np.repeat(p + np.arange(m), 3))
                p += m
            else:  # R-test rows always train
                fold.append(np.full(3 * m, -1))
                pos.append(np.full(3 * m, -1))
        self.sigma = np.concatenate(sig)
        self.noise = np.concatenate(noise)
        self.fold = np.concatenate(fold)
        self.pos = np.concatenate(pos)
        self.folds = folds
        sv = np.linalg.svd(self.J, compute_uv=False)
        self.tol = RANK_TOL * (sv[0] if sv.size and sv[0] > 0 else 1.0)

    def _basis(self, rows: np.ndarray, cols: list[int]) -> tuple[np.ndarray, np.ndarray,
                                                                   np.ndarray]:
        """Truncated SVD (U, s, V) of J[rows, cols] (rank by :data:`RANK_TOL`)."""
        U, s, Vt = np.linalg.svd(self.J[np.ix_(rows, cols)], full_matrices=False)
        keep = s > self.tol
        return U[:, keep], s[keep], Vt[keep].T

    def fit(self, base: list[int], extra: list[int], rows: np.ndarray,
            basis: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Least squares of r0[rows] on the columns ``base`` + ``extra`` (min-norm in the
        base): (z_base, v_extra, B) with B the extra columns outside the base's span.
        ``basis``: the SVD of J[rows, base] (:meth:`_basis`), computed once per base."""
        U, s, V = basis if basis is not None else self._basis(rows, base)
        r = self.r0[rows]
        if extra:
            E = self.J[np.ix_(rows, extra)]
            B = E - U @ (U.T @ E)
            v, *_ = np.linalg.lstsq(B, r - U @ (U.T @ r), rcond=None)
            rest = r - E @ v
        else:
            B, v, rest = np.zeros((len(rows), 0)), np.zeros(0), r
        z = V @ ((U.T @ rest) / s)
        return z, v, B

    def predict(self, rows: np.ndarray, base: list[int], extra: list[int], z: np.ndarray,
                v: np.ndarray) -> np.ndarray:
        """Weighted residual of ``rows`` after the fit (z, v)."""
        out = self.r0[rows] - self.J[np.ix_(rows, base)] @ z
        return out - self.J[np.ix_(rows, extra)] @ v if extra else out

    def fold_bases(self, base: list[int]) -> list[tuple[np.ndarray, np.ndarray,
                                                         tuple[np.ndarray, np.ndarray, np.ndarray]]]:
        """Per fold (held rows, training rows, SVD of the training rows on ``base``)."""
        out = []
        for f in range(self.folds):
            held = np.flatnonzero(self.fold == f)
            if held.size:
                train = np.flatnonzero(self.fold != f)
                out.append((held, train, self._basis(train, base)))
        return out

    def heldout(self, base: list[int], extra: list[int], bases=None,  # noqa: ANN001
                floor: bool = False) -> tuple[float, float]:
        """(held-out RMS 3-D centre error, its floor or NaN) in um over the folds: each
        fold's positions predicted from a fit of the others. The floor: the centres' noise
        (``noise``) times sqrt(1 + leverage through the fold's fit)."""
        sq, fl, n = 0.0, 0.0, 0
        for held, train, basis in bases if bases is not None else self.fold_bases(base):
            z, v, B = self.fit(base, extra, train, basis)
            r = self.predict(held, base, extra, z, v) * self.sigma[held]
            sq += float(np.sum(r ** 2))
            n += held.size // 3
            if floor:
                cols = base + extra
                A = self.J[np.ix_(train, cols)]
                Jh = self.J[np.ix_(held, cols)]
                h = np.einsum("ij,ij->i", Jh @ np.linalg.pinv(A.T @ A, rcond=1e-12), Jh)
                fl += float(np.sum(self.noise[held] ** 2 * (1.0 + h)))
        if n == 0:
            return float("nan"), float("nan")
        return float(np.sqrt(sq / n)), (float(np.sqrt(fl / n)) if floor else float("nan"))


def diagnose_chain(chain: KinematicChain, setups: list[ChainSetup],
                   model: dict[str, float] | None = None, folds: int = 4) -> ChainDiagnosis:
    """Name what the base model misses (module docstring). ``model``: location errors and
    motion coefficients by name (um / urad; None: the plan's location-only fit is the
    base). The set-ups' sigma: re-estimated from the base model's residuals."""
    location_candidates = model is not None
    probe = [s for s in setups if s.kind == "probe"]
    if not probe:
        raise ValueError("diagnose needs at least one probing set-up (the held-out data)")
    cands_all = catalogue(chain, setups, location_candidates)
    harmonics = max([int(c.key.split(" ")[1]) for c in cands_all if " " in c.key] + [0])
    noise = [s.sigma_um for s in setups]  # the centres' noise (sphere fits): the floor's
    # the model's own error motions are held at every harmonic it has
    harmonics = max([harmonics] + [int(n.split(" ")[1][3:]) for n in (model or {}) if " " in n])
    if model is None:
        fit = identify_chain(chain, setups, explain=False)
        setups = reweight(chain, setups, fit)
    names = [u[0] for u in _unknowns(chain, setups, harmonics)]
    x0 = np.array([float((model or {}).get(n, 0.0)) for n in names])
    lin = _Linear(chain, setups, x0, harmonics, folds, noise)
    setup_cols = [i for i, n in enumerate(names) if "." in n]
    base = setup_cols if model is not None else list(range(10)) + setup_cols
    if model is not None:  # re-weight each set-up by its residual with the model
        every = np.arange(lin.r0.size)
        z, _v, _B = lin.fit(base, [], every)
        r = lin.predict(every, base, [], z, np.zeros(0))
        k, new = 0, []
        for s in setups:
            m = 3 * len(s.obs)
            raw = r[k:k + m] * s.sigma_um
            new.append(ChainSetup(s.kind, s.name, s.sphere_mm, s.angles_deg, s.obs, s.tip_mm,
                                  max(float(np.sqrt(np.mean(raw ** 2))), 0.05)))
            k += m
        setups = new
        lin = _Linear(chain, setups, x0, harmonics, folds, noise)
    cands = [c for c in cands_all if all(p in lin.index for p in c.params)]
    level = 1.0 - FALSE_ALARM / max(len(cands), 1)
    held0, floor0 = lin.heldout(base, [], floor=True)
    diag = ChainDiagnosis(chain, "the model given (set-ups refitted)" if model is not None
                          else "location-only fit of the plan", held0, floor0, held0, floor0,
                          n_candidates=len(cands))
    every = np.arange(lin.r0.size)
    current, prev_held = list(base), held0
    for _ in range(MAX_EFFECTS):
        best = None
        basis = lin._basis(every, current)
        folds_b = lin.fold_bases(current)
        rank = basis[1].size
        for c in cands:
            if any(n.candidate.key == c.key for n in diag.named):
                continue
            cols = [lin.index[p] for p in c.params]
            z, v, B = lin.fit(current, cols, every, basis)
            sb = np.linalg.svd(B, compute_uv=False)
            seen = bool(sb.size and sb[-1] > lin.tol * 10.0)
            entry: dict[str, Any] = {"effect": c.key, "observable": seen}
            diag.tried.append(entry)
            if not seen:
                continue
            r = lin.predict(every, current, cols, z, v)
            dof = max(r.size - rank - len(cols), 1)
            s2 = max(float(r @ r) / dof, 1.0)
            try:
                cov = np.linalg.inv(B.T @ B) * s2
                stat = float(v @ np.linalg.solve(cov, v))
            except np.linalg.LinAlgError:  # seen only at the edge of the rank tolerance
                entry["observable"] = False
                continue
            held, _fl = lin.heldout(current, cols, folds_b)
            gain = (prev_held - held) / prev_held if prev_held > 0 else 0.0
            entry.update({"chi2": stat, "heldout_um": held, "gain": gain})
            if stat > chi2.ppf(level, len(cols)) and gain >= MIN_GAIN \
                    and (best is None or gain > best[0]):
                best = (gain, c, cols, v, cov, held, stat, B)
        if best is None:
            break
        gain, c, cols, v, cov, held, stat, B = best
        sc = lin.scale[cols]
        vals = {p: float(x * q) for p, x, q in zip(c.params, v, sc)}
        ci = {p: float(1.96 * np.sqrt(cov[i, i]) * sc[i]) for i, p in enumerate(c.params)}
        sig = B @ v
        amb = []
        n2 = float(sig @ sig)
        for o in cands:
            if o.key == c.key or n2 <= 0:
                continue
            _z, _v, Bo = lin.fit(current, [lin.index[p] for p in o.params], every, basis)
            coef, *_ = np.linalg.lstsq(Bo, sig, rcond=None)
            r2 = 1.0 - float(np.sum((sig - Bo @ coef) ** 2)) / n2
            if r2 >= AMBIGUITY_R2:
                amb.append((o.key, r2))
        amp = float(np.sqrt(sum(x * x for x in vals.values())))
        diag.named.append(Named(c, vals, ci, amp, prev_held, held, stat, amb))
        current = current + cols
        prev_held = held
    diag.heldout_after_um, diag.floor_after_um = lin.heldout(current, [], floor=True)
    return diag


def model_values(doc: dict[str, Any]) -> dict[str, float]:
    """The location errors and motion coefficients of an ``abbe fit`` chain_fit.json: the
    values the fit holds in its convention (what its table holds: an error the plan saw
    only in a combination carries that combination), the identified value otherwise."""
    out: dict[str, float] = {}
    for r in list(doc.get("location", [])) + list(doc.get("motions", [])):
        v = r.get("value_in_convention", r.get("value"))
        if v is not None:
            out[str(r["name"])] = float(v)
    return out
