"""The wheel works outside the checkout (scripts/test.sh runs this as its own step).

Builds the wheel from host_tools/ (scikit-build-core runs the repository's CMake
project), installs it with the pinned environment of host_tools/requirements.lock
into a fresh venv in a temporary directory, and runs ``abbe`` there from a working
directory outside the checkout, with no ABBE_LIB and no build tree in reach:
``abbe demo`` (no argument), ``abbe fit`` with its C-library check, ``abbe diagnose``.
Nothing may be written into site-packages.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest

HOST_TOOLS = Path(__file__).resolve().parents[2]
LOCK = HOST_TOOLS / "requirements.lock"


def _run(cmd: list[str], cwd: Path, env: dict[str, str], timeout: float = 600) -> subprocess.CompletedProcess:
    r = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert r.returncode == 0, f"{' '.join(map(str, cmd))} -> {r.returncode}\n{r.stdout}\n{r.stderr}"
    return r


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    tmp = tmp_path_factory.mktemp("wheel")
    env = {k: v for k, v in os.environ.items()
           if k not in ("ABBE_LIB", "PYTHONPATH", "VIRTUAL_ENV", "PYTHONHOME")}
    t0 = time.perf_counter()
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
          "-w", str(tmp / "dist"), str(HOST_TOOLS)], cwd=tmp, env=env)
    build_s = time.perf_counter() - t0
    (wheel,) = (tmp / "dist").glob("abbe-*.whl")
    venv = tmp / "venv"
    _run([sys.executable, "-m", "venv", str(venv)], cwd=tmp, env=env)
    py = venv / "bin" / "python"
    _run([str(py), "-m", "pip", "install", "-q", "--require-hashes", "--no-deps", "-r", str(LOCK)],
         cwd=tmp, env=env)
    _run([str(py), "-m", "pip", "install", "-q", "--no-deps", str(wheel)], cwd=tmp, env=env)
    site = Path(_run([str(py), "-c", "import abbe, pathlib; print(pathlib.Path(abbe.__file__).parent)"],
                     cwd=tmp, env=env).stdout.strip())
    work = tmp / "work"
    work.mkdir()
    return {"wheel": wheel, "venv": venv, "abbe": venv / "bin" / "abbe", "py": py, "site": site,
            "work": work, "env": env, "build_s": build_s}


def _snapshot(d: Path) -> dict[str, float]:
    return {str(p.relative_to(d)): p.stat().st_mtime for p in d.rglob("*")
            if "__pycache__" not in p.parts}


def test_wheel_carries_the_library_headers_and_examples(installed: dict) -> None:
    names = zipfile.ZipFile(installed["wheel"]).namelist()
    assert "abbe/_lib/libabbe.so" in names
    assert "abbe/_lib/include/abbe/abbe.h" in names
    assert "abbe/examples/vmc500/machine.toml" in names
    assert not any(n.startswith(("tests/", "cases/", "bench/")) for n in names)
    size = Path(installed["wheel"]).stat().st_size
    print(f"\nwheel {Path(installed['wheel']).name}: {size} bytes, built in {installed['build_s']:.1f} s")


def test_installed_package_is_not_the_checkout(installed: dict) -> None:
    site: Path = installed["site"]
    assert HOST_TOOLS not in site.parents and site != HOST_TOOLS / "abbe"
    r = _run([str(installed["py"]), "-c", "from abbe import paths; print(paths.library_path()); "
              "print(paths.checkout_root())"], cwd=installed["work"], env=installed["env"])
    lib, root = r.stdout.split()
    assert Path(lib) == site / "_lib" / "libabbe.so" and root == "None"
    r = _run([str(installed["abbe"]), "--version"], cwd=installed["work"], env=installed["env"])
    assert r.stdout.startswith("abbe ")


def test_demo_fit_diagnose_outside_the_checkout(installed: dict) -> None:
    abbe, work, env, site = installed["abbe"], installed["work"], installed["env"], installed["site"]
    before = _snapshot(site)
    t0 = time.perf_counter()
    _run([str(abbe), "demo", "--json", "summary.json"], cwd=work, env=env)
    demo_s = time.perf_counter() - t0
    assert (work / "abbe-demo" / "index.html").is_file()
    s = json.loads((work / "summary.json").read_text())
    assert s["roundness_after_um"] < 0.5 * s["roundness_before_um"]
    print(f"\nabbe demo from the wheel: {demo_s:.1f} s; roundness {s['roundness_before_um']} -> "
          f"{s['roundness_after_um']} um")

    machine = site / "examples" / "vmc500" / "machine.toml"
    r = _run([str(abbe), "fit", str(machine), "-o", "fit-out", "-q"], cwd=work, env=env)
    assert "C library agrees with the reference" in r.stdout
    assert (work / "fit-out" / "model.bin").is_file()

    _run([str(abbe), "diagnose", str(machine), "--model", "fit-out/model.bin", "--ballbar",
          "circle1", "-o", "diag-out", "--json", "diag.json"], cwd=work, env=env)
    d = json.loads((work / "diag.json").read_text())
    named = {e["key"] for e in d["effects"]}
    assert "squareness_xy" in named, named
    assert (work / "diag-out" / "model.bin").is_file()
    assert _snapshot(site) == before, "abbe wrote into site-packages"
