"""`abbe program`: ISO 230-2 targets, travel checks, and every dialect replayed by a small
reader written from docs/programs.md ("Dialects"), not from the writer: each dialect's
program must visit the same points, dwell the same times and turn the same way."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from abbe.errors import AbbeInputError
from abbe.programs.plan import iso230_2_targets
from fuzzing.harness import run_case

ROOT = Path(__file__).resolve().parents[3]
MACHINE = ROOT / "examples" / "vmc500" / "machine.toml"
DIALECTS = ("linuxcnc", "grblhal", "fanuc", "sinumerik", "heidenhain")


def abbe(*argv: str):
    """Run ``abbe`` in-process (the fuzz harness: exit status, output, promises checked)."""
    return run_case(list(argv))


def program(tmp_path: Path, dialect: str, *opts: str, machine: Path = MACHINE) -> str:
    out = tmp_path / f"p.{dialect}"
    r = abbe("program", str(machine), *opts, "--dialect", dialect, "-o", str(out))
    assert r.rc == 0 and r.ok, (r.stderr, r.problems)
    return out.read_text()


def replay(text: str, dialect: str) -> list[tuple]:
    """Events ("move", x, y, z) / ("arc", ccw, x, y, z, cx, cy, cz) / ("dwell", s) /
    ("stop",) from a program, per the documented syntax of each dialect."""
    pos = [None, None, None]
    ev: list[tuple] = []
    centre = None
    ax = "XYZ"
    plane = (0, 1)
    for raw in text.splitlines():
        ln = raw.strip()
        if dialect == "heidenhain":
            ln = ln.split(" ", 1)[1] if " " in ln else ""
            if ln.startswith(";") or ln.startswith(("BEGIN", "END")):
                continue
            if ln.startswith("TOOL CALL"):
                plane = {"Z": (0, 1), "Y": (2, 0), "X": (1, 2)}[ln.split()[-1]]
                continue
            if ln.startswith("CYCL DEF 9.1"):
                ev.append(("dwell", float(ln.split()[-1])))
                continue
            if ln.startswith("CYCL DEF 9.0"):
                continue
            if ln == "STOP":
                ev.append(("stop",))
                continue
            words = dict(re.findall(r"([XYZ])([+-][0-9.]+)", ln))
            if ln.startswith("CC "):
                centre = list(pos)
                for k, v in words.items():
                    centre[ax.index(k)] = float(v)
                continue
            for k, v in words.items():
                pos[ax.index(k)] = float(v)
            if ln.startswith("L "):
                ev.append(("move", *pos))
            elif ln.startswith("C "):
                ev.append(("arc", "DR+" in ln, *pos, *centre))
            continue
        ln = re.sub(r"\([^)]*\)", "", ln).split(";")[0].strip()
        if not ln or ln in ("%",) or ln.startswith("O"):
            continue
        g = re.findall(r"G0*([0-9]+)", ln)
        if "17" in g or "18" in g or "19" in g:
            plane = {"17": (0, 1), "18": (2, 0), "19": (1, 2)}[[x for x in g if x in
                                                               ("17", "18", "19")][0]]
        if "4" in g:
            m = re.search(r"[PXF]([0-9.]+)", ln.split("G4" if "G4 " in ln else "G04")[1])
            ev.append(("dwell", float(m.group(1))))
            continue
        if re.match(r"M0*0?\b", ln) and re.match(r"M0+$", ln.split()[0]):
            ev.append(("stop",))
            continue
        words = {k: float(v) for k, v in re.findall(r"([XYZIJK])(-?[0-9]+\.[0-9]+)", ln)}
        start = list(pos)
        for k in "XYZ":
            if k in words:
                pos[ax.index(k)] = words[k]
        if "1" in g:
            ev.append(("move", *pos))
        elif "2" in g or "3" in g:
            c = list(start)
            for k, i in zip("IJK", range(3)):
                if k in words:
                    c[i] = start[i] + words[k]
            ev.append(("arc", "3" in g, *pos, *c))
    return ev


def test_long_target_lists_keep_lines_short(tmp_path: Path) -> None:
    text = program(tmp_path, "grblhal", "--test", "positioning", "--axis", "X", "--targets", "41")
    assert max(len(ln) for ln in text.splitlines()) < 100
    t = " ".join(re.findall(r"\(targets mm: ([^)]*)\)", text)).split()
    assert len(t) == 41


def test_iso230_2_targets_uneven_and_per_metre() -> None:
    t = iso230_2_targets(0.0, 2000.0)
    assert t.size == 11 and t[0] == 0.0 and t[-1] == 2000.0
    steps = np.diff(t)
    assert np.ptp(steps) > 5.0  # not evenly spaced
    assert np.all(np.abs(steps - 200.0) <= 100.0 + 1e-9)
    assert iso230_2_targets(0.0, 300.0).size == 5  # at least five
    assert np.array_equal(iso230_2_targets(0, 500, seed=3), iso230_2_targets(0, 500, seed=3))


@pytest.mark.parametrize("opts", [
    ("--test", "positioning", "--axis", "X", "--dwell-s", "1.5"),
    ("--test", "angular", "--axis", "Z", "--sequence", "pendulum", "--runs", "2"),
    ("--test", "ballbar", "--plane", "XY"),
])
def test_every_dialect_replays_to_the_same_path(tmp_path: Path, opts) -> None:
    ref = replay(program(tmp_path, "linuxcnc", *opts), "linuxcnc")
    assert ref and any(e[0] == "dwell" for e in ref)
    for d in DIALECTS[1:]:
        got = replay(program(tmp_path, d, *opts), d)
        assert len(got) == len(ref), d
        for a, b in zip(ref, got):
            assert a[0] == b[0], (d, a, b)
            if a[0] == "arc":
                assert a[1] == b[1], (d, a, b)
                np.testing.assert_allclose(a[2:], b[2:], atol=1e-4, err_msg=d)
            elif a[0] != "stop":
                np.testing.assert_allclose(a[1:], b[1:], atol=1e-4, err_msg=d)


def test_positioning_program_visits_targets_with_overrun_and_dwell(tmp_path: Path) -> None:
    text = program(tmp_path, "linuxcnc", "--test", "positioning", "--axis", "Y",
                   "--dwell-s", "2.5")
    t = np.array([float(v) for v in " ".join(re.findall(r"\(targets mm: ([^)]*)\)", text)).split()])
    ev = replay(text, "linuxcnc")
    caps = [ev[k - 1][2] for k, e in enumerate(ev) if e[0] == "dwell"]
    assert len(caps) == 5 * 2 * t.size
    assert all(e[1] == 2.5 for e in ev if e[0] == "dwell")
    run1 = caps[:2 * t.size]
    np.testing.assert_allclose(run1, np.concatenate([t, t[::-1]]))
    ys = [e[2] for e in ev if e[0] == "move"]
    assert min(ys) == pytest.approx(t[0] - 5.0) and max(ys) == pytest.approx(t[-1] + 5.0)
    assert min(ys) >= -400.0 and max(ys) <= 0.0  # the travel


def test_ballbar_program_covers_the_data_arc_with_feed_arcs(tmp_path: Path) -> None:
    ev = replay(program(tmp_path, "fanuc", "--test", "ballbar", "--plane", "XY",
                        "--feed-arc-deg", "30"), "fanuc")
    arcs = [e for e in ev if e[0] == "arc"]
    c = np.array(arcs[0][5:8])
    ang = [math.degrees(math.atan2(a[3] - c[1], a[2] - c[0])) for a in arcs]
    start = next(e for e in ev if e[0] == "move")
    a0 = math.degrees(math.atan2(start[2] - c[1], start[1] - c[0]))
    assert a0 == pytest.approx(-30.0, abs=1e-3)
    ccw = [a for a, e in zip(ang, arcs) if e[1]]
    assert len(ccw) == len(arcs) // 2 and ccw[-1] % 360 == pytest.approx(30.0, abs=1e-3)
    assert ("stop",) in ev and any(e[0] == "dwell" for e in ev)
    for e in arcs:
        assert math.hypot(e[2] - e[5], e[3] - e[6]) == pytest.approx(100.0, abs=1e-3)


@pytest.mark.parametrize("opts,msg", [
    (("--test", "positioning", "--axis", "X", "--targets", "1"), "argument --targets"),
    (("--test", "ballbar", "--axis", "X"), "--plane"),
    (("--test", "positioning"), "needs --axis"),
    (("--test", "ballbar", "--plane", "YZ"), "no \\[ballbar"),
    (("--test", "positioning", "--axis", "X", "--runs", "0"), "argument --runs"),
])
def test_refusals(tmp_path: Path, opts, msg) -> None:
    out = tmp_path / "p.ngc"
    r = abbe("program", str(MACHINE), *opts, "--dialect", "linuxcnc", "-o", str(out))
    assert r.rc == 2 and r.ok and re.search(msg, r.stderr), r.stderr
    assert not out.exists()


def test_circle_outside_the_travel_is_refused(tmp_path: Path) -> None:
    m = tmp_path / "m.toml"
    m.write_text(MACHINE.read_text().replace("radius_mm = 100.0", "radius_mm = 290.0"))
    r = abbe("program", str(m), "--test", "ballbar", "--plane", "XY", "--dialect", "linuxcnc",
             "-o", str(tmp_path / "b.ngc"))
    assert r.rc == 2 and "travel" in r.stderr and "m.toml" in r.stderr, r.stderr


def test_line_program_api_refuses_unknown_sequence() -> None:
    from abbe.programs.plan import line_program
    with pytest.raises(AbbeInputError, match="unknown sequence"):
        line_program("positioning", "X", (0, 0, 0), (100, 0, 0), {"X": (0, 100), "Y": (0, 1),
                     "Z": (0, 1)}, feed=100, dwell_s=1, overrun_mm=1, runs=1, sequence="spiral")
