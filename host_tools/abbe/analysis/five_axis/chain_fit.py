"""Location errors of any kinematic chain from sphere probing, R-test and rotary ballbar
data, with what the plan cannot see (docs/concepts.md, "Five-axis machines: the kinematic chain").

Unknowns: the ten location errors of the two rotary axes (ISO 230-7 names), with
``harmonics`` H > 0 the error motions' Fourier coefficients of both axes (``EXC(C) sin2``
..., ISO 230-7 names, from :func:`abbe.model.five_axis.lowest_harmonic` to H), and per
set-up the sphere's place on the table (3, um) and, for an R-test, its zero (3, um); per
rotary ballbar set-up (tests sharing a table ball and a tool cup) the table ball's place
on the table (3, um, workpiece frame) and the tool ball's offset from its nominal place
in the spindle's frame (3, um: a tool-side rotary axis swings it with the spindle), and
per ballbar test its length zero (um).
Residuals: measured minus predicted through the exact chain model, each block divided
by its standard deviation; Gauss-Newton on a forward-difference Jacobian (the model is
linear in the location errors to 0.1 um at 100 um / 100 urad).

Observability: the weighted Jacobian, columns scaled by each unknown's typical size,
has a null space; an unknown is *observable* when no null direction moves it. A
maximal set of the others is fixed at 0 by convention (angular zeros first, then
positions, tilts, error motions, the set-up last); each unobservable location error and
error motion coefficient is named with the unknowns it is confounded with and the first of a list of added measurements that
would make it observable (:data:`EXTRA_MEASUREMENTS`). Intervals: 1.96 sigma from
``s^2 (J^T J)^-1`` (s^2 the weighted residual variance, at least 1).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from abbe.analysis.uncertainty import K

from abbe.model.chain import (KinematicChain, nominal_joints, tool_tip, tool_transform,
                              workpiece_transform)
from abbe.model.five_axis import (LOCATION_ERRORS, MOTION_COMPONENTS, FiveAxisErrors,
                                  lowest_harmonic, motion_name)
from abbe.model.five_axis_base import linear_axis_errors, small_rotation

#: Typical sizes of the unknowns (the solver's column scaling): um for positions, urad
#: for tilts and zeros, um for the set-up unknowns, um / urad for error motion coefficients.
SCALE_UM, SCALE_URAD, SCALE_SETUP_UM = 10.0, 50.0, 100.0
SCALE_MOTION_UM, SCALE_MOTION_URAD = 1.0, 5.0
#: Singular values below this share of the largest count as zero (the forward
#: differences carry ~1e-10 of relative rounding; a real plan's weakest seen direction
#: sits above 1e-4).
RANK_TOL = 1e-7


@dataclass
class ChainSetup:
    """One measurement set-up: ``kind`` ``probe`` (the machine positions q that put the
    stylus tip on the sphere's centre, mm), ``rtest`` (readings, nest frame um) or
    ``ballbar`` (a rotary ballbar test: the bar's length minus its nominal length, um),
    the sphere's (ballbar: the table ball's) nominal centre (workpiece mm), the tool tip
    (stylus, nest or tool ball) relative to the controlled point at zero angles (mm), the
    angle pairs (M, 2) deg (alphabetical axes), observations (M, 3) (ballbar (M,)), sigma
    per axis (um); a ballbar's tool ball's nominal centre (workpiece mm, held there under
    tool-centre-point control) and the set-up it shares with other tests ("": its own)."""

    kind: str
    name: str
    sphere_mm: tuple[float, float, float]
    angles_deg: np.ndarray
    obs: np.ndarray
    tip_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sigma_um: float = 1.0
    tool_ball_mm: tuple[float, float, float] | None = None
    balls: str = ""

    @property
    def balls_key(self) -> str:
        """Whose ball unknowns a ballbar test uses: its set-up's, or its own."""
        return f"set-up {self.balls}" if self.balls else self.name


@dataclass
class ChainFitRow:
    """One row of the ISO 230-7 report: name, value (um / urad, None when the plan cannot
    see it), 95 % half-width, unit, status (``identified``, ``fixed at 0``, ``convention``),
    what it is confounded with and what would see it."""

    name: str
    value: float | None
    u95: float | None
    unit: str
    status: str
    confounded_with: tuple[str, ...] = ()
    seen_by: str = ""
    #: standard uncertainty (um / urad, Type A: the identification's covariance), None
    #: when the plan cannot see the error
    u: float | None = None

    @property
    def U(self) -> float | None:
        """Expanded uncertainty, k = 2 (um / urad)."""
        return None if self.u is None else K * self.u


@dataclass
class ChainFit:
    """Result: rows per location error, the values (fixed ones 0), rank, condition
    number, weighted RMS residual, the set-up unknowns (um)."""

    chain: KinematicChain
    rows: list[ChainFitRow]
    values: dict[str, float]
    rank: int
    n_unknowns: int
    condition: float
    rms_weighted: float
    setup: dict[str, float] = field(default_factory=dict)
    #: error motion coefficients (with ``harmonics`` > 0), rows as the location errors'
    motion_rows: list[ChainFitRow] = field(default_factory=list)
    harmonics: int = 0
    #: every motion coefficient as solved (the unobservable ones in the fit's convention:
    #: fixed at 0 or the value the convention gives them), um / urad
    motion_values: dict[str, float] = field(default_factory=dict)
    #: the weighted residual variance the covariance is scaled by (at least 1: the
    #: blocks' sigmas are not trusted to be too large)
    s2: float = 1.0

    def errors(self) -> FiveAxisErrors:
        """The fitted errors in the fit's convention (what a table holds): location errors
        and error motions as :class:`FiveAxisErrors` (Fourier ``[sin k, cos k]`` per
        component, k = 1..harmonics)."""
        mot: dict[tuple[str, str], np.ndarray] = {}
        for name, v in self.motion_values.items():
            head, term = name.split(" ")
            comp, axis = head[1], head[2]
            k = int(term[3:])
            c = mot.setdefault((axis, comp), np.zeros(2 * self.harmonics))
            c[2 * (k - 1) + (0 if term.startswith("sin") else 1)] = v
        return FiveAxisErrors(dict(self.values), mot)

    @property
    def observable(self) -> tuple[str, ...]:
        return tuple(r.name for r in self.rows if r.status == "identified")

    @property
    def unobservable(self) -> tuple[str, ...]:
        return tuple(r.name for r in self.rows if r.status != "identified")


def _unknowns(chain: KinematicChain, setups: list[ChainSetup], harmonics: int = 0
              ) -> list[tuple[str, float, str]]:
    """(name, scale, unit) of every unknown: the ten location errors, the error motions'
    Fourier coefficients up to ``harmonics`` (``EXC(C) sin2``; from
    :func:`abbe.model.five_axis.lowest_harmonic`), the set-ups' unknowns."""
    out = []
    for ax in chain.rotaries:
        for i, n in enumerate(LOCATION_ERRORS[ax]):
            out.append((n, SCALE_UM if i < 2 else SCALE_URAD, "um" if i < 2 else "urad"))
    for ax in chain.rotaries:
        for j, comp in enumerate(MOTION_COMPONENTS):
            for k in range(lowest_harmonic(ax, comp), harmonics + 1):
                for trig in ("sin", "cos"):
                    out.append((f"{motion_name(ax, comp)} {trig}{k}",
                                SCALE_MOTION_UM if j < 3 else SCALE_MOTION_URAD,
                                "um" if j < 3 else "urad"))
    balls: set[str] = set()
    for s in setups:
        if s.kind == "ballbar":
            if s.balls_key not in balls:
                balls.add(s.balls_key)
                out += [(f"{s.balls_key}.table_ball_{c}", SCALE_SETUP_UM, "um") for c in "xyz"]
                out += [(f"{s.balls_key}.tool_ball_{c}", SCALE_SETUP_UM, "um") for c in "xyz"]
            out.append((f"{s.name}.length_zero", SCALE_UM, "um"))
            continue
        for c in "xyz":
            out.append((f"{s.name}.sphere_{c}", SCALE_SETUP_UM, "um"))
        if s.kind == "rtest":
            for c in "xyz":
                out.append((f"{s.name}.zero_{c}", SCALE_SETUP_UM, "um"))
    return out


def _errors(chain: KinematicChain, names: list[str], x: np.ndarray, harmonics: int
            ) -> tuple[FiveAxisErrors, int]:
    """The errors the unknowns ``x`` hold, and the index of the first set-up unknown."""
    mot: dict[tuple[str, str], np.ndarray] = {}
    k = 10
    for ax in chain.rotaries:
        for comp in MOTION_COMPONENTS:
            c = np.zeros(2 * harmonics)
            for h in range(lowest_harmonic(ax, comp), harmonics + 1):
                c[2 * (h - 1):2 * h] = x[k:k + 2]
                k += 2
            if harmonics:
                mot[(ax, comp)] = c
    return FiveAxisErrors({n: float(v) for n, v in zip(names[:10], x[:10])}, mot), k


def predict(chain: KinematicChain, setups: list[ChainSetup], x: np.ndarray,
            harmonics: int = 0, only: frozenset[int] | None = None) -> list[np.ndarray]:
    """Predicted observations of every set-up for the unknowns ``x`` (in :func:`_unknowns`
    order, um / urad): probe machine positions (mm), R-test readings (um), ballbar lengths
    minus nominal (um). ``only``: the indices of the set-ups to predict (the others get an
    empty array)."""
    names = [u[0] for u in _unknowns(chain, setups, harmonics)]
    errs, k = _errors(chain, names, x, harmonics)
    index = {n: i for i, n in enumerate(names)}
    out = []
    # set-ups of one plan share their angles: each transform once per distinct angle set
    # (the same arithmetic, so the same bits)
    work: dict[bytes, np.ndarray] = {}
    tool: dict[bytes, np.ndarray] = {}
    nominal: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}
    for i_s, s in enumerate(setups):
        if only is not None and i_s not in only:
            out.append(np.zeros(0))
            continue
        ang = np.asarray(s.angles_deg, dtype=np.float64).reshape(-1, 2)
        key = ang.tobytes()
        if key not in work:
            work[key] = workpiece_transform(chain, errs, ang)
        T = work[key]
        if s.kind == "ballbar":
            if key not in tool:
                tool[key] = tool_transform(chain, errs, ang)
            if key not in nominal:
                nominal[key] = (workpiece_transform(chain, None, ang),
                                tool_transform(chain, None, ang))
            out.append(_ballbar(chain, errs, s, T, tool[key], nominal[key], x, index))
            continue
        k = index[f"{s.name}.sphere_x"]
        w = np.asarray(s.sphere_mm, dtype=np.float64) + x[k:k + 3] * 1e-3
        k += 3
        centre = np.einsum("nij,j->ni", T[:, :3, :3], w) + T[:, :3, 3]
        if s.kind == "probe":
            # the machine position at which the true tip is on the centre
            if key not in tool:
                tool[key] = tool_transform(chain, errs, ang)
            Ta = tool[key]
            tip = np.asarray(s.tip_mm, dtype=np.float64)
            out.append(centre - (np.einsum("nij,j->ni", Ta[:, :3, :3], tip) + Ta[:, :3, 3]))
        else:
            s_nom = np.asarray(s.sphere_mm, dtype=np.float64)
            q = nominal_joints(chain, s_nom[None, :].repeat(len(ang), 0), ang, s.tip_mm)
            nest = tool_tip(chain, errs, q, ang, s.tip_mm)
            R = tool_transform(chain, None, ang)[:, :3, :3]
            d = np.einsum("nji,nj->ni", R, (centre - nest) * 1e3)
            out.append(d + x[k:k + 3][None, :])
            k += 3
    return out


