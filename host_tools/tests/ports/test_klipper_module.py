"""port/klipper/abbe.py with stand-ins for Klipper's objects: what batch mode cannot
show (it stops at the first G-code error) and the module's refusals.

The module is Klipper's (loaded into klippy, never imported by abbe): it is loaded
here from its file. Klipper's own batch-mode proof is port/klipper/tests/klipper_batch.py.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from abbe import paths
from abbe.model import clib

REPO = Path(__file__).resolve().parents[3]
MODULE = REPO / "port" / "klipper" / "abbe.py"

pytestmark = pytest.mark.skipif(not clib.available(), reason="C library not built")


def _module():
    spec = importlib.util.spec_from_file_location("abbe_klipper_module", MODULE)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _stubs():
    spec = importlib.util.spec_from_file_location("abbe_klipper_stubs", MODULE.with_name("stubs.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


STUBS = _stubs()
ConfigError, CommandError, FakeGcmd = STUBS.ConfigError, STUBS.CommandError, STUBS.Gcmd


class FakeSkew:
    def __init__(self, xy=0.0):
        self.xy_factor, self.xz_factor, self.yz_factor = xy, 0.0, 0.0


def make(table: Path, *, enable=True, skew=None, **extra):
    mod = _module()
    printer = STUBS.Printer(**({"skew_correction": skew} if skew is not None else {}))
    values = {"table": str(table), "library": str(paths.library_path()), "enable": enable,
              "fade_segments": 1, "max_change_per_segment": 1000.0, **extra}
    comp = mod.AbbeCompensation(STUBS.Config(printer, values))
    comp.next_transform = STUBS.Recorder()
    if enable:
        comp._enable()
    return mod, printer, comp


@pytest.fixture(scope="module")
def fitted(tmp_path_factory) -> Path:
    """A table fitted by `abbe fit` from the example machine's laser lines."""
    from abbe.cli import main
    out = tmp_path_factory.mktemp("fit")
    assert main(["fit", str(REPO / "examples" / "vmc500" / "machine.toml"), "-o", str(out)]) == 0
    return out / "model.bin"


def _expected(table: Path, p, d):
    model = clib.CModel(table.read_bytes())
    e, _ = model.error_f32(np.array([p], dtype=float), dir_state=np.array([d], dtype=float),
                           temp_c=np.full((1, 3), 20.0))
    return np.asarray(p) - e[0] * 1e-3


def test_move_end_is_p_minus_error_and_position_is_programmed(fitted):
    _, _, comp = make(fitted)
    comp.move([100.0, -100.0, -100.0, 0.0], 50.0)
    end = comp.next_transform.moves[-1]
    want = _expected(fitted, [100.0, -100.0, -100.0], [1, -1, -1])
    assert np.max(np.abs(np.array(end[:3]) - want)) < 2e-6  # mm: float32 of the library
    assert np.max(np.abs(np.array(end[:3]) - [100.0, -100.0, -100.0])) > 2e-3  # really corrected
    # the G-code layer gets the programmed point back, not the corrected one
    assert np.allclose(comp.get_position()[:3], [100.0, -100.0, -100.0], atol=1e-9)


def test_long_move_is_split_to_the_bound(fitted):
    _, _, comp = make(fitted)
    comp.move([400.0, 0.0, 0.0, 0.0], 50.0)
    n = len(comp.next_transform.moves)
    assert n == int(np.ceil(400.0 / comp.split_mm))
    assert comp.split_mm == pytest.approx(np.sqrt(8 * 1.0 / comp.kappa))


def test_disabled_passes_moves_untouched(fitted):
    _, _, comp = make(fitted, enable=False)
    comp.move([400.0, -300.0, -100.0, 1.0], 50.0)
    assert comp.next_transform.moves == [[400.0, -300.0, -100.0, 1.0]]


def test_bad_load_keeps_the_running_table(fitted, tmp_path):
    _, printer, comp = make(fitted)
    comp.move([100.0, -100.0, -100.0, 0.0], 50.0)
    before = comp.next_transform.moves[-1]
    bad = tmp_path / "bad.bin"
    blob = bytearray(fitted.read_bytes())
    blob[100] ^= 0xFF
    bad.write_bytes(bytes(blob))
    with pytest.raises(CommandError, match=r"refused by the abbe library.*running table .* is kept"):
        printer.gcode.commands["ABBE_LOAD"](FakeGcmd({"TABLE": str(bad)}, printer.gcode))
    comp.move([120.0, -100.0, -100.0, 0.0], 50.0)
    comp.move([100.0, -100.0, -100.0, 0.0], 50.0)  # back: the same correction as before
    comp.move([90.0, -100.0, -100.0, 0.0], 50.0)
    comp.move([100.0, -100.0, -100.0, 0.0], 50.0)
    assert np.allclose(comp.next_transform.moves[-1], before, atol=1e-9)


def test_bad_table_is_a_config_error(tmp_path, fitted):
    bad = tmp_path / "short.bin"
    bad.write_bytes(fitted.read_bytes()[:200])
    with pytest.raises(ConfigError, match="refused by the abbe library"):
        make(bad)


def test_table_beyond_max_correction_is_refused(fitted):
    with pytest.raises(ConfigError, match="above max_correction"):
        make(fitted, max_correction=1.0)


def test_skew_twice_is_refused(tmp_path):
    paper = REPO / "examples" / "paper_table" / "model.bin"  # has SQUARENESS
    _, printer, comp = make(paper, enable=False, skew=FakeSkew(xy=0.001))
    with pytest.raises(CommandError, match="skew_correction"):
        printer.gcode.commands["ABBE_ENABLE"](FakeGcmd({}, printer.gcode))
    assert not comp.enabled
    printer.objects["skew_correction"].xy_factor = 0.0
    printer.gcode.commands["ABBE_ENABLE"](FakeGcmd({}, printer.gcode))
    assert comp.enabled


def test_curvature_inside_the_travel(fitted):
    """kappa from the table inside its travel: the example's 0.05 um/mm^2, not the
    end kink (0.5) the grblHAL plugin once measured half a millimetre outside."""
    _, _, comp = make(fitted)
    assert 0.01 < comp.kappa < 0.2
