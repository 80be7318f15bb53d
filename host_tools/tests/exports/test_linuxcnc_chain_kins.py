"""``abbe export`` linuxcnc-5axiskins / linuxcnc-maxkins / linuxcnc-xyzab-tdr from a fitted
chain: the written HAL / INI text read back here without abbe's writer (a regex and
configparser), the module's inverse kinematics written here again from LinuxCNC's
sources, and a true machine written here as rotations about the fitted axis lines
(Rodrigues, the product of exponentials at the home pose). Held errors leave the quantum
of the written text; every error leaves abbe's reported residual, pose by pose; bad
input exits 2 with nothing written."""

from __future__ import annotations

import configparser
import json
import re
from pathlib import Path

import numpy as np
import pytest

from abbe.cli.entry import main
from abbe.formats.machine import load_machine
from cases.chain_suite import CHAINS

D2R = np.pi / 180.0
#: a small work volume keeps the test quick (the poses are the residual's, not the check's)
SMALL = ["volume_points=3", "rotary_points=5"]
FILES = {"linuxcnc-5axiskins": "head-head-5axiskins.toml",
         "linuxcnc-maxkins": "head-table-maxkins.toml",
         "linuxcnc-xyzab-tdr": "table-dual-rotary-xyzab.toml"}
HELD = {"linuxcnc-5axiskins": {"EZ0B": -26.7, "EB0B": -115.6, "EC0C": 69.6},
        "linuxcnc-maxkins": {"EZ0B": 31.2, "EX0C": -23.4, "EY0C": 17.9, "EB0B": 84.0,
                             "EC0C": -52.5},
        "linuxcnc-xyzab-tdr": {"EX0B": 12.5, "EZ0B": -19.1, "EY0A": -34.8, "EZ0A": 26.7,
                               "EA0A": -115.6, "EB0B": 69.6}}
UNHELD = {"EX0B": -34.8, "EX0C": -3.8, "EY0C": -19.1, "EA0B": -68.1, "EC0B": -17.6,
          "EA0C": 44.7, "EB0C": 47.8, "EB0A": -30.2, "EC0A": 22.0}
NAMES = {"A": ("EY0A", "EZ0A", "EB0A", "EC0A", "EA0A"), "B": ("EX0B", "EZ0B", "EA0B", "EC0B", "EB0B"),
         "C": ("EX0C", "EY0C", "EA0C", "EB0C", "EC0C")}


def _fit_json(path: Path, chain, values: dict[str, float]) -> Path:
    rows = []
    for ax in chain.rotaries:
        for n in NAMES[ax]:
            rows.append({"name": n, "value": values.get(n, 0.0), "u95": 1.0,
                         "unit": "urad" if n[1] in "ABC" else "um", "status": "identified"})
    path.write_text(json.dumps({"chain": chain.name, "kind": chain.kind, "location": rows}))
    return path


def _read(out: Path) -> tuple[dict[str, float], dict[int, float]]:
    """The pins (name -> value) and the joints' HOME_OFFSET from the written text."""
    pins = {}
    for f in out.glob("*.hal"):
        for line in f.read_text().splitlines():
            m = re.fullmatch(r"setp\s+\S+?\.([a-z-]+)\s+(-?\d+\.\d+)", line)
            if m:
                pins[m.group(1)] = float(m.group(2))
            else:
                assert line.startswith("#"), line
    ini = configparser.ConfigParser(comment_prefixes=("#",))
    ini.read_string(next(out.glob("*.ini")).read_text())
    home = {int(s.split("_")[1]): float(ini[s]["HOME_OFFSET"]) for s in ini.sections()}
    return pins, home


def _rod(u: np.ndarray, t: float) -> np.ndarray:
    u = u / np.linalg.norm(u)
    k = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    return np.eye(3) + np.sin(t) * k + (1.0 - np.cos(t)) * (k @ k)


def _turn(x: np.ndarray, chain, axis: str, err: dict[str, float], t_deg: float,
          base: np.ndarray) -> np.ndarray:
    """x turned about ``axis``' fitted line by the joint angle t (deg): the line through
    pivot + its position errors, its direction the machine axis tilted, the angle
    direction * t + E0 (ISO 230-1 location errors, um / urad)."""
    k = "ABC".index(axis)
    n = NAMES[axis]
    others = [i for i in range(3) if i != k]
    p = base + chain.pivot(axis)
    tilt = np.zeros(3)
    for j, i in enumerate(others):
        p[i] += err.get(n[j], 0.0) * 1e-3
        tilt[i] = err.get(n[2 + j], 0.0) * 1e-6
    u = np.zeros(3)
    u[k] = 1.0
    u = u + np.cross(tilt, u)
    ang = chain.axis(axis).direction * t_deg * D2R + err.get(n[4], 0.0) * 1e-6
    return p + _rod(u, ang) @ (x - p)


