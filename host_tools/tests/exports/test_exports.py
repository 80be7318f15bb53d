"""abbe export: for every target an independent reader (tests/export_readers.py, written
from the format descriptions) parses the files, applies them as the controller does,
and reproduces the model (abbe.model.reference) within the residual the export reported.
Also: limits are enforced, terms a target cannot hold are named with their size.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from export_readers import READERS, FormatError, read_linuxcnc_comp

from abbe.cli.entry import main as cli_main
from abbe.formats.blob import read_blob, write_blob
from abbe.exports import TARGETS
from abbe.model.backlash import backlash_state
from abbe.model.geometry import circle_points, radial_units
from abbe.model.reference import reversal_values, spatial_error
from abbe.model.table import AXES, OWN_SIGN, Table

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[2]
MACHINE = REPO / "examples" / "vmc500" / "machine.toml"
MODELS = {"fit": HERE / "golden" / "vmc500-fit" / "model.bin",
          "demo": HERE / "golden" / "vmc500-demo" / "model.bin"}


def export(tmp: Path, model: Path, target: str, *opts: str, machine: bool = True) -> tuple[int, Path]:
    out = tmp / target
    args = ["export", str(model), "--format", target, "-o", str(out)]
    if machine:
        args += ["--machine", str(MACHINE)]
    for o in opts:
        args += ["--set", o]
    return cli_main(args), out


def reversal_model() -> Table:
    """The demo model with a position-dependent reversal on every axis (format 1.1
    reversal blocks, um): on X it runs from +24 um at one end to -6 um at the other,
    as the ESS stage's does; Y has a degree-5 block, Z a bow."""
    t = read_blob(MODELS["demo"].read_bytes())
    t.axes["X"].reversal_cheb_um = (7.0, -15.0, 3.0, 1.0)
    t.axes["Y"].reversal_cheb_um = (0.0, 4.0, -2.5, 1.5, 0.75, -0.5)
    t.axes["Z"].reversal_cheb_um = (0.0, 0.0, 6.0)
    return read_blob(write_blob(t))


@pytest.fixture(scope="module")
def model_paths(tmp_path_factory) -> dict[str, Path]:
    """The golden vmc500 models and the reversal model (a blob written here)."""
    p = tmp_path_factory.mktemp("reversal-model") / "model.bin"
    p.write_bytes(write_blob(reversal_model()))
    return {**MODELS, "reversal": p}


@pytest.fixture(scope="module")
def done(tmp_path_factory, model_paths):
    """Every target for every model: (model name, target) -> output directory."""
    res = {}
    for name, model in model_paths.items():
        base = tmp_path_factory.mktemp(name)
        for t in TARGETS:
            rc, out = export(base, model, t)
            assert rc == 0, (name, t)
            res[(name, t)] = out
    return res


def volume_grid(rep: dict) -> np.ndarray:
    ax = rep["volume"]["axes"]
    s = [np.linspace(ax[a]["min_mm"], ax[a]["max_mm"], ax[a]["points"]) for a in AXES]
    g = np.meshgrid(*s, indexing="ij")
    return np.column_stack([v.ravel() for v in g])


def residual(table, corr, pos: np.ndarray, s_model: np.ndarray, s_target: np.ndarray) -> np.ndarray:
    """model error (reference) + the reader's correction, relative to the reference point."""
    ref = np.asarray(table.reference_mm)[None, :]
    one = np.ones((1, 3))
    off = spatial_error(table, ref)[0] + 0.5 * (corr(ref, one) + corr(ref, -one))[0]
    return spatial_error(table, pos, s_model) + corr(pos, s_target) - off


def sign_hold(p: np.ndarray) -> np.ndarray:
    d = np.sign(np.diff(p))
    out = np.empty(p.size)
    nz = np.flatnonzero(d)
    last = d[nz[0]] if nz.size else 0.0
    out[0] = last
    for i, v in enumerate(d, start=1):
        if v != 0:
            last = v
        out[i] = last
    return out


