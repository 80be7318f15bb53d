#!/usr/bin/env python3
"""The measurement programs of `abbe program` (grblHAL dialect) run in the unmodified
grblHAL Simulator (docs/programs.md, "Checked in grblHAL"). port/grblhal/tests/run.sh
runs it after the plugin checks, with the stock Simulator it built; so can you:

  cd host_tools && ../.venv/bin/python ../port/grblhal/tests/program_sim.py \
      --stock ../build-grblhal/stock/grblHAL_sim [--json FIGURES.json]

1. `abbe program` writes, for examples/vmc500/machine.toml (the ballbar feed raised to
   6000 mm/min to keep the run short), the grblHAL dialect: ISO 230-2 positioning of X
   (linear sequence) and of Y (pendulum sequence), a straightness line along Z, the XY
   ballbar circle.
2. Each runs in a fresh Simulator (power-up position MPos 0,0,0: the Simulator has no
   switches, so the machine file's origin is taken to be where it powers up; homing,
   soft and hard limits off), after the $ settings that fit the machine: 250 steps/mm,
   max rates, accelerations, max travel = the machine file's travel lengths; G54 and
   G92 offsets zeroed. The program is streamed ahead of execution (character counting
   within the Simulator's receive buffer, as a sender does: a dwell is followed at once
   by the next block, not by a serial round trip); an M0 is answered with a cycle start
   (~) once the status report says Hold. After the program, a 1 mm X move (the
   marker, not part of the record) gives the program's last stop its end (below).
3. The path: step.out (steps sampled every -r s of simulated time while the planner has
   a block, plus one line each time the block changes), / 250 steps/mm. The Simulator
   writes no sample while its planner is empty (a dwell, a programmed stop, the last
   segments of the move before it): a stop shows as the gap between the last moving
   sample and the first sample of the next move, which is how the shared checks bracket
   it (host_tools/cases/program_path.py: the same judging as LinuxCNC's proof, with the
   position resolution half a step). The programmed stop's time: the first sample at
   the MPos the Hold status reported.
4. Checks (program_path.py): every target visited in order, each from its approach side
   (the overrun), the dwell as stated, every point in the machine file's travel; the
   circle covers the data arc [0, 360] deg with the feed arcs each side on the radius,
   CCW then CW, with the pause and one programmed stop. Protocol replies in resp.out,
   any error:/ALARM fails.
"""

from __future__ import annotations

import argparse
import json
import os
import queue
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
import tomllib
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "host_tools"))
from cases.program_path import PathCheckFailed, check, check_ballbar, check_positioning, params_of  # noqa: E402

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[2]
MACHINE = REPO / "examples" / "vmc500" / "machine.toml"
ABBE = REPO / ".venv" / "bin" / "abbe"
STEPS_PER_MM = 250.0
#: grblHAL rounds each block end to whole steps: a stated point is reached within half a step.
TOL_MM = 0.5 / STEPS_PER_MM + 1e-9
#: Simulated time per wall time (sim_test.py: 0, "as fast as possible", starves grblHAL's
#: own thread on a loaded machine).
SPEEDUP = float(os.environ.get("ABBE_GRBLHAL_SPEEDUP", "10"))
#: Runs of one program at most: a failed run runs again at half the speed-up (twice the
#: wall time per simulated second for grblHAL's thread): 10, 5, 2.5, 1.25; a failure at
#: every one stands.
ATTEMPTS = 4


def late_s(speedup: float) -> float:
    """How much longer than stated a dwell may last (s): LinuxCNC's 0.3 s, plus 0.25 s of
    wall time for grblHAL's own thread (it runs on wall time, the Simulator's clock on
    simulated time: after a dwell it plans the next block, a whole arc before the motion
    starts, and a scheduler delay of L s shows as speedup x L s of standing still)."""
    return 0.3 + 0.25 * speedup


SAMPLE_S = 0.02
#: Bytes in flight: below the Simulator's receive buffer (RX_BUFFER_SIZE, 1024).
WINDOW = 256
RUN_TIMEOUT_S = 240
#: Wall time after which a cycle start is sent (again) to a hold still complete, or to a
#: machine standing Idle with blocks planned (Run.stream).
RESEND_S = 1.0
#: The Simulator's rates: above the programs' feeds, accelerations of a machine tool.
RATE_MM_MIN = 15000.0
ACCEL_MM_S2 = 1000.0
PROGRAMS = {
    "x_linear": ["--test", "positioning", "--axis", "X", "--feed", "12000", "--dwell-s", "0.2"],
    "y_pendulum": ["--test", "positioning", "--axis", "Y", "--sequence", "pendulum",
                   "--feed", "3000", "--dwell-s", "0.2"],
    "z_straightness": ["--test", "straightness", "--axis", "Z", "--feed", "6000",
                       "--dwell-s", "0.2", "--runs", "2"],
    "ballbar_xy": ["--test", "ballbar", "--plane", "XY", "--pause-s", "1"],
}