def _ballbar(chain: KinematicChain, errs: FiveAxisErrors, s: ChainSetup, T: np.ndarray,
             Ta: np.ndarray, nom: tuple[np.ndarray, np.ndarray], x: np.ndarray,
             index: dict[str, int]) -> np.ndarray:
    """A rotary ballbar test's readings (um): the distance of the actual tool ball from the
    actual table ball minus the balls' nominal distance, plus the test's length zero.

    The table ball sits on the table (its place an unknown of the set-up, workpiece frame);
    the controller holds the tool ball's nominal centre on its workpiece point under
    tool-centre-point control (the tool ball as the programmed tool: joints
    ``T_W,nom w - T_T,nom tip``), and the actual tool ball is where the actual chain puts
    the tool ball's actual place in the spindle (``tip`` + its unknown offset, spindle
    frame at zero angles: a head's axes turn the offset with the spindle, as they turn a
    stylus or an R-test nest). ``T``, ``Ta``: the actual workpiece and tool transforms at
    the test's angles, ``nom`` the nominal ones (as :func:`nominal_joints` and
    :func:`tool_tip` compute them, shared by the tests of one angle path)."""
    kb = index[f"{s.balls_key}.table_ball_x"]
    table = np.asarray(s.sphere_mm, dtype=np.float64) + x[kb:kb + 3] * 1e-3
    centre = np.einsum("nij,j->ni", T[:, :3, :3], table) + T[:, :3, 3]
    tool_nom = np.asarray(s.tool_ball_mm, dtype=np.float64)
    tip = np.asarray(s.tip_mm, dtype=np.float64)
    Tw, Tt = nom
    q = (np.einsum("nij,j->ni", Tw[:, :3, :3], tool_nom) + Tw[:, :3, 3]
         - (np.einsum("nij,j->ni", Tt[:, :3, :3], tip) + Tt[:, :3, 3]))
    kt = index[f"{s.balls_key}.tool_ball_x"]
    dl, rl = linear_axis_errors(chain, errs, q)  # type: ignore[arg-type]
    held = np.einsum("nij,j->ni", Ta[:, :3, :3], tip + x[kt:kt + 3] * 1e-3) + Ta[:, :3, 3]
    ball = q + dl * 1e-3 + np.einsum("nij,nj->ni", small_rotation(rl * 1e-6), held)
    length = float(np.linalg.norm(tool_nom - np.asarray(s.sphere_mm, dtype=np.float64)))
    return ((np.linalg.norm(ball - centre, axis=1) - length) * 1e3
            + x[index[f"{s.name}.length_zero"]])


