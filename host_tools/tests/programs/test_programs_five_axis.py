"""Five-axis part programs of `abbe program` (docs/programs.md, "Five-axis programs"), read
back by an independent G-code reader written here from the G-code standard (RS274/NGC
words, LinuxCNC's G38.2 / LOG / M428 / M429), with its own trt kinematics (Rodrigues,
the LinuxCNC trt geometry): every probing move stays within the travel, runs along the
sphere's normal from outside its surface to inside it, no other move enters the sphere;
the R-test path holds the ball's nominal centre under TCP; and a closed loop: the
programs' probing moves touched on the virtual machine's (errored) sphere, logged as the
LOG lines say, read by `abbe fit` through the machine file (the plan), give back the
location errors."""

from __future__ import annotations

import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from abbe.cli.entry import main
from abbe.formats.machine import load_machine
from abbe.sim.five_axis import VirtualFiveAxis, random_errors

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "trunnion5ax" / "machine.toml"
WORD = re.compile(r"([A-Z])\s*(-?\d+(?:\.\d*)?)")


# ---------------------------------------------------------------- the independent reader


def read_gcode(text: str) -> list[dict]:
    """One dict per executable block: ``g`` (motion word or None), ``words`` {letter: value},
    ``m`` (M number or None), ``log`` (the LOG text or None), ``line`` (1-based)."""
    out = []
    for i, raw in enumerate(text.splitlines(), 1):
        s = raw.strip().upper() if not raw.strip().startswith("(LOG") else raw.strip()
        log = re.fullmatch(r"\(LOG,(.*)\)", s)
        if log:
            out.append({"g": None, "words": {}, "m": None, "log": log.group(1), "line": i})
            continue
        code = re.sub(r"\([^)]*\)", "", s).strip()
        if not code:
            continue
        g38 = code.startswith("G38.2")
        words = {k: float(v) for k, v in WORD.findall(code.replace("G38.2", ""))}
        g = "G38.2" if g38 else (f"G{int(words['G'])}" if "G" in words and
                                 int(words["G"]) in (0, 1) else None)
        m = int(words["M"]) if "M" in words else None
        out.append({"g": g, "words": words, "m": m, "log": None, "line": i, "text": code})
    return out


def rod(k: np.ndarray, deg: float) -> np.ndarray:
    t = math.radians(deg)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(t) * K + (1 - math.cos(t)) * K @ K


def trt(toml: dict, w: np.ndarray, a: float, c: float) -> np.ndarray:
    """Nominal machine position of workpiece point ``w`` at tilt ``a``, C ``c`` (LinuxCNC trt
    geometry: C about the rotation point, the tilt axis through it plus the offsets)."""
    r = toml["rotary"]
    pc = np.array([r["x_rot_point_mm"], r["y_rot_point_mm"], r["z_rot_point_mm"]])
    ac = r["kinematics"] == "xyzac-trt"
    pt = pc + (np.array([0.0, r["y_offset_mm"], r["z_offset_mm"]]) if ac
               else np.array([r["x_offset_mm"], 0.0, r["z_offset_mm"]]))
    y = pc + rod(np.array([0.0, 0.0, 1.0]), c) @ (w - pc)
    return pt + rod(np.eye(3)[0 if ac else 1], a) @ (y - pt)


def seg_distance(p: np.ndarray, q: np.ndarray, x: np.ndarray) -> float:
    d = q - p
    t = 0.0 if not d.any() else float(np.clip((x - p) @ d / (d @ d), 0.0, 1.0))
    return float(np.linalg.norm(p + t * d - x))


def walk(blocks: list[dict], tilt: str) -> list[dict]:
    """Every move with its start and end (x, y, z, tilt, c) and the kinematics mode."""
    pos = {k: None for k in ("X", "Y", "Z", tilt, "C")}
    tcp, moves, modal = False, [], None
    for b in blocks:
        if b["m"] in (428, 429):
            tcp = b["m"] == 428
        if b["g"] is not None:
            modal = b["g"]
        axes = {k: v for k, v in b["words"].items() if k in pos}
        if axes and b["log"] is None:
            start = dict(pos)
            pos.update(axes)
            moves.append({"g": b["g"] or modal, "start": start, "end": dict(pos), "tcp": tcp,
                          "line": b["line"]})
        if b["log"] is not None:
            moves.append({"g": "LOG", "log": b["log"], "end": dict(pos), "line": b["line"]})
    return moves


# ---------------------------------------------------------------- the checks


