"""chain_fit.json, predict.json 1.1 and iso230_3.json 1.1 read by the independent readers
of tests/doc_json_readers.py (written from docs/formats.md, not from the writers): the
real commands on the example inputs pass every documented check, and each reader refuses
a document broken the ways the formats forbid (NaN, a U below 0 or not 2 u, k != 2, the
wrong version tag, a range that is not max - min, a stated U the 10 % rule does not give,
an envelope that is not the largest channel, a table that is not the one named), so the
checks can fail. The same readers run inside the tests that already produce these files
with other options (error motions, --mc 200 / 1000, no table): test_fit_chain.py,
test_fit_chain_ballbar.py, test_predict.py, test_cli_thermal.py."""

from __future__ import annotations

import copy
import json
import shutil
from pathlib import Path

import pytest

from abbe.cli.entry import main
from diagnose_json_reader import read_diagnose_uncertainty
from doc_json_readers import FormatError, read_chain_fit, read_iso230_3, read_predict

REPO = Path(__file__).resolve().parents[3]
VMC = REPO / "examples" / "vmc500"
THERMAL = REPO / "examples" / "spindle_thermal" / "machine.toml"


def _rewrite(src: Path, dst_dir: Path, doc: dict) -> Path:
    """The document as a writer would put it (indented, strict unless told otherwise),
    beside a copy of the files it names."""
    if dst_dir.exists():
        shutil.rmtree(dst_dir)
    shutil.copytree(src.parent, dst_dir)
    out = dst_dir / src.name
    out.write_text(json.dumps(doc, indent=1), encoding="utf-8")
    return out


def _refused(reader, src: Path, tmp: Path, change, match: str, **kw) -> None:
    doc = json.loads(src.read_text(encoding="utf-8"))
    bad = copy.deepcopy(doc)
    change(bad)
    with pytest.raises(FormatError, match=match):
        reader(_rewrite(src, tmp / "bad", bad), **kw)
    reader(_rewrite(src, tmp / "good", doc), **kw)  # the untouched copy still passes


# ------------------------------------------------------------------------ chain_fit.json

@pytest.fixture(scope="module")
def chain_fit(tmp_path_factory) -> tuple[Path, Path]:
    """abbe fit --mc 20 on a dual-rotary table's rotary ballbar campaign (the independent
    generator's readings, tests/cli/test_fit_chain_ballbar.py)."""
    from cli.test_fit_chain_ballbar import _write
    tmp = tmp_path_factory.mktemp("chainfit")
    m, _truth = _write(tmp, "table-dual-rotary-xyzab.toml", 17)
    assert main(["fit", str(m), "-o", str(tmp / "o"), "-q", "--mc", "20"]) == 0
    return tmp / "o" / "chain_fit.json", m


def test_chain_fit_json_reads_as_documented(chain_fit) -> None:
    path, machine = chain_fit
    d = read_chain_fit(path, machine)
    seen = [r for r in d["location"] if r["value"] is not None]
    assert seen and all(r["U"] > 0 and "U_mc" in r for r in seen)
    assert len(d["rotary_ballbar"]) == 12 and d["blob"]["file"] == "model_five.bin"


@pytest.mark.parametrize("change, match", [
    (lambda d: d.update(format="abbe-chain-fit 1.1"), "format"),
    (lambda d: d["uncertainty"].update(k=1.96), "k must be 2"),
    (lambda d: d["location"][_seen(d)].update(U=-1.0), r"\.U"),
    (lambda d: d["location"][_seen(d)].update(u95=d["location"][_seen(d)]["U"]), "u95"),
    (lambda d: d["location"][_seen(d)].update(value=float("nan")), "NaN"),
    (lambda d: d["location"][_none(d)].update(U=1.0), "unseen"),
    (lambda d: d["location"][_seen(d)].update(status="convention"), "status"),
    (lambda d: _flip_from(d["location"][_seen(d)]), "U_from"),
    (lambda d: d["uncertainty"]["monte_carlo"].update(of=99), "monte_carlo.of"),
    (lambda d: d["blob"].update(crc32="0x00000000"), "crc32"),
    (lambda d: d["blob"].update(bytes=d["blob"]["bytes"] + 4), "blob.bytes"),
    (lambda d: d["blob"]["convention"]["fixed_at_zero"].pop(), "convention"),
    (lambda d: d["provenance"].update(sha256="0" * 64), "sha256"),
    (lambda d: d.update(extra=1), "undocumented"),
    (lambda d: d["setup_um"].pop("set-up K1.tool_ball_y"), "tool_ball_y"),
    (lambda d: next(iter(d["rotary_ballbar"].values())).update(left_rms_um=1e3), "peak-to-valley"),
])
def test_chain_fit_reader_refuses_what_the_format_forbids(chain_fit, tmp_path, change,
                                                         match) -> None:
    path, machine = chain_fit
    _refused(read_chain_fit, path, tmp_path, change, match, machine_file=machine)