def _residual(chain: KinematicChain, setups: list[ChainSetup], x: np.ndarray,
              harmonics: int = 0, only: frozenset[int] | None = None) -> np.ndarray:
    """Weighted residuals of every set-up (``only``: of those set-ups, in order)."""
    pred = predict(chain, setups, x, harmonics, only)
    r = []
    for i_s, (s, p) in enumerate(zip(setups, pred)):
        if only is not None and i_s not in only:
            continue
        diff = (np.asarray(s.obs) - p) * (1e3 if s.kind == "probe" else 1.0)
        r.append((diff / s.sigma_um).ravel())
    return np.concatenate(r)


def _jacobian(chain: KinematicChain, setups: list[ChainSetup], x: np.ndarray,
              scale: np.ndarray, central: bool = False, harmonics: int = 0) -> np.ndarray:
    """d(prediction)/d(unknown / scale), weighted. ``central``: central differences (no
    second-order part: what the rank needs, where a direction the model sees only to
    second order must count as unseen); forward differences for the iterations.

    A set-up's own unknown (a sphere's place, a ballbar's length zero) moves only that
    set-up's rows: its column is computed from those rows alone (the others' differences
    are exactly 0 either way)."""
    r0 = _residual(chain, setups, x, harmonics)
    J = np.zeros((r0.size, x.size))
    names = [u[0] for u in _unknowns(chain, setups, harmonics)]
    ends = np.cumsum([np.asarray(s.obs).size for s in setups])
    rows = [np.arange(e - np.asarray(s.obs).size, e) for s, e in zip(setups, ends)]
    owners = {i: {s.name, s.balls_key} if s.kind == "ballbar" else {s.name}
              for i, s in enumerate(setups)}
    for j in range(x.size):
        h = np.zeros(x.size)
        h[j] = scale[j]  # one typical size: the model is linear to 1e-3 um there
        only = None
        if "." in names[j] and "(" not in names[j]:
            who = names[j].rsplit(".", 1)[0]
            only = frozenset(i for i, o in owners.items() if who in o)
        sel = slice(None) if only is None else np.concatenate([rows[i] for i in sorted(only)])
        if central:
            J[sel, j] = -(_residual(chain, setups, x + h, harmonics, only)
                          - _residual(chain, setups, x - h, harmonics, only)) / 2.0
        else:
            J[sel, j] = -(_residual(chain, setups, x + h, harmonics, only) - r0[sel]) \
                / h[j] * scale[j]
    return J


