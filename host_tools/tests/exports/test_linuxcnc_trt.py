"""abbe export --format linuxcnc-trt and grblhal-rtcp-ac (issue 23 parts 3a, 4).

* golden files of examples/trunnion5ax (golden/trunnion5ax-fit: model_five.bin is
  ``abbe fit examples/trunnion5ax/machine.toml``'s, five_axis.json its ``blob`` entry);
* an independent reader (tests/export_readers.py, from docs/exports.md) applies the
  written pins as trtfuncs.c does, on the poses docs/exports.md describes, and the exact
  model (abbe.model.five_axis) gives back the residual.json figures;
* a machine whose only errors are what trt holds (both kinds) is corrected exactly,
  which pins down every sign of the mapping;
* bad input exits 2 and writes nothing.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from export_readers import read_grblhal_rtcp, read_linuxcnc_trt, rtcp_joints, trt_joints
from golden_compare import compare_dir

from abbe.cli.entry import main as cli_main
from abbe.formats.five_axis_blob import write_five_blob
from abbe.formats.machine import load_machine
from abbe.model.five_axis import (
    FiveAxisErrors,
    linear_axis_errors,
    nominal_joints,
    table_transform,
)

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[2]
MACHINE = REPO / "examples" / "trunnion5ax" / "machine.toml"
GOLDEN = HERE / "golden" / "trunnion5ax-fit"
MODEL = GOLDEN / "model_five.bin"

BC_MACHINE = """[machine]
name = "bc test"
[axes.X]
travel_mm = [-300.0, 300.0]
[axes.Y]
travel_mm = [-200.0, 200.0]
[axes.Z]
travel_mm = [-400.0, 100.0]
[reference]
point_mm = [0.0, 0.0, 0.0]
[rotary]
kinematics = "xyzbc-trt"
x_rot_point_mm = 10.0
y_rot_point_mm = -5.0
z_rot_point_mm = -250.0
x_offset_mm = 30.0
z_offset_mm = -60.0
tool_length_mm = 100.0
[rotary.B]
travel_deg = [-100.0, 100.0]
[rotary.C]
travel_deg = [-360.0, 360.0]
[indexer.C]
file = "indexer_C.csv"
"""


def export(out: Path, model: Path, machine: Path | None = MACHINE, *opts: str,
           target: str = "linuxcnc-trt") -> int:
    args = ["export", str(model), "--format", target, "-o", str(out)]
    if machine is not None:
        args += ["--machine", str(machine)]
    for o in opts:
        args += ["--set", o]
    return cli_main(args)


TARGETS5 = ("linuxcnc-trt", "grblhal-rtcp-ac")
#: how close the reader's residual is to residual.json, um (rtcp_ac computes in float32:
#: writer and reader both do, in a different order; float32 alone is 0.27 um at 900 mm)
AGREE_UM = {"linuxcnc-trt": 2e-3, "grblhal-rtcp-ac": 0.1}


@pytest.mark.parametrize("target", TARGETS5)
def test_golden_files(tmp_path, target) -> None:
    assert export(tmp_path / target, MODEL, target=target) == 0
    assert compare_dir(tmp_path / target, GOLDEN / target) == []


# ---- the independent check: poses as docs/exports.md describes them, trtfuncs.c's
# ---- arithmetic (export_readers.trt_joints), the exact model


def doc_poses(geom, travel, n_lin=5, n_tilt=9, n_c=12, tcp=(100.0, 0.0, 50.0), tilt_max=90.0):
    """(volume (W, ANG), path (W, ANG)) per docs/exports.md, "linuxcnc-trt"."""
    tilt, _ = geom.rotaries
    axes = [np.linspace(*travel[a], n_lin) for a in "XYZ"]
    ang = [(a, c) for a in np.linspace(*geom.travel_deg[tilt], n_tilt)
           for c in sorted(set(np.clip(np.arange(n_c) * 360.0 / n_c, *geom.travel_deg["C"])))]
    W, A = [], []
    for x in axes[0]:
        for y in axes[1]:
            for z in axes[2]:
                for a, c in ang:
                    T = np.linalg.inv(table_transform(geom, None, np.array([[a, c]]))[0])
                    W.append(T[:3, :3] @ np.array([x, y, z]) + T[:3, 3])
                    A.append((a, c))
    s = np.linspace(0.0, 1.0, 361)
    lo, hi = geom.travel_deg[tilt]
    up = np.column_stack([np.clip(tilt_max * np.sin(np.pi * s), lo, hi), 360.0 * s])
    dn = np.column_stack([np.clip(-tilt_max * np.sin(np.pi * s), lo, hi), 360.0 * s[::-1]])
    pa = np.vstack([up, dn[1:]])
    pw = np.tile(np.asarray(geom.rot_point_mm) + np.asarray(tcp), (len(pa), 1))
    return (np.array(W), np.array(A)), (pw, pa)


def exact_position_error(geom, errs, W, A, q, t) -> np.ndarray:
    """Tool tip (joints + linear-axis errors) minus the workpiece point where the actual
    table puts it at joint angles t, um."""
    T = table_transform(geom, errs, t)
    dl, _ = linear_axis_errors(geom, errs, q)
    return (q + dl * 1e-3 - (np.einsum("nij,nj->ni", T[:, :3, :3], W) + T[:, :3, 3])) * 1e3


def reader_joints(out: Path, target: str, geom):
    """(W, A) -> (joints mm, joint angles deg in the model's convention) from the files."""
    if target == "linuxcnc-trt":
        comp, pins, home = read_linuxcnc_trt(out)
        assert comp == f"{geom.kind}-kins"
        shift = np.array([home[3], home[4]])  # joints 3 (tilt), 4 (C); HOME_OFFSET today 0
        return lambda W, A: (trt_joints(geom.kind, pins, W, A), A - shift), (pins, home)
    a, c = read_grblhal_rtcp(out)
    return lambda W, A: (rtcp_joints(a, c, W, A), A), (a, c)


def reader_residual(out: Path, machine: Path, model_errs=None, target="linuxcnc-trt"):
    """{"volume"/"tcp_path": (residual norms, uncompensated norms)} from the written files."""
    from abbe.formats.five_axis_blob import read_five_blob

    m = load_machine(machine)
    geom = m.five_axis.geometry
    errs = model_errs or read_five_blob((out.parent / "model_five.bin").read_bytes()).errors
    joints, written = reader_joints(out, target, geom)
    travel = {a: m.axes[a].travel_mm for a in "XYZ"}
    vol, path = doc_poses(geom, travel)
    got = {}
    for key, (W, A) in (("volume", vol), ("tcp_path", path)):
        q, t = joints(W, A)
        r = exact_position_error(geom, errs, W, A, q, t)
        u = exact_position_error(geom, errs, W, A, nominal_joints(geom, W, A), A)
        got[key] = (np.linalg.norm(r, axis=1), np.linalg.norm(u, axis=1))
    return got, written


def check_against_report(out: Path, got, tol: float = 2e-3) -> None:
    rep = json.loads((out / "residual.json").read_text())
    for key, (r, u) in got.items():
        for which, v in (("residual", r), ("uncompensated", u)):
            want = rep[key][which]["norm"]
            assert abs(float(np.max(v)) - want["max_um"]) < tol, (key, which)
            assert abs(float(np.sqrt(np.mean(v ** 2))) - want["rms_um"]) < tol, (key, which)


@pytest.mark.parametrize("target", TARGETS5)
def test_reader_reproduces_the_residual_of_the_example(tmp_path, target) -> None:
    (tmp_path / "model_five.bin").write_bytes(MODEL.read_bytes())
    (tmp_path / "five_axis.json").write_bytes((GOLDEN / "five_axis.json").read_bytes())
    out = tmp_path / "trt"
    assert export(out, tmp_path / "model_five.bin", target=target) == 0
    got, _ = reader_residual(out, MACHINE, target=target)
    check_against_report(out, got, AGREE_UM[target])
    # the identified pivot takes a share of the error off the tool-centre-point path
    r, u = got["tcp_path"]
    assert np.max(r) < 0.5 * np.max(u)
    rep = json.loads((out / "residual.json").read_text())
    names = {d["item"] for d in rep["not_held"]}
    assert {"EB0A", "EC0A"} <= names and not names & {"EX0C", "EY0A", "EZ0A"}
    assert "EA0C" in rep["not_observable"]["items"]


HELD_ERRORS = {"xyzac-trt": {"EX0C": 30.0, "EY0C": -20.0, "EY0A": 15.0, "EZ0A": -25.0,
                             "EA0A": 40.0, "EC0C": -60.0},
               "xyzbc-trt": {"EX0C": -18.0, "EY0C": 22.0, "EX0B": 35.0, "EZ0B": 12.0,
                             "EB0B": -45.0, "EC0C": 70.0}}


def machine_for(kind: str, tmp_path: Path) -> Path:
    """The example's machine file (A/C) or BC_MACHINE written into tmp_path."""
    if kind == "xyzac-trt":
        return MACHINE
    machine = tmp_path / "bc.toml"
    machine.write_text(BC_MACHINE)
    return machine


@pytest.mark.parametrize("kind", sorted(HELD_ERRORS))
def test_what_trt_holds_is_corrected_exactly(tmp_path, kind) -> None:
    machine = machine_for(kind, tmp_path)
    geom = load_machine(machine).five_axis.geometry
    errs = FiveAxisErrors(location=dict(HELD_ERRORS[kind]))
    (tmp_path / "model_five.bin").write_bytes(write_five_blob(geom, errs))
    out = tmp_path / "trt"
    assert export(out, tmp_path / "model_five.bin", machine) == 0
    got, (pins, home) = reader_residual(out, machine, errs)
    check_against_report(out, got)
    for key, (r, u) in got.items():
        assert np.max(r) < 0.01, key      # nm text of the pins, 1e-9 deg of the offsets
        assert np.max(u) > 10.0, key
    e = HELD_ERRORS[kind]
    assert pins["x-rot-point"] == pytest.approx(geom.rot_point_mm[0] + e["EX0C"] * 1e-3, abs=1e-9)
    tilt = geom.tilt
    assert home[3] == pytest.approx(np.degrees(e[f"E{tilt}0{tilt}"] * 1e-6), abs=1e-9)
    assert home[4] == pytest.approx(np.degrees(e["EC0C"] * 1e-6), abs=1e-9)
    assert json.loads((out / "residual.json").read_text())["not_held"] == []


def test_rtcp_ac_holds_the_two_centres(tmp_path) -> None:
    """Only EX0C, EY0C, EY0A, EZ0A: corrected to the settings' 1 um steps and float32;
    the angular zeros are named, not held."""
    geom = load_machine(MACHINE).five_axis.geometry
    held = {"EX0C": 30.0, "EY0C": -20.0, "EY0A": 15.0, "EZ0A": -25.0}
    (tmp_path / "model_five.bin").write_bytes(write_five_blob(geom, FiveAxisErrors(location=held)))
    out = tmp_path / "g"
    assert export(out, tmp_path / "model_five.bin", target="grblhal-rtcp-ac") == 0
    got, (a, c) = reader_residual(out, MACHINE, FiveAxisErrors(location=held), "grblhal-rtcp-ac")
    check_against_report(out, got, AGREE_UM["grblhal-rtcp-ac"])
    for key, (r, u) in got.items():
        assert np.max(r) < 1.0, key     # 0.5 um rounding per setting
        assert np.max(u) > 10.0, key
    assert a + c == pytest.approx(np.array(geom.rot_point_mm) + [0.030, -0.020, 0.0], abs=6e-4)
    assert a[1:] == pytest.approx(np.array(geom.pivot("A"))[1:] + [0.015, -0.025], abs=6e-4)
    with_zero = FiveAxisErrors(location={**held, "EA0A": 40.0})
    (tmp_path / "z.bin").write_bytes(write_five_blob(geom, with_zero))
    assert export(tmp_path / "z", tmp_path / "z.bin", target="grblhal-rtcp-ac") == 0
    rep = json.loads((tmp_path / "z" / "residual.json").read_text())
    assert [d["item"] for d in rep["not_held"]] == ["EA0A"]
    assert rep["tcp_path"]["residual"]["norm"]["max_um"] > 1.0


def test_a_tilt_is_named_with_its_size(tmp_path) -> None:
    geom = load_machine(MACHINE).five_axis.geometry
    errs = FiveAxisErrors(location={"EY0A": 10.0, "EB0A": 50.0})
    (tmp_path / "m.bin").write_bytes(write_five_blob(geom, errs))
    assert export(tmp_path / "o", tmp_path / "m.bin") == 0
    rep = json.loads((tmp_path / "o" / "residual.json").read_text())
    (item,) = rep["not_held"]
    assert item["item"] == "EB0A"
    # what is left is the tilt's own error (up to second order)
    assert abs(rep["volume"]["residual"]["norm"]["max_um"] - item["volume"]["max_um"]) < 0.05
    assert rep["volume"]["residual"]["norm"]["max_um"] > 1.0


def test_bad_input_exits_2_and_writes_nothing(tmp_path, capsys) -> None:
    vmc_model = HERE / "golden" / "vmc500-fit" / "model.bin"
    vmc_machine = REPO / "examples" / "vmc500" / "machine.toml"
    bc = tmp_path / "bc.toml"
    bc.write_text(BC_MACHINE)
    bad = tmp_path / "short.bin"
    bad.write_bytes(MODEL.read_bytes()[:300])
    cases = [(vmc_model, MACHINE, (), "rotary section"),
             (MODEL, None, (), "--machine"),
             (MODEL, vmc_machine, (), "[rotary]"),
             (MODEL, bc, (), "xyzac-trt"),
             (MODEL, MACHINE, ("tilt_joint=99",), "tilt_joint"),
             (MODEL, MACHINE, ("tcp_point=X=nan",), "tcp_point"),
             (MODEL, MACHINE, ("c_joint=3",), "both joint 3"),
             (bad, MACHINE, (), "short.bin")]
    for i, (model, machine, opts, words) in enumerate(cases):
        out = tmp_path / f"out{i}"
        assert export(out, model, machine, *opts) == 2, (i, words)
        err = capsys.readouterr().err
        assert words in err, (i, err)
        assert not out.exists()
    out = tmp_path / "bc-grbl"
    geom = load_machine(bc).five_axis.geometry
    (tmp_path / "bc.bin").write_bytes(write_five_blob(geom, FiveAxisErrors()))
    assert export(out, tmp_path / "bc.bin", bc, target="grblhal-rtcp-ac") == 2
    assert "A/C" in capsys.readouterr().err and not out.exists()


@pytest.mark.parametrize("kind", sorted(HELD_ERRORS))
def test_component_table_is_the_same_machine(tmp_path, kind) -> None:
    """abbe-five.bin (the HAL component's table) with the written pins as its geometry and
    the joints reading the true angle (joint = t + E0) describes the model's machine: the
    table transforms agree at every angle, and it holds none of what trt holds."""
    from abbe.formats.five_axis_blob import read_five_blob

    machine = machine_for(kind, tmp_path)
    geom = load_machine(machine).five_axis.geometry
    tilt = geom.tilt
    rng = np.random.default_rng(23)
    loc = dict(HELD_ERRORS[kind])
    loc.update({"EA0C": 80.0, "EB0C": -60.0, f"E{'B' if tilt == 'A' else 'A'}0{tilt}": 120.0,
                f"EC0{tilt}": -90.0})
    motions = {(a, c): np.concatenate([[0.0, 0.0] if c in "XY" and a == "C" else
                                       rng.normal(0, 3, 2), rng.normal(0, 3, 2)])
               for a in geom.rotaries for c in ("X", "Y", "Z", "A", "B", "C")}
    for (a, c), v in motions.items():  # radial and tilt motions start at harmonic 2
        if "XYZ"["ABC".index(a) if a != "C" else 2] != c and c in "XYZ" or (c in "ABC" and c != a):
            v[:2] = 0.0
    errs = FiveAxisErrors(location=loc, motions=motions)
    (tmp_path / "model_five.bin").write_bytes(write_five_blob(geom, errs))
    out = tmp_path / "trt"
    assert export(out, tmp_path / "model_five.bin", machine) == 0
    _comp, pins, home = read_linuxcnc_trt(out)
    comp = read_five_blob((out / "abbe-five.bin").read_bytes())
    held = {"EX0C", "EY0C", "EC0C", *{"A": ("EY0A", "EZ0A", "EA0A"),
                                      "B": ("EX0B", "EZ0B", "EB0B")}[tilt]}
    assert all(comp.errors.location.get(n, 0.0) == 0.0 for n in held)
    assert comp.rot_point_mm == pytest.approx((pins["x-rot-point"], pins["y-rot-point"],
                                               pins["z-rot-point"]), abs=1e-9)
    cg = comp.geometry()
    full = read_five_blob((tmp_path / "model_five.bin").read_bytes())
    t_old = np.column_stack([rng.uniform(-90, 90, 200), rng.uniform(-360, 360, 200)])
    t_new = t_old + np.array([home[3], home[4]])[None, :]
    Tf = table_transform(full.geometry(), full.errors, t_old)
    Tc = table_transform(cg, comp.errors, t_new)
    p = rng.uniform(-200, 200, (200, 3))
    d = (np.einsum("nij,nj->ni", Tf[:, :3, :3] - Tc[:, :3, :3], p) + Tf[:, :3, 3] - Tc[:, :3, 3])
    # mm: the pins' and the table's 1 nm steps, and the tilt line's pivot sliding along its
    # own axis by the C centre's shift (x for A, y for B), which its tilts turn into a lever
    slide_mm = abs(loc["EX0C" if tilt == "A" else "EY0C"]) * 1e-3
    tilts = [loc[n] for n in (("EB0A", "EC0A") if tilt == "A" else ("EA0B", "EC0B"))]
    assert float(np.max(np.abs(d))) < 2e-6 + slide_mm * float(np.hypot(*tilts)) * 1e-6
