"""abbe.formats.golden: the committed golden vectors are reproducible and say what they claim."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from abbe.formats import golden
from abbe.formats.blob import read_blob
from abbe.model.reference import out_of_travel, reversal_values, spatial_error, term_values
from abbe.model.table import AXES, TERMS
from textnum import differences

REPO = Path(__file__).resolve().parents[3]
GOLDEN = REPO / "tests" / "golden"


def test_regenerated_files_match(tmp_path: Path) -> None:
    """The same files again: text and hex literals (blobs, f32 inputs) exactly, expected
    values within 1 pm (docs/formats.md, "Reproducibility")."""
    golden.write(tmp_path)
    for name in ("golden_data.h", "golden_data.c"):
        assert differences((GOLDEN / name).read_text(), (tmp_path / name).read_text()) == [], name


def test_header_declares_the_agreed_types() -> None:
    h = (GOLDEN / "golden_data.h").read_text()
    for line in golden.HEADER.splitlines():
        assert line in h
    assert "typedef struct { uint8_t axis, term; float pos_mm; int32_t pos_nm; " \
           "int32_t expect_f32_pico; int32_t expect_q_pico; } abbe_golden_term_t;" in h
    assert "#define ABBE_GOLDEN_TOL_PM 2000" in h


# --------------------------------------------------------------------------- parse the C back

_HEX = r"-?0x[0-9a-f.]+p[+-]\d+f"


def _floats(s: str) -> list[float]:
    return [float.fromhex(v[:-1]) for v in re.findall(_HEX, s)]


def parse_golden_c(text: str) -> dict:
    """Blobs, points and terms as written in golden_data.c."""
    blobs = {}
    for name, body in re.findall(r"golden_blob_(\w+)\[\d+\](?: ABBE_GOLDEN_ALIGNED)? = \{(.*?)\};", text, re.S):
        blobs[name] = bytes(int(v, 16) for v in re.findall(r"0x([0-9A-F]{2})", body))
    tables = re.findall(r'\{golden_blob_(\w+), (\d+)u, "(\w+)", (\d+)u, (\d+)u, (\d+)u, (\d+)u\}',
                        text)
    pts_body = text.split("abbe_golden_points[] = {", 1)[1].split("};", 1)[0]
    points = []
    for line in pts_body.splitlines():
        line = re.sub(r"/\*.*?\*/", "", line).strip()
        if not line.startswith("{"):
            continue
        f = _floats(line)
        ints_part = re.sub(_HEX, "", line)
        ints = [int(v, 0) for v in re.findall(r"-?(?:0x[0-9A-F]+|\d+)", ints_part)]
        points.append((np.array(f[:9]).reshape(3, 3), np.array(ints[:15]).reshape(5, 3),
                       ints[15]))
    terms_body = text.split("abbe_golden_terms[] = {", 1)[1].split("};", 1)[0]
    terms = []
    for line in terms_body.splitlines():
        line = re.sub(r"/\*.*?\*/", "", line).strip()
        if not line.startswith("{"):
            continue
        f = _floats(line)
        ints = [int(v) for v in re.findall(r"-?\d+", re.sub(_HEX, "", line))]
        terms.append((ints[0], ints[1], f[0], ints[2], ints[3], ints[4]))
    return {"blobs": blobs, "tables": tables, "points": points, "terms": terms}


@pytest.fixture(scope="module")
def parsed() -> dict:
    return parse_golden_c((GOLDEN / "golden_data.c").read_text())


def test_tables_and_counts(parsed: dict) -> None:
    tables = parsed["tables"]
    assert [t[2] for t in tables] == ["paper", "full", "sparse", "negative", "backlash",
                                      "reversal", "reversal_sparse"]
    text = (GOLDEN / "golden_data.c").read_text()
    assert f"abbe_golden_point_count = {len(parsed['points'])}u;" in text
    assert f"abbe_golden_term_count = {len(parsed['terms'])}u;" in text
    first_p = first_t = 0
    for sym, size, name, fp, n_p, ft, n_t in tables:
        assert parsed["blobs"][sym] and len(parsed["blobs"][sym]) == int(size)
        assert (int(fp), int(ft)) == (first_p, first_t)
        # format 1.1 tables add 8 total-reversal entries per axis
        assert 100 <= int(n_p) <= 200 and 15 <= int(n_t) <= (54 if "reversal" in name else 30)
        first_p += int(n_p)
        first_t += int(n_t)
    assert first_p == len(parsed["points"]) and first_t == len(parsed["terms"])


def test_table_shapes(parsed: dict) -> None:
    t = {name: read_blob(parsed["blobs"][name]) for name in parsed["blobs"]}
    full = t["full"]
    assert full.features() == 0xF
    for a in AXES:
        ax = full.axes[a]
        assert ax.trend_degree == 7 and [b.harmonics for b in ax.blocks] == [8, 8]
        assert 5.0 <= ax.blocks[1].period_mm <= 20.0
        assert ax.travel_mm[1] - ax.travel_mm[0] == 2000.0
    peaks = {k: max(np.abs(term_values(full, a, k, np.linspace(*full.axes[a].travel_mm, 20001))).max()
                    for a in AXES) for k in TERMS}
    assert peaks["dx"] == pytest.approx(200.0, rel=1e-3)
    assert peaks["ey"] == pytest.approx(500.0, rel=1e-3)
    sparse = t["sparse"]
    assert sparse.axes["Y"].coef == {} and sparse.axes["Z"].coef == {}
    assert 0 < len(sparse.axes["X"].coef) < 6 and sparse.features() == 0
    neg = t["negative"]
    assert all(neg.axes[a].travel_mm[1] < 0 for a in AXES)
    assert neg.axes["Y"].trend_degree is None and neg.axes["Z"].blocks[0] is None
    paper = t["paper"]
    assert paper.reference_mm == (163.626, -212.772, -290.704)
    # format 1.0 tables first (minor 0, unchanged), then the reversal blocks (1.1)
    for name, blob in parsed["blobs"].items():
        assert blob[6] == (1 if name.startswith("reversal") else 0), name
    rev = t["reversal"]
    assert rev.features() == 0x17                          # all but THERMAL
    assert [len(rev.axes[a].reversal_cheb_um) for a in AXES] == [4, 8, 1]
    r_x = reversal_values(rev, "X", np.linspace(*rev.axes["X"].travel_mm, 201))
    assert r_x.max() > 30.0 and r_x.min() < -5.0          # changes sign along the travel
    for a in AXES:                                         # the backlash table + blocks
        for k, c in rev.axes[a].coef.items():
            np.testing.assert_array_equal(c, t["backlash"].axes[a].coef[k])
        assert rev.axes[a].backlash_um == t["backlash"].axes[a].backlash_um
    sp = t["reversal_sparse"]
    assert sp.axes["Y"].coef == {} and sp.axes["Z"].coef == {}
    assert sp.axes["X"].backlash_um == 0.0 and "dx" not in sp.axes["X"].coef
    assert all(sp.axes[a].reversal_cheb_um is not None for a in AXES)


def test_points_reproduce_from_the_written_inputs(parsed: dict) -> None:
    """Recompute every expectation from the values as the C compiler will read
    them (hex floats, integers): the emission is exact and the expectations are
    the reference at each input."""
    by_table = {}
    for sym, size, name, fp, n_p, ft, n_t in parsed["tables"]:
        by_table[name] = (read_blob(parsed["blobs"][sym]), int(fp), int(n_p), int(ft), int(n_t))
    dir_values = set()
    n_out = 0
    for name, (t, fp, n_p, ft, n_t) in by_table.items():
        pts = parsed["points"][fp:fp + n_p]
        pos_f = np.array([p[0][0] for p in pts])
        dir_f = np.array([p[0][1] for p in pts])
        tmp_f = np.array([p[0][2] for p in pts])
        ints = np.array([p[1] for p in pts])
        flags = np.array([p[2] for p in pts])
        e_f = spatial_error(t, pos_f, dir_f, tmp_f) * 1e6
        e_q = spatial_error(t, ints[:, 0] / 1e6, ints[:, 1] / 2.0**30, ints[:, 2] / 1e3) * 1e6
        np.testing.assert_allclose(ints[:, 3], e_f, atol=0.5 + 1e-6)
        np.testing.assert_allclose(ints[:, 4], e_q, atol=0.5 + 1e-6)
        # f32 and q inputs are close (within float32 rounding of the position)
        assert np.abs(pos_f * 1e6 - ints[:, 0]).max() < 200.0          # nm
        np.testing.assert_array_equal(flags, out_of_travel(t, pos_f).astype(int))
        np.testing.assert_array_equal(flags, out_of_travel(t, ints[:, 0] / 1e6).astype(int))
        assert 0.05 < flags.mean() < 0.5
        n_out += flags.sum()
        dir_values |= set(dir_f.ravel().tolist())
        assert tmp_f.min() >= 15.0 and tmp_f.max() <= 35.0
        # the reference point and both travel ends of every axis are there
        ref = np.array(t.reference_mm)
        assert np.any(np.all(ints[:, 0] == np.rint(ref * 1e6), axis=1))
        for j, a in enumerate(AXES):
            for end in t.axes[a].travel_mm:
                assert np.any(ints[:, 0, j] == round(end * 1e6)), (name, a, end)
        # single terms
        for axis, term, p32, p_nm, ef, eq in parsed["terms"][ft:ft + n_t]:
            a = AXES[axis]
            if term == golden.REVERSAL_TERM:      # the total reversal, pm
                f = lambda p, a=a: reversal_values(t, a, p)  # noqa: E731
            else:
                f = lambda p, a=a, k=TERMS[term]: term_values(t, a, k, p)  # noqa: E731
            assert ef == pytest.approx(f([p32])[0] * 1e6, abs=0.5 + 1e-6)
            assert eq == pytest.approx(f([p_nm / 1e6])[0] * 1e6, abs=0.5 + 1e-6)
    assert dir_values == {-1.0, -0.5, 0.0, 1.0}
    assert n_out > 0


def test_terms_cover_every_axis(parsed: dict) -> None:
    for sym, size, name, fp, n_p, ft, n_t in parsed["tables"]:
        terms = parsed["terms"][int(ft):int(ft) + int(n_t)]
        axes = [t[0] for t in terms if t[1] != golden.REVERSAL_TERM]
        assert all(5 <= axes.count(j) <= 10 for j in range(3)), name
        rev = [t[0] for t in terms if t[1] == golden.REVERSAL_TERM]
        assert rev == ([] if "reversal" not in name else sorted(rev)) and \
            all(rev.count(j) == 8 for j in (range(3) if rev else ())), name


@pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")
def test_golden_c_compiles(tmp_path: Path) -> None:
    main = tmp_path / "main.c"
    main.write_text('#include <stdio.h>\n#include "golden_data.h"\n'
                    "int main(void) {\n"
                    '  printf("%u %u %u %.9g %d\\n", (unsigned)abbe_golden_table_count,\n'
                    "         (unsigned)abbe_golden_point_count, (unsigned)abbe_golden_term_count,\n"
                    "         (double)abbe_golden_points[1].pos_mm[1],\n"
                    "         (int)abbe_golden_points[1].pos_nm[1]);\n  return 0; }\n")
    exe = tmp_path / "g"
    subprocess.run(["cc", "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror",
                    f"-I{GOLDEN}", str(main), str(GOLDEN / "golden_data.c"), "-o", str(exe)],
                   check=True, capture_output=True)
    out = subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout.split()
    parsed = parse_golden_c((GOLDEN / "golden_data.c").read_text())
    assert int(out[0]) == 7 and int(out[1]) == len(parsed["points"])
    assert int(out[2]) == len(parsed["terms"])
    assert float(out[3]) == pytest.approx(parsed["points"][1][0][0][1], abs=0)
    assert int(out[4]) == parsed["points"][1][1][0][1]