def _reduced(J: np.ndarray) -> np.ndarray:
    """A square matrix with the singular values and right singular vectors of a tall ``J``
    (its QR factor R): the SVD of a plan's (rows x unknowns) Jacobian without the rows."""
    return np.linalg.qr(J, mode="r") if J.shape[0] > J.shape[1] else J


def _rank(J: np.ndarray) -> int:
    s = np.linalg.svd(_reduced(J), compute_uv=False)
    return int(np.sum(s > s[0] * RANK_TOL)) if s.size and s[0] > 0 else 0


def _fix_order(names: list[str]) -> list[int]:
    """Unknowns in the order the convention fixes them: angular zeros, positions, tilts,
    the set-up's last."""
    def key(i: int) -> tuple[int, int]:
        n = names[i]
        if "." in n:
            return (4, i)
        if "(" in n:  # an error motion's coefficient
            return (3, i)
        if n[1] == n[3]:  # EC0C: the zero of the axis itself
            return (0, i)
        return (1 if n[1] in "XYZ" else 2, i)
    return sorted(range(len(names)), key=key)


def observability(chain: KinematicChain, setups: list[ChainSetup], harmonics: int = 0
                  ) -> tuple[list[int], list[int], np.ndarray, int]:
    """(unobservable indices, fixed indices, null space (n, k) scaled, rank) of a plan."""
    unk = _unknowns(chain, setups, harmonics)
    scale = np.array([u[1] for u in unk])
    J = _jacobian(chain, setups, np.zeros(len(unk)), scale, central=True, harmonics=harmonics)
    _u, s, vt = np.linalg.svd(_reduced(J), full_matrices=True)
    rank = int(np.sum(s > s[0] * RANK_TOL))
    null = vt[rank:].T
    unobs = [j for j in range(len(unk)) if np.linalg.norm(null[j]) > 1e-6]
    fixed: list[int] = []
    for j in _fix_order([u[0] for u in unk]):
        if j not in unobs or len(fixed) == len(unk) - rank:
            continue
        keep = [i for i in range(len(unk)) if i not in fixed and i != j]
        if _rank(J[:, keep]) == rank:
            fixed.append(j)
    return unobs, fixed, null, rank


