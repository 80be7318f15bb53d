"""Mutation fuzzing of every command through the promise-checking harness (seeded, bounded).

For each command (fuzzing.commands): its input file is replaced by mutated bytes
(hypothesis-drawn operators of fuzzing.mutate) and the command is run in-process;
the harness checks that it exits 0 or 2 (3 without the C library; 1 for a Modbus
client without a server), never 70 or a traceback, prints one line naming the file,
leaves every output exactly as it was when it fails (the outputs of a first, valid
run are in place, so "the old result stays intact" is checked too), leaves no
staging folders, and writes strict JSON. Option values are fuzzed the same way.
Longer runs: ``python -m fuzzing.run`` (from host_tools/).
"""

from __future__ import annotations

import shutil

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from fuzz_budget import DERANDOMIZE, examples

from fuzzing.commands import (
    OPTION_VALUES,
    option_slots,
    targets,
    with_option_value,
    without_comments,
)
from fuzzing.harness import run_case
from fuzzing.mutate import mutate, replace_number

#: Mutated inputs per command in CI (cheap commands get more).
EXAMPLES = {"table info": 100, "table eval": 60, "table from-json": 100, "table to-json": 50,
            "table cgen": 50, "iso230-2 dat": 100, "iso230-2 csv": 100, "fit machine": 50,
            "fit laser": 50, "fit declared": 50, "simulate": 25, "ballbar machine": 25,
            "ballbar csv": 50, "diagnose iso230-2": 25, "upload": 50, "predict": 30,
            "diagnose machine": 15, "diagnose model": 25,
            "export isg-csv": 12, "export sinumerik-lec": 12, "export sinumerik-cec": 12,
            "export heidenhain-com": 12, "export fanuc-pitch": 12, "export klipper-skew": 12,
            "export marlin": 12, "export linuxcnc-comp": 12, "export linuxcnc-matrixkins": 12,
            "export fit-json": 12, "import isg-csv": 15, "import isg-lis": 15,
            "import etalon": 15, "import machine": 10, "iso230-2 rtl": 60, "fit rtl": 25,
            "ballbar b5r": 30, "ballbar renishaw machine": 20, "program positioning": 40,
            "program ballbar": 30, "fit five-axis machine": 6, "fit five-axis probe": 6,
            "fit five-axis rtest": 4, "fit five-axis indexer": 4}


@pytest.fixture(scope="module")
def fuzz_env(seed_ws, tmp_path_factory):
    from abbe.cli.entry import main
    from abbe.model import clib
    root = tmp_path_factory.mktemp("fuzzcmd")
    model = root / "fit0"
    assert main(["fit", str(seed_ws.machine), "-o", str(model), "--no-clib-check", "--no-report",
                 "-q"]) == 0
    return root, model / "model.bin", clib.available()


def _names():
    return list(EXAMPLES)


@pytest.mark.parametrize("name", _names())
def test_command_promises_under_mutation(seed_ws, fuzz_env, name, capsys):
    root, model, have_clib = fuzz_env
    out = root / name.replace(" ", "_")
    t = {x.name: x for x in targets(seed_ws, out, model)}[name]
    if t.needs_clib and not have_clib:
        pytest.skip("C library not built")
    first = run_case(t.argv, t.outputs, allowed=t.allowed, json_stdout=t.json_stdout,
                     budget_s=t.budget_s)  # a valid first run: its outputs must survive failures
    assert first.ok and first.rc in (0, 1, 3), (first.problems, first.stderr)
    seed = t.mutated.read_bytes()
    tried = []

    @settings(max_examples=examples(EXAMPLES[name]), derandomize=DERANDOMIZE, database=None, deadline=None,
              suppress_health_check=list(HealthCheck))
    @given(st.data())
    def run(data):
        pick = lambda n: data.draw(st.integers(0, max(n - 1, 0)))  # noqa: E731
        blob, ops = mutate(seed, pick, data.draw(st.integers(1, 3)))
        t.mutated.write_bytes(blob)
        try:
            o = run_case(t.argv, t.outputs, allowed=t.allowed, json_stdout=t.json_stdout,
                         budget_s=t.budget_s)
        finally:
            t.mutated.write_bytes(seed)
        tried.append(o.rc)
        assert o.ok, (ops, o.problems, o.stderr[-500:])

    run()
    capsys.readouterr()
    assert len(tried) >= EXAMPLES[name], f"only {len(tried)} inputs tried"
    print(f"{name}: {len(tried)} inputs, exit 0: {tried.count(0)}, exit 2: {tried.count(2)}")