def log(msg: str) -> None:
    print(f"[grblhal-programs] {msg}", flush=True)


def settings(travel: dict) -> list[str]:
    """The $ settings sent before each program (grblHAL numbering)."""
    s = ["$20=0", "$21=0", "$22=0"]  # soft limits need homing; the Simulator has no switches
    for k, a in enumerate("XYZ"):
        lo, hi = travel[a]
        s += [f"$10{k}={STEPS_PER_MM:g}", f"$11{k}={RATE_MM_MIN:g}", f"$12{k}={ACCEL_MM_S2:g}",
              f"$13{k}={hi - lo:g}"]
    return s + ["G10 L2 P1 X0 Y0 Z0", "G92.1", "G54"]


class Run:
    """One program in a fresh grblHAL_sim under timeout -s KILL."""

    def __init__(self, exe: Path, work: Path, speedup: float) -> None:
        self.dir = work
        work.mkdir(parents=True, exist_ok=True)
        self.step = work / "step.out"
        cmd = ["timeout", "-s", "KILL", str(RUN_TIMEOUT_S), "stdbuf", "-oL", str(exe), "-n",
               "-t", f"{speedup:g}", "-r", str(SAMPLE_S), "-s", str(self.step),
               "-b", str(work / "block.out"), "-e", str(work / "EEPROM.DAT")]
        self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                     cwd=work, start_new_session=True)
        self.lines: queue.Queue[str] = queue.Queue()
        self.log: list[str] = []
        self.holds: list[str] = []  # the status line of each programmed stop
        self.cycle_restarts = 0  # cycle starts sent again (stream's docstring)
        self.free_blocks = 0  # the most free planner blocks a status report gave (Bf)
        threading.Thread(target=self._reader, daemon=True).start()
        while not self._next(60).startswith("GrblHAL"):  # a fresh EEPROM.DAT says error:7 first
            pass

    def _reader(self) -> None:
        assert self.proc.stdout is not None
        for raw in self.proc.stdout:
            self.lines.put(raw.decode(errors="replace").rstrip("\r\n"))

    def _next(self, timeout: float) -> str:
        line = self.lines.get(timeout=timeout)
        self.log.append(line)
        return line

    def _write(self, b: bytes) -> None:
        assert self.proc.stdin is not None
        self.proc.stdin.write(b)
        self.proc.stdin.flush()

    def kill(self) -> None:
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass

    def stream(self, lines: list[str]) -> None:
        """Send ``lines`` ahead of execution (at most WINDOW bytes unacknowledged), poll
        the status, answer each programmed stop with a cycle start; return when all are
        acknowledged and the machine is Idle.

        The cycle start goes on a ``Hold:0`` report (hold complete), never on ``Hold:1``:
        grblHAL ignores a cycle start while the hold is pending (state_machine.c,
        state_await_hold), and one sent then is lost, leaving the program on hold (a
        hang to the deadline). If the hold is still complete RESEND_S later, it is
        sent again. A machine that stands still for RESEND_S of wall time, Idle with blocks
        in its planner (the status report's Bf: fewer free than when empty), gets a cycle
        start too, as a sender sends one: grblHAL's thread fell behind the Simulator's
        stepper, the segment buffer ran empty and the cycle ended with blocks planned,
        which nothing restarts (sim_test.py's Sim.send; a run here stood mid-arc to the
        deadline so). Never with the planner empty: before an M0 grblHAL syncs the buffer
        and stands Idle, and a cycle start arriving with its hold cancelled the stop (seen
        under load when this sent one on any standstill). Each resend is counted
        (``cycle_restarts``)."""
        pending = [ln for ln in lines if ln.strip()]
        inflight: list[tuple[str, int]] = []
        idle = False
        resumed_at: float | None = None  # when the cycle start for the current hold went
        stalled_at, stalled_since = "", time.monotonic()  # the MPos not left since
        last = ""
        deadline = time.monotonic() + RUN_TIMEOUT_S - 10
        while pending or inflight or not idle:
            now = time.monotonic()
            check(now < deadline, f"no end within {RUN_TIMEOUT_S - 10} s: {len(pending)} lines "
                  f"unsent, {len(inflight)} unacknowledged (first: {inflight[0][0] if inflight else '-'}), "
                  f"last status {last!r}, cycle starts resent {self.cycle_restarts}")
            while pending and sum(n for _, n in inflight) + len(pending[0]) + 1 <= WINDOW:
                ln = pending.pop(0)
                self._write(ln.encode() + b"\n")
                inflight.append((ln, len(ln) + 1))
            try:
                r = self._next(0.05)
            except queue.Empty:
                self._write(b"?")
                continue
            if r == "ok":
                check(bool(inflight), "an ok for no line")
                inflight.pop(0)
            elif r.startswith("error") or r.startswith("ALARM"):
                raise PathCheckFailed(f"grblHAL: {r} after {inflight[0][0] if inflight else '?'}")
            elif r.startswith("<"):
                last = r
                state = r[1:].split("|", 1)[0]
                if state == "Hold:0":
                    if resumed_at is None:
                        self.holds.append(r)
                        self._write(b"~")
                        resumed_at = now
                    elif now - resumed_at > RESEND_S:
                        self._write(b"~")
                        resumed_at = now
                        self.cycle_restarts += 1
                elif not state.startswith("Hold"):
                    resumed_at = None
                fields = dict(f.split(":", 1) for f in r.strip("<>").split("|")[1:] if ":" in f)
                mpos = fields.get("MPos", "")
                free = int(fields.get("Bf", "0,0").split(",")[0])
                self.free_blocks = max(self.free_blocks, free)  # the planner's size: Bf when empty
                done = state == "Idle" and not pending and not inflight
                # a stall: Idle with blocks planned (fewer free than when empty), not moving;
                # never Idle with the planner empty (a dwell; the buffer sync before an M0,
                # whose hold a cycle start arriving with it would cancel)
                if state != "Idle" or free >= self.free_blocks or done or mpos != stalled_at:
                    stalled_at, stalled_since = mpos, now
                elif now - stalled_since > RESEND_S:
                    self._write(b"~")
                    stalled_since = now
                    self.cycle_restarts += 1
                idle = done

    def close(self) -> None:
        try:
            self._write(b"\x06")
            assert self.proc.stdin is not None
            self.proc.stdin.close()
        except BrokenPipeError:
            pass
        self.proc.wait(timeout=30)
        (self.dir / "resp.out").write_text("\n".join(self.log) + "\n")