#: Measurements a plan may add to see what it cannot: (label, how to build its set-ups
#: from the plan's first set-up). The last one matters for error motions: a radial or tilt
#: motion moves a sphere by the same amount at every radius, a line's tilt does not.
EXTRA_MEASUREMENTS: tuple[str, ...] = (
    "a second sphere 100 mm higher on the table",
    "a second stylus (or R-test nest) 100 mm longer",
    "the sphere's place on the table known (probed at zero angles against a reference)",
    "a second sphere 100 mm further out (70 mm along X and along Y)",
)
#: What an error motion coefficient nothing of :data:`EXTRA_MEASUREMENTS` separates needs
#: (the trunnion report's wording, abbe.analysis.five_axis.identify.SEEN_BY["motion"]).
MOTION_SEEN_BY = ("more angles of the axis per turn (the harmonic below half their number), "
                  "an R-test with spheres at two heights (tilt against radial), the laser + "
                  "rotary indexer for the angular motion")


#: What a plan of rotary ballbar tests alone adds first: the ballbar reads one distance,
#: so a shift of an axis line is a shift of the table ball on the table plus one of the tool
#: ball in the spindle (docs/concepts.md, "The rotary ballbar"); a probed sphere fixes it.
BALLBAR_EXTRA = "a sphere probed with a touch probe where the table ball sits"


def _probed_sphere(setups: list[ChainSetup]) -> ChainSetup:
    """:data:`BALLBAR_EXTRA`: a sphere where the first table ball sits, probed at every
    angle pair the ballbar tests reach."""
    s = setups[0]
    ang = np.unique(np.concatenate([np.asarray(b.angles_deg, dtype=np.float64).reshape(-1, 2)
                                    for b in setups]), axis=0)
    return ChainSetup("probe", s.name + "_probed", s.sphere_mm, ang, np.zeros((len(ang), 3)),
                      (0.0, 0.0, 0.0), s.sigma_um)


def _extra_setups(label: str, s: ChainSetup) -> list[ChainSetup]:
    if label.startswith("a second sphere 100 mm higher"):
        w = (s.sphere_mm[0], s.sphere_mm[1], s.sphere_mm[2] + 100.0)
        return [replace(s, name=s.name + "_high", sphere_mm=w,
                        balls=s.balls + "_high" if s.balls else "")]
    if label.startswith("a second sphere 100 mm further"):
        w = (s.sphere_mm[0] + 70.0, s.sphere_mm[1] + 70.0, s.sphere_mm[2])
        return [replace(s, name=s.name + "_out", sphere_mm=w,
                        balls=s.balls + "_out" if s.balls else "")]
    if label.startswith("a second stylus"):
        tip = (s.tip_mm[0], s.tip_mm[1], s.tip_mm[2] - 100.0)
        return [replace(s, name=s.name + "_long", tip_mm=tip, balls=s.balls + "_long"
                        if s.balls else "")]
    return []


def _seen_by_all(chain: KinematicChain, setups: list[ChainSetup], js: list[int],
                 harmonics: int = 0) -> dict[int, str]:
    """For each unobservable unknown ``js``: the first of :data:`EXTRA_MEASUREMENTS` that
    makes it observable ("none of ..." when none does). Each added measurement's rank
    analysis runs once for all of them."""
    if setups and all(s.kind == "ballbar" for s in setups):
        # rotary ballbar tests alone: a probed sphere first, then the others on top of it
        base = setups + [_probed_sphere(setups)]
        unobs, _f, _n, _r = observability(chain, base, harmonics)
        out = {j: BALLBAR_EXTRA for j in js if j not in unobs}
        rest = [j for j in js if j in unobs]
        if rest:
            more = _seen_by_all(chain, base, rest, harmonics)
            out.update({j: (f"{BALLBAR_EXTRA}, with {v}" if not v.startswith("none of") else
                            f"none of: {BALLBAR_EXTRA}, with {v[len('none of '):]}")
                        for j, v in more.items()})
        return out
    out: dict[int, str] = {}
    todo = list(js)
    extras = EXTRA_MEASUREMENTS
    for label in extras:
        if not todo:
            break
        if label.startswith("the sphere's place"):
            unk = _unknowns(chain, setups, harmonics)
            scale = np.array([u[1] for u in unk])
            J = _jacobian(chain, setups, np.zeros(len(unk)), scale, central=True,
                          harmonics=harmonics)
            keep = [i for i in range(len(unk)) if "sphere_" not in unk[i][0]]
            _u, s, vt = np.linalg.svd(J[:, keep])
            rank = int(np.sum(s > s[0] * RANK_TOL))
            null = vt[rank:].T
            seen = [j for j in todo if np.linalg.norm(null[keep.index(j)]) <= 1e-6]
        else:
            # the plan's first sphere (a ballbar plan's first table ball) is the template
            first = next((s for s in setups if s.kind != "ballbar"), setups[0])
            more = setups + _extra_setups(label, first)
            unobs, _f, _n, _r = observability(chain, more, harmonics)
            seen = [j for j in todo if j not in unobs]
        for j in seen:
            out[j] = label
        todo = [j for j in todo if j not in seen]
    for j in todo:
        out[j] = "none of " + "; ".join(extras)
    return out