def _tool_minus_work(chain, err, q: np.ndarray, angles: dict[str, float], w: np.ndarray):
    """The true machine: tool tip (the controlled point, carried by the tool-side axes,
    the one next to the tool first) minus the workpiece point (carried by the
    workpiece-side axes, the one next to the workpiece first), mm."""
    tip = q.copy()
    for axis in reversed(chain.tool_side):
        tip = _turn(tip, chain, axis, err, angles[axis], q)
    x = w.copy()
    for axis in chain.workpiece_side:
        x = _turn(x, chain, axis, err, angles[axis], np.zeros(3))
    return tip - x


def _module_joints(fmt: str, pins: dict[str, float], P: np.ndarray, ang: dict[str, float]):
    """The module's inverse (LinuxCNC sources: 5axiskins.c, maxkins.c,
    xyzab_tdr_kins.comp type 1), tool offset 0."""
    if fmt == "linuxcnc-5axiskins":
        L, b, c = pins["pivot-length"], ang["B"] * D2R, ang["C"] * D2R
        return P - L * np.array([np.sin(b) * np.cos(c), np.sin(b) * np.sin(c), 1 - np.cos(b)])
    if fmt == "linuxcnc-maxkins":
        L, b = pins["pivot-length"], ang["B"] * D2R
        r, th = np.hypot(P[0], P[1]), np.arctan2(P[1], P[0]) - ang["C"] * D2R
        return np.array([r * np.cos(th) - L * np.sin(b), r * np.sin(th), P[2] - L * (1 - np.cos(b))])
    sa, ca, sb, cb = (np.sin(ang["A"] * D2R), np.cos(ang["A"] * D2R), np.sin(ang["B"] * D2R),
                      np.cos(ang["B"] * D2R))
    rx, ry, rz, dx, dz = (pins[k] for k in ("x-rot-point", "y-rot-point", "z-rot-point",
                                             "x-offset", "z-offset"))
    qx, qy, qz = P[0] - rx - dx, P[1] - ry, P[2] - rz - dz
    return np.array([cb * qx + sa * sb * qy - ca * sb * qz + cb * dx - sb * dz + rx,
                     ca * qy + sa * qz + ry,
                     sb * qx - sa * cb * qy + ca * cb * qz + sb * dx + cb * dz + rz])


JOINTS = {"linuxcnc-5axiskins": {"B": 3, "C": 4}, "linuxcnc-maxkins": {"X": 0, "Y": 1, "B": 4, "C": 5},
          "linuxcnc-xyzab-tdr": {"A": 3, "B": 4}}


def _independent(fmt, chain, err, pins, home, w, ang):
    """Tool minus workpiece point (um) of the true machine at the joints the module
    commands for w at ang, with the written home offsets (today's are 0)."""
    e = np.array([home.get(JOINTS[fmt].get("X", -1), 0.0), home.get(JOINTS[fmt].get("Y", -1), 0.0), 0.0])
    e = -e  # X/Y HOME_OFFSET = 0 - the C line's offset: the new origin sits at +e
    q = _module_joints(fmt, pins, w - e, ang) + e
    phys = {a: ang[a] - home[JOINTS[fmt][a]] for a in chain.rotaries}
    return _tool_minus_work(chain, err, q, phys, w) * 1e3


def _poses(chain, rng, n=40):
    out = []
    for _ in range(n):
        w = rng.uniform([-150, -150, -200], [150, 150, 50])
        ang = {a: float(rng.uniform(*np.clip(chain.travel_deg[a], -150, 150))) for a in chain.rotaries}
        out.append((w, ang))
    return out