def _bc(text: str) -> str:
    """The example as a B/C trunnion (xyzbc-trt: the tilt axis B, its x offset)."""
    return (text.replace('"xyzac-trt"', '"xyzbc-trt"').replace("y_offset_mm", "x_offset_mm")
            .replace("[rotary.A]", "[rotary.B]"))


def _program(tmp: Path, test: str, *opts: str, kind: str = "xyzac-trt") -> tuple[Path, dict, str]:
    mf = tmp / "machine.toml"
    if not mf.exists():
        text = EXAMPLE.read_text()
        mf.write_text(text if kind == "xyzac-trt" else _bc(text))
    out = tmp / f"{test}.ngc"
    assert main(["program", str(mf), "--test", test, "--dialect", "linuxcnc", "-o", str(out),
                 *opts]) == 0
    import tomllib
    return out, tomllib.loads(mf.read_text()), out.read_text()


@pytest.mark.parametrize("kind", ["xyzac-trt", "xyzbc-trt"])
def test_probing_program_moves(tmp_path: Path, kind: str) -> None:
    tilt = "A" if kind == "xyzac-trt" else "B"
    ngc, toml, text = _program(tmp_path, "five-axis-probing", "--tilt-positions", "3",
                               "--c-positions", "6", "--points", "7", kind=kind)
    pr = toml["probing"]["S1"]
    reach = pr["sphere_radius_mm"] + pr["stylus_radius_mm"]
    s = np.array(pr["sphere_mm"])
    moves = walk(read_gcode(text), tilt)
    travel = {a: toml["axes"][a]["travel_mm"] for a in "XYZ"}
    travel.update({a: toml["rotary"][a]["travel_deg"] for a in (tilt, "C")})
    logs, probes, backoff = [], 0, None
    assert re.search(r"^M429", text, re.M) and "M428" not in text  # identity kins: machine coords
    # relative to the machine file's folder, where abbe fit reads it: no path of this computer
    assert "(LOGOPEN,probe.csv)" in text and str(tmp_path) not in text
    assert "abbe fit reads probe.csv" in text and "configuration folder" in text
    for mv in moves:
        e = mv["end"]
        for a, (lo, hi) in travel.items():
            assert e[a] is None or lo <= e[a] <= hi, (mv["line"], a, e[a])
        if mv["g"] == "LOG":
            logs.append((mv["log"], e))
            continue
        st = mv["start"]
        if None in st.values():
            continue  # the first moves from an unknown place go up, then to the plan
        centre = trt(toml, s, e[tilt], e["C"])
        p0 = np.array([st[k] for k in "XYZ"])
        p1 = np.array([e[k] for k in "XYZ"])
        if (st[tilt], st["C"]) != (e[tilt], e["C"]):
            # the table turns (joints linearly) under a tool well above the sphere all the way
            for f in np.linspace(0.0, 1.0, 41):
                on_way = trt(toml, s, st[tilt] + f * (e[tilt] - st[tilt]),
                             st["C"] + f * (e["C"] - st["C"]))
                assert p0[2] >= on_way[2] + reach + 10.0, mv["line"]
            continue
        if backoff is not None:
            # the move after a probe starts where the stylus stopped (on the surface): it
            # must back off along the same normal to where the probe move started
            assert np.allclose(p1, backoff, atol=1e-4), mv["line"]
            backoff = None
        elif mv["g"] == "G38.2":
            probes += 1
            backoff = p0
            n = (p0 - centre) / np.linalg.norm(p0 - centre)
            d = (p1 - p0) / np.linalg.norm(p1 - p0)
            assert np.allclose(d, -n, atol=1e-5), mv["line"]  # normal to the surface
            assert np.linalg.norm(p0 - centre) > reach + 1.0  # starts outside
            assert np.linalg.norm(p1 - centre) < reach - 0.5  # would reach inside
            assert n[2] >= math.sin(math.radians(19.0)) - 1e-9  # the reachable upper cap
        else:
            assert seg_distance(p0, p1, centre) >= reach + 0.5, mv["line"]  # no collision
    assert probes == 3 * 6 * 7
    assert logs[0][0] == f"position,t_s,{tilt.lower()}_deg,c_deg,x_mm,y_mm,z_mm"
    rows = [ln.split(",") for ln, _e in logs[1:]]
    assert len(rows) == probes and all(r[4:] == ["#5061", "#5062", "#5063"] for r in rows)
    for (ln, e), r in zip(logs[1:], rows):
        assert float(r[2]) == pytest.approx(e[tilt], abs=1e-4)
        assert float(r[3]) == pytest.approx(e["C"], abs=1e-4)
    t = [float(r[1]) for r in rows]
    assert t == sorted(t) and len({r[0] for r in rows}) == 18


