#!/usr/bin/python3
"""Drive the LinuxCNC simulator headless and record it (runs as the LinuxCNC
user; e2e_sim.py copies it into the work directory and starts it).

  sim_drive.py --ini WORK/config/vmc500.ini --program WORK/config/ballbar_circle.ngc --out WORK

Starts `linuxcnc INI` (DISPLAY = linuxcncrsh), waits until linuxcncrsh answers
on 127.0.0.1:5007, adds a sampler at the end of the servo thread, then:
e-stop reset, machine on, home all, run the program (recorded from before
homing: run_enabled.[01].txt), set abbe.enable 0, wait for the offsets to leave,
run the program again (run_disabled.[01].txt). Stops LinuxCNC by the pid of its
display (the linuxcnc script then cleans up). Writes drive.json (what
happened, pin values, errors). Every wait is bounded.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import linuxcnc

# Recorded every servo period by two samplers (a HAL stream has at most 20
# pins), both enabled by one signal so their samples pair up; abbe.cycles is in
# both to prove it. e2e_sim.py reads the same lists.
RECORD = [
    [("abbe.cycles", "u"),
     ("axis.x.pos-cmd", "f"), ("axis.y.pos-cmd", "f"), ("axis.z.pos-cmd", "f"),
     ("axis.x.eoffset", "f"), ("axis.y.eoffset", "f"), ("axis.z.eoffset", "f"),
     ("axis.x.eoffset-request", "f"), ("axis.y.eoffset-request", "f"), ("axis.z.eoffset-request", "f"),
     ("joint.0.motor-pos-cmd", "f"), ("joint.1.motor-pos-cmd", "f"), ("joint.2.motor-pos-cmd", "f"),
     ("motion.is-all-homed", "b"), ("motion.motion-enabled", "b"), ("motion.eoffset-limited", "b")],
    [("abbe.cycles", "u"),
     ("abbe.x.offset-mm", "f"), ("abbe.y.offset-mm", "f"), ("abbe.z.offset-mm", "f"),
     ("abbe.x.target-mm", "f"), ("abbe.y.target-mm", "f"), ("abbe.z.target-mm", "f"),
     ("abbe.x.corr-mm", "f"), ("abbe.y.corr-mm", "f"), ("abbe.z.corr-mm", "f"),
     ("abbe.x.counts", "s"), ("abbe.y.counts", "s"), ("abbe.z.counts", "s"),
     ("abbe.state", "s"), ("abbe.flags", "u")],
]

LOG = []


class Abort(BaseException):
    """SIGTERM or the overall timeout: not an Exception, so no wait swallows it."""


def log(msg: str) -> None:
    line = f"[sim] {time.monotonic():9.2f} {msg}"
    LOG.append(line)
    print(line, flush=True)


def halcmd(*args: str, check: bool = True) -> str:
    res = subprocess.run(["halcmd", *args], capture_output=True, text=True,
                         stdin=subprocess.DEVNULL, timeout=30)
    if check and res.returncode != 0:
        raise RuntimeError(f"halcmd {' '.join(args)}: {res.stderr.strip() or res.stdout.strip()}")
    return res.stdout.strip()


def getp(name: str) -> float:
    v = halcmd("getp", name)
    if v in ("TRUE", "FALSE"):
        return 1.0 if v == "TRUE" else 0.0
    return float(int(v, 0)) if v.startswith("0x") else float(v)


def wait_for(pred, timeout: float, what: str, step: float = 0.05):
    t_end = time.monotonic() + timeout
    last_exc = None
    while time.monotonic() < t_end:
        try:
            v = pred()
            if v:
                return v
        except Exception as e:  # not up yet
            last_exc = e
        time.sleep(step)
    raise RuntimeError(f"timed out after {timeout:.0f} s waiting for {what}"
                       + (f" (last error: {last_exc})" if last_exc else ""))


def rsh_hello() -> bool:
    """linuxcncrsh answers the handshake on 127.0.0.1:5007."""
    with socket.create_connection(("127.0.0.1", 5007), timeout=2) as s:
        s.sendall(b"hello EMC abbe-e2e 1.0\r\n")
        data = b""
        t_end = time.monotonic() + 3
        while b"\n" not in data and time.monotonic() < t_end:
            data += s.recv(256)
        s.sendall(b"quit\r\n")
        return data.startswith(b"HELLO ACK")


def signal_of(pin: str) -> str | None:
    """The signal a pin is on, or None. halcmd show pin matches by prefix:
    take the line of exactly this pin."""
    for line in halcmd("-s", "show", "pin", pin).splitlines():
        f = line.split()
        if len(f) >= 5 and f[4] == pin:
            return f[6] if len(f) >= 7 and f[5] in ("<==", "==>", "<=>") else None
    raise RuntimeError(f"no pin {pin}")


def add_recorder() -> None:
    cfgs = ",".join("".join(t for _, t in pins) for pins in RECORD)
    halcmd("loadrt", "sampler", "depth=20000,20000", f"cfg={cfgs}")
    halcmd("net", "e2e-record", "sampler.0.enable", "sampler.1.enable")
    halcmd("sets", "e2e-record", "0")
    for n, pins in enumerate(RECORD):
        for i, (pin, _) in enumerate(pins):
            sig = signal_of(pin)
            if sig is None:
                sig = "e2e-" + pin.replace(".", "-")
                halcmd("net", sig, pin)
            halcmd("net", sig, f"sampler.{n}.pin.{i}")
    halcmd("addf", "sampler.0", "servo-thread")  # last: after motion and abbe
    halcmd("addf", "sampler.1", "servo-thread")


class Recorder:
    """Both samplers into NAME.0.txt and NAME.1.txt."""

    def __init__(self, out: Path, name: str):
        self.procs = [subprocess.Popen(["halsampler", "-c", str(n), "-t", str(out / f"{name}.{n}.txt")],
                                       stdin=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
                      for n in range(len(RECORD))]
        time.sleep(0.2)
        halcmd("sets", "e2e-record", "1")

    def stop(self) -> list[int]:
        halcmd("sets", "e2e-record", "0")
        for n in range(len(RECORD)):
            wait_for(lambda: getp(f"sampler.{n}.curr-depth") == 0, 20, "the sampler FIFO to drain")
        time.sleep(0.2)
        for p in self.procs:
            p.send_signal(signal.SIGTERM)
        for p in self.procs:
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        return [int(getp(f"sampler.{n}.overruns")) for n in range(len(RECORD))]


def run_program(c, s, program: Path, timeout: float) -> float:
    c.mode(linuxcnc.MODE_AUTO)
    c.wait_complete()
    c.program_open(str(program))
    c.wait_complete()
    t0 = time.monotonic()
    c.auto(linuxcnc.AUTO_RUN, 0)
    wait_for(lambda: (s.poll() or True) and s.interp_state != linuxcnc.INTERP_IDLE, 10,
             "the program to start")
    wait_for(lambda: (s.poll() or True) and s.interp_state == linuxcnc.INTERP_IDLE
             and s.queue == 0 and s.inpos, timeout, "the program to finish")
    return time.monotonic() - t0


def children(pid: int) -> list[int]:
    try:
        text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    except OSError:
        return []
    return [int(x) for x in text.split()]


def comm(pid: int) -> str:
    try:
        return Path(f"/proc/{pid}/comm").read_text().strip()
    except OSError:
        return ""


def stop_linuxcnc(proc: subprocess.Popen) -> str:
    """End the display (linuxcncrsh, a child of the linuxcnc script): the
    script then shuts LinuxCNC down. Fallback: the process group we created."""
    rsh = [p for p in children(proc.pid) if comm(p) == "linuxcncrsh"]
    how = "no display found"
    if rsh:
        os.kill(rsh[0], signal.SIGTERM)
        how = f"SIGTERM to linuxcncrsh pid {rsh[0]}"
    try:
        proc.wait(timeout=45)
        return how + ", linuxcnc exited"
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        return how + ", linuxcnc did not exit: process group terminated"


def bounded(timeout: int) -> None:
    """SIGTERM (the caller giving up) and SIGALRM after ``timeout`` s raise Abort, so the
    caller's finally stops LinuxCNC whatever happens."""
    def give_up(signum, _frame):
        raise Abort(f"stopped by signal {signum} (overall timeout {timeout} s or SIGTERM)")
    signal.signal(signal.SIGTERM, give_up)
    signal.signal(signal.SIGALRM, give_up)
    signal.alarm(timeout)