@pytest.mark.parametrize("fmt", sorted(FILES))
def test_held_errors_leave_the_quantum_and_the_residual_is_abbes(tmp_path: Path, fmt: str) -> None:
    from abbe.exports import run_chain_export
    from abbe.exports.chain_kins import pose_error

    machine = CHAINS / FILES[fmt]
    chain = load_machine(machine).extra["chain"]
    rng = np.random.default_rng(5)
    # 1. only what the module holds: the true machine meets the programmed point to 1 nm
    fit = _fit_json(tmp_path / "held.json", chain, HELD[fmt])
    assert main(["export", str(fit), "-f", fmt, "-o", str(tmp_path / "h"), "--machine",
                 str(machine), "--set", *SMALL]) == 0
    pins, home = _read(tmp_path / "h")
    report = json.loads((tmp_path / "h" / "residual.json").read_text())
    assert report["volume"]["residual"]["norm"]["max_um"] <= 0.005
    assert report["volume"]["uncompensated"]["norm"]["max_um"] > 20.0
    worst_held = 0.0
    for w, ang in _poses(chain, rng):
        worst_held = max(worst_held, float(np.linalg.norm(
            _independent(fmt, chain, HELD[fmt], pins, home, w, ang))))
    assert worst_held <= 0.005, worst_held
    # the same text on the nominal machine misses by the held errors themselves
    miss = max(float(np.linalg.norm(_independent(fmt, chain, {}, pins, home, w, ang)))
               for w, ang in _poses(chain, rng, 10))
    assert miss > 10.0
    # 2. every error: what remains is what abbe reports, pose by pose (tilts and off-axis
    # translations are not held)
    err = {**{n: v for n, v in UNHELD.items() if n in chain.location_names()}, **HELD[fmt]}
    fit = _fit_json(tmp_path / "all.json", chain, err)
    assert main(["export", str(fit), "-f", fmt, "-o", str(tmp_path / "a"), "--machine",
                 str(machine), "--set", *SMALL]) == 0
    pins, home = _read(tmp_path / "a")
    exp, rep = run_chain_export(fit, fmt, SMALL, load_machine(machine))
    assert rep["volume"]["residual"]["norm"]["max_um"] > 1.0  # the tilts remain
    assert {d["item"] for d in rep["not_held"]} == set(err) - set(HELD[fmt])
    worst = 0.0
    for w, ang in _poses(chain, rng):
        mine = _independent(fmt, chain, err, pins, home, w, ang)
        A = np.array([[ang[a] for a in chain.rotaries]])
        q, t = exp.joints(w[None, :], A)
        theirs, _rot = pose_error(chain, exp_errors(err), w[None, :], A, q, t)
        assert np.max(np.abs(mine - theirs[0])) <= 2e-3, (w, ang, mine, theirs)
        worst = max(worst, float(np.linalg.norm(mine)))
    assert worst > 1.0


def exp_errors(err):
    from abbe.model.five_axis_base import FiveAxisErrors
    return FiveAxisErrors(location=dict(err))


def test_written_values_follow_the_fit(tmp_path: Path) -> None:
    """The mapping stated in docs/exports.md, read from the text: tdr's pins and zeros."""
    fmt = "linuxcnc-xyzab-tdr"
    machine = CHAINS / FILES[fmt]
    chain = load_machine(machine).extra["chain"]
    fit = _fit_json(tmp_path / "f.json", chain, HELD[fmt])
    assert main(["export", str(fit), "-f", fmt, "-o", str(tmp_path / "o"), "--machine",
                 str(machine), "--set", "a_home_offset_deg=10", *SMALL]) == 0
    pins, home = _read(tmp_path / "o")
    pa, pb = chain.pivot("A"), chain.pivot("B")
    assert pins["x-rot-point"] == pytest.approx(pb[0] + 0.0125, abs=1e-6)
    assert pins["z-rot-point"] == pytest.approx(pb[2] - 0.0191, abs=1e-6)
    assert pins["y-rot-point"] == pytest.approx(pa[1] - 0.0348, abs=1e-6)
    assert pins["z-rot-point"] + pins["z-offset"] == pytest.approx(pa[2] + 0.0267, abs=1e-6)
    # direction -1: the joint reads -E0 more
    assert home[3] == pytest.approx(10.0 + np.degrees(115.6e-6), abs=1e-9)
    assert home[4] == pytest.approx(-np.degrees(69.6e-6), abs=1e-9)
    # an error motion of a fit with harmonics: not exportable, said and sized (not dropped)
    doc = json.loads(fit.read_text())
    doc["motions"] = [{"name": "EXA(A) sin2", "value": 0.5, "u95": 0.1, "unit": "um",
                       "status": "identified"}]
    fit.write_text(json.dumps(doc))
    assert main(["export", str(fit), "-f", fmt, "-o", str(tmp_path / "m"), "--machine",
                 str(machine), "--set", *SMALL]) == 0
    rep = json.loads((tmp_path / "m" / "residual.json").read_text())
    assert any("not exportable" in n and "EXA(A)" in n for n in rep["notes"])
    assert [d["item"] for d in rep["not_held"] if d["kind"] == "error motion"] == ["EXA(A)"]


