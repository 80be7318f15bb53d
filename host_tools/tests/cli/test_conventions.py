"""CLI conventions (abbe.cli.conventions): repeatable list options, single options given
once, an example in every command's help, --version, exit status 2 on usage errors."""

from __future__ import annotations

import argparse

import pytest

from abbe import __version__
from abbe.cli import conventions
from abbe.cli.entry import build_parser, main


def _commands() -> list[tuple[tuple[str, ...], argparse.ArgumentParser]]:
    return [(path, p) for path, p in conventions.walk(build_parser())]


def test_every_command_help_has_an_example() -> None:
    missing = []
    for path, p in _commands():
        if not (p.epilog or "").startswith(("example:\n", "examples:\n")):
            missing.append(" ".join(("abbe",) + path))
        else:
            for line in p.epilog.splitlines()[1:]:
                assert line.strip().startswith("abbe"), (path, line)
    assert not missing, f"commands without an example in --help: {missing}"


def test_every_list_option_extends() -> None:
    """A list option must accept `--opt a b` and `--opt a --opt b` (action='extend')."""
    bad = []
    for path, p in _commands():
        for a in p._actions:
            if a.option_strings and a.nargs in ("+", "*") and not isinstance(a, argparse._ExtendAction):
                bad.append((" ".join(path), a.option_strings))
            if isinstance(a, argparse._AppendAction) and not isinstance(a, argparse._ExtendAction):
                bad.append((" ".join(path), a.option_strings))  # append: `--opt a b` fails
    assert not bad, f"list options that drop repeated values: {bad}"


@pytest.mark.parametrize("argv, want", [
    (["--ballbar", "xy", "--ballbar", "zx", "--ballbar", "yz"], ["xy", "zx", "yz"]),
    (["--ballbar", "xy", "zx", "yz"], ["xy", "zx", "yz"]),
    (["--ballbar", "xy", "zx", "--ballbar", "yz"], ["xy", "zx", "yz"]),
])
def test_repeated_list_option_keeps_every_value(argv: list[str], want: list[str]) -> None:
    args = build_parser().parse_args(["diagnose", "m.toml", "--model", "m.bin", "-o", "out", *argv])
    assert args.ballbar == want
    args = build_parser().parse_args(["predict", "m.toml", "--model", "m.bin", *argv])
    assert args.ballbar == want


def test_repeated_single_option_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as e:
        build_parser().parse_args(["diagnose", "m.toml", "--model", "a.bin", "--model", "b.bin",
                                   "-o", "out"])
    assert e.value.code == 2
    assert "--model given more than once" in capsys.readouterr().err


def test_single_option_once_is_fine() -> None:
    args = build_parser().parse_args(["diagnose", "m.toml", "--model", "a.bin", "-o", "out"])
    assert args.model == "a.bin" and not hasattr(conventions.clean(args), "_abbe_options_seen")


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    assert capsys.readouterr().out.strip() == f"abbe {__version__}"


def test_usage_error_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as e:
        main(["fit"])  # missing machine file and -o
    assert e.value.code == 2
