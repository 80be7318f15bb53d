"""One --json convention across the command line (docs/cli.md): ``--json FILE`` writes
the document, ``--json -`` prints it (and nothing else) on stdout, the bare ``--json``
of abbe 0.1 still prints it with a deprecation warning on stderr, and a bare --json in
front of an input file cannot overwrite that file."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest

from abbe.cli import conventions
from abbe.cli.entry import build_parser, main

REPO = Path(__file__).resolve().parents[3]
VMC = REPO / "examples" / "vmc500"
PAPER_TABLE = REPO / "examples" / "paper_table" / "model.bin"
DEPRECATED = "--json without a FILE is deprecated"


def _printer_cfg(tmp: Path) -> Path:
    x = np.linspace(10.0, 210.0, 9)
    y = np.linspace(10.0, 190.0, 7)
    X, Y = np.meshgrid(x, y)
    z = 0.05 * np.sin(X / 60.0) + 0.03 * (Y / 190.0) ** 2
    rows = "\n".join("#*# \t  " + ", ".join(f"{v:.6f}" for v in row) for row in z)
    p = tmp / "printer.cfg"
    p.write_text("[printer]\nkinematics: cartesian\n\n"
                 "#*# <---------------------- SAVE_CONFIG ---------------------->\n"
                 "#*# DO NOT EDIT THIS BLOCK OR BELOW. The contents are auto-generated.\n#*#\n"
                 f"#*# [bed_mesh default]\n#*# version = 1\n#*# points =\n{rows}\n"
                 f"#*# x_count = {len(x)}\n#*# y_count = {len(y)}\n#*# mesh_x_pps = 2\n"
                 "#*# mesh_y_pps = 2\n#*# algo = bicubic\n#*# tension = 0.2\n"
                 f"#*# min_x = {x[0]}\n#*# max_x = {x[-1]}\n#*# min_y = {y[0]}\n"
                 f"#*# max_y = {y[-1]}\n")
    return p


def _thermal_machine(tmp: Path) -> Path:
    from cases.thermal_independent import generate
    from thermal_helpers import machine_text
    csv, _truth, _ = generate(seed=3, noise_um=0.3)
    (tmp / "record.csv").write_text(csv)
    m = tmp / "machine.toml"
    m.write_text(machine_text("record.csv", {"chz": "z", "chx": "x"}))
    return m


def _commands(tmp: Path) -> dict[str, list[str]]:
    """Each command with a JSON document, without its --json (the output folders are
    per form: the caller appends a suffix)."""
    return {
        "iso230-2": ["iso230-2", str(VMC / "laser" / "x.csv"), "--mc", "0"],
        "ballbar": ["ballbar", str(VMC / "machine.toml"), "circle1", "--mc", "0", "--no-plot"],
        "simulate": ["simulate", str(VMC / "spec.toml"), "-o", "{out}"],
        "export": ["export", str(PAPER_TABLE), "-f", "fanuc-pitch", "-o", "{out}"],
        "printer fit": ["printer", "fit", str(_printer_cfg(tmp)), "-o", "{out}"],
        "diagnose": ["diagnose", "--iso230-2", str(VMC / "laser" / "x.csv"), "--axis", "X",
                     "-o", "{out}", "--no-plots", "--backend", "reference",
                     "--candidates", "backlash_x"],
        "thermal evaluate": ["thermal", "evaluate", str(_thermal_machine(tmp))],
    }


def _argv(cmd: list[str], out: Path) -> list[str]:
    return [str(out) if a == "{out}" else a for a in cmd]


def _drop_paths(d):
    """The document less what names the run's own output paths (they differ per run)."""
    if isinstance(d, dict):
        return {k: _drop_paths(v) for k, v in d.items() if k not in ("out", "model_path", "model")}
    if isinstance(d, list):
        return [_drop_paths(v) for v in d]
    return d


