"""The atomic output writer: all outputs of a command or none, the old result intact."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from abbe.errors import AbbeInputError
from abbe.formats import output
from abbe.formats.output import Outputs


def _tree(p: Path) -> dict[str, bytes]:
    return {str(q.relative_to(p)): q.read_bytes() for q in sorted(p.rglob("*")) if q.is_file()}


def _no_leftovers(parent: Path) -> None:
    assert not [q for q in parent.iterdir() if ".abbe-" in q.name]


def test_new_folder_appears_whole(tmp_path):
    out = tmp_path / "a" / "b" / "out"
    with Outputs() as o:
        d = o.directory(out)
        assert not out.exists() and d.parent == out.parent
        (d / "x.txt").write_text("1")
        (d / "sub").mkdir()
        (d / "sub" / "y.txt").write_text("2")
    assert _tree(out) == {"x.txt": b"1", "sub/y.txt": b"2"}
    _no_leftovers(out.parent)


def test_existing_folder_swapped_keeping_foreign_entries(tmp_path):
    out = tmp_path / "out"
    (out / "report").mkdir(parents=True)
    (out / "report" / "old.png").write_text("stale")
    (out / "model.bin").write_text("old")
    (out / "notes.txt").write_text("mine")
    (out / "mydir").mkdir()
    (out / "mydir" / "f").write_text("keep")
    inode = os.stat(out / "notes.txt").st_ino
    with Outputs() as o:
        d = o.directory(out)
        (d / "model.bin").write_text("new")
        (d / "report").mkdir()
        (d / "report" / "new.png").write_text("n")
        assert (out / "model.bin").read_text() == "old"  # untouched until the swap
    assert _tree(out) == {"model.bin": b"new", "notes.txt": b"mine", "mydir/f": b"keep",
                          "report/new.png": b"n"}
    assert os.stat(out / "notes.txt").st_ino == inode  # carried over as a hard link
    _no_leftovers(tmp_path)


def test_failure_keeps_the_old_result_and_removes_created_folders(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "model.bin").write_text("old")
    before = _tree(out)
    with pytest.raises(RuntimeError):
        with Outputs() as o:
            d = o.directory(out)
            (d / "model.bin").write_text("half")
            raise RuntimeError("boom")
    assert _tree(out) == before
    fresh = tmp_path / "new" / "deeper" / "out"
    with pytest.raises(RuntimeError):
        with Outputs() as o:
            o.directory(fresh)
            raise RuntimeError("boom")
    assert not (tmp_path / "new").exists()
    _no_leftovers(tmp_path)


def test_second_output_failing_rolls_back_the_first(tmp_path, monkeypatch):
    out = tmp_path / "out"
    out.mkdir()
    (out / "model.bin").write_text("old")
    js = tmp_path / "d.json"
    js.write_text("old json")
    real = os.replace

    def failing_replace(a, b):
        if str(b) == str(js):
            raise OSError(28, "No space left on device", str(b))
        return real(a, b)

    monkeypatch.setattr(output.os, "replace", failing_replace)
    with pytest.raises(AbbeInputError, match="No space left"):
        with Outputs() as o:
            d = o.directory(out)
            f = o.file(js, option="--json")
            (d / "model.bin").write_text("new")
            f.write_text("new json")
    assert (out / "model.bin").read_text() == "old"
    assert js.read_text() == "old json"
    _no_leftovers(tmp_path)


def test_without_rename_exchange_the_fallback_still_swaps(tmp_path, monkeypatch):
    monkeypatch.setattr(output, "_exchange", lambda a, b: False)
    out = tmp_path / "out"
    out.mkdir()
    (out / "a").write_text("old")
    (out / "keep").write_text("k")
    with Outputs() as o:
        (o.directory(out) / "a").write_text("new")
    assert _tree(out) == {"a": b"new", "keep": b"k"}
    _no_leftovers(tmp_path)


def test_working_directory_output_swaps_entries(tmp_path, monkeypatch):
    out = tmp_path / "here"
    out.mkdir()
    (out / "spec.toml").write_text("input")
    (out / "laser").mkdir()
    (out / "laser" / "x.csv").write_text("old")
    monkeypatch.chdir(out)
    with Outputs() as o:
        d = o.directory(".")
        (d / "laser").mkdir()
        (d / "laser" / "x.csv").write_text("new")
        (d / "machine.toml").write_text("m")
    assert Path.cwd().samefile(out)
    assert _tree(out) == {"spec.toml": b"input", "laser/x.csv": b"new", "machine.toml": b"m"}
    _no_leftovers(tmp_path)
    _no_leftovers(out)


@pytest.mark.parametrize("make,kind,msg", [
    (lambda p: p.write_text("x"), "dir", "exists and is not a folder"),
    (lambda p: p.mkdir(), "file", "is a folder"),
])
def test_wrong_kind_of_target(tmp_path, make, kind, msg):
    p = tmp_path / "t"
    make(p)
    o = Outputs()
    with pytest.raises(AbbeInputError, match=msg) as ei:
        o.directory(p) if kind == "dir" else o.file(p, option="--json")
    assert ei.value.file == str(p)
    (tmp_path / "f").write_text("x")
    with pytest.raises(AbbeInputError, match="is a file, not a folder"):
        Outputs().directory(tmp_path / "f" / "sub")
    _no_leftovers(tmp_path)


def test_symlinked_output_is_written_through(tmp_path):
    real = tmp_path / "real"
    real.mkdir()
    link = tmp_path / "link"
    link.symlink_to(real)
    with Outputs() as o:
        (o.directory(link) / "a").write_text("1")
    assert link.is_symlink() and (real / "a").read_text() == "1"


def test_a_file_inside_the_output_folder_lands_with_it(tmp_path):
    """``-o OUT --json OUT/summary.json`` (the README's demo command): the file is staged
    inside the folder's staging, both appear together, nothing is left beside them."""
    out = tmp_path / "out"
    with Outputs() as o:
        d = o.directory(out, option="--out")
        js = o.file(out / "summary.json", option="--json")
        deep = o.file(out / "sub" / "x.json", option="--other")
        assert not out.exists() and js.parent == d and deep.parent == d / "sub"
        (d / "index.html").write_text("page")
        js.write_text("{}")
        deep.write_text("[]")
    assert _tree(out) == {"index.html": b"page", "summary.json": b"{}", "sub/x.json": b"[]"}
    _no_leftovers(tmp_path)
    _no_leftovers(out)
    # again over the old result: what this run writes is replaced, the rest carried over
    (out / "mine.txt").write_text("keep")
    with Outputs() as o:
        d = o.directory(out, option="--out")
        js = o.file(out / "summary.json", option="--json")
        (d / "index.html").write_text("page 2")
        js.write_text('{"n": 2}')
    assert _tree(out) == {"index.html": b"page 2", "summary.json": b'{"n": 2}', "mine.txt": b"keep",
                          "sub/x.json": b"[]"}
    _no_leftovers(tmp_path)
    _no_leftovers(out)


def test_a_failure_leaves_the_folder_and_its_file_as_they_were(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(RuntimeError):
        with Outputs() as o:
            o.directory(out, option="--out")
            o.file(out / "summary.json", option="--json").write_text("half")
            raise RuntimeError("boom")
    assert not out.exists()
    _no_leftovers(tmp_path)


def test_a_file_output_cannot_be_the_output_folder(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(AbbeInputError, match="is also the path of --out"):
        with Outputs() as o:
            o.directory(out, option="--out")
            o.file(out, option="--json")
    assert not out.exists()
    _no_leftovers(tmp_path)


def test_an_output_folder_that_appears_meanwhile_is_left_alone_and_nothing_staged_stays(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(AbbeInputError, match="appeared while the command ran"):
        with Outputs() as o:
            d = o.directory(out, option="--out")
            (d / "model.bin").write_text("new")
            out.mkdir()
            (out / "theirs.txt").write_text("someone else's")
    assert _tree(out) == {"theirs.txt": b"someone else's"}
    _no_leftovers(tmp_path)