def _seen(d: dict) -> int:
    return next(i for i, r in enumerate(d["location"]) if r["value"] is not None)


def _flip_from(r: dict) -> None:
    """U_from naming the other source than the one the 10 % rule picked."""
    r["U_from"] = "first order" if r["U_from"].startswith("Monte Carlo") else "Monte Carlo"


def _none(d: dict) -> int:
    return next(i for i, r in enumerate(d["location"]) if r["value"] is None)


# -------------------------------------------------------------------------- predict.json

@pytest.fixture(scope="module")
def predict_json(tmp_path_factory) -> Path:
    """abbe predict --mc 20 of examples/vmc500's circle1 through its true table."""
    from abbe.formats.blob import quantize, write_blob
    from abbe.model import clib
    from abbe.sim.truth import load_truth, truth_table
    if not clib.available():
        pytest.skip("C library not built (build/lib/libabbe.so): abbe predict needs it")
    tmp = tmp_path_factory.mktemp("predict")
    (tmp / "model.bin").write_bytes(write_blob(quantize(truth_table(
        load_truth(VMC / "truth" / "truth.json")))))
    assert main(["predict", str(VMC / "machine.toml"), "--model", str(tmp / "model.bin"),
                 "--ballbar", "circle1", "-o", str(tmp / "o"), "--mc", "20"]) == 0
    return tmp / "o" / "predict.json"


def test_predict_json_reads_as_documented(predict_json) -> None:
    d = read_predict(predict_json)
    (p,) = d["predictions"]
    assert p["ballbar"] == "circle1" and p["residual_max_U_um"] > 0 and p["roundness_before_U_um"] > 0


def _p(d: dict) -> dict:
    return d["predictions"][0]


@pytest.mark.parametrize("change, match", [
    (lambda d: d.update(format="abbe-predict 1.0"), "format"),
    (lambda d: d.update(k=3), "k must be 2"),
    (lambda d: _p(d).update(residual_rms_U_um=-0.1), "residual_rms_U_um"),
    (lambda d: _p(d).update(roundness_before_U_um=float("inf")), "Infinity"),
    (lambda d: _p(d).update(residual_max_U_um=_p(d)["residual_max_U_um"] + 0.01), "rounded"),
    (lambda d: _p(d).update(ideal_improvement_pct=_p(d)["ideal_improvement_pct"] + 1), "100 \\(1"),
    (lambda d: _p(d)["uncertainty"]["rms"].update(U_um=_p(d)["uncertainty"]["rms"]["u_um"]), "k = 2"),
    (lambda d: _p(d)["uncertainty"]["max_abs"]["budget_u_um"].update(scale=1.0), "root sum"),
    (lambda d: _p(d)["uncertainty"]["max_abs"].pop("U_mc_um"), "draws"),
    (lambda d: _p(d)["uncertainty"]["max_abs"].update(U_mc_um=None), "expected a number"),
    (lambda d: d["budget"]["figures"].pop("drift_c"), "missing"),
])
def test_predict_reader_refuses_what_the_format_forbids(predict_json, tmp_path, change,
                                                       match) -> None:
    _refused(read_predict, predict_json, tmp_path, change, match)


# ------------------------------------------------------------------------- iso230_3.json

@pytest.fixture(scope="module")
def iso230_3_json(tmp_path_factory) -> Path:
    """abbe thermal evaluate --mc 20 of examples/spindle_thermal (the real 46 h record)."""
    out = tmp_path_factory.mktemp("iso3") / "ev"
    assert main(["thermal", "evaluate", str(THERMAL), "-o", str(out), "--mc", "20"]) == 0
    return out / "iso230_3.json"


def test_iso230_3_json_reads_as_documented(iso230_3_json) -> None:
    d = read_iso230_3(iso230_3_json)
    assert (len(d["channels"]), len(d["tilts"]), len(d["temperatures"])) == (5, 2, 16)
    assert d["envelope"]["channel"] == "ch3" and d["envelope"]["U_um"] > 0


def _ch(d: dict, i: int = 0) -> dict:
    return d["channels"][i]