@pytest.mark.parametrize("model", [*MODELS, "reversal"])
@pytest.mark.parametrize("target", list(TARGETS))
def test_reader_reproduces_model_within_reported_residual(done, model_paths, model, target) -> None:
    out = done[(model, target)]
    rep = json.loads((out / "residual.json").read_text())
    table = read_blob(model_paths[model].read_bytes())
    corr = READERS[target](out)
    P = volume_grid(rep)
    r = np.vstack([residual(table, corr, P, np.full(P.shape, s), np.full(P.shape, s))
                   for s in (1.0, -1.0)])
    vr = rep["volume"]["residual"]
    for k, a in enumerate(AXES):
        got = float(np.max(np.abs(r[:, k])))
        assert got == pytest.approx(vr[f"d{a}"]["max_um"], abs=5e-3 + 1e-3 * got), (target, a)
        rms = float(np.sqrt(np.mean(r[:, k] ** 2)))
        assert rms == pytest.approx(vr[f"d{a}"]["rms_um"], abs=5e-3 + 1e-3 * rms)
    # between the grid points: within the reported maximum plus what a grid can miss
    rng = np.random.default_rng(7)
    lo = np.array([rep["volume"]["axes"][a]["min_mm"] for a in AXES])
    hi = np.array([rep["volume"]["axes"][a]["max_mm"] for a in AXES])
    Q = lo + (hi - lo) * rng.random((3000, 3))
    s = np.where(rng.random((3000, 3)) < 0.5, -1.0, 1.0)
    rq = residual(table, corr, Q, s, s)
    assert np.max(np.linalg.norm(rq, axis=1)) <= 1.25 * vr["norm"]["max_um"] + 0.1
    # the machine file's circle, CCW then CW, with each side's direction rule
    c = rep["circles"]["circle1"]
    up = np.linspace(-45.0, 405.0, 4501)
    ang = np.concatenate([up, up[::-1][1:]])
    circ = type("C", (), {"center_mm": c["center_mm"], "radius_mm": c["radius_mm"],
                          "plane": c["plane"]})
    path = circle_points(circ, ang)
    sm = np.column_stack([backlash_state(path[:, j], table.axes[a].backlash_takeup_mm or 1e-9,
                                         sign_hold(path[:, j])[0]) for j, a in enumerate(AXES)])
    st = np.column_stack([sign_hold(path[:, j]) for j in range(3)])
    if target == "marlin":
        S = float(next((w[1:] for w in (out / "marlin.gcode").read_text().split()
                        if w.startswith("S") and w[1:2].isdigit()), "0"))
        st = np.column_stack([backlash_state(path[:, j], S, st[0, j]) if S > 0 else st[:, j]
                              for j in range(3)])
    rc = residual(table, corr, path, sm, st)
    m = (ang >= 0) & (ang < 360)
    m[up.size - 1] = False
    radial = np.sum(rc[m] * radial_units(c["plane"], ang[m]), axis=1)
    assert float(np.max(np.abs(radial))) == pytest.approx(c["residual"]["radial"]["max_um"],
                                                           abs=0.02)


def test_linuxcnc_comp_reproduces_the_positioning_term(done) -> None:
    """Issue 12, test 3: the COMP_FILE applied as LinuxCNC does (linear interpolation,
    held ends, forward / reverse by direction) reproduces the model's positioning term
    of each joint (own term and reversal, on its line through the reference point)
    within the interpolation residual the export reported."""
    for model in MODELS:
        out = done[(model, "linuxcnc-comp")]
        rep = json.loads((out / "residual.json").read_text())
        table = read_blob(MODELS[model].read_bytes())
        _, tabs = read_linuxcnc_comp(out)
        for j, a in enumerate(AXES):
            nom, fwd, rev = tabs[j]
            lo, hi = rep["volume"]["axes"][a]["min_mm"], rep["volume"]["axes"][a]["max_mm"]
            q = np.linspace(lo - 5.0, hi + 5.0, 7919)  # beyond both ends too: held
            pos = np.tile(np.asarray(table.reference_mm), (q.size, 1))
            pos[:, j] = q
            reported = next(t for t in rep["tables"] if t["name"].startswith(f"{a}.comp"))
            for s, trim in ((1.0, fwd), (-1.0, rev)):
                ds = np.zeros_like(pos)
                ds[:, j] = s
                err = spatial_error(table, pos, ds)[:, j]  # um, positioning of joint a
                applied = np.interp(q, nom, trim) * 1e3
                inside = (q >= lo) & (q <= hi)
                gap = np.max(np.abs(err[inside] + applied[inside]))
                assert gap <= reported["interpolation_residual_um"] + 1e-3, (model, a, s)
            B = table.axes[a].backlash_um
            assert np.allclose((fwd - rev) * 1e3, -OWN_SIGN[a] * B, atol=2e-4)