def test_every_json_option_is_the_one_convention() -> None:
    """No command may add a --json of its own kind (a store_true or a plain FILE)."""
    seen = []
    for path, p in conventions.walk(build_parser()):
        for a in p._actions:
            if "--json" in a.option_strings:
                seen.append(" ".join(path))
                assert isinstance(a, conventions._JsonAction), path
                assert a.metavar == "FILE" and "docs/cli.md" in (a.help or ""), path
    # the commands of docs/cli.md (demo has it once for both of its pipelines)
    assert sorted(seen) == sorted(["iso230-2", "ballbar", "predict", "simulate", "export",
                                   "printer fit", "demo", "diagnose", "thermal evaluate",
                                   "table uncertainty"])


@pytest.mark.parametrize("name", ["iso230-2", "ballbar", "simulate", "export", "printer fit",
                                  "diagnose", "thermal evaluate"])
def test_file_stdout_and_the_deprecated_bare_form_give_the_same_document(name, tmp_path,
                                                                          capsys) -> None:
    cmd = _commands(tmp_path)[name]
    js = tmp_path / "doc.json"
    assert main(_argv(cmd, tmp_path / "a") + ["--json", str(js)]) == 0
    text = capsys.readouterr()
    from_file = json.loads(js.read_text())
    assert DEPRECATED not in text.err
    assert main(_argv(cmd, tmp_path / "b") + ["--json", "-"]) == 0
    out = capsys.readouterr()
    from_stdout = json.loads(out.out)  # stdout is the document alone
    assert DEPRECATED not in out.err
    assert main(_argv(cmd, tmp_path / "c") + ["--json"]) == 0
    old = capsys.readouterr()
    from_bare = json.loads(old.out)
    assert old.err.count(DEPRECATED) == 1 and "--json -" in old.err
    assert _drop_paths(from_file) == _drop_paths(from_stdout) == _drop_paths(from_bare)
    # --json FILE keeps the command's text on stdout (it is not JSON)
    if name not in ("simulate",):
        with pytest.raises(json.JSONDecodeError):
            json.loads(text.out)


def test_a_bare_json_in_front_of_the_input_cannot_overwrite_it(tmp_path, capsys) -> None:
    x = tmp_path / "x.csv"
    x.write_bytes((VMC / "laser" / "x.csv").read_bytes())
    before = x.read_bytes()
    with pytest.raises(SystemExit) as exc:
        main(["iso230-2", "--json", str(x)])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "exists and is not a .json file" in err and "--json -" in err
    assert x.read_bytes() == before
    # a .json FILE that exists is replaced (a rerun writes its document again)
    js = tmp_path / "old.json"
    js.write_text("{}")
    assert main(["iso230-2", str(x), "--mc", "0", "--json", str(js)]) == 0
    assert json.loads(js.read_text())["standard"].startswith("ISO 230-2")


def test_json_given_twice_is_refused(capsys) -> None:
    with pytest.raises(SystemExit) as exc:
        main(["iso230-2", str(VMC / "laser" / "x.csv"), "--json", "-", "--json", "a.json"])
    assert exc.value.code == 2
    assert "given more than once" in capsys.readouterr().err


def test_the_help_documents_the_one_form(capsys) -> None:
    with pytest.raises(SystemExit):
        main(["ballbar", "--help"])
    out = capsys.readouterr().out
    assert "[--json FILE]" in out and "'-': print it on stdout" in out
    with pytest.raises(SystemExit):
        main(["--help"])
    top = capsys.readouterr().out
    assert "--json FILE" in top and "docs/cli.md" in top
    assert "3-axis" not in top and "five-axis" in top and "thermal" in top


def test_the_bare_form_is_a_namespace_value_of_stdout() -> None:
    p = argparse.ArgumentParser()
    conventions.json_option(p)
    conventions.apply(p)
    args = p.parse_args(["--json"])
    assert args.json == conventions.STDOUT
    assert args._abbe_deprecations
    conventions.clean(args)
    assert not hasattr(args, "_abbe_deprecations")
