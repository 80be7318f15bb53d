"""port/klipper/tests/klippy_drained.py: the launcher that lets Klipper's batch mode
exit only once its serial queue has written every message (see that file for the
loss it prevents). Klipper itself is stood in for by a fake klippy folder whose
serial queue drains after a number of polls, or never."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]
LAUNCHER = REPO / "port" / "klipper" / "tests" / "klippy_drained.py"

FAKE_SERIALHDL = '''
import os
class SerialReader:
    def __init__(self, polls_until_empty):
        self.serialqueue = object()
        self.left = polls_until_empty
    def stats(self, eventtime):
        if self.left is not None and self.left > 0:
            self.left -= 1
        held = 0 if self.left == 0 else 24
        if os.environ.get("FAKE_OLD_STATS"):  # a Klipper whose stats lack the fields
            return "bytes_write=7197 bytes_read=0"
        return ("bytes_write=7197 bytes_read=0 ready_bytes=0 upcoming_bytes=%d" % held)
    def disconnect(self):
        print("klipper disconnect, queue held %s" % self.stats(0).split()[-1], flush=True)
        self.serialqueue = None
'''

FAKE_KLIPPY = '''
import sys, serialhdl
def main():
    print("argv", sys.argv[1:], flush=True)
    polls = None if sys.argv[1] == "never" else int(sys.argv[1])
    serialhdl.SerialReader(polls).disconnect()
    print("klippy went on", flush=True)
'''


def _fake_klippy(tmp_path: Path) -> Path:
    d = tmp_path / "klippy"
    d.mkdir()
    (d / "serialhdl.py").write_text(FAKE_SERIALHDL)
    (d / "klippy.py").write_text(FAKE_KLIPPY)
    return d


def _run(klippy_dir: Path, arg: str, drain_s: str, **extra: str) -> subprocess.CompletedProcess:
    env = dict(os.environ, ABBE_KLIPPY_DRAIN_S=drain_s, **extra)
    return subprocess.run([sys.executable, str(LAUNCHER), str(klippy_dir), arg],
                          capture_output=True, text=True, env=env, timeout=60)


def test_klipper_disconnects_only_after_the_queue_is_empty(tmp_path):
    res = _run(_fake_klippy(tmp_path), "5", "30")
    assert res.returncode == 0, res.stderr
    # klippy saw its own arguments, and its disconnect ran with nothing held
    assert "argv ['5']" in res.stdout
    assert "klipper disconnect, queue held upcoming_bytes=0" in res.stdout
    assert "klippy went on" in res.stdout


def test_a_queue_that_never_drains_is_an_error_not_a_short_file(tmp_path):
    res = _run(_fake_klippy(tmp_path), "never", "0.2")
    assert res.returncode == 3
    assert "still holds 24 bytes" in res.stderr and "incomplete" in res.stderr
    # Klipper's disconnect (which would drop the 24 bytes) never ran
    assert "klipper disconnect" not in res.stdout


def test_stats_the_launcher_cannot_read_are_an_error_not_a_short_file(tmp_path):
    # klippy would log an exception from its disconnect handler and exit 0: the launcher
    # must exit 3 itself
    res = _run(_fake_klippy(tmp_path), "5", "30", FAKE_OLD_STATS="1")
    assert res.returncode == 3
    assert "without ready_bytes/upcoming_bytes" in res.stderr
    assert "klipper disconnect" not in res.stdout


def test_stats_without_the_queue_fields_are_refused():
    spec = importlib.util.spec_from_file_location("klippy_drained", LAUNCHER)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.queued_bytes("bytes_write=1 ready_bytes=10 upcoming_bytes=24") == 34
    with pytest.raises(ValueError, match="ready_bytes"):
        mod.queued_bytes("bytes_write=1 upcoming_bytes=24")
