#!/usr/bin/env python3
"""halrun test of the abbe HAL component's thermal block pins (format 1.3 tables).

The installed component runs the golden thermal table (tests/golden/golden_thermal.*:
16 temperatures + spindle speed, 5 channels) on a 1 ms thread in halrun; a halstreamer
drives the 17 abbe.th.in-NN pins with the golden record's samples (a new one every
0.1 s, thermal-sample-s 0.1) and abbe.th.fault-03 (input 3 open from 3.0 to 3.5 s); a
halsampler records th.flags, th.input-faults, th.samples, th.channel-00..04 and the
targets. Checks: the channels before the fault equal abbe.model.thermal.evaluate of the
table's model within 5 nm (variant q); the fault raises OPEN and HOLD with input 3
named; the targets never jump (largest change per period with the fault at most the
largest without it plus one fade step of every channel).

Usage (the component installed: port/linuxcnc/build.sh --install; as root the
tests run halrun as $ABBE_LCNC_USER; under flock /tmp/abbe-linuxcnc.lock):
    .venv/bin/python port/linuxcnc/tests/halrun_thermal_test.py
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from lcnc_common import (REPO, TestFailure, as_user, check, cleanup, give, log, main_wrapper,
                         read_samples, work_dir)

sys.path.insert(0, str(REPO / "host_tools"))
from abbe.formats.golden_thermal import golden_blob_and_model, golden_record  # noqa: E402
from abbe.formats.golden_thermal import SEED  # noqa: E402
from abbe.model.thermal import evaluate  # noqa: E402

N = 6000
EVERY = 100              # periods per thermal sample (0.1 s)
FAULT = (3000, 3500)     # periods with input 3 open
OPEN, HOLD = 0x01, 0x20
OUT_PINS = ["abbe.th.flags", "abbe.th.input-faults", "abbe.th.samples"] + \
    [f"abbe.th.channel-{c:02d}" for c in range(5)] + ["abbe.x.target-mm", "abbe.y.target-mm", "abbe.z.target-mm"]
OUT_CFG = "uuu" + "f" * 5 + "fff"
IN_PINS = [f"abbe.th.in-{k:02d}" for k in range(17)] + ["abbe.th.fault-03"]
IN_CFG = "f" * 17 + "b"  # halstreamer takes at most 20 pins: the rest is set once


def run(work: Path, table: Path, xs: np.ndarray, with_fault: bool) -> np.ndarray:
    """One halrun of N periods; the sampler's columns (OUT_PINS)."""
    lines = []
    for k in range(N):
        s = xs[k // EVERY]
        fault = 1 if with_fault and FAULT[0] <= k < FAULT[1] else 0
        lines.append(" ".join([f"{v:.3f}" for v in s[:16]] + [f"{s[16]:.0f}", str(fault)]))
    stream = work / "stream.txt"
    stream.write_text("\n".join(lines) + "\n")
    give(stream)
    samples_path = work / "samples.txt"
    samples_path.unlink(missing_ok=True)
    hal = ["loadrt threads name1=servo period1=1000000",
           f"loadrt streamer depth={N + 16} cfg={IN_CFG}",
           f"loadrt sampler depth=8000 cfg={OUT_CFG}",
           f"loadrt abbe variant=q table={table}"]
    hal += [f"net in{i} streamer.0.pin.{i} => {p}" for i, p in enumerate(IN_PINS)]
    hal += [f"net out{i} {p} => sampler.0.pin.{i}" for i, p in enumerate(OUT_PINS)]
    hal += ["addf streamer.0 servo", "addf abbe servo", "addf sampler.0 servo",
            "setp abbe.thermal-sample-s 0.1",
            "setp abbe.x.pos-mm 250", "setp abbe.y.pos-mm -200", "setp abbe.z.pos-mm -150",
            "setp abbe.enable 1", "setp abbe.homed 1", "setp abbe.machine-on 1",
            "setp abbe.x.warn-mm 5", "setp abbe.y.warn-mm 5", "setp abbe.z.warn-mm 5",
            "setp abbe.x.limit-mm 10", "setp abbe.y.limit-mm 10", "setp abbe.z.limit-mm 10",
            f"loadusr -w halstreamer {stream}", "start",
            f"loadusr -w halsampler -t -n {N} {samples_path}"]
    script = work / "test.hal"
    script.write_text("\n".join(hal) + "\n")
    give(script)
    res = subprocess.run(as_user(["halrun", "-f", str(script)]), cwd=work, capture_output=True, text=True,
                         stdin=subprocess.DEVNULL, timeout=120)
    subprocess.run(as_user(["halrun", "-U"]), capture_output=True, timeout=60)
    check(res.returncode == 0, f"halrun exit {res.returncode}: {res.stdout}\n{res.stderr}")
    return read_samples(samples_path, len(OUT_PINS))[:, 1:]


def main() -> None:
    work = work_dir("abbe-halrun-thermal-")
    try:
        blob, model = golden_blob_and_model()
        table = work / "thermal.bin"
        table.write_bytes(blob)
        give(table)
        _, x = golden_record(np.random.default_rng(SEED + 1))
        n_samples = N // EVERY
        xs = x[:n_samples]
        clean_run = run(work, table, xs, False)
        a = run(work, table, xs, True)
        flags, faults, samples = a[:, 0].astype(int), a[:, 1].astype(int), a[:, 2].astype(int)
        ch, target = a[:, 3:8], a[:, 8:11]
        check(samples[-1] >= n_samples - 2, f"{samples[-1]} thermal samples, expected about {n_samples}")
        # the channels against the reference: sample j taken at the j-th sample instant
        t = np.arange(n_samples) * EVERY * 1e-3
        xq = xs.copy()
        xq[:, :16] = np.round(xq[:, :16] * 1000) / 1000
        ref = evaluate(model, t, xq)
        worst = 0.0
        for j in range(1, FAULT[0] // EVERY - 1):
            rows = np.flatnonzero(samples == j + 1)
            check(rows.size > 0, f"no period after thermal sample {j}")
            d = np.max(np.abs(ch[rows[0]] - ref[j])) * 1000
            worst = max(worst, d)
        check(worst <= 5.0, f"channels differ from the reference by {worst:.1f} nm (> 5)")
        f_rows = np.arange(FAULT[0] + EVERY, FAULT[1])
        check(bool(np.all(flags[f_rows] & OPEN)) and bool(np.all(flags[f_rows] & HOLD)),
              "input 3 open: the OPEN and HOLD flags are not up")
        check(bool(np.all(faults[f_rows] == 1 << 3)), "th.input-faults does not name input 3")
        check(not np.any(flags[1000:FAULT[0]] & 0x0F), "a thermal fault flag before the fault")
        check(not np.any(clean_run[:, 0].astype(int)[1000:] & 0x2F), "the run without a fault flagged one")
        # no jump: over the same periods, the faulted run's largest step per period is at
        # most the clean run's plus one fade step (1 ms of the table's fade) of every channel
        win = slice(FAULT[0] - 1, N - 1)
        clean = (np.abs(np.diff(clean_run[:, 8:11], axis=0)) * 1e6)[win].max()
        faulted = (np.abs(np.diff(target, axis=0)) * 1e6)[win].max()
        bound = clean + np.abs(clean_run[:, 3:8]).max(axis=0).sum() * 1000 * 1e-3 / model.fade_s + 2
        log(f"halrun thermal: channels within {worst:.2f} nm of the reference; largest target step "
            f"{clean:.0f} nm without the fault, {faulted:.0f} nm with it (bound {bound:.0f})")
        check(faulted <= bound, f"the target jumped: {faulted:.0f} nm in one period (bound {bound:.0f})")
        log("halrun thermal test: OK")
    finally:
        cleanup(work)


if __name__ == "__main__":
    main_wrapper(main)
