"""Shared helpers of the LinuxCNC port's tests (run with the system python3,
which has LinuxCNC's modules and numpy).

The reference values come from the ``abbe`` command line only (``abbe table
eval``: the float64 Python reference; ``abbe table to-json``: the table's
fields), never from host_tools' Python internals. The backlash direction state
is rebuilt here from the documented rules (docs/linuxcnc.md, "Backlash
direction"; docs/table-format.md, "What the table means").
"""

from __future__ import annotations

import json
import os
import pwd
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[3]
ABBE_CLI = Path(os.environ.get("ABBE_CLI", REPO / ".venv" / "bin" / "abbe"))
USER = os.environ.get("ABBE_LCNC_USER", "abbe-lcnc")

# The library's numerics requirement (docs/numerics.md): either variant within
# 2 nm of the float64 reference.
NUMERICS_BOUND_NM = 2.0


class TestFailure(AssertionError):
    pass


def check(cond: bool, what: str) -> None:
    if not cond:
        raise TestFailure(what)


def log(msg: str) -> None:
    print(f"[lcnc] {msg}", flush=True)


def headless_halfile(line: str) -> str:
    """A sample INI's ``HALFILE = LIB:basic_sim.tcl`` line for a run without a display:
    without hal_manualtoolchange (basic_sim.tcl's option; its tool-change loop stays, so
    an M6 completes at once). That program calls ``h.ready()`` and only then opens its
    Tk window, which fails without $DISPLAY; when it dies before ``loadusr -W`` has seen
    it ready, LinuxCNC stops at start with status 255 (seen once in ~55 CI runs:
    ~/linuxcnc_debug.txt "hal_manualtoolchange exited without becoming ready")."""
    s = line.strip()
    if (s.split("=", 1)[0].strip() == "HALFILE" and "basic_sim.tcl" in s
            and "-no_use_hal_manualtoolchange" not in s):
        return line.rstrip() + " -no_use_hal_manualtoolchange"
    return line


def as_user(cmd: list[str]) -> list[str]:
    """LinuxCNC's tools refuse root: run them as the unprivileged test user."""
    if os.geteuid() == 0:
        return ["runuser", "-u", USER, "--"] + cmd
    return cmd


def user_ids() -> tuple[int, int]:
    if os.geteuid() != 0:
        return os.getuid(), os.getgid()
    pw = pwd.getpwnam(USER)
    return pw.pw_uid, pw.pw_gid


def work_dir(prefix: str) -> Path:
    """A temporary directory the LinuxCNC user can write."""
    d = Path(tempfile.mkdtemp(prefix=prefix))
    uid, gid = user_ids()
    os.chown(d, uid, gid)
    return d


def give(path: Path) -> None:
    uid, gid = user_ids()
    os.chown(path, uid, gid)


def cleanup(d: Path) -> None:
    if os.environ.get("ABBE_LCNC_KEEP"):
        log(f"kept {d}")
        return
    shutil.rmtree(d, ignore_errors=True)


def hal_clean() -> None:
    """Unload anything a previous, interrupted run left in HAL (halrun -U)."""
    subprocess.run(as_user(["halrun", "-U"]), stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL, stdin=subprocess.DEVNULL, timeout=60)


def cli(*args: str, **kw) -> str:
    res = subprocess.run([str(ABBE_CLI), *args], capture_output=True, text=True,
                         stdin=subprocess.DEVNULL, timeout=300, **kw)
    if res.returncode != 0:
        raise TestFailure(f"abbe {' '.join(args[:3])} ...: exit {res.returncode}: {res.stderr.strip()}")
    return res.stdout


def make_table(json_path: Path, out: Path) -> Path:
    cli("table", "from-json", str(json_path), "-o", str(out))
    give(out)
    return out


