"""Drive grblHAL's Simulator (grblHAL_sim) for the plugin's checks: one process per
session under `timeout -s KILL`, G-code line by line, and its sampled steps (step.out).

Shared by sim_test.py (the plugin against the Python reference) and sim_thermal.py (the
thermal block). Steps at $100..$102 (250 steps/mm, the Simulator's default), positions mm.
"""

from __future__ import annotations

import os
import queue
import signal
import subprocess
import threading
import time
from pathlib import Path

import numpy as np

STEPS_PER_MM = 250.0
STEP_MM = 1.0 / STEPS_PER_MM
TIMEOUT_S = 900
# Simulated time runs at this multiple of wall time. "0" (as fast as possible)
# lets the simulator thread starve grblHAL's own on a loaded machine.
SPEEDUP = os.environ.get("ABBE_GRBLHAL_SPEEDUP", "20")
# Where the plugin keeps an uploaded table in the Simulator's EEPROM.DAT: above
# the 2048 bytes grblHAL buffers (NVS_SIZE), a 16-byte header then the blob.
NVS_TABLE_AT = 2048


class Sim:
    """grblHAL_sim under timeout -s KILL, driven line by line (wait for ok)."""

    running: list["Sim"] = []
    cycle_restarts = 0

    def __init__(self, exe: Path, workdir: Path, name: str) -> None:
        self.dir = workdir / name
        self.dir.mkdir(parents=True, exist_ok=True)
        self.block = self.dir / "block.out"
        self.step = self.dir / "step.out"
        cmd = ["timeout", "-s", "KILL", str(TIMEOUT_S), "stdbuf", "-oL", str(exe), "-n", "-t", SPEEDUP,
               "-r", "0.02", "-s", str(self.step), "-b", str(self.block), "-e", str(self.dir / "EEPROM.DAT")]
        # Own session: timeout and the simulator are one process group, killed
        # together (kill()) if a check fails before the orderly 0x06 exit.
        self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE, cwd=self.dir,
                                     start_new_session=True)
        self.lines: queue.Queue[str] = queue.Queue()
        self.log: list[str] = []
        threading.Thread(target=self._reader, daemon=True).start()
        Sim.running.append(self)
        # Everything before the banner (a fresh EEPROM.DAT reports error:7) is start-up.
        while not self._next().startswith("GrblHAL"):
            pass

    def _reader(self) -> None:
        assert self.proc.stdout is not None
        for raw in self.proc.stdout:
            self.lines.put(raw.decode(errors="replace").rstrip("\r\n"))

    def kill(self) -> None:
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass

    def _next(self, timeout: float = 300.0) -> str:
        line = self.lines.get(timeout=timeout)
        self.log.append(line)
        return line

    def send(self, line: str) -> tuple[str, list[str]]:
        """Send one line; return ('ok' | 'error:N', the lines before it).

        When the Simulator's grblHAL thread falls behind its stepper (a loaded
        machine), the segment buffer runs empty: the stepper flags the cycle
        complete and grblHAL goes Idle with blocks still planned. Inside a
        buffer sync (G4, $ commands) nothing starts them again and the reply
        never comes. As a sender would, a cycle start ('~', a no-op while
        moving or with nothing planned) is sent after 2 s without output;
        the number sent is reported (cycle_restarts)."""
        assert self.proc.stdin is not None
        self.proc.stdin.write(line.encode() + b"\n")
        self.proc.stdin.flush()
        seen = []
        waited = 0.0
        while True:
            try:
                r = self._next(timeout=2.0)
            except queue.Empty:
                waited += 2.0
                if waited > 300.0:
                    raise
                self.proc.stdin.write(b"~")
                self.proc.stdin.flush()
                Sim.cycle_restarts += 1
                continue
            if r == "ok" or r.startswith("error"):
                return r, seen
            seen.append(r)

    def ok(self, line: str) -> list[str]:
        r, seen = self.send(line)
        if r != "ok":
            raise RuntimeError(f"{line!r} -> {r} {seen}")
        return seen

    def _query(self) -> str:
        """Send '?' and return the status report it answers with."""
        assert self.proc.stdin is not None
        self.proc.stdin.write(b"?")
        self.proc.stdin.flush()
        while True:
            r = self._next()
            if r.startswith("<"):
                return r

    def status(self) -> str:
        """Wait for the planner to drain (G4), then the '?' report."""
        self.ok("G4 P0.01")
        return self._query()

    def until_alarm(self, line: str) -> str:
        """Send a line that raises an alarm; return the first ALARM / ok / error reply."""
        assert self.proc.stdin is not None
        self.proc.stdin.write(line.encode() + b"\n")
        self.proc.stdin.flush()
        while True:
            r = self._next(timeout=60.0)
            if r.startswith("ALARM") or r == "ok" or r.startswith("error"):
                return r

    def report(self) -> str:
        """The '?' report now (no G4 first: also in an alarm state)."""
        time.sleep(0.5)  # let a stop settle (wall time; the simulated machine runs ahead)
        return self._query()

    def abbe(self) -> dict[str, str]:
        """The plugin's $ABBE fields ({} without the plugin)."""
        r, seen = self.send("$ABBE")
        for ln in seen:
            if ln.startswith("[ABBE:") and "|SEGMENTS:" in ln:
                return dict(x.split(":", 1) for x in ln.strip("[]").split("|"))
        return {}

    def segments(self) -> int:
        """Segment ends the plugin computed so far ($ABBE; 0 without the plugin)."""
        return int(self.abbe().get("SEGMENTS", 0))

    def planned_steps(self) -> np.ndarray:
        """The planner's target of the last segment end, steps ($ABBE STEPS)."""
        return np.array([int(v) for v in self.abbe()["STEPS"].split(",")], dtype=np.int64)

    def mpos(self, wait: bool = True) -> np.ndarray:
        s = self.status() if wait else self.report()
        field_ = [f for f in s.strip("<>").split("|") if f.startswith("MPos:")][0]
        return np.array([float(v) for v in field_[5:].split(",")[:3]])

    def close(self) -> None:
        assert self.proc.stdin is not None
        try:
            self.proc.stdin.write(b"\x06")
            self.proc.stdin.flush()
            self.proc.stdin.close()
        except BrokenPipeError:
            pass
        self.proc.wait(timeout=TIMEOUT_S)
        Sim.running.remove(self)
        (self.dir / "resp.out").write_text("\n".join(self.log) + "\n")


def read_samples(path: Path) -> np.ndarray:
    """step.out: the step counts sampled every -r s (N, 3)."""
    rows = []
    for ln in path.read_text().splitlines():
        if not ln.strip() or ln.startswith("#"):
            continue
        t, rest = ln.split(None, 1)
        rows.append([int(v) for v in rest.split(",")[:3]])
    return np.array(rows, dtype=np.int64).reshape(-1, 3)


class Checks:
    def __init__(self) -> None:
        self.failed: list[str] = []
        self.summary: dict = {}

    def check(self, ok: bool, what: str) -> None:
        print(("  ok    " if ok else "  FAIL  ") + what)
        if not ok:
            self.failed.append(what)
