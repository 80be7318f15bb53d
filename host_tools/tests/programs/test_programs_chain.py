"""``abbe program`` five-axis-probing / five-axis-rtest on the [chain] machines of
LinuxCNC's head-head (5axiskins), head-table (maxkins) and dual-rotary-table
(xyzab_tdr_kins) samples, read back by a G-code reader written here (RS274/NGC words,
G38.2, LOG) and run on a true machine written here (rotations about the errored axis
lines, Rodrigues, the product of exponentials at the home pose): every probing move
runs along a normal of the sphere from outside to inside it; the logged trigger points
go through `abbe fit` and give back the location errors it can see; the R-test program
holds the ball's nominal centre under TCP and its approach puts the nest on the ball."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from abbe.cli.entry import main
from abbe.formats.chain import chain_toml
from abbe.formats.machine import load_machine
from cases.chain_suite import CHAINS

FILES = {"5axiskins": "head-head-5axiskins.toml", "maxkins": "head-table-maxkins.toml",
         "xyzab-tdr": "table-dual-rotary-xyzab.toml"}
WORD = re.compile(r"([A-Z])\s*(-?\d+(?:\.\d*)?)")
NAMES = {"A": ("EY0A", "EZ0A", "EB0A", "EC0A", "EA0A"), "B": ("EX0B", "EZ0B", "EA0B", "EC0B", "EB0B"),
         "C": ("EX0C", "EY0C", "EA0C", "EB0C", "EC0C")}
TRUTH = {"EX0B": -14.8, "EZ0B": 26.7, "EA0B": -48.1, "EC0B": 27.6, "EB0B": 65.6,
         "EX0C": 13.8, "EY0C": -19.1, "EA0C": 44.7, "EB0C": -37.8, "EC0C": -59.6,
         "EY0A": 22.5, "EZ0A": -16.1, "EB0A": 35.2, "EC0A": -42.0, "EA0A": 55.4}
SPHERE, RADIUS, STYLUS = (50.0, 20.0, 30.0), 12.5, 1.5


def read_gcode(text: str) -> list[dict]:
    """Executable blocks: words {letter: value}, ``g`` G0/G1/G38.2, ``m``, ``log``."""
    out = []
    for raw in text.splitlines():
        s = raw.strip()
        log = re.fullmatch(r"\(LOG,(.*)\)", s)
        if log:
            out.append({"g": None, "words": {}, "m": None, "log": log.group(1)})
            continue
        code = re.sub(r"\([^)]*\)", "", s).strip().upper()
        if not code:
            continue
        g38 = code.startswith("G38.2")
        words = {k: float(v) for k, v in WORD.findall(code.replace("G38.2", ""))}
        g = "G38.2" if g38 else (f"G{int(words['G'])}" if "G" in words and int(words["G"]) in (0, 1)
                                 else None)
        out.append({"g": g, "words": words, "m": int(words["M"]) if "M" in words else None,
                    "log": None})
    return out


def _rod(u: np.ndarray, t: float) -> np.ndarray:
    u = u / np.linalg.norm(u)
    k = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    return np.eye(3) + math.sin(t) * k + (1.0 - math.cos(t)) * (k @ k)


def _turn(x, chain, axis, err, t_deg, base):
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
    ang = chain.axis(axis).direction * math.radians(t_deg) + err.get(n[4], 0.0) * 1e-6
    return p + _rod(u, ang) @ (x - p)


def stylus(chain, err, q, ang, tip):
    """Where the true machine's stylus (``tip`` from the controlled point) is at joints q."""
    x = q + np.asarray(tip, dtype=float)
    for axis in reversed(chain.tool_side):
        x = _turn(x, chain, axis, err, ang[axis], q)
    return x


def sphere_at(chain, err, ang, s):
    x = np.asarray(s, dtype=float)
    for axis in chain.workpiece_side:
        x = _turn(x, chain, axis, err, ang[axis], np.zeros(3))
    return x