def test_error_motions_are_not_exportable_and_sized(tmp_path: Path, capsys) -> None:
    """maxkins (head-table): the table C's angular motion ECC(C) = 50 urad sin C turns the
    workpiece about C's line; on the tool-centre-point path (C one turn, the point (50, 20,
    -50) mm, 53.85 mm off the line) the tool misses it by 50 urad x 53.85 mm = 2.693 um at
    C = 90 deg (by hand). No module parameter holds it: listed as not held with that size,
    and the residual (the held location errors written exactly) is it."""
    fmt = "linuxcnc-maxkins"
    machine = CHAINS / FILES[fmt]
    chain = load_machine(machine).extra["chain"]
    fit = _fit_json(tmp_path / "f.json", chain, HELD[fmt])
    doc = json.loads(fit.read_text())
    doc["harmonics"] = 1
    doc["motions"] = [{"name": "ECC(C) sin1", "value": 50.0, "u95": 1.0, "unit": "urad",
                       "status": "identified"},
                      {"name": "ECC(C) cos1", "value": None, "u95": None, "unit": "urad",
                       "status": "fixed at 0"}]
    fit.write_text(json.dumps(doc))
    assert main(["export", str(fit), "-f", fmt, "-o", str(tmp_path / "o"), "--machine",
                 str(machine), "--set", *SMALL]) == 0
    rep = json.loads((tmp_path / "o" / "residual.json").read_text())
    mot = [d for d in rep["not_held"] if d["kind"] == "error motion"]
    assert [d["item"] for d in mot] == ["ECC(C)"] and "no parameter" in mot[0]["reason"]
    assert mot[0]["coefficients"] == {"sin1": 50.0}
    assert mot[0]["tcp_path"]["max_um"] == pytest.approx(50e-6 * np.hypot(50.0, 20.0) * 1e3,
                                                          abs=0.005)
    assert rep["tcp_path"]["residual"]["norm"]["max_um"] == pytest.approx(
        mot[0]["tcp_path"]["max_um"], abs=0.01)
    assert "ECC(C) cos1" in rep["not_observable"]["items"]
    # a coefficient that is not one of this chain's: refused, nothing written
    doc["motions"][0]["name"] = "ECA(A) sin1"
    fit.write_text(json.dumps(doc))
    assert main(["export", str(fit), "-f", fmt, "-o", str(tmp_path / "x"), "--machine",
                 str(machine), "--set", *SMALL]) == 2
    assert "motions[0].name" in capsys.readouterr().err and not (tmp_path / "x").exists()
    doc["motions"][0].update(name="ECC(C) sin1", value=float("inf"))
    fit.write_text(json.dumps(doc).replace("Infinity", "1e999"))
    assert main(["export", str(fit), "-f", fmt, "-o", str(tmp_path / "x"), "--machine",
                 str(machine), "--set", *SMALL]) == 2
    assert "motions[0].value" in capsys.readouterr().err


def test_bad_inputs_exit_2(tmp_path: Path, capsys) -> None:
    machine = CHAINS / FILES["linuxcnc-xyzab-tdr"]
    chain = load_machine(machine).extra["chain"]
    good = _fit_json(tmp_path / "g.json", chain, {})
    out = tmp_path / "o"

    def run(*args: str) -> str:
        assert main(["export", *args, "-o", str(out)]) == 2
        assert not out.exists()
        return capsys.readouterr().err

    assert "--machine" in run(str(good), "-f", "linuxcnc-xyzab-tdr")
    err = run(str(good), "-f", "linuxcnc-maxkins", "--machine", str(machine))
    assert "maxkins cannot describe this chain" in err and "order C, X, Y, Z, B" in err
    other = CHAINS / FILES["linuxcnc-5axiskins"]
    assert "5axiskins" in run(str(good), "-f", "linuxcnc-5axiskins", "--machine", str(other))
    doc = json.loads(good.read_text())
    doc["location"][2]["value"] = float("nan")
    bad = tmp_path / "nan.json"
    bad.write_text(json.dumps(doc))
    err = run(str(bad), "-f", "linuxcnc-xyzab-tdr", "--machine", str(machine))
    assert "nan.json" in err and "location[2].value" in err and "finite" in err
    doc["location"][2]["value"] = 0.0
    doc["location"] = doc["location"][:-1]
    bad.write_text(json.dumps(doc))
    assert "missing location errors: EB0B" in run(str(bad), "-f", "linuxcnc-xyzab-tdr",
                                                  "--machine", str(machine))
    bad.write_text('{"chain": "xyzab-tdr",\n "kind": }')
    assert "nan.json:2" in run(str(bad), "-f", "linuxcnc-xyzab-tdr", "--machine", str(machine))
    trt = Path(__file__).resolve().parents[3] / "examples" / "trunnion5ax" / "machine.toml"
    assert "[chain]" in run(str(good), "-f", "linuxcnc-xyzab-tdr", "--machine", str(trt))
    assert "a_joint" in run(str(good), "-f", "linuxcnc-xyzab-tdr", "--machine", str(machine),
                            "--set", "a_joint=99")