def launch(ini: Path, out: Path):
    """Start ``linuxcnc INI`` headless (its output in OUT/linuxcnc.log): (process, log file)."""
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    lc_log = open(out / "linuxcnc.log", "w")
    log(f"starting linuxcnc {ini}")
    proc = subprocess.Popen(["linuxcnc", str(ini)], cwd=ini.parent, env=env,
                            stdin=subprocess.DEVNULL, stdout=lc_log, stderr=subprocess.STDOUT,
                            start_new_session=True)
    return proc, lc_log


def connect(proc: subprocess.Popen):
    """Wait for linuxcncrsh and for the task in e-stop: (stat, command, error channel)."""
    def up() -> bool:
        if proc.poll() is not None:
            # on an error the linuxcnc script copies its debug output to ~/linuxcnc_debug.txt
            # (its stdout, linuxcnc.log, may be empty): its end says why
            debug = Path.home() / "linuxcnc_debug.txt"
            try:
                tail = "\n".join(debug.read_text(errors="replace").splitlines()[-25:])
            except OSError as e:
                tail = f"({debug}: {e.strerror})"
            raise SystemExit(f"linuxcnc exited with status {proc.returncode} (see linuxcnc.log); "
                             f"the end of {debug}:\n{tail}")
        return rsh_hello()
    wait_for(up, 90, "linuxcncrsh on 127.0.0.1:5007")
    log("linuxcncrsh answers HELLO ACK")
    s = linuxcnc.stat()
    c = linuxcnc.command()
    e = linuxcnc.error_channel()
    wait_for(lambda: (s.poll() or True) and s.task_state == linuxcnc.STATE_ESTOP, 30,
             "task in e-stop")
    return s, c, e