def run_probing(chain, err, text: str, tip, sphere) -> tuple[str, int]:
    """Run the program's moves on the true machine: the CSV its LOG lines write, and the
    number of probing moves. Every G38.2 starts outside the sphere and ends inside it,
    along a normal through the (nominal) centre."""
    pos = {"X": 0.0, "Y": 0.0, "Z": 0.0}
    rot = {a: 0.0 for a in chain.rotaries}
    rows, header, trig, n = [], None, None, 0
    reach = RADIUS + STYLUS
    for b in read_gcode(text):
        if b["log"] is not None:
            parts = b["log"].split(",")
            if header is None:
                header = b["log"]
                continue
            vals = {"#5061": trig[0], "#5062": trig[1], "#5063": trig[2]}
            rows.append(",".join(f"{vals[p]:.6f}" if p in vals else p for p in parts))
            continue
        w = b["words"]
        new = {a: w.get(a, pos[a]) for a in "XYZ"}
        for a in chain.rotaries:
            rot[a] = w.get(a, rot[a])
        if b["g"] == "G38.2":
            n += 1
            p0 = np.array([pos[a] for a in "XYZ"])
            p1 = np.array([new[a] for a in "XYZ"])
            c = sphere_at(chain, err, rot, sphere)
            s0 = stylus(chain, err, p0, rot, tip)
            d = p1 - p0  # the linear axes translate the stylus
            assert np.linalg.norm(s0 - c) > reach, "a probing move starts inside the sphere"
            assert np.linalg.norm(stylus(chain, err, p1, rot, tip) - c) < reach
            # along the normal: the line through the start passes the centre within 0.2 mm
            u = d / np.linalg.norm(d)
            assert np.linalg.norm(np.cross(c - s0, u)) < 0.2
            # the first touch: |s0 + l d - c| = reach
            a2, a1, a0 = d @ d, 2 * d @ (s0 - c), (s0 - c) @ (s0 - c) - reach ** 2
            lam = (-a1 - math.sqrt(a1 * a1 - 4 * a2 * a0)) / (2 * a2)
            trig = p0 + lam * d
            new = {a: trig[i] for i, a in enumerate("XYZ")}
        pos = new
    return header + "\n" + "\n".join(rows) + "\n", n


def _machine(tmp: Path, chain, probes: list[tuple[str, tuple, tuple]], rtest: bool) -> Path:
    text = ["[machine]\nname = \"closed loop\"\n",
            "[axes.X]\ntravel_mm = [-500.0, 500.0]\n[axes.Y]\ntravel_mm = [-500.0, 500.0]\n"
            "[axes.Z]\ntravel_mm = [-600.0, 400.0]\n", "[reference]\npoint_mm = [0.0, 0.0, 0.0]\n",
            chain_toml(chain)]
    for name, s, tip in probes:
        text.append(f'[probing.{name}]\nfile = "{name}.csv"\nsphere_mm = {list(s)!r}\n'
                    f"sphere_radius_mm = {RADIUS}\nstylus_radius_mm = {STYLUS}\n"
                    f"tip_mm = {list(tip)!r}\n")
    if rtest:
        text.append(f'[rtest.R1]\nfile = "rtest.csv"\nsphere_mm = {list(SPHERE)!r}\n')
    (tmp / "machine.toml").write_text("\n".join(text))
    return tmp / "machine.toml"


@pytest.mark.parametrize("name", sorted(FILES))
def test_probing_program_closed_loop(tmp_path: Path, name: str) -> None:
    chain = load_machine(CHAINS / FILES[name]).extra["chain"]
    err = {n: v for n, v in TRUTH.items() if n in chain.location_names()}
    tips = [(0.0, 0.0, 0.0), (0.0, 0.0, -100.0)] if chain.tool_side else [(0.0, 0.0, 0.0)]
    probes = [(f"S{i}{j}", (SPHERE[0], SPHERE[1], SPHERE[2] + h), tip)
              for i, h in enumerate((0.0, 100.0)) for j, tip in enumerate(tips)]
    m = _machine(tmp_path, chain, probes, rtest=False)
    moves = 0
    for pname, s, tip in probes:
        ngc = tmp_path / f"{pname}.ngc"
        assert main(["program", str(m), "--test", "five-axis-probing", "--dialect", "linuxcnc",
                     "--name", pname, "--tilt-positions", "3", "--c-positions", "5",
                     "-o", str(ngc)]) == 0
        text = ngc.read_text()
        assert (("M429" in text) != (name == "maxkins")) and "G38.2" in text
        csv, n = run_probing(chain, err, text, tip, s)
        moves += n
        (tmp_path / f"{pname}.csv").write_text(csv)
    assert moves == 3 * 5 * 5 * len(probes)
    assert main(["fit", str(m), "-o", str(tmp_path / "fit"), "-q"]) == 0
    doc = json.loads((tmp_path / "fit" / "chain_fit.json").read_text())
    seen = [r for r in doc["location"] if r["value"] is not None]
    assert len(seen) >= 5
    for r in seen:
        floor = 1.0 if r["unit"] == "um" else 5.0
        assert abs(r["value"] - err[r["name"]]) <= max(r["u95"], floor), r
    # the fit goes on to the module's parameters: abbe export reads the real chain_fit.json
    target = {"5axiskins": "linuxcnc-5axiskins", "maxkins": "linuxcnc-maxkins",
              "xyzab-tdr": "linuxcnc-xyzab-tdr"}[name]
    assert main(["export", str(tmp_path / "fit" / "chain_fit.json"), "-f", target, "-o",
                 str(tmp_path / "x"), "--machine", str(m), "--set", "volume_points=3",
                 "rotary_points=5"]) == 0
    rep = json.loads((tmp_path / "x" / "residual.json").read_text())
    assert sorted(rep["not_observable"]["items"]) == sorted(
        r["name"] for r in doc["location"] if r["value"] is None)
    for key in ("volume", "tcp_path"):
        assert rep[key]["residual"]["norm"]["rms_um"] < rep[key]["uncompensated"]["norm"]["rms_um"]


