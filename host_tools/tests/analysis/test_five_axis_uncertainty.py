"""Five-axis results with U (k = 2): the JSON and text carry U and the budget (each block's
standard deviation), and the Monte Carlo (new observations, the exact model solved again)
agrees with the analytic U of the location errors within 10 %."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from abbe.analysis.five_axis import uncertainty as fx
from abbe.analysis.five_axis.data import load_plan
from abbe.analysis.five_axis.identify import identify
from abbe.analysis.five_axis.problem import build_params
from abbe.analysis.five_axis.report import text_report, to_json
from abbe.formats.machine import load_machine

REPO = Path(__file__).resolve().parents[3]
EXAMPLE = REPO / "examples" / "trunnion5ax" / "machine.toml"


@pytest.fixture(scope="module")
def solved():
    spec = load_machine(EXAMPLE).five_axis
    plan = load_plan(spec)
    params = build_params(spec, plan.blocks)
    return spec, plan, params, identify(spec, plan.blocks, params)


def test_json_and_text_carry_U_and_the_budget(solved) -> None:
    spec, plan, params, res = solved
    doc = to_json(res, spec, plan)
    rows = {r["name"]: r for r in doc["parameters"]}
    ey = rows["EY0A"]
    assert ey["U"] == pytest.approx(2.0 * ey["u"]) and ey["ci95"] == pytest.approx(1.96 * ey["u"])
    assert rows["EA0A"]["U"] is None  # not observable: no number
    b = doc["uncertainty"]
    assert b["k"] == 2.0 and {i["block"] for i in b["inputs"]} == {x.key for x in plan.blocks}
    text = text_report(doc)
    assert "k = 2" in text and f"+- {ey['U']:.3f}" in text


def test_monte_carlo_checks_every_U_and_is_stated_where_first_order_fails(tmp_path) -> None:
    """abbe fit --mc: the Monte Carlo (new observations, the exact model solved again)
    beside every observable parameter's U; within 10 % the first order is stated, else
    the Monte Carlo's U (and u, ci95 with it), and the text report states that figure."""
    from abbe.cli.entry import main
    out = tmp_path / "fit5"
    assert main(["fit", str(EXAMPLE), "-o", str(out), "--mc", "200", "--no-report", "-q"]) == 0
    import json
    doc = json.loads((out / "five_axis.json").read_text())
    mc = doc["uncertainty"]["monte_carlo"]
    assert mc["draws"] == 200 and 0 < mc["agree"] < mc["of"]
    rows = {r["name"]: r for r in doc["parameters"] if r["observable"]}
    for r in rows.values():
        assert r["U_mc"] > 0 and np.isfinite(r["U_mc"])
        ok = abs(r["U_mc"] / r["U_first_order"] - 1.0) <= fx.AGREEMENT
        assert r["U"] == pytest.approx(r["U_first_order"] if ok else r["U_mc"])
        assert r["ci95"] == pytest.approx(0.98 * r["U"], rel=1e-3)
        assert r["U_from"].startswith("first order" if ok else "Monte Carlo")
    for n in ("EY0A", "EZ0A", "EC0A"):
        assert rows[n]["U_from"].startswith("first order"), rows[n]
    # EX0C (U 37 um: weakly seen, the R-test mount's bilinear terms beside it) is where the
    # first order fails (the Monte Carlo's U 23-25 % larger, 200-400 draws): stated from it
    ex = rows["EX0C"]
    assert ex["U_mc"] / ex["U_first_order"] - 1.0 > fx.AGREEMENT and ex["U"] == ex["U_mc"]
    text = (out / "report.txt").read_text()
    assert f"+- {ex['U']:.3f}" in text


def test_mc_is_refused_on_a_three_axis_file(tmp_path, capsys) -> None:
    from abbe.cli.entry import main
    assert main(["fit", str(REPO / "examples" / "vmc500" / "machine.toml"), "-o",
                 str(tmp_path / "o"), "--mc", "10"]) == 2
    assert "abbe table uncertainty --mc" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_a_second_sphere_height_identifies_ex0c_and_eb0c(tmp_path: Path) -> None:
    """Issue 37 item 5, measured: the example's plan plus a second sphere height
    (cases/five_axis_second_sphere.py) sees EX0C within a few um (37 um without) and EB0C;
    what stays unseen needs a datum, and the confounded group says so."""
    import json

    from cases.five_axis_second_sphere import generate
    mf = generate(tmp_path)
    spec = load_machine(mf).five_axis
    plan = load_plan(spec)
    params = build_params(spec, plan.blocks)
    res = identify(spec, plan.blocks, params)
    truth = json.loads((tmp_path / "truth.json").read_text())["location"]
    names = [p.name for p in params]
    for n in ("EX0C", "EB0C", "EY0A", "EB0A"):
        i = names.index(n)
        assert res.obs.observable[i], n
        assert abs(res.x[i] - truth[n]) <= 2.0 * res.sd[i] + 0.3, (n, res.x[i], truth[n])
    assert 2.0 * res.sd[names.index("EX0C")] < 5.0
    unseen = {n for i, n in enumerate(names) if params[i].kind == "location"
              and not res.obs.observable[i]}
    assert unseen == {"EA0A", "EY0C", "EA0C", "EC0C"}
    group = next(g for g in res.obs.groups if "EA0A" in g)
    assert "probe.S2 sphere y" in group  # the spheres' positions: a datum would fix them