@pytest.mark.parametrize("change, match", [
    (lambda d: d.update(format="abbe-iso230-3 1.0"), "format"),
    (lambda d: d["uncertainty"].update(k=2.5), "k must be 2"),
    (lambda d: _ch(d).update(range=_ch(d)["range"] + 1.0), "max - min"),
    (lambda d: _ch(d).update(U=-_ch(d)["U"], u=-_ch(d)["u"]), r"\.u"),
    (lambda d: _ch(d).update(U=3 * _ch(d)["u"]), "k = 2"),
    (lambda d: _ch(d).update(U_first_order=_ch(d)["U_first_order"] * 1.5), "RSS"),
    (lambda d: _ch(d).update(max_h=d["duration_h"] + 1.0), "max_h"),
    (lambda d: _ch(d).update(U_mc=float("nan")), "NaN"),
    (lambda d: d["temperatures"][0].update(unit="degC"), "unit"),
    (lambda d: d["envelope"].update(channel="ch1"), "largest"),
    (lambda d: d["envelope"].update(U_um=d["envelope"]["U_um"] * 2), "envelope.U_um"),
    (lambda d: d["uncertainty"]["monte_carlo"].update(agree=-1), "agree"),
    (lambda d: d["tilts"][0]["budget_u"].pop(d["tilts"][0]["name"][-4:-1]), "no line for"),
])
def test_iso230_3_reader_refuses_what_the_format_forbids(iso230_3_json, tmp_path, change,
                                                        match) -> None:
    _refused(read_iso230_3, iso230_3_json, tmp_path, change, match)


# ------------------------------------------------------------------ diagnose.json (U fields)

@pytest.fixture(scope="module")
def diagnose_json(tmp_path_factory) -> Path:
    """abbe diagnose --iso230-2 on examples/vmc500's Y line with --mc 20 (position-only
    model: backlash_y and cyclic_y named; ~2 s)."""
    tmp = tmp_path_factory.mktemp("diag")
    assert main(["diagnose", "--iso230-2", str(VMC / "laser" / "y.csv"), "--axis", "Y", "-o",
                 str(tmp / "o"), "--no-plots", "--mc", "20"]) == 0
    return tmp / "o" / "diagnose.json"


def test_diagnose_json_uncertainty_reads_as_documented(diagnose_json) -> None:
    d = read_diagnose_uncertainty(diagnose_json, mc=20)
    assert {e["key"] for e in d["effects"]} >= {"backlash_y"}
    assert d["uncertainty"]["monte_carlo"]["of"] == len(d["effects"]) + 4


def _eff(d: dict) -> dict:
    return d["effects"][0]


def _mc_stated(d: dict) -> dict:
    """An effect and its summary entry with U taken the other way than the 10 % rule says."""
    e = _eff(d)
    other = e["U_mc"] if e["U_from"] == "first order" else e["U_first_order"]
    e.update(U=other, u=other / 2)
    return d


@pytest.mark.parametrize("change, match", [
    (lambda d: d["uncertainty"].update(k=1.96), "k must be 2"),
    (lambda d: _eff(d).update(U=2.5 * _eff(d)["u"]), "U = 2 u"),
    (lambda d: _eff(d).update(u=float("nan")), "NaN"),
    (lambda d: _eff(d)["budget_u"].update({"extra line": _eff(d)["U_first_order"]}), "RSS"),
    (lambda d: _eff(d).pop("budget_u"), "budget_u"),
    (lambda d: _eff(d).update(mc_agreement=0.5), "mc_agreement"),
    (_mc_stated, r"\.U"),
    (lambda d: d["gap"]["after"].update(rms_U_um=3 * d["gap"]["after"]["rms_U_um"]), "gap"),
    (lambda d: d["uncertainty"]["monte_carlo"].update(of=99), "of"),
    (lambda d: d["uncertainty"]["monte_carlo"].update(draws=200), "draws"),
    (lambda d: d["uncertainty"].pop("assumptions"), "assumptions"),
])
def test_diagnose_reader_refuses_what_the_docs_forbid(diagnose_json, tmp_path, change,
                                                      match) -> None:
    _refused(lambda p: read_diagnose_uncertainty(p, mc=20), diagnose_json, tmp_path, change,
             match)


def test_diagnose_reader_refuses_mc_fields_without_mc(diagnose_json) -> None:
    with pytest.raises(FormatError, match="without --mc"):
        read_diagnose_uncertainty(diagnose_json, mc=0)