@pytest.mark.parametrize("name", sorted(FILES))
def test_rtest_program_holds_the_ball(tmp_path: Path, name: str) -> None:
    chain = load_machine(CHAINS / FILES[name]).extra["chain"]
    m = _machine(tmp_path, chain, [], rtest=True)
    ngc = tmp_path / "r.ngc"
    assert main(["program", str(m), "--test", "five-axis-rtest", "--dialect", "linuxcnc",
                 "-o", str(ngc)]) == 0
    blocks = read_gcode(ngc.read_text())
    tcp = name == "maxkins"  # maxkins has no identity mode: the whole program is TCP
    pos = {"X": 0.0, "Y": 0.0, "Z": 0.0}
    rot = {a: 0.0 for a in chain.rotaries}
    held, stops = 0, 0
    swept = {a: set() for a in chain.rotaries}
    for b in blocks:
        if b["m"] == 428:
            tcp = True
        elif b["m"] == 429:
            tcp = False
        elif b["m"] == 0:
            stops += 1
            if stops == 1:  # the nest is fitted where the ball is
                if tcp:
                    assert np.allclose([pos[a] for a in "XYZ"], SPHERE, atol=1e-4)
                else:  # identity: the nominal machine's nest on the ball
                    q = np.array([pos[a] for a in "XYZ"])
                    assert np.allclose(stylus(chain, {}, q, rot, (0, 0, 0)),
                                       sphere_at(chain, {}, rot, SPHERE), atol=1e-3)
        w = b["words"]
        for a in "XYZ":
            pos[a] = w.get(a, pos[a])
        for a in chain.rotaries:
            rot[a] = w.get(a, rot[a])
            lo, hi = chain.travel_deg[a]
            assert lo <= rot[a] <= hi
        if b["g"] == "G1" and any(a in w for a in chain.rotaries) and stops == 1:
            assert tcp and np.allclose([pos[a] for a in "XYZ"], SPHERE, atol=1e-4)
            held += 1
            for a in chain.rotaries:
                swept[a].add(round(rot[a], 3))
    assert held >= 30 and stops == 2
    for a in chain.rotaries:  # both axes move on the path
        assert max(swept[a]) - min(swept[a]) >= 60.0, (a, sorted(swept[a]))


def test_chain_program_refusals(tmp_path: Path, capsys) -> None:
    chain = load_machine(CHAINS / FILES["xyzab-tdr"]).extra["chain"]
    m = _machine(tmp_path, chain, [("S1", (50.0, 20.0, 30.0), (0.0, 0.0, 0.0))], rtest=False)
    out = tmp_path / "p.ngc"
    assert main(["program", str(m), "--test", "five-axis-rtest", "--dialect", "linuxcnc",
                 "-o", str(out)]) == 2
    assert "rtest" in capsys.readouterr().err and not out.exists()
    far = _machine(tmp_path, chain, [("S1", (50.0, 20.0, 900.0), (0.0, 0.0, 0.0))], rtest=False)
    assert main(["program", str(far), "--test", "five-axis-probing", "--dialect", "linuxcnc",
                 "-o", str(out)]) == 2
    assert "outside the travel" in capsys.readouterr().err and not out.exists()