def _seen_by(chain: KinematicChain, setups: list[ChainSetup], j: int, harmonics: int = 0) -> str:
    return _seen_by_all(chain, setups, [j], harmonics)[j]


def identify_chain(chain: KinematicChain, setups: list[ChainSetup],
                   iterations: int = 3, explain: bool = True, harmonics: int = 0) -> ChainFit:
    """Fit the location errors of ``chain`` (and, with ``harmonics`` > 0, its error
    motions' Fourier coefficients up to that harmonic) to the set-ups (see module)."""
    unk = _unknowns(chain, setups, harmonics)
    names = [u[0] for u in unk]
    scale = np.array([u[1] for u in unk])
    unobs, fixed, null, rank = observability(chain, setups, harmonics)
    free = [j for j in range(len(unk)) if j not in fixed]
    x = np.zeros(len(unk))
    for _ in range(iterations):
        J = _jacobian(chain, setups, x, scale, harmonics=harmonics)[:, free]
        r = _residual(chain, setups, x, harmonics)
        step, *_ = np.linalg.lstsq(J, r, rcond=None)
        x[free] += step * scale[free]
    J = _jacobian(chain, setups, x, scale, harmonics=harmonics)[:, free]
    r = _residual(chain, setups, x, harmonics)
    dof = max(r.size - len(free), 1)
    s2 = max(float(r @ r) / dof, 1.0)
    cov = np.linalg.pinv(J.T @ J) * s2
    sig = np.sqrt(np.clip(np.diag(cov), 0.0, None)) * scale[free]
    sv = np.linalg.svd(J, compute_uv=False)
    n_mot = sum(1 for u in unk if "(" in u[0])
    seen_by = _seen_by_all(chain, setups, [j for j in unobs if j < 10 + n_mot], harmonics) \
        if explain else {}

    def confounded(j: int) -> tuple[str, ...]:
        return tuple(names[i] for i in range(len(unk)) if i != j
                     and abs(float(null[i] @ null[j])) > 1e-6)

    rows = []
    for j in range(10):
        n, unit = names[j], unk[j][2]
        if j in unobs:
            rows.append(ChainFitRow(n, None, None, unit,
                                    "fixed at 0" if j in fixed else "convention", confounded(j),
                                    seen_by.get(j, "")))
        else:
            sd = float(sig[free.index(j)])
            rows.append(ChainFitRow(n, float(x[j]), 1.96 * sd, unit, "identified", u=sd))
    motions = []
    for j in range(10, 10 + n_mot):
        if j in unobs:
            by = seen_by.get(j, "")
            if by.startswith("none of"):
                by = MOTION_SEEN_BY
            motions.append(ChainFitRow(names[j], None, None, unk[j][2],
                                       "fixed at 0" if j in fixed else "convention",
                                       confounded(j), by))
        else:
            sd = float(sig[free.index(j)])
            motions.append(ChainFitRow(names[j], float(x[j]), 1.96 * sd, unk[j][2],
                                       "identified", u=sd))
    return ChainFit(chain, rows, {names[j]: float(x[j]) for j in range(10)}, rank, len(unk),
                    float(sv[0] / sv[-1]) if sv[-1] > 0 else float("inf"),
                    float(np.sqrt(np.mean(r ** 2))),
                    {names[j]: float(x[j]) for j in range(10 + n_mot, len(unk))}, motions,
                    harmonics, {names[j]: float(x[j]) for j in range(10, 10 + n_mot)}, s2)