def read_path(step_out: Path) -> tuple[np.ndarray, np.ndarray]:
    """step.out up to the marker block's first sample (the last block: the line before
    its header): simulated time s (N,) and position mm (N, 3)."""
    lines = step_out.read_text().splitlines()
    last = max(k for k, ln in enumerate(lines) if ln.startswith("# block"))
    t, st = [], []
    for ln in lines[:last]:
        if not ln.strip() or ln.startswith("#"):
            continue
        ts, rest = ln.split(None, 1)
        t.append(float(ts))
        st.append([int(v) for v in rest.split(",")[:3]])
    return np.array(t), np.array(st, dtype=np.int64).reshape(-1, 3) / STEPS_PER_MM


def run_program(exe: Path, prog: Path, travel: dict, work: Path, speedup: float) -> dict:
    t0 = time.monotonic()
    run = Run(exe, work, speedup)
    try:
        run.stream(settings(travel))
        # the marker: a 1 mm X move after the program end (towards the middle of the
        # travel) starts a planner block whose first sample closes the program's last stop
        # and ends the record (a block shorter than the segment buffer can pass unsampled)
        text = prog.read_text()
        x_end = float(re.findall(r"^G[0-3] .*X(-?[0-9.]+)", text, flags=re.M)[-1])
        step = 1.0 if x_end < 0.5 * sum(travel["X"]) else -1.0
        run.stream(text.splitlines() + [f"G91 G1 X{step:.1f} F100"])
        run.close()
    except PathCheckFailed as e:
        e.cycle_restarts = run.cycle_restarts  # type: ignore[attr-defined]
        raise
    finally:
        run.kill()
    t, pos = read_path(run.step)
    stops = []
    for h in run.holds:  # the first sample at the position the Hold:0 report gave
        mpos = np.array([float(v) for v in
                         [f for f in h.strip("<>").split("|") if f.startswith("MPos:")][0][5:]
                         .split(",")[:3]])
        at = np.flatnonzero(np.all(np.abs(pos - mpos) <= 0.0015, axis=1))
        check(at.size > 0, f"{prog.name}: no sample at the Hold position {mpos}")
        stops.append([float(t[at[0]]), float(t[at[0]])])
    return {"program": prog.name, "t_s": t, "pos_mm": pos, "stops": stops,
            "seconds": float(t[-1] - t[0]) if t.size else 0.0,
            "wall_s": time.monotonic() - t0, "samples": int(t.size),
            "cycle_restarts": run.cycle_restarts}


