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

``--stuck`` (opt-in, about 75 s of wall time: the real-time thread runs in real time and
the table's shortest stuck time is 1 min): the golden table with input 5's stuck check on
(1 min, 0.02 K; the ports' C tests use 2 min), a 10 ms thread, a thermal sample every 1 s;
input 5 ramps 0.05 K per sample, is held at one value for 63 s, then ramps again. Checks:
no stuck flag before 60 s after the last change; th.flags STUCK (128) and HOLD (32) and
th.input-faults bit 5 from the first sample at or after 60 s; cleared at the first sample
that moves; the targets do not jump (at a sample at most the largest step at the samples
before the flag plus one fade step of every channel; between samples at most one fade step
of every channel).

Usage (the component installed: port/linuxcnc/build.sh --install; as root the
tests run halrun as $ABBE_LCNC_USER; under flock /tmp/abbe-linuxcnc.lock):
    .venv/bin/python port/linuxcnc/tests/halrun_thermal_test.py [--stuck]
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


def run(work: Path, table: Path, xs: np.ndarray, with_fault: bool, n: int = N,
        every: int = EVERY, period_ns: int = 1000000) -> np.ndarray:
    """One halrun of n periods of period_ns, a thermal sample every ``every`` periods; the
    sampler's columns (OUT_PINS)."""
    lines = []
    for k in range(n):
        s = xs[k // every]
        fault = 1 if with_fault and FAULT[0] <= k < FAULT[1] else 0
        lines.append(" ".join([f"{v:.3f}" for v in s[:16]] + [f"{s[16]:.0f}", str(fault)]))
    stream = work / "stream.txt"
    stream.write_text("\n".join(lines) + "\n")
    give(stream)
    samples_path = work / "samples.txt"
    samples_path.unlink(missing_ok=True)
    hal = [f"loadrt threads name1=servo period1={period_ns}",
           f"loadrt streamer depth={n + 16} cfg={IN_CFG}",
           f"loadrt sampler depth=8000 cfg={OUT_CFG}",
           f"loadrt abbe variant=q table={table}"]
    hal += [f"net in{i} streamer.0.pin.{i} => {p}" for i, p in enumerate(IN_PINS)]
    hal += [f"net out{i} {p} => sampler.0.pin.{i}" for i, p in enumerate(OUT_PINS)]
    hal += ["addf streamer.0 servo", "addf abbe servo", "addf sampler.0 servo",
            f"setp abbe.thermal-sample-s {every * period_ns * 1e-9:g}",
            "setp abbe.x.pos-mm 250", "setp abbe.y.pos-mm -200", "setp abbe.z.pos-mm -150",
            "setp abbe.enable 1", "setp abbe.homed 1", "setp abbe.machine-on 1",
            "setp abbe.x.warn-mm 5", "setp abbe.y.warn-mm 5", "setp abbe.z.warn-mm 5",
            "setp abbe.x.limit-mm 10", "setp abbe.y.limit-mm 10", "setp abbe.z.limit-mm 10",
            f"loadusr -w halstreamer {stream}", "start",
            f"loadusr -w halsampler -t -n {n} {samples_path}"]
    script = work / "test.hal"
    script.write_text("\n".join(hal) + "\n")
    give(script)
    res = subprocess.run(as_user(["halrun", "-f", str(script)]), cwd=work, capture_output=True, text=True,
                         stdin=subprocess.DEVNULL, timeout=120 + n * period_ns * 1e-9)
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


STUCK_INPUT = 5
STUCK_S, STUCK_RES = 60.0, 0.02     # the table's shortest stuck time (whole minutes)
RAMP = 0.05                          # K per sample while the sensor moves (> the resolution)
HELD = (3, 66)                       # samples held at the value of sample HELD[0] - 1
STUCK_SAMPLES = 72                   # 1 s each
STUCK_EVERY, STUCK_PERIOD_NS = 100, 10000000   # 10 ms periods, a sample every 1 s
STUCK = 0x80


def stuck_table() -> tuple[bytes, object]:
    """The golden table with input STUCK_INPUT's stuck check on (written by the reference
    writer, not patched by hand: the C ports' thermal_stuck.h patches the bytes)."""
    import dataclasses

    from abbe.formats.blob import write_blob
    from abbe.formats.golden import full_table
    from abbe.formats.golden_thermal import golden_model
    from abbe.formats.thermal_blob import read_thermal_blob, write_thermal_blob
    rng = np.random.default_rng(SEED)
    table = full_table(rng)
    model = golden_model(rng)
    inputs = list(model.inputs)
    inputs[STUCK_INPUT] = dataclasses.replace(inputs[STUCK_INPUT], stuck_s=STUCK_S,
                                              stuck_resolution=STUCK_RES)
    blob = write_thermal_blob(write_blob(table), dataclasses.replace(model, inputs=tuple(inputs)))
    back = read_thermal_blob(blob)[1]
    check(back is not None and back.inputs[STUCK_INPUT].stuck_s == STUCK_S,
          "the stuck table does not read back with its stuck check")
    return blob, back


def main_stuck() -> None:
    work = work_dir("abbe-halrun-stuck-")
    try:
        blob, model = stuck_table()
        table = work / "thermal_stuck.bin"
        table.write_bytes(blob)
        give(table)
        _, x = golden_record(np.random.default_rng(SEED + 1))
        xs = x[:STUCK_SAMPLES].copy()
        i = np.arange(STUCK_SAMPLES)
        moving = np.where(i < HELD[0], i, np.where(i < HELD[1], HELD[0] - 1, i - (HELD[1] - HELD[0])))
        xs[:, STUCK_INPUT] = xs[0, STUCK_INPUT] + RAMP * moving
        n = STUCK_SAMPLES * STUCK_EVERY
        a = run(work, table, xs, False, n=n, every=STUCK_EVERY, period_ns=STUCK_PERIOD_NS)
        flags, faults, samples = a[:, 0].astype(int), a[:, 1].astype(int), a[:, 2].astype(int)
        ch, target = a[:, 3:8], a[:, 8:11]
        # sample j (0-based) reaches the runtime in the period where th.samples becomes j + 1;
        # the last change is sample HELD[0] - 1
        def first_period(j: int) -> int:
            rows = np.flatnonzero(samples >= j + 1)
            check(rows.size > 0, f"thermal sample {j} never taken ({samples[-1]} samples)")
            return int(rows[0])
        t_change = first_period(HELD[0] - 1)
        up = np.flatnonzero(flags & STUCK)
        check(up.size > 0, "the held input was never flagged stuck")
        t_flag = (int(up[0]) - t_change) * STUCK_PERIOD_NS * 1e-9
        log(f"halrun stuck: flagged {t_flag:.2f} s after the last change (stuck time {STUCK_S:g} s, "
            f"samples every {STUCK_EVERY * STUCK_PERIOD_NS * 1e-9:g} s)")
        check(STUCK_S - 1e-6 <= t_flag <= STUCK_S + STUCK_EVERY * STUCK_PERIOD_NS * 1e-9 + 1e-6,
              f"stuck flagged {t_flag:.2f} s after the last change, expected {STUCK_S:g} s "
              f"(+ at most one sample)")
        t_move = first_period(HELD[1])
        flagged = slice(int(up[0]), t_move)
        check(bool(np.all(flags[flagged] & STUCK)) and bool(np.all(flags[flagged] & HOLD)),
              "STUCK and HOLD not up from the flag to the first moving sample")
        check(bool(np.all(faults[flagged] == 1 << STUCK_INPUT)),
              f"th.input-faults does not name input {STUCK_INPUT} alone while stuck")
        check(not np.any(flags[t_move:] & STUCK), "the stuck flag stays after the input moves")
        check(not np.any(flags[STUCK_EVERY:int(up[0])] & 0x8F),
              "a thermal fault flag before the stuck time ran out")
        # no jump: from the flag on, the largest target step at a sample is at most the
        # largest at the samples before it (the golden record moves every input but the held
        # one) plus one fade step of every channel; between samples only the fades move it
        steps = np.abs(np.diff(target, axis=0)).max(axis=1) * 1e6   # nm, period k -> k + 1
        at_sample = np.diff(samples) > 0
        fade = np.abs(ch).max(axis=0).sum() * 1000 * STUCK_PERIOD_NS * 1e-9 / model.fade_s
        k0 = int(up[0]) - 1
        before = steps[STUCK_EVERY:k0][at_sample[STUCK_EVERY:k0]].max()
        after = steps[k0:][at_sample[k0:]].max()
        between = steps[k0:][~at_sample[k0:]].max()
        log(f"halrun stuck: largest target step at a sample {before:.0f} nm before the flag, "
            f"{after:.0f} nm from the flag through the fade-out and back (bound "
            f"{before + fade + 2:.0f}); between samples {between:.1f} nm (one fade step of every "
            f"channel {fade:.1f} nm)")
        check(after <= before + fade + 2, f"the target jumped at a sample: {after:.0f} nm "
              f"(bound {before + fade + 2:.0f})")
        check(between <= fade + 2, f"the target moved {between:.1f} nm between samples "
              f"(bound: one fade step {fade:.1f} nm + 2)")
        log("halrun thermal stuck test: OK")
    finally:
        cleanup(work)



if __name__ == "__main__":
    main_wrapper(main_stuck if "--stuck" in sys.argv[1:] else main)