def power_on(c, s) -> None:
    """E-stop reset, machine on."""
    c.state(linuxcnc.STATE_ESTOP_RESET)
    c.wait_complete()
    c.state(linuxcnc.STATE_ON)
    c.wait_complete()
    wait_for(lambda: (s.poll() or True) and s.task_state == linuxcnc.STATE_ON, 10, "machine on")


def home_all(c, s) -> None:
    c.mode(linuxcnc.MODE_MANUAL)
    c.wait_complete()
    c.home(-1)
    c.wait_complete()
    wait_for(lambda: (s.poll() or True) and all(s.homed[:3]), 30, "homing")
    log("homed")


def operator_errors(e) -> list[str]:
    msgs = []
    while True:
        m = e.poll()
        if not m:
            return msgs
        msgs.append(m[1])


def shutdown(proc: subprocess.Popen, lc_log, result: dict) -> None:
    """Stop LinuxCNC (the finally of a driver): no alarm, SIGTERM ignored meanwhile."""
    signal.alarm(0)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # let the shutdown finish
    result["stop"] = stop_linuxcnc(proc)
    log(result["stop"])
    lc_log.close()


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--ini", type=Path, required=True)
    ap.add_argument("--program", type=Path, required=True)
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--program-timeout", type=float, default=120.0)
    ap.add_argument("--timeout", type=int, default=360, help="for everything, s")
    args = ap.parse_args()

    bounded(args.timeout)
    args.ini, args.program, args.out = args.ini.resolve(), args.program.resolve(), args.out.resolve()
    result = {"ok": False, "errors": [], "runs": {}}
    proc, lc_log = launch(args.ini, args.out)
    result["linuxcnc_pid"] = proc.pid
    try:
        s, c, e = connect(proc)
        result["model_crc"] = int(getp("abbe.model-crc"))
        add_recorder()
        log("recorder added")

        rec = Recorder(args.out, "run_enabled")
        power_on(c, s)
        time.sleep(0.3)  # recorded: machine on, not homed
        result["before_home"] = {p: getp(p) for p in ("abbe.state", "axis.x.eoffset",
                                                      "abbe.x.target-mm", "abbe.homed")}
        home_all(c, s)
        wait_for(lambda: getp("abbe.active") == 1.0, 10, "abbe active")
        time.sleep(1.0)  # the fade-in (0.5 s) and the offset planner settle
        result["after_home"] = {p: getp(p) for p in ("abbe.state", "abbe.x.corr-mm", "axis.x.eoffset",
                                                     "abbe.y.corr-mm", "axis.y.eoffset",
                                                     "abbe.z.corr-mm", "axis.z.eoffset")}
        dt = run_program(c, s, args.program, args.program_timeout)
        log(f"program with compensation: {dt:.1f} s")
        time.sleep(0.3)
        result["runs"]["enabled"] = {"seconds": dt, "overruns": rec.stop()}

        halcmd("setp", "abbe.enable", "0")
        wait_for(lambda: all(abs(getp(f"axis.{a}.eoffset")) < 1e-6 for a in "xyz"), 10,
                 "the offsets to fade out")
        log("compensation disabled, offsets zero")
        rec = Recorder(args.out, "run_disabled")
        time.sleep(0.2)
        dt = run_program(c, s, args.program, args.program_timeout)
        log(f"program without compensation: {dt:.1f} s")
        time.sleep(0.3)
        result["runs"]["disabled"] = {"seconds": dt, "overruns": rec.stop()}
        result["operator_errors"] = operator_errors(e)
        result["ok"] = True
    except (Exception, SystemExit, Abort) as exc:  # reported by e2e_sim.py
        result["errors"].append(f"{type(exc).__name__}: {exc}")
        log(f"ERROR {exc}")
    finally:
        shutdown(proc, lc_log, result)
        result["log"] = LOG
        (args.out / "drive.json").write_text(json.dumps(result, indent=1))
    return 0 if result["ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