def report_rows(fit: ChainFit, U_stated: dict[str, float] | None = None) -> list[str]:
    """The ISO 230-7 table of a fit as text lines (name, value, U (k = 2), status, notes).
    ``U_stated``: name -> the U to print where the Monte Carlo's is stated
    (:func:`state_monte_carlo_chain`); else the first order's."""
    stated = U_stated or {}

    def U(r: ChainFitRow) -> float:
        return float(stated.get(r.name, r.U))

    out = [f"{fit.chain.name} ({fit.chain.kind}; workpiece side "
           f"{', '.join(fit.chain.workpiece_side) or '-'}, tool side "
           f"{', '.join(fit.chain.tool_side) or '-'}): rank {fit.rank} of {fit.n_unknowns}, "
           f"condition {fit.condition:.3g}",
           f"{'error':8s} {'value':>10s} {'U (k=2)':>8s} unit  status"]
    for r in fit.rows:
        if r.value is None:
            out.append(f"{r.name:8s} {'-':>10s} {'-':>8s} {r.unit:5s} {r.status}: confounded "
                       f"with {', '.join(r.confounded_with) or '-'}; seen by {r.seen_by or '?'}")
        else:
            out.append(f"{r.name:8s} {r.value:10.3f} {U(r):8.3f} {r.unit:5s} {r.status}")
    if fit.motion_rows:
        n_seen = sum(r.value is not None for r in fit.motion_rows)
        out.append(f"error motions (ISO 230-7, Fourier coefficients up to harmonic "
                   f"{fit.harmonics}): {n_seen} of {len(fit.motion_rows)} observable")
        for r in fit.motion_rows:
            if r.value is not None:
                out.append(f"{r.name:14s} {r.value:10.3f} {U(r):8.3f} {r.unit:5s} {r.status}")
                continue
            conf = list(r.confounded_with)
            more = f" and {len(conf) - 6} more" if len(conf) > 6 else ""
            out.append(f"{r.name:14s} {'-':>10s} {'-':>8s} {r.unit:5s} {r.status}: confounded "
                       f"with {', '.join(conf[:6]) or '-'}{more}; seen by {r.seen_by or '?'}")
    out.append("U (k = 2): Type A, the identification's covariance s^2 (J^T W J)^-1 (each "
               "set-up weighted by its own residual's sigma); not included: the instruments' "
               "calibration, the model's adequacy beyond its residuals (docs/uncertainty.md)")
    return out


def setups_from_machine(machine) -> list[ChainSetup]:  # noqa: ANN001 (abbe.formats.machine.Machine)
    """The set-ups of a ``[chain]`` machine file: each probing file's positions fitted as
    spheres (the centres are machine positions: the stylus' radius and the sphere's cancel),
    each R-test file's readings, each rotary ballbar file's lengths. Sigma per set-up:
    probing from the sphere fits' point noise and centre factor, R-test and ballbar 1 um
    until :func:`reweight` re-estimates it."""
    from abbe.analysis.five_axis.spheres import sphere_centres
    from abbe.errors import AbbeInputError
    from abbe.formats.five_axis import read_probe_points, read_rotary_ballbar, read_rtest

    chain = machine.extra["chain"]
    plans = machine.extra["chain_plans"]
    r1, r2 = chain.rotaries
    out = []
    for p in plans.probing.values():
        pts = read_probe_points(p.file, r1, r2)
        sc = sphere_centres(pts, p.sphere_radius_mm + p.stylus_radius_mm, p.radius_tolerance_mm)
        if not bool(np.all(sc.radius_ok)):
            i = int(np.flatnonzero(~sc.radius_ok)[0])
            raise AbbeInputError(
                f"position {int(sc.position[i])}: fitted radius {sc.radius_mm[i]:.4f} mm, "
                f"expected {p.sphere_radius_mm + p.stylus_radius_mm:.4f} +- "
                f"{p.radius_tolerance_mm} mm (sphere + stylus radius)", file=str(p.file),
                field="position")
        noise = sc.point_noise_um() or 1.0
        sigma = max(noise * float(np.sqrt(np.mean(sc.centre_factor) / 3.0)), 0.05)
        out.append(ChainSetup("probe", p.name, p.sphere_mm, sc.angles_deg, sc.centre_mm,
                              p.tip_mm, sigma))
    for r in plans.rtest.values():
        tr = read_rtest(r.file, r1, r2)
        out.append(ChainSetup("rtest", r.name, r.sphere_mm, tr.angles_deg, tr.displacement_um,
                              r.tip_mm, 1.0))
    for b in getattr(plans, "ballbar", {}).values():
        bt = read_rotary_ballbar(b.file, r1, r2)
        out.append(ChainSetup("ballbar", b.name, b.table_ball_mm, bt.angles_deg, bt.radial_um,
                              b.tip_mm, 1.0, b.tool_ball_mm, b.setup))
    return out