# the targets with a direction-dependent table of each axis' own positioning (forward /
# reverse columns, BACKLASH column, bidirectional pitch, CEC direction pairs)
DIRECTIONAL = ("linuxcnc-comp", "heidenhain-com", "fanuc-pitch", "sinumerik-cec")


@pytest.mark.parametrize("target", DIRECTIONAL)
def test_a_position_dependent_reversal_is_held(tmp_path, done, model_paths, target) -> None:
    """Format 1.1 reversal blocks: what a target applies moving + minus moving -, on each
    axis' line through the reference point, is the model's reversal R(q) there (changing
    size and sign along the travel), within the interpolation residual the export
    reported; the volume residual is that of the same model with a constant reversal.
    (CEC: with 12 tables, so that every axis' direction pair fits beside its cross tables.)"""
    out, const = done[("reversal", target)], done[("demo", target)]
    if target == "sinumerik-cec":
        (rc, out), (rc0, const) = (export(tmp_path / m, model_paths[m], target, "tables=12")
                                   for m in ("reversal", "demo"))
        assert rc == rc0 == 0
    rep = json.loads((out / "residual.json").read_text())
    table = read_blob(model_paths["reversal"].read_bytes())
    corr = READERS[target](out)
    assert not any(k.endswith("backlash / reversal of its positioning") for k in _not_held(out))
    for j, a in enumerate(AXES):
        lo, hi = rep["volume"]["axes"][a]["min_mm"], rep["volume"]["axes"][a]["max_mm"]
        q = np.linspace(lo, hi, 2001)
        pos = np.tile(np.asarray(table.reference_mm), (q.size, 1))
        pos[:, j] = q
        st = np.zeros_like(pos)
        st[:, j] = 1.0
        applied = corr(pos, st)[:, j] - corr(pos, -st)[:, j]        # um
        want = -OWN_SIGN[a] * reversal_values(table, a, q)          # correction = -error
        R = reversal_values(table, a, q)
        assert np.ptp(R) > 5.0                                      # really position dependent
        tol = 2 * rep["volume"]["residual"][f"d{a}"]["max_um"] + 0.01
        assert np.max(np.abs(applied - want)) <= tol, (target, a, np.max(np.abs(applied - want)))
    r_const = json.loads((const / "residual.json").read_text())["volume"]["residual"]["norm"]
    assert rep["volume"]["residual"]["norm"]["max_um"] <= r_const["max_um"] + 0.5


def test_the_reversal_is_named_where_a_target_cannot_hold_it(done, model_paths) -> None:
    """Targets without direction tables name the reversal with its size: max |R(q)| / 2."""
    table = read_blob(model_paths["reversal"].read_bytes())
    for target in ("isg-csv", "klipper-skew", "linuxcnc-matrixkins"):
        nh = _not_held(done[("reversal", target)])
        for a in AXES:
            R = reversal_values(table, a, np.linspace(*table.axes[a].travel_mm, 4001))
            d = nh[f"{a} backlash / reversal of its positioning"]
            assert d["max_um"] == pytest.approx(np.max(np.abs(R)) / 2, rel=2e-2), (target, a)


def test_comp_file_holds_only_triplets_and_both_types_agree(tmp_path) -> None:
    rc0, out0 = export(tmp_path / "t0", MODELS["demo"], "linuxcnc-comp", "type=0")
    rc1, out1 = export(tmp_path / "t1", MODELS["demo"], "linuxcnc-comp", "type=1")
    assert rc0 == rc1 == 0
    for a in AXES:
        lines = (out0 / f"{a}.comp").read_text().splitlines()
        assert len(lines) <= 256 and all(len(ln.split()) == 3 for ln in lines)
    c0, c1 = READERS["linuxcnc-comp"](out0), READERS["linuxcnc-comp"](out1)
    P = np.random.default_rng(1).random((500, 3)) * [500, -400, -300]
    for s in (1.0, -1.0):
        st = np.full(P.shape, s)
        assert np.max(np.abs(c0(P, st) - c1(P, st))) < 2e-3  # um: 7 decimals of mm each


