"""``abbe fit`` end to end: outputs, provenance, reproducibility, backlash, reference,
the C-library check and bad input (exit 2, no partial output)."""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path

import numpy as np
import pytest

from abbe.cli.entry import main
from abbe.formats.blob import read_blob
from abbe.model import clib
from abbe.model.reference import term_values
from abbe.model.table import FEATURE_BACKLASH, FEATURE_REVERSAL
from cases.synthetic_laser import make_dataset

SMALL = {"X": 26, "Y": 21, "Z": 16}  # 20 mm spacing: quick


def dataset(tmp_path: Path, name: str = "d", **kw):
    kw.setdefault("n_targets", SMALL)
    kw.setdefault("n_runs", 3)
    kw.setdefault("wave_period_mm", 130.0)
    return make_dataset(tmp_path / name, **kw)


def fit(machine: Path, out: Path, *extra: str) -> int:
    return main(["fit", str(machine), "-o", str(out), *extra])


def sha(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


@pytest.fixture(scope="module")
def fitted(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("fit")
    syn = dataset(tmp, seed=3)
    out = tmp / "out"
    assert fit(syn.machine, out, "--no-clib-check") == 0
    return syn, out


def test_outputs_exist(fitted) -> None:
    syn, out = fitted
    for f in ("model.bin", "abbe_model.c", "abbe_model.h", "model.json", "report/index.html"):
        assert (out / f).is_file(), f
    pngs = sorted(p.name for p in (out / "report").glob("*.png"))
    assert len(pngs) == 18 and "Y_dy.png" in pngs
    html = (out / "report" / "index.html").read_text()
    for p in pngs:
        assert f"src='{p}'" in html
    assert "paper 3rd-order Fourier" in html and "held-out" in html
    c = (out / "abbe_model.c").read_text()
    assert "abbe_model_blob" in c and "#include \"abbe_model.h\"" in c
    assert not list(out.parent.glob(".out.tmp-*"))  # temp dir cleaned up


def test_model_json_provenance_and_content(fitted) -> None:
    syn, out = fitted
    d = json.loads((out / "model.json").read_text())
    prov = d["provenance"]
    assert prov["tool"] == "abbe" and prov["version"]
    assert prov["inputs"]["machine"]["sha256"] == sha(syn.machine)
    for a in "XYZ":
        assert prov["inputs"][f"laser.{a}"]["sha256"] == sha(syn.laser[a])
    assert d["squareness"]["S_xy_urad"] == 0.0 and d["squareness"]["observable"] is False
    assert "unobservable" in d["squareness"]["note"]
    blob = (out / "model.bin").read_bytes()
    assert d["table"]["crc32"] == f"0x{int.from_bytes(blob[-4:], 'little'):08X}"
    for a in "XYZ":
        ax = d["axes"][a]
        assert set(ax["terms"]) == {"dx", "dy", "dz", "ex", "ey", "ez"}
        assert ax["backlash"]["significant"] is True and ax["backlash"]["in_table"] is True
        for t, tj in ax["terms"].items():
            u = tj["unit"]
            assert u == ("um" if t.startswith("d") else "urad")
            assert len(tj[f"coef_{u}"]) == len(ax["terms"]["dx"][f"coef_{u}"]) if u == "um" else True
            assert tj[f"quantization_error_{u}"] < 1e-4
            for model in ("chosen", "paper_fourier3", "paper_poly7"):
                for kind in ("in_sample", "held_out"):
                    assert set(tj["metrics"][model][kind]) == {f"emax_{u}", "r2", f"sse_{u}2",
                                                               f"rmse_{u}"}
        # straightness terms carry the removed line, the others do not
        own = {"X": "dx", "Y": "dy", "Z": "dz"}[a]
        for t in ("dx", "dy", "dz"):
            assert (ax["terms"][t]["detrend"] is None) == (t == own)
    text = (out / "model.json").read_text().lower()
    assert "timestamp" not in text and "date" not in text


def test_reproducible_bytes(fitted, tmp_path: Path) -> None:
    syn, out = fitted
    out2 = tmp_path / "again"
    assert fit(syn.machine, out2, "--no-clib-check") == 0
    files = sorted(p.relative_to(out) for p in out.rglob("*") if p.is_file())
    assert files == sorted(p.relative_to(out2) for p in out2.rglob("*") if p.is_file())
    for f in files:
        assert sha(out / f) == sha(out2 / f), f


def test_table_matches_truth_and_reference(fitted) -> None:
    syn, out = fitted
    t = read_blob((out / "model.bin").read_bytes())
    ref = t.reference_mm
    assert t.features() & FEATURE_BACKLASH
    for j, a in enumerate("XYZ"):
        ax = t.axes[a]
        assert ax.backlash_um == pytest.approx(syn.reversal_um[a], abs=0.3)
        assert ax.backlash_takeup_mm == 1.0
        p = syn.targets_mm[a]
        for term in ("dx", "dy", "dz", "ex", "ey", "ez"):
            # exactly zero at the reference point (up to quantisation)
            assert abs(term_values(t, a, term, np.array([ref[j]]))[0]) < 1e-4
            truth = syn.truth[(a, term)](p)
            if term != {"X": "dx", "Y": "dy", "Z": "dz"}[a] and term.startswith("d"):
                k, b = np.polyfit(p, truth, 1)        # Eq. 1 detrending of the truth
                truth = truth - (k * p + b)
            truth = truth - np.interp(ref[j], p, truth)
            fitted_v = term_values(t, a, term, p)
            err = fitted_v - truth
            err -= np.mean(err)  # the run drift and reference offsets shift by a constant
            assert np.max(np.abs(err)) < 0.45, (a, term, np.max(np.abs(err)))


def test_a_reversal_that_changes_along_the_travel_goes_into_the_reversal_block(
        tmp_path: Path) -> None:
    """X's reversal grows from 1 um at one end to 11 um at the other: the table gets the
    level in backlash_um and the slope in a format 1.1 reversal block, and its total
    reversal R(p) follows the truth along the travel (a constant would miss it by 5 um
    at the ends)."""
    syn = dataset(tmp_path, seed=6, reversal_um=6.0, reversal_gradient_um=10.0, axes=("X",))
    out = tmp_path / "o"
    args = () if clib.available() else ("--no-clib-check",)
    assert fit(syn.machine, out, *args) == 0
    t = read_blob((out / "model.bin").read_bytes())
    ax = t.axes["X"]
    assert t.features() & FEATURE_REVERSAL and ax.reversal_cheb_um is not None
    assert ax.reversal_cheb_um[0] == 0.0 and len(ax.reversal_cheb_um) >= 2
    p = syn.targets_mm["X"]
    lo, hi = p[0], p[-1]
    truth = 6.0 + 10.0 * ((p - lo) / (hi - lo) - 0.5)
    assert np.max(np.abs(ax.reversal_um(p) - truth)) < 0.5, ax.reversal_cheb_um
    rv = json.loads((out / "model.json").read_text())["axes"]["X"]["backlash"]["reversal"]
    assert rv["position_dependent"] is True and rv["in_table"] is True
    assert "reversal block" in rv["note"]
    html = (out / "report" / "index.html").read_text()
    assert re.search(r"<p>Reversal: changes along the travel \(Chebyshev degree \d, p (&lt;|=) ", html)


def test_no_backlash_term_when_reversal_is_noise(tmp_path: Path) -> None:
    syn = dataset(tmp_path, seed=4, reversal_um=0.0, axes=("X",))
    out = tmp_path / "o"
    assert fit(syn.machine, out, "--no-clib-check", "--no-report") == 0
    t = read_blob((out / "model.bin").read_bytes())
    assert t.axes["X"].backlash_um == 0.0 and not t.features() & FEATURE_BACKLASH
    bl = json.loads((out / "model.json").read_text())["axes"]["X"]["backlash"]
    assert bl["significant"] is False and bl["in_table"] is False
    assert abs(bl["mean_reversal_um"]) < 3 * bl["se_um"]
    # axes without a laser line are present in the table with no terms
    assert t.axes["Y"].coef == {} and t.axes["Z"].coef == {}


def test_paper_model_option(tmp_path: Path, capsys) -> None:
    syn = dataset(tmp_path, seed=5, axes=("Y",))
    out = tmp_path / "o"
    assert fit(syn.machine, out, "--no-clib-check", "--no-report", "--model", "paper-poly7") == 0
    table = capsys.readouterr().out   # the paper Table 4 layout, 3 rows per term
    assert "in-sample" in table and "held-out" in table and "RMSE" in table
    assert table.count("paper Fourier 3") == 6 and table.count("paper poly 7") == 6
    assert "Y dy (um)" in table and "Y ez (urad)" in table
    d = json.loads((out / "model.json").read_text())
    assert d["axes"]["Y"]["trend_degree"] == 7 and d["axes"]["Y"]["block0"] is None
    assert {(v["trend_degree"], v["harmonics"]) for v in d["axes"]["Y"]["terms"].values()} == {(7, 0)}


@pytest.mark.skipif(not clib.available(), reason="C library not built (cmake --build build)")
def test_clib_check_passes(tmp_path: Path, capsys) -> None:
    syn = dataset(tmp_path, seed=6)
    out = tmp_path / "o"
    assert fit(syn.machine, out, "--no-report") == 0
    chk = json.loads((out / "model.json").read_text())["clib_check"]
    assert chk["max_diff_f32_nm"] <= 2.0 and chk["max_diff_q_nm"] <= 2.0
    assert "C library agrees" in capsys.readouterr().out


def test_missing_clib_fails_with_build_hint(tmp_path: Path, monkeypatch, capsys) -> None:
    syn = dataset(tmp_path, seed=7, axes=("X",))
    monkeypatch.setenv("ABBE_LIB", str(tmp_path / "no" / "libabbe.so"))
    monkeypatch.setattr(clib.library, "_LIB", None)  # the cache of load_library
    out = tmp_path / "o"
    assert fit(syn.machine, out) == 3
    err = capsys.readouterr().err
    assert "cmake" in err and "--no-clib-check" in err
    assert not out.exists()


def test_clib_mismatch_fails(tmp_path: Path, monkeypatch, capsys) -> None:
    from abbe.analysis.fit import check as fit_check

    syn = dataset(tmp_path, seed=8, axes=("X",))
    monkeypatch.setattr(fit_check, "require_clib", lambda: None)

    def fake_check(blob, **kw):
        raise fit_check.ClibMismatch("C library and Python reference differ: 5 nm")
    import abbe.analysis.fit.check as fc
    monkeypatch.setattr(fc, "check_blob", fake_check)
    out = tmp_path / "o"
    assert fit(syn.machine, out, "--no-report") == 4
    assert "differ" in capsys.readouterr().err and not out.exists()


def _replace(old: str, new: str):
    def edit(text: str) -> str:
        assert old in text, old
        return text.replace(old, new, 1)
    return edit


def _cell(row_prefix: str, value: str, col: int = 3):
    """Set cell ``col`` of the first row starting with ``row_prefix``."""
    def edit(text: str) -> str:
        lines = text.split("\n")
        for i, ln in enumerate(lines):
            if ln.startswith(row_prefix):
                c = ln.split(",")
                c[col] = value
                lines[i] = ",".join(c)
                return "\n".join(lines)
        raise AssertionError(row_prefix)
    return edit


def _drop_row(row_prefix: str):
    def edit(text: str) -> str:
        lines = text.split("\n")
        i = next(i for i, ln in enumerate(lines) if ln.startswith(row_prefix))
        return "\n".join(lines[:i] + lines[i + 1:])
    return edit


def _drop_column(name: str):
    def edit(text: str) -> str:
        lines = text.split("\n")
        k = lines[0].split(",").index(name)
        return "\n".join(",".join(c for j, c in enumerate(ln.split(",")) if j != k) if ln else ln
                         for ln in lines)
    return edit


BAD = [
    # (what, file to edit: "machine" or an axis, edit, field named in the message)
    ("unknown machine key", "machine", _replace("[reference]", "[reference]\npoint = 1"),
     "reference.point"),
    ("map names unknown term", "machine", _replace('"+dx"', '"+dw"'), "laser.X.map.linear"),
    ("map names unknown channel", "machine", _replace("linear =", "lineer ="),
     "laser.X.map.lineer"),
    ("line not along its axis", "machine",
     _replace("end_mm = [500.0, -212.772", "end_mm = [500.0, -200.0"), "laser.X.end_mm"),
    ("line outside the travel", "machine",
     _replace("end_mm = [500.0, -212.772", "end_mm = [510.0, -212.772"), "laser.X.end_mm"),
    ("reference outside the line", "machine",
     _replace("point_mm = [163.626", "point_mm = [-1.0"), "reference.point_mm"),
    ("bad fit option", "machine", _replace("[tool]", "[fit]\nfolds = 1\n\n[tool]"),
     "fit.folds"),
    ("missing column", "X", _drop_column("roll_urad"), "roll_urad"),
    ("misspelt column", "X", _replace("yaw_urad", "yaw_rad"), "yaw_rad"),
    ("non-numeric cell", "X", _cell("1,+,20.000,", "x"), "linear_um"),
    ("NaN cell", "X", _cell("1,+,20.000,", "nan"), "linear_um"),
    ("Inf cell", "X", _cell("2,-,60.000,", "-inf", 7), "yaw_urad"),
    ("duplicated target", "X", _cell("1,+,40.000,", "20.000", 2), "target_mm"),
    ("unsorted targets", "X", _cell("1,+,40.000,", "10.000", 2), "target_mm"),
    ("unequal run counts", "X", _drop_row("2,-,40.000,"), "target_mm"),
    ("target outside travel", "X", _cell("1,+,500.000,", "500.500", 2), "target_mm"),
]


@pytest.mark.parametrize("what,which,edit,field", BAD, ids=[b[0] for b in BAD])
def test_bad_input_exit_2_and_no_output(tmp_path: Path, capsys, what, which, edit,
                                        field) -> None:
    syn = dataset(tmp_path, seed=9, axes=("X",))
    path = syn.machine if which == "machine" else syn.laser[which]
    path.write_text(edit(path.read_text()))
    out = tmp_path / "o"
    out.mkdir()
    (out / "keep.txt").write_text("previous output")
    assert fit(syn.machine, out, "--no-clib-check") == 2
    err = capsys.readouterr().err
    assert f"{path}:" in err and f"field '{field}'" in err, err
    assert sorted(p.name for p in out.iterdir()) == ["keep.txt"]  # nothing partial written
    assert not list(tmp_path.glob(".o.tmp-*"))


def test_late_failure_leaves_no_output(tmp_path: Path, capsys) -> None:
    """X fits, then the Y file is bad: still nothing written."""
    syn = dataset(tmp_path, seed=10, axes=("X", "Y"))
    syn.laser["Y"].write_text(_cell("3,-,-100.000,", "NaN", 5)(syn.laser["Y"].read_text()))
    out = tmp_path / "o"
    assert fit(syn.machine, out, "--no-clib-check") == 2
    assert f"{syn.laser['Y']}:" in capsys.readouterr().err
    assert not out.exists() and not list(tmp_path.glob(".o.tmp-*"))


def test_thermal_terms_fitted_from_temp_c(tmp_path: Path) -> None:
    """Laser lines with temp_c: the fit models the own positioning term's offset and
    expansion per kelvin (the table's THERMAL feature), the other terms hold at T_ref."""
    from abbe.model.table import FEATURE_THERMAL
    spec = (Path(__file__).resolve().parents[3] / "examples" / "vmc500" / "spec.toml").read_text()
    spec = (spec.replace("rise_k = 1.2", "rise_k = 4.0")
            .replace("time_constant_s = 7200.0", "time_constant_s = 2400.0")
            .replace("expansion_ppm_per_k = [2.0, 2.0, 3.0]", "expansion_ppm_per_k = [8.0, 6.0, 10.0]")
            .replace("offset_um_per_k = [0.5, -0.5, 1.0]", "offset_um_per_k = [2.0, -1.5, 1.0]"))
    (tmp_path / "spec.toml").write_text(spec)
    assert main(["simulate", str(tmp_path / "spec.toml"), "-o", str(tmp_path / "sim")]) == 0
    out = tmp_path / "out"
    assert fit(tmp_path / "sim" / "machine.toml", out, "--no-clib-check", "--no-report", "-q") == 0
    d = json.loads((out / "model.json").read_text())
    t = read_blob((out / "model.bin").read_bytes())
    assert t.features() & FEATURE_THERMAL
    truth = {"X": (2.0, 8.0), "Y": (-1.5, 6.0), "Z": (1.0, 10.0)}
    fitted = 0
    for a, (o, al) in truth.items():
        th = d["axes"][a]["thermal"]
        if th["temp_range_k"] < 0.5:      # measured once warm (the Z line comes last)
            continue
        fitted += 1
        assert th["in_table"], (a, th)
        assert abs(th["offset_um_per_k"] - o) < 4 * th["se_offset_um_per_k"] + 0.1 * abs(o), (a, th)
        assert abs(th["expansion_ppm_per_k"] - al) < 4 * th["se_expansion_ppm_per_k"] + 0.1 * al, (a, th)
        ax = t.axes[a]
        assert ax.thermal_offset_um_per_k == pytest.approx(th["offset_um_per_k"], abs=1e-3)
        assert ax.thermal_tref_c == pytest.approx(th["tref_c"], abs=1e-3)
    assert fitted >= 2


def test_read_only_out_is_bad_input_and_nothing_changes(tmp_path: Path) -> None:
    """``-o OUT`` where OUT exists and is read-only: exit 2 naming OUT, OUT untouched
    (issue 24: it was an internal error, exit 70). Run as an unprivileged user, since
    root may write into a read-only folder."""
    import os
    import shutil
    import subprocess
    import sys

    import tempfile

    if os.geteuid() == 0 and shutil.which("setpriv") is None:
        pytest.skip("running as root without setpriv: cannot drop privileges")
    # pytest's own temporary folders are private to root: a world-traversable one
    tmp_path = Path(tempfile.mkdtemp(prefix="abbe-ro-", dir=tempfile.gettempdir()))
    try:
        _read_only_out(tmp_path)
    finally:
        for p in tmp_path.rglob("*"):
            if p.is_dir():
                p.chmod(0o755)
        shutil.rmtree(tmp_path, ignore_errors=True)


def _read_only_out(tmp_path: Path) -> None:
    import os
    import subprocess
    import sys

    syn = dataset(tmp_path, seed=5)
    out = tmp_path / "OUT"
    out.mkdir()
    (out / "old.txt").write_text("kept\n")
    for p in [tmp_path, *tmp_path.rglob("*")]:
        if os.geteuid() == 0:
            os.chown(p, 65534, 65534)
    os.chmod(tmp_path, 0o777)
    out.chmod(0o555)
    cmd = [sys.executable, "-m", "abbe.cli", "fit", str(syn.machine), "-o", str(out),
           "--no-report", "--no-clib-check", "-q"]
    if os.geteuid() == 0:
        cmd = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups", *cmd]
    env = dict(os.environ, HOME=str(tmp_path), MPLCONFIGDIR=str(tmp_path / ".mpl"),
               PYTHONPATH=str(Path(__file__).resolve().parents[2]))
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    out.chmod(0o755)
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert str(out) in r.stderr and "read-only" in r.stderr, r.stderr
    assert "internal error" not in r.stderr
    assert sorted(p.name for p in out.iterdir()) == ["old.txt"]
    assert (out / "old.txt").read_text() == "kept\n"
    assert not [p for p in tmp_path.iterdir() if ".abbe-" in p.name]


def test_write_error_in_the_staging_names_out(tmp_path: Path, monkeypatch, capsys) -> None:
    """A write that fails inside the staging folder (here: permission, simulated) is
    bad input naming OUT, exit 2, and leaves nothing behind."""
    import errno

    import abbe.cli.fit as fit_cli

    syn = dataset(tmp_path, seed=5)
    out = tmp_path / "out"

    def refuse(res, staging, **kw):
        raise PermissionError(errno.EACCES, "Permission denied", str(staging / "model.bin"))

    monkeypatch.setattr(fit_cli, "write_outputs", refuse)
    assert fit(syn.machine, out, "--no-clib-check", "--no-report", "-q") == 2
    err = capsys.readouterr().err
    assert str(out) in err and "Permission denied" in err, err
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if ".abbe-" in p.name]


def test_fit_report_reads_verdict_first(fitted) -> None:
    """The fit report opens with machine, test, date and table, then the band: what the
    written table leaves of each axis' own positioning error with its U (k = 2); the
    per-term detail follows."""
    from report_shots import assert_band_before

    syn, out = fitted
    page = (out / "report" / "index.html").read_text()
    assert page.index("<b>Machine</b>") < page.index("<b>Date</b>") < page.index("id='verdict'")
    assert_band_before(page, "<h2>X axis</h2>", "paper 3rd-order Fourier")
    band = page[page.index("id='verdict'"):page.index("</div>", page.index("id='verdict'"))]
    mj = json.loads((out / "model.json").read_text())
    for a, own in (("X", "dx"), ("Y", "dy"), ("Z", "dz")):
        c = mj["uncertainty"]["axes"][a]["terms"][own]["compensated_residual_um"]
        assert f"{a} {c['max_abs']:.2f} &plusmn; {c['max_abs_U']:.2f} um" in band