def reweight(chain: KinematicChain, setups: list[ChainSetup], fit: ChainFit,
             harmonics: int = 0) -> list[ChainSetup]:
    """The set-ups with each sigma replaced by its RMS residual (um, at least 0.05) after
    ``fit``: blocks of unknown noise weighted by what they show."""
    unk = _unknowns(chain, setups, harmonics)
    mot = dict(fit.motion_values)
    x = np.array([fit.values.get(u[0], mot.get(u[0], fit.setup.get(u[0], 0.0))) for u in unk])
    pred = predict(chain, setups, x, harmonics)
    out = []
    for s, p in zip(setups, pred):
        raw = (np.asarray(s.obs) - p) * (1e3 if s.kind == "probe" else 1.0)
        out.append(replace(s, sigma_um=max(float(np.sqrt(np.mean(raw ** 2))), 0.05)))
    return out


def fit_to_json(fit: ChainFit, setups: list[ChainSetup]) -> dict:
    """The fit as JSON (units in the keys and rows): every identified error with ``u``,
    ``U`` (k = 2) and ``u95`` (1.96 u), and the budget (``uncertainty``)."""
    c = fit.chain

    def row(r: ChainFitRow, held: float) -> dict:
        return {"name": r.name, "value": r.value, "u": r.u, "U": r.U, "u95": r.u95,
                "unit": r.unit, "status": r.status, "confounded_with": list(r.confounded_with),
                "seen_by": r.seen_by, "value_in_convention": held}

    return {"chain": c.name, "kind": c.kind, "workpiece_side": list(c.workpiece_side),
            "tool_side": list(c.tool_side), "rank": fit.rank, "unknowns": fit.n_unknowns,
            "condition": fit.condition, "rms_weighted": fit.rms_weighted,
            "sigma_um": {s.name: s.sigma_um for s in setups},
            "location": [row(r, fit.values[r.name]) for r in fit.rows],
            "harmonics": fit.harmonics,
            "motions": [row(r, fit.motion_values.get(r.name, 0.0)) for r in fit.motion_rows],
            "setup_um": fit.setup,
            "rotary_ballbar": ballbar_summary(fit, setups),
            "uncertainty": {
                "method": "GUM, Type A: the identification's covariance s^2 (J^T W J)^-1 "
                          "at the solution, each set-up's rows weighted by 1 / its sigma",
                "k": K,
                "budget": {"block_sigma_um": {s.name: s.sigma_um for s in setups},
                           "block_sigma_from": "each set-up's RMS residual after a first "
                                               "fit (at least 0.05 um): a Type A "
                                               "evaluation from the block's own residuals",
                           "s2": fit.s2},
                "not_included": ["the instruments' calibration (the probe's scale, an "
                                 "R-test's sensitivity)", "the model's adequacy beyond its "
                                 "residuals"],
                "unobservable": "no U: the plan cannot see the error (its value is the "
                                "convention's, value_in_convention)"}}


def ballbar_summary(fit: ChainFit, setups: list[ChainSetup]) -> dict[str, dict]:
    """Per rotary ballbar test: the axis that turns (the one with the larger range), the
    bar's nominal length (mm), readings, the measured deviation's peak-to-valley less its
    mean and what the fitted chain leaves of it (um; the length zero taken out)."""
    bbs = [s for s in setups if s.kind == "ballbar"]
    if not bbs:
        return {}
    unk = _unknowns(fit.chain, setups, fit.harmonics)
    mot = dict(fit.motion_values)
    x = np.array([fit.values.get(u[0], mot.get(u[0], fit.setup.get(u[0], 0.0))) for u in unk])
    pred = dict(zip((s.name for s in setups), predict(fit.chain, setups, x, fit.harmonics)))
    out = {}
    for s in bbs:
        ang = np.asarray(s.angles_deg, dtype=np.float64)
        turning = fit.chain.rotaries[int(np.argmax(np.ptp(ang, axis=0)))]
        obs = np.asarray(s.obs, dtype=np.float64)
        left = obs - pred[s.name]
        out[s.name] = {
            "turning_axis": turning, "setup": s.balls,
            "length_mm": float(np.linalg.norm(np.subtract(s.tool_ball_mm, s.sphere_mm))),
            "readings": int(obs.size), "measured_pv_um": float(np.ptp(obs - obs.mean())),
            "left_pv_um": float(np.ptp(left)), "left_rms_um": float(np.sqrt(np.mean(left ** 2)))}
    return out