@pytest.mark.parametrize("target,opt,msg", [
    ("linuxcnc-comp", "points=257", "256"),
    ("linuxcnc-comp", "type=2", r"in \[0, 1\], got '2': COMP_FILE_TYPE"),
    ("heidenhain-com", "points=1", r"in \[2, 10000\], got '1'"),
    ("sinumerik-cec", "tables=0", r"in \[1, 128\]"),
    ("marlin", "skew_factor_max=0.00001", "SKEW_FACTOR_MAX"),
    ("fanuc-pitch", "points=3;unit_um=0.001;max_value=1;max_magnification=1", "no interval"),
    ("fanuc-pitch", "total_points=100", "pitch error data points"),
    ("isg-csv", "max_records=4", r"in \[8, 100000\]"),
    ("klipper-skew", "profile=a b", "expected a name.*profile name"),
    ("linuxcnc-comp", "nosuch=1", "unknown option"),
])
def test_limits_are_enforced(tmp_path, capsys, target, opt, msg) -> None:
    rc, out = export(tmp_path, MODELS["demo"], target, *opt.split(";"))
    err = capsys.readouterr().err
    assert rc == 2 and re.search(msg, err), err
    assert len(err.strip().splitlines()) == 1, err
    assert not out.exists()  # nothing written


def _not_held(out: Path) -> dict[str, dict]:
    return {d["item"]: d for d in json.loads((out / "residual.json").read_text())["not_held"]}


def test_terms_a_target_cannot_hold_are_named_with_their_size(done) -> None:
    table = read_blob(MODELS["demo"].read_bytes())
    sxy = table.squareness_urad[0]
    y = np.linspace(-400.0, 0.0, 21) - table.reference_mm[1]
    expect = np.max(np.abs(y)) * sxy * 1e-3  # um: y S_xy in dX
    for target in ("linuxcnc-comp", "fanuc-pitch", "sinumerik-lec"):
        nh = _not_held(done[("demo", target)])
        assert nh["squareness S_xy"]["max_um"] == pytest.approx(expect, rel=1e-3), target
    for target in ("isg-csv", "klipper-skew", "linuxcnc-matrixkins"):
        nh = _not_held(done[("demo", target)])
        for a in AXES:
            d = nh[f"{a} backlash / reversal of its positioning"]
            assert d["max_um"] == pytest.approx(abs(table.axes[a].backlash_um) / 2, rel=1e-3)
    # what a target holds is not reported as missing
    assert "squareness S_xy" not in _not_held(done[("demo", "isg-csv")])
    assert not any(k.endswith("backlash / reversal of its positioning")
                   for k in _not_held(done[("demo", "linuxcnc-comp")]))


@pytest.mark.parametrize("make", [lambda: read_blob(MODELS["demo"].read_bytes()), reversal_model])
def test_reversal_is_the_model_difference_of_the_two_directions(make) -> None:
    """terms.reversal_um (the one place the exports take the reversal from) agrees with
    the reference evaluation of both directions, constant or position dependent."""
    from abbe.exports.terms import line_positions, reversal_um
    table = make()
    for j, a in enumerate(AXES):
        q = np.linspace(*table.axes[a].travel_mm, 57)
        pos = line_positions(table, a, q)
        ds = np.zeros_like(pos)
        ds[:, j] = 1.0
        diff = spatial_error(table, pos, ds)[:, j] - spatial_error(table, pos, -ds)[:, j]
        assert np.allclose(diff, OWN_SIGN[a] * reversal_um(table, a, q), atol=1e-9)


def test_readers_refuse_what_the_controller_refuses(tmp_path) -> None:
    from export_readers import load_comp_file
    p = tmp_path / "bad.comp"
    p.write_text("0 0 0\n0 0 0\n")
    with pytest.raises(FormatError):
        load_comp_file(p, 1)
    p.write_text("".join(f"{i} 0 0\n" for i in range(257)))
    with pytest.raises(FormatError):
        load_comp_file(p, 1)
    p.write_text("# comment\n0 0 0\n")  # LinuxCNC stops at the first non-triplet line
    assert load_comp_file(p, 1)[0].size == 0