def test_rtest_program_holds_the_ball(tmp_path: Path) -> None:
    _ngc, toml, text = _program(tmp_path, "five-axis-rtest", "--step-deg", "15")
    s = np.array(toml["rtest"]["R1"]["sphere_mm"])
    moves = [m for m in walk(read_gcode(text), "A") if m["g"] != "LOG"]
    tcp = [m for m in moves if m["tcp"]]
    assert len(tcp) > 40
    turned = set()
    for m in tcp:
        e = m["end"]
        assert np.allclose([e["X"], e["Y"], e["Z"]], s, atol=1e-4), m["line"]
        lo, hi = toml["rotary"]["A"]["travel_deg"]
        assert lo <= e["A"] <= hi
        q = trt(toml, s, e["A"], e["C"])  # what the trt kinematics asks of the joints
        for k, a in enumerate("XYZ"):
            lo, hi = toml["axes"][a]["travel_mm"]
            assert lo <= q[k] <= hi
        turned.add((round(e["A"], 3), round(e["C"], 3)))
    cs = {c for _a, c in turned}
    assert len(cs) >= 24 and max(cs) - min(cs) >= 345.0  # C a full turn
    assert len({a for a, _c in turned}) >= 10  # the tilt swept
    assert text.index("M0") < text.index("M428")  # the nest is fitted before TCP


def test_refusals(tmp_path: Path, capsys) -> None:
    mf = tmp_path / "machine.toml"
    shutil.copy(EXAMPLE, mf)
    base = ["program", str(mf), "--dialect", "linuxcnc", "-o", str(tmp_path / "p.ngc")]
    assert main(base[:3] + ["fanuc"] + base[4:] + ["--test", "five-axis-probing"]) == 2
    assert "--dialect" in capsys.readouterr().err
    mf.write_text(EXAMPLE.read_text().replace("travel_mm = [-600.0, 200.0]",
                                              "travel_mm = [-330.0, 200.0]"))
    assert main(base + ["--test", "five-axis-probing"]) == 2
    err = capsys.readouterr().err
    assert "outside the travel" in err and "axes.Z" in err and str(mf) in err
    assert not (tmp_path / "p.ngc").exists()  # nothing half written
    mf.write_text(EXAMPLE.read_text().split("[probing.S1]")[0])
    assert main(base + ["--test", "five-axis-probing"]) == 2
    assert "[probing" in capsys.readouterr().err


def test_closed_loop_program_to_fit(tmp_path: Path) -> None:
    """The program's G38.2 moves run on a virtual machine with hidden location errors (the
    stylus touches the actual sphere along the commanded line), logged as its LOG lines
    say into the file the plan names; `abbe fit` on the machine file gives the errors back."""
    ngc, toml, text = _program(tmp_path, "five-axis-probing")
    mf = tmp_path / "machine.toml"
    # the plan: this probing only, location errors
    mf.write_text(mf.read_text().split("[rtest.R1]")[0].replace("harmonics = 2", "harmonics = 0"))
    spec = load_machine(tmp_path / "machine.toml").five_axis
    vm = VirtualFiveAxis(spec.geometry, random_errors(spec.geometry, np.random.default_rng(4)))
    pr = toml["probing"]["S1"]
    reach = pr["sphere_radius_mm"] + pr["stylus_radius_mm"]
    rows = []
    rng = np.random.default_rng(5)
    for mv in walk(read_gcode(text), "A"):
        if mv["g"] == "G38.2":
            p0 = np.array([mv["start"][k] for k in "XYZ"])
            p1 = np.array([mv["end"][k] for k in "XYZ"])
            c = vm.sphere_centre(np.array(pr["sphere_mm"]), np.array([mv["end"]["A"],
                                                                       mv["end"]["C"]]), 0.0)
            d = (p1 - p0) / np.linalg.norm(p1 - p0)
            o = p0 - c
            b = float(d @ o)
            hit = p0 + d * (-b - math.sqrt(b * b - (o @ o - reach * reach)))
            trip = hit + rng.normal(0.0, 0.3e-3, 3)
        elif mv["g"] == "LOG":
            f = mv["log"].split(",")
            if f[0] == "position":
                rows.append(mv["log"])
            else:  # LinuxCNC substitutes #5061..#5063 with the trip point
                rows.append(",".join(f[:4] + [f"{v:.6f}" for v in trip]))
    Path(pr["file"] if Path(pr["file"]).is_absolute() else tmp_path / pr["file"]).write_text(
        "\n".join(rows) + "\n")
    assert main(["fit", str(tmp_path / "machine.toml"), "-o", str(tmp_path / "out"),
                 "--quiet"]) == 0
    doc = json.loads((tmp_path / "out" / "five_axis.json").read_text())
    n = 0
    for r in doc["parameters"]:
        if r["kind"] == "location" and r["observable"]:
            n += 1
            tol = max(r["ci95"], 1.0 if r["unit"] == "um" else 5.0)
            assert abs(r["value"] - vm.errors.location[r["name"]]) <= tol, r
    assert n >= 5


