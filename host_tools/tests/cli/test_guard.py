"""The top-level guard: a bug is exit 70 with one line and a log; input problems stay exit 2."""

from __future__ import annotations

import pytest

from abbe.cli import guard
from abbe.cli.entry import main
from abbe.errors import AbbeInputError


def test_unexpected_exception_is_exit_70_with_a_log(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("ABBE_CRASH_DIR", str(tmp_path / "logs"))

    def boom():
        raise ZeroDivisionError("float division by zero")

    rc = guard.run_guarded("abbe fit", boom, ["fit", "m.toml"])
    err = capsys.readouterr().err
    assert rc == 70
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "internal error" in lines[0] and "ZeroDivisionError" in lines[0]
    log = next((tmp_path / "logs").glob("abbe-crash-*.log"))
    assert str(log) in lines[0]
    text = log.read_text()
    assert "Traceback" in text and "abbe fit m.toml" in text and "boom" in text
    assert "Traceback" not in err


def test_log_falls_back_when_the_crash_dir_cannot_be_written(tmp_path, monkeypatch, capsys):
    f = tmp_path / "afile"
    f.write_text("x")
    monkeypatch.setenv("ABBE_CRASH_DIR", str(f / "sub"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    rc = guard.run_guarded("abbe x", lambda: 1 / 0, [])
    assert rc == 70
    assert list((tmp_path / "cache" / "abbe").glob("abbe-crash-*.log"))


def test_known_problems_keep_their_statuses(capsys):
    def bad():
        raise AbbeInputError("expected a number", file="f.csv", line=3, field="x")
    assert guard.run_guarded("abbe t", bad) == 2
    assert capsys.readouterr().err == "abbe t: error: f.csv:3: field 'x': expected a number\n"

    def interrupted():
        raise KeyboardInterrupt
    assert guard.run_guarded("abbe t", interrupted) == 130

    def pipe():
        raise BrokenPipeError
    assert guard.run_guarded("abbe t", pipe) == 141


def test_a_crash_inside_a_command_through_main(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("ABBE_CRASH_DIR", str(tmp_path))
    import abbe.formats.positioning as pos

    def broken(path, **kwargs):
        raise RuntimeError("injected")
    monkeypatch.setattr(pos, "load_positioning", broken)
    import abbe.cli.iso230_2 as cmd
    monkeypatch.setattr(cmd, "load_positioning", broken)
    assert main(["iso230-2", "whatever.csv"]) == 70
    assert "RuntimeError: injected" in capsys.readouterr().err


@pytest.mark.parametrize("argv", [["fit"], ["table", "eval"], ["nosuchcommand"]])
def test_usage_errors_are_exit_2(argv, capsys):
    with pytest.raises(SystemExit) as ei:
        main(argv)
    assert ei.value.code == 2