def table_info(blob: Path) -> dict:
    """Table fields from the CLI: CRC, features, per-axis backlash take-up."""
    info = cli("table", "info", str(blob))
    m = re.search(r"CRC-32 0x([0-9A-Fa-f]{8})", info)
    check(m is not None, f"abbe table info gave no CRC: {info}")
    doc = json.loads(cli("table", "to-json", str(blob)))
    axes = [doc["axes"][a] for a in "XYZ"]
    return {
        "crc": int(m.group(1), 16),
        "takeup_mm": [float(ax.get("backlash_takeup_mm", 0.0) or 0.0) for ax in axes],
        "backlash_um": [float(ax.get("backlash_um", 0.0) or 0.0) for ax in axes],
        "thermal": any("thermal_tref_c" in ax for ax in axes),
    }


def _eval(blob: Path, pos_mm: np.ndarray, dir_state, temp_c, chunk: int = 8000) -> np.ndarray:
    if len(pos_mm) > chunk:  # keep the command line well below ARG_MAX
        return np.vstack([_eval(blob, pos_mm[i:i + chunk], dir_state, temp_c, chunk)
                          for i in range(0, len(pos_mm), chunk)])
    args = ["table", "eval", str(blob)]
    args += [f"{v:.6f}" for v in pos_mm.reshape(-1)]
    args += ["--dir", *[f"{s:g}" for s in dir_state]]
    if temp_c is not None:
        args += ["--temp-c", *[f"{t:.6f}" for t in temp_c]]
    out = cli(*args).splitlines()
    rows = [ln for ln in out if "|" in ln and not ln.startswith("pos_mm")]
    check(len(rows) == len(pos_mm), f"abbe table eval: {len(rows)} rows for {len(pos_mm)} points")
    err = np.array([[float(v) for v in ln.split("|")[1].split()] for ln in rows])
    return err  # um


def reference_error_um(blob: Path, pos_mm: np.ndarray, dir_state: np.ndarray,
                       temp_c: np.ndarray | None) -> np.ndarray:
    """The model's (dX, dY, dZ) in um at each row of pos_mm, with a direction
    state per row and axis, from ``abbe table eval``.

    The CLI takes one direction state for all points; the error is affine in
    each axis' state (the backlash term s_j B_j / 2 adds to axis j's own
    positioning term, which enters Eq. 3 linearly: docs/table-format.md), so
    e(p, s) = e(p, 0) + sum_j s_j (e(p, e_j) - e(p, 0)). Rows are grouped by
    temperature (one CLI call set per distinct temperature triple)."""
    err = np.zeros((len(pos_mm), 3))
    if temp_c is None:
        groups = {None: np.arange(len(pos_mm))}
    else:
        keys = [tuple(np.round(t, 6)) for t in temp_c]
        groups = {}
        for i, k in enumerate(keys):
            groups.setdefault(k, []).append(i)
        groups = {k: np.array(v) for k, v in groups.items()}
    for key, idx in groups.items():
        p = pos_mm[idx]
        e0 = _eval(blob, p, (0, 0, 0), key)
        total = e0.copy()
        for j in range(3):
            unit = [0, 0, 0]
            unit[j] = 1
            ej = _eval(blob, p, unit, key)
            total += dir_state[idx, j:j + 1] * (ej - e0)
        err[idx] = total
    return err


def direction_states(pos_nm: np.ndarray, valid: np.ndarray, deadband_nm: int,
                     takeup_mm: list[float], moved_nm: np.ndarray | None = None) -> np.ndarray:
    """Backlash direction state per cycle and axis, from the documented rules:

    - direction (port): from the commanded positions pos_nm: 0 until the axis
      has moved more than the deadband from where it was first seen; then it
      turns once the axis has moved back by more than the deadband from its
      furthest point in the current direction, and stays while the axis
      stands;
    - state (library): starts at 0; while the direction is non-zero it moves
      toward it by 2 x (distance moved this cycle) / take-up, clamped to
      [-1, 1]; a cycle's move of a whole take-up or more flips it completely.
      The distance is that of the positions the model sees (moved_nm, the
      lead positions; default pos_nm).
    """
    if moved_nm is None:
        moved_nm = pos_nm
    n = len(pos_nm)
    s = np.zeros((n, 3))
    for j in range(3):
        state, direction, anchor, last = 0.0, 0, None, None
        takeup_nm = takeup_mm[j] * 1e6
        for k in range(n):
            if not valid[k]:
                s[k, j] = state
                continue
            p = int(pos_nm[k, j])
            if anchor is None:
                anchor = p
            else:
                d = p - anchor
                if (direction > 0 and d > 0) or (direction < 0 and d < 0):
                    anchor = p
                elif d > deadband_nm:
                    direction, anchor = 1, p
                elif d < -deadband_nm:
                    direction, anchor = -1, p
            m = int(moved_nm[k, j])
            if last is not None and direction != 0 and takeup_nm > 0:
                dist = abs(m - last)
                step = 2.0 if dist >= takeup_nm else 2.0 * dist / takeup_nm
                state = min(1.0, max(-1.0, state + (step if direction > 0 else -step)))
            last = m
            s[k, j] = state
    return s