def test_diagnosis_plan_runs_the_grid_twice(tmp_path: Path) -> None:
    """``--passes 2`` (docs/programs.md): the grid, then again backwards with C half a step
    on. Read back from the G-code's LOG lines; the independent generator's own reading of
    the same docs (cases.five_axis_independent, Campaign.positions) gives the same order."""
    from cases.five_axis_independent import make_campaign

    _ngc, _toml, text = _program(tmp_path, "five-axis-probing", "--tilt-positions", "3",
                                 "--c-positions", "6", "--points", "5", "--passes", "2")
    rows = [ln.split(",") for ln, _e in
            [(m["log"], m["end"]) for m in walk(read_gcode(text), "A") if m["g"] == "LOG"][1:]]
    order: list[tuple[float, float]] = []
    for r in rows:
        if not order or int(r[0]) >= len(order):
            order.append((float(r[2]), float(r[3]) % 360.0))
    assert len(order) == 36 and len(rows) == 36 * 5
    first, second = order[:18], order[18:]
    assert [a for a, _c in first] == sorted(a for a, _c in first)  # tilt by tilt, upwards
    assert [a for a, _c in second] == sorted((a for a, _c in second), reverse=True)
    for a in {a for a, _c in order}:  # each tilt: 12 C angles 30 deg apart, 6 in each pass
        cs = sorted(c for b, c in order if b == a)
        assert np.allclose(np.diff(cs), 30.0) and len(cs) == 12
        assert {round(c) % 60 for b, c in first if b == a} == {0}
    t = [float(r[1]) for r in rows]
    assert t == sorted(t)
    camp = make_campaign(0)
    camp.n_tilt, camp.n_c, camp.passes = 3, 6, 2
    other = camp.positions()
    assert np.allclose([a for a, _c in other], [a for a, _c in order])
    assert np.allclose([c % 360.0 for _a, c in other], [c for _a, c in order])


def test_probing_log_path_relative_or_stated(tmp_path: Path) -> None:
    """LOGOPEN names the probing file relative to the machine file (a sub-folder stays
    relative); --log-file writes exactly what it is given; a file outside the machine
    file's folder keeps its absolute path, said in the comment; a name that cannot go
    into a G-code comment is refused (exit 2)."""
    mf = tmp_path / "m" / "machine.toml"
    mf.parent.mkdir()
    base = EXAMPLE.read_text()
    assert 'file = "probe.csv"' in base
    for file_value, want in (('"logs/probe.csv"', "logs/probe.csv"),
                             (f'"{(tmp_path / "elsewhere.csv").as_posix()}"',
                              (tmp_path / "elsewhere.csv").as_posix())):
        mf.write_text(base.replace('file = "probe.csv"', f"file = {file_value}", 1))
        out = tmp_path / "p.ngc"
        assert main(["program", str(mf), "--test", "five-axis-probing", "--dialect", "linuxcnc",
                     "-o", str(out)]) == 0
        text = out.read_text()
        assert f"(LOGOPEN,{want})" in text, want
        assert f"abbe fit reads {want}" in text
    mf.write_text(base)
    out = tmp_path / "q.ngc"
    assert main(["program", str(mf), "--test", "five-axis-probing", "--dialect", "linuxcnc",
                 "--log-file", "/home/cnc/probe.csv", "-o", str(out)]) == 0
    text = out.read_text()
    assert "(LOGOPEN,/home/cnc/probe.csv)" in text and "abbe fit reads probe.csv" in text
    bad = tmp_path / "r.ngc"
    assert main(["program", str(mf), "--test", "five-axis-probing", "--dialect", "linuxcnc",
                 "--log-file", "probe(1).csv", "-o", str(bad)]) == 2
    assert not bad.exists()
