"""A message that tells the user what to do says it once (issue 37): `abbe fit` and
`abbe demo` without the C library (a fresh `scripts/setup.sh` venv before the CMake
build) name where they looked and the build command one time each, exit 3, and write
nothing."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]


def _abbe(tmp: Path, *argv: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, ABBE_LIB=str(tmp / "missing" / "libabbe.so"))
    return subprocess.run([sys.executable, "-m", "abbe.cli", *argv], capture_output=True,
                          text=True, env=env, cwd=tmp, timeout=600)


@pytest.mark.parametrize("argv", [["fit", str(REPO / "examples" / "vmc500" / "machine.toml"),
                                   "-o", "out"],
                                  ["demo", "-o", "out"]])
def test_missing_library_advice_is_said_once(tmp_path, argv) -> None:
    r = _abbe(tmp_path, *argv)
    assert r.returncode == 3, r.stderr
    err = r.stderr
    assert err.count("cmake -S . -B build") == 1, err
    assert err.count("ABBE_LIB") == 1, err
    assert err.count(str(tmp_path / "missing" / "libabbe.so")) == 1, err
    assert len(err.strip().splitlines()) == 1, err
    # the demo has no --no-clib-check: only abbe fit offers it
    assert ("--no-clib-check" in err) == (argv[0] == "fit")
    assert not (tmp_path / "out").exists()