@pytest.mark.parametrize("name", ["table eval", "fit machine", "diagnose iso230-2", "upload",
                                  "export heidenhain-com", "export fanuc-pitch",
                                  "import isg-csv", "import etalon", "program positioning"])
def test_option_values_are_range_checked(seed_ws, fuzz_env, name, capsys):
    """Every numeric option value (and every --set NAME=VALUE) replaced by a hostile one:
    0 or 2, never a crash."""
    root, model, _ = fuzz_env
    out = root / ("opt_" + name.replace(" ", "_"))
    t = {x.name: x for x in targets(seed_ws, out, model)}[name]
    extra = {"table eval": ["--temp-c", "20", "20", "20"],
             "fit machine": ["--folds", "5", "--max-degree", "3", "--max-harmonics", "2"],
             "diagnose iso230-2": ["--alpha", "0.01", "--min-effect-um", "0.15"],
             "upload": ["--unit", "1", "--chunk", "100"],
             "export heidenhain-com": [],
             "export fanuc-pitch": ["--set", "unit_um=1", "max_value=127"],
             "import isg-csv": [], "import etalon": [],
             "program positioning": ["--feed", "2000", "--dwell-s", "3", "--overrun-mm", "4",
                                     "--runs", "5", "--targets", "7", "--seed", "3"]}[name]
    argv = t.argv + extra
    numeric = option_slots(argv)
    assert numeric

    @settings(max_examples=examples(25), derandomize=DERANDOMIZE, database=None, deadline=None,
              suppress_health_check=list(HealthCheck))
    @given(st.sampled_from(numeric), st.sampled_from(OPTION_VALUES))
    def run(i, value):
        a = with_option_value(argv, i, value)
        o = run_case(a, t.outputs, allowed=t.allowed, budget_s=t.budget_s)
        assert o.ok, (a, o.problems, o.stderr[-400:])

    run()
    capsys.readouterr()
    shutil.rmtree(out, ignore_errors=True)


HOSTILE = ["iso230-2 csv", "fit laser", "ballbar csv", "import isg-csv", "import etalon",
           "iso230-2 rtl", "fit rtl", "ballbar b5r", "fit five-axis probe", "fit five-axis rtest",
           "fit five-axis indexer"]


@pytest.mark.parametrize("name", HOSTILE)
def test_a_hostile_number_makes_the_command_refuse(seed_ws, fuzz_env, name, capsys):
    """One number of the data file replaced by a hostile one (nan, 1e400, 1_0, full-width
    digits, ...): the command must refuse it (exit 2), never exit 0 on it."""
    root, model, _ = fuzz_env
    out = root / ("hostile_" + name.replace(" ", "_"))
    t = {x.name: x for x in targets(seed_ws, out, model)}[name]
    assert t.hostile_numbers
    seed = t.mutated.read_bytes()

    @settings(max_examples=examples(20), derandomize=DERANDOMIZE, database=None, deadline=None,
              suppress_health_check=list(HealthCheck))
    @given(st.data())
    def run(data):
        pick = lambda n: data.draw(st.integers(0, max(n - 1, 0)))  # noqa: E731
        t.mutated.write_bytes(replace_number(without_comments(seed), pick))
        try:
            o = run_case(t.argv, t.outputs, allowed=t.allowed, budget_s=t.budget_s)
        finally:
            t.mutated.write_bytes(seed)
        assert o.ok and o.rc == 2, (o.rc, o.problems, o.stderr[-400:])

    run()
    capsys.readouterr()
