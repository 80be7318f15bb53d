"""The headless copies of LinuxCNC's five-axis samples that the LinuxCNC tests run
(port/linuxcnc/tests: trt_sim_check.headless_ini, kinds_sim.headless) load basic_sim.tcl
without hal_manualtoolchange: that Tk dialog reports itself ready, then dies without a
display, and when it dies before ``loadusr -W`` has seen it ready LinuxCNC exits at start
with status 255 (once in ~55 CI runs). Pure text checks: no LinuxCNC runs here."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parents[3] / "port" / "linuxcnc" / "tests"
sys.path.insert(0, str(TESTS))

import kinds_sim as ks  # noqa: E402
import trt_sim_check as trt  # noqa: E402
from lcnc_common import headless_halfile  # noqa: E402

SAMPLES = Path("/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/vismach/5axis")
OPTION = "-no_use_hal_manualtoolchange"


def halfiles(text: str) -> list[str]:
    return [ln.strip() for ln in text.splitlines() if ln.strip().split("=", 1)[0].strip() == "HALFILE"]


def test_headless_halfile_adds_the_option_once_and_leaves_other_lines():
    assert headless_halfile("        HALFILE = LIB:basic_sim.tcl") == f"        HALFILE = LIB:basic_sim.tcl {OPTION}"
    assert headless_halfile(f"HALFILE = LIB:basic_sim.tcl -no_sim_spindle {OPTION}") == \
        f"HALFILE = LIB:basic_sim.tcl -no_sim_spindle {OPTION}"
    for line in ("HALFILE = abbe-five.hal", "POSTGUI_HALFILE = basic_sim.tcl.hal", "# HALFILE basic_sim.tcl",
                 "HALCMD = loadusr -W hal_manualtoolchange"):
        assert headless_halfile(line) == line


def test_trt_headless_ini_of_a_synthetic_sample():
    text = "[DISPLAY]\nDISPLAY = axis\n[HAL]\n        HALFILE = LIB:basic_sim.tcl\nHALFILE = x.hal\n"
    out = trt.headless_ini(text, {}, {})
    assert halfiles(out) == [f"HALFILE = LIB:basic_sim.tcl {OPTION}", "HALFILE = x.hal"]
    assert "DISPLAY = linuxcncrsh" in out


@pytest.mark.skipif(not SAMPLES.is_dir(), reason=f"LinuxCNC's sample configs not installed ({SAMPLES})")
@pytest.mark.parametrize("kind", ["xyzac-trt", "xyzbc-trt"])
def test_trt_headless_copy_of_the_installed_sample(kind: str):
    src = SAMPLES / "table-rotary-tilting" / f"{kind}.ini"
    assert any("basic_sim.tcl" in h for h in halfiles(src.read_text()))  # what the fix is for
    pins = {"x-rot-point": 0.0, "y-rot-point": 0.0, "z-rot-point": 0.0, "x-offset": 0.0,
            "y-offset": 0.0, "z-offset": 0.0}
    out = trt.headless_ini(src.read_text(), pins, {}, kind)
    sims = [h for h in halfiles(out) if "basic_sim.tcl" in h]
    assert sims and all(h.endswith(OPTION) for h in sims)


@pytest.mark.skipif(not SAMPLES.is_dir(), reason=f"LinuxCNC's sample configs not installed ({SAMPLES})")
@pytest.mark.parametrize("name", sorted(ks.CASES))
def test_kinds_headless_copy_of_the_installed_sample(tmp_path: Path, name: str):
    case = ks.CASES[name]
    src_ini = SAMPLES / case.folder / case.ini
    cfg = tmp_path / "cfg"
    shutil.copytree(src_ini.parent, cfg)
    ini = ks.headless(case, cfg, case.ini)
    texts = [ini.read_text()] + [(cfg / ln.split(None, 1)[1].strip()).read_text()
                                 for ln in ini.read_text().splitlines() if ln.startswith("#INCLUDE")]
    sims = [h for t in texts for h in halfiles(t) if "basic_sim.tcl" in h]
    assert all(h.endswith(OPTION) for h in sims), sims


@pytest.mark.parametrize("script", ["trt_sim_check.py", "kinds_sim.py"])
def test_the_drive_copy_imports_without_the_test_folder(tmp_path: Path, script: str):
    """Each of these files also runs as a copy beside sim_drive.py in the drive's work folder
    (the LinuxCNC user's run), where lcnc_common is not: a top-level import of it failed
    every sample there (CI, the run before this test)."""
    import subprocess
    shutil.copy(TESTS / script, tmp_path / script)
    env = {k: v for k, v in __import__("os").environ.items() if k != "PYTHONPATH"}
    r = subprocess.run([sys.executable, "-c", f"import {Path(script).stem}"], cwd=tmp_path,
                       capture_output=True, text=True, env=env, timeout=60)
    assert r.returncode == 0, r.stderr