def run_and_judge(exe: Path, prog: Path, prm: dict, travel: dict, machine: dict,
                  work: Path, speedup: float) -> dict:
    """One run of ``prog`` and its checks: the figures (PathCheckFailed carries the run's
    ``cycle_restarts``)."""
    rec = run_program(exe, prog, travel, work, speedup)
    rec["kinematics"] = {"accel_mm_s2": ACCEL_MM_S2, "feed_mm_min": float(prm["feed_mm_min"])}
    try:
        if prm["test"] == "ballbar":
            f = check_ballbar(rec, prm, travel, TOL_MM, late_s(speedup))
        else:
            f = check_positioning(rec, prm, travel, machine["laser"][prm["axis"]]["start_mm"],
                                  TOL_MM, late_s(speedup))
            f.pop("captures")
    except PathCheckFailed as e:
        e.cycle_restarts = rec["cycle_restarts"]  # type: ignore[attr-defined]
        raise
    f.update(samples=rec["samples"], wall_s=round(rec["wall_s"], 1),
             cycle_restarts=rec["cycle_restarts"], speedup=speedup, late_s=late_s(speedup))
    return f


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--stock", type=Path, required=True, help="the unmodified grblHAL_sim")
    ap.add_argument("--json", type=Path, help="also write the figures here")
    ap.add_argument("--keep", type=Path, help="keep the programs and outputs here")
    ap.add_argument("--only", choices=list(PROGRAMS), action="append", help="run only these")
    args = ap.parse_args()
    t_all = time.monotonic()
    m = tomllib.loads(MACHINE.read_text())
    travel = {a: m["axes"][a]["travel_mm"] for a in "XYZ"}
    with tempfile.TemporaryDirectory(prefix="abbe-gh-programs-") as tmp:
        work = args.keep.resolve() if args.keep else Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        mf = work / "machine.toml"
        text = MACHINE.read_text()
        check("feed_mm_min = 200.0" in text, "the ballbar feed of examples/vmc500 changed")
        mf.write_text(text.replace("feed_mm_min = 200.0", "feed_mm_min = 6000.0"))
        figures: dict = {}
        try:
            for name, opts in PROGRAMS.items():
                if args.only and name not in args.only:
                    continue
                p = work / f"{name}.nc"
                subprocess.run([str(ABBE), "program", str(mf), *opts, "--dialect", "grblhal",
                                "-o", str(p)], check=True, capture_output=True, text=True)
                prm = params_of(p.read_text())
                speedup, failures = SPEEDUP, []
                for attempt in range(1, ATTEMPTS + 1):
                    try:
                        f = run_and_judge(args.stock.resolve(), p, prm, travel, m,
                                          work / (name if attempt == 1 else f"{name}-{attempt}"),
                                          speedup)
                        break
                    except PathCheckFailed as e:
                        # the program is the same G-code at any speed-up: what fails at one
                        # and passes at a lower one is the host's scheduling (grblHAL's
                        # thread on wall time: a stall, a late dwell end, a slow arc), so a
                        # failed run runs again in a fresh Simulator at half the speed-up;
                        # a failure at every speed-up (a wrong target, order, side) stands
                        stalls = getattr(e, "cycle_restarts", 0)
                        failures.append(f"speed-up {speedup:g}: {e}"
                                        + (f" ({stalls} cycle starts resent)" if stalls else ""))
                        if attempt == ATTEMPTS:
                            raise PathCheckFailed(f"{name} failed at every speed-up: "
                                                  + "; ".join(failures)) from e
                        log(f"{name}: failed at speed-up {speedup:g} ({failures[-1]}): again at "
                            f"{speedup / 2:g}")
                        speedup = speedup / 2
                f.update(attempts=attempt, failed_runs=failures)
                figures[name] = f
                log(f"{name}: OK {json.dumps(f)}")
        except PathCheckFailed as e:
            print(f"[grblhal-programs] FAIL: {e}", file=sys.stderr, flush=True)
            return 1
        figures["wall_s"] = round(time.monotonic() - t_all, 1)
        if args.json:
            args.json.parent.mkdir(parents=True, exist_ok=True)
            args.json.write_text(json.dumps(figures, indent=1) + "\n")
    log(f"measurement programs in grblHAL's Simulator: OK ({figures['wall_s']} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