def lead_positions(pos_nm: np.ndarray, lead: float) -> np.ndarray:
    """Where the port evaluates the model: p + round(lead * (p - p_previous)),
    the first period at p (docs/linuxcnc.md, "Lead")."""
    out = pos_nm.astype(np.int64).copy()
    step = np.diff(pos_nm.astype(np.int64), axis=0)
    out[1:] += np.sign(step) * np.floor(np.abs(step) * lead + 0.5).astype(np.int64)
    return out


def read_samples(path: Path, ncols: int) -> np.ndarray:
    """halsampler -t output: sample number, then the channels. Fails on an
    'overrun' line (a lost sample would break the cycle alignment) and on a
    gap in the sample numbers. halsampler compares the first number with 0,
    so a second recording from the same sampler starts with 'overrun': that
    first line is not a loss."""
    rows = []
    for i, ln in enumerate(path.read_text().splitlines()):
        if ln.strip() == "overrun":
            if i == 0:
                continue
            raise TestFailure(f"{path.name}: halsampler overrun: samples were lost")
        parts = ln.split()
        check(len(parts) == ncols + 1, f"{path.name}: {len(parts)} fields, expected {ncols + 1}: {ln!r}")
        rows.append([float(v) for v in parts])
    check(rows, f"{path.name}: no samples")
    data = np.array(rows)
    check(np.all(np.diff(data[:, 0]) == 1), f"{path.name}: sample numbers not consecutive")
    return data


def run_checked(cmd: list[str], timeout: float, **kw) -> subprocess.CompletedProcess:
    res = subprocess.run(cmd, capture_output=True, text=True, stdin=subprocess.DEVNULL,
                         timeout=timeout, **kw)
    return res


def drive_programs(work: Path, ini: Path, args: list[str]) -> dict:
    """Run program_drive.py (copied into ``work``) as the LinuxCNC user on ``ini`` with
    ``args`` (its options and programs), bounded in time; return drive.json, or raise
    TestFailure with the driver's output and the end of linuxcnc.log."""
    proc = subprocess.Popen(as_user(["/usr/bin/python3", str(work / "program_drive.py"),
                                     "--ini", str(ini), "--out", str(work), "--timeout", "600",
                                     *args]),
                            cwd=work, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        out, err = proc.communicate(timeout=660)
    except subprocess.TimeoutExpired:
        proc.terminate()
        out, err = proc.communicate(timeout=90)
    drive = json.loads((work / "drive.json").read_text()) if (work / "drive.json").exists() else {}
    if proc.returncode != 0 or not drive.get("ok"):
        lc = (work / "linuxcnc.log").read_text() if (work / "linuxcnc.log").exists() else ""
        raise TestFailure(f"driving LinuxCNC failed: {drive.get('errors')}\n{out}\n{err}\n"
                          f"--- linuxcnc.log ---\n{lc[-3000:]}")
    check(not drive.get("operator_errors"), f"LinuxCNC errors: {drive.get('operator_errors')}")
    return drive


def main_wrapper(fn) -> None:
    try:
        fn()
    except AssertionError as e:  # TestFailure, and the shared path checks' PathCheckFailed
        print(f"[lcnc] FAIL: {e}", file=sys.stderr, flush=True)
        sys.exit(1)
