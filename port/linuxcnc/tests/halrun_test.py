#!/usr/bin/python3
"""halrun test of the abbe HAL component (port/linuxcnc/abbe.comp).

The installed component runs on a 1 ms thread in halrun (POSIX non-realtime),
fed every period by halstreamer (positions along the vmc500 ballbar circle,
temperatures, enable / homed / machine-on) and recorded every period by
halsampler, in the same thread, so sample k belongs to input line k.

Checked against the model through the ``abbe`` CLI (the float64 reference):
  - every period: the model correction (target) within 2 nm of the reference;
  - homed low: zero correction, zero counts, state off;
  - after each fade-in: the correction equals the reference within 2 nm;
  - enable off / on: fades of the configured length, never a jump;
  - parameters changed while running (fade-s, rate) take effect, no jump;
  - machine-on low: the counts hold (LinuxCNC would drop changes), and the
    port's view of LinuxCNC's offset restarts from zero at machine-on;
  - the counts never change by more than the rate limit in a period;
  - the f32 variant agrees with the reference as well;
  - a missing, damaged or foreign table file refuses the load with the
    library's status text; so do a 3-axis and a five-axis table together.

Usage: halrun_test.py (the component installed: port/linuxcnc/build.sh --install)
"""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

import numpy as np

from lcnc_common import (NUMERICS_BOUND_NM, REPO, TestFailure, as_user, check, cleanup, give,
                         hal_clean, lead_positions, log, main_wrapper, make_table, read_samples,
                         reference_error_um, direction_states, table_info, work_dir)

CENTRE_MM = (343.507, -285.09, -286.43)  # examples/vmc500/machine.toml, ballbar circle1
RADIUS_MM = 100.0
SPEED_MM_S = 100.0
PERIOD_S = 0.001
FADE_S = 0.2          # set before start
FADE_S_LATER = 0.1    # set while running, before the disable
RATE_Y_LATER = 0.5    # mm/s, set while running
CHANGE_AT = 2500      # cycle after which the driver changes them
DEADBAND_MM = 0.0005  # the default
LEAD_PERIODS = 2.0    # the default

# Phases of the main run: (first cycle, enable, homed, machine-on)
PHASES = [
    (0, 1, 0, 1),      # not homed: nothing
    (500, 1, 1, 1),    # homed: fade in
    (6000, 0, 1, 1),   # disable: fade out
    (6600, 1, 1, 1),   # enable: fade in
    (7400, 1, 1, 0),   # machine off: hold
    (7700, 1, 1, 1),   # machine on
]
N_MAIN = 9000
TEMPS = [(0, (23.5, 21.0, 18.5)), (3500, (25.0, 22.0, 17.0))]

SAMPLER_PINS = [
    "abbe.x.pos-mm", "abbe.y.pos-mm", "abbe.z.pos-mm",
    "abbe.x.corr-mm", "abbe.y.corr-mm", "abbe.z.corr-mm",
    "abbe.x.target-mm", "abbe.y.target-mm", "abbe.z.target-mm",
    "abbe.x.counts", "abbe.y.counts", "abbe.z.counts",
    "abbe.x.offset-mm", "abbe.y.offset-mm", "abbe.z.offset-mm",
    "abbe.state", "abbe.flags", "abbe.cycles",
]
SAMPLER_CFG = "fffffffffsssfffsuu"
STREAM_PINS = ["abbe.x.pos-mm", "abbe.y.pos-mm", "abbe.z.pos-mm",
               "abbe.x.temp-c", "abbe.y.temp-c", "abbe.z.temp-c",
               "abbe.enable", "abbe.homed", "abbe.machine-on"]
STREAM_CFG = "ffffffbbb"

FLAG_FADING = 0x0100
FLAG_RATE_LIMITED = 0x0040
FLAG_HOLD = 0x00040000


def circle_positions(n: int) -> np.ndarray:
    """n periods along the circle at SPEED_MM_S, rounded to whole nm."""
    w = SPEED_MM_S / RADIUS_MM * PERIOD_S
    a = w * np.arange(n)
    pos = np.column_stack([CENTRE_MM[0] + RADIUS_MM * np.cos(a),
                           CENTRE_MM[1] + RADIUS_MM * np.sin(a),
                           np.full(n, CENTRE_MM[2])])
    return np.round(pos * 1e6) / 1e6


def levels(n: int, phases) -> np.ndarray:
    out = np.zeros((n, 3), dtype=int)
    for i, (start, en, homed, on) in enumerate(phases):
        end = phases[i + 1][0] if i + 1 < len(phases) else n
        out[start:end] = (en, homed, on)
    return out


def temperatures(n: int, temps) -> np.ndarray:
    out = np.zeros((n, 3))
    for i, (start, t) in enumerate(temps):
        end = temps[i + 1][0] if i + 1 < len(temps) else n
        out[start:end] = t
    return out


def write_stream(path: Path, pos, temp, lev) -> None:
    with path.open("w") as f:
        for p, t, l in zip(pos, temp, lev):
            f.write(f"{p[0]:.6f} {p[1]:.6f} {p[2]:.6f} {t[0]:.6f} {t[1]:.6f} {t[2]:.6f} "
                    f"{l[0]} {l[1]} {l[2]}\n")
    give(path)


def hal_script(work: Path, table: Path | None, n: int, variant: str, fade_s: float) -> Path:
    lines = [
        "loadrt threads name1=servo period1=1000000",
        f"loadrt streamer depth={n + 16} cfg={STREAM_CFG}",
        f"loadrt sampler depth=4000 cfg={SAMPLER_CFG}",
        f"loadrt abbe variant={variant}" + (f" table={table}" if table is not None else ""),
    ]
    for i, pin in enumerate(STREAM_PINS):
        lines.append(f"net in{i} streamer.0.pin.{i} => {pin}")
    for i, pin in enumerate(SAMPLER_PINS):
        if pin in STREAM_PINS:
            lines.append(f"net in{STREAM_PINS.index(pin)} => sampler.0.pin.{i}")
        else:
            lines.append(f"net out{i} {pin} => sampler.0.pin.{i}")
    lines += [
        "addf streamer.0 servo",
        "addf abbe servo",
        "addf sampler.0 servo",
        f"setp abbe.fade-s {fade_s}",
        # the whole stream is in the FIFO before the thread starts
        f"loadusr -w halstreamer {work / 'stream.txt'}",
        "start",
        f"loadusr -w halsampler -t -n {n} {work / 'samples.txt'}",
    ]
    path = work / "test.hal"
    path.write_text("\n".join(lines) + "\n")
    give(path)
    return path


def halcmd(*args: str) -> str:
    res = subprocess.run(as_user(["halcmd", *args]), capture_output=True, text=True,
                         stdin=subprocess.DEVNULL, timeout=30)
    if res.returncode != 0:
        raise TestFailure(f"halcmd {' '.join(args)}: {res.stderr.strip() or res.stdout.strip()}")
    return res.stdout.strip()


def run_halrun(work: Path, table: Path | None, pos, temp, lev, variant: str, changes: bool) -> dict:
    """Run one scenario; returns the samples and what the driver saw."""
    n = len(pos)
    write_stream(work / "stream.txt", pos, temp, lev)
    script = hal_script(work, table, n, variant, FADE_S)
    hal_clean()
    t0 = time.monotonic()
    proc = subprocess.Popen(as_user(["halrun", "-f", str(script)]), cwd=work,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            stdin=subprocess.DEVNULL)
    seen = {}
    try:
        # Wait until the thread runs, read the CRC, change parameters mid-run.
        deadline = t0 + 60 + n * PERIOD_S * 3
        stage = 0
        while proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
            try:
                cycles = int(halcmd("getp", "abbe.cycles"), 0)
            except TestFailure:
                continue  # not loaded yet
            if stage == 0 and cycles > 0:
                seen["crc"] = int(halcmd("getp", "abbe.model-crc"), 0)
                seen["tables"] = int(halcmd("getp", "abbe.tables"), 0)
                stage = 1
            if stage == 1 and changes and cycles >= CHANGE_AT:
                halcmd("setp", "abbe.fade-s", f"{FADE_S_LATER}")
                halcmd("setp", "abbe.y.rate-mm-per-s", f"{RATE_Y_LATER}")
                seen["changed_after"] = cycles
                seen["changed_before"] = int(halcmd("getp", "abbe.cycles"), 0)
                stage = 2
        out, _ = proc.communicate(timeout=max(5.0, deadline - time.monotonic()))
    except subprocess.TimeoutExpired:
        proc.kill()
        raise TestFailure("halrun did not finish in time")
    finally:
        if proc.poll() is None:
            proc.kill()
    check(proc.returncode == 0, f"halrun exit {proc.returncode}:\n{out}")
    data = read_samples(work / "samples.txt", len(SAMPLER_PINS))
    check(len(data) == n, f"{len(data)} samples, expected {n}")
    seen["samples"] = data
    seen["wall_s"] = time.monotonic() - t0
    return seen


def columns(data: np.ndarray) -> dict:
    c = {name: data[:, 1 + i] for i, name in enumerate(SAMPLER_PINS)}
    c["tag"] = data[:, 0]
    return c


def nm(x) -> np.ndarray:
    return np.rint(np.asarray(x) * 1e6)


def check_alignment(c: dict, pos: np.ndarray) -> None:
    got = np.column_stack([c["abbe.x.pos-mm"], c["abbe.y.pos-mm"], c["abbe.z.pos-mm"]])
    check(np.max(np.abs(nm(got) - nm(pos))) <= 1, "sampled positions are not the streamed ones")
    check(np.all(np.diff(c["tag"]) == 1), "halsampler sample numbers are not consecutive")
    cyc = c["abbe.cycles"]
    check(np.all(np.diff(cyc) == 1), "the component did not run exactly once per sample")


def reference(table: Path, info: dict, pos: np.ndarray, temp: np.ndarray) -> np.ndarray:
    """The correction the model asks for, nm: -(dX, dY, dZ) at the lead
    positions, with the direction states of the documented rules."""
    pos_nm = nm(pos).astype(np.int64)
    ahead_nm = lead_positions(pos_nm, LEAD_PERIODS)
    s = direction_states(pos_nm, np.ones(len(pos), bool), int(round(DEADBAND_MM * 1e6)),
                         info["takeup_mm"], moved_nm=ahead_nm)
    err_um = reference_error_um(table, ahead_nm / 1e6, s, temp if info["thermal"] else None)
    return -err_um * 1e3, s


def max_jump_ok(corr_nm, target_nm, fade_cycles, k0, k1, what) -> None:
    """No jump in [k0, k1): a period's change is at most the fade step of the
    target plus the target's own change (plus rounding)."""
    d = np.abs(np.diff(corr_nm[k0 - 1:k1], axis=0))
    allow = (np.abs(target_nm[k0:k1]) / fade_cycles + np.abs(np.diff(target_nm[k0 - 1:k1], axis=0))
             + 2.0)
    bad = np.argwhere(d > allow)
    if len(bad):
        k, j = bad[0]
        raise TestFailure(f"{what}: correction jumped {d[k, j]:.0f} nm at cycle {k0 + k} axis {'xyz'[j]}"
                          f" (allowed {allow[k, j]:.0f} nm)")


def test_main(work: Path, table: Path, info: dict) -> dict:
    pos = circle_positions(N_MAIN)
    temp = temperatures(N_MAIN, TEMPS)
    lev = levels(N_MAIN, PHASES)
    log(f"main run: {N_MAIN} periods of 1 ms, q variant")
    seen = run_halrun(work, table, pos, temp, lev, "q", changes=True)
    c = columns(seen["samples"])
    check_alignment(c, pos)
    check(seen.get("crc") == info["crc"], f"model-crc 0x{seen.get('crc', 0):08X}, table CRC 0x{info['crc']:08X}")
    check(seen.get("tables") == 1, "tables pin")
    check("changed_after" in seen, "the driver could not change the parameters while running")
    k_change = seen["changed_before"]
    check(k_change < 6000 - 500, f"parameters changed too late (cycle {k_change})")

    ref_nm, s = reference(table, info, pos, temp)
    corr = np.column_stack([nm(c[f"abbe.{a}.corr-mm"]) for a in "xyz"])
    target = np.column_stack([nm(c[f"abbe.{a}.target-mm"]) for a in "xyz"])
    counts = np.column_stack([c[f"abbe.{a}.counts"] for a in "xyz"])
    offset = np.column_stack([nm(c[f"abbe.{a}.offset-mm"]) for a in "xyz"])
    state = c["abbe.state"].astype(int)
    flags = c["abbe.flags"].astype(np.int64)
    res = {}

    # The model itself, every period (enabled or not).
    d_target = np.abs(target - ref_nm)
    res["target_max_nm"] = float(d_target.max())
    check(res["target_max_nm"] <= NUMERICS_BOUND_NM,
          f"target differs from the reference by {res['target_max_nm']:.1f} nm")
    # The run exercised backlash and the temperature pins.
    check(np.ptp(s[:, 0]) >= 2.0 and np.ptp(s[:, 1]) >= 2.0, "backlash direction never reversed")
    dT = ref_nm[3500] - ref_nm[3499]
    check(np.max(np.abs(dT)) > 500, f"the temperature step moved the reference by only {dT} nm")

    # Homed low: nothing at all.
    check(np.all(corr[:500] == 0) and np.all(counts[:500] == 0) and np.all(state[:500] == 0),
          "correction, counts or state non-zero before homing")

    # Fade-in after homing: complete within the fade, then equal to the reference.
    fade = int(round(FADE_S / PERIOD_S))
    max_jump_ok(corr, target, fade, 501, 700 + 50, "fade-in")
    steady = ((state == 1) & ((flags & (FLAG_FADING | FLAG_RATE_LIMITED)) == 0))
    check(not steady[500:500 + fade - 1].any(), "the fade-in ended early")
    check(steady[500 + fade + 2], "the fade-in did not end after fade-s")
    d_corr = np.abs(corr - ref_nm)[steady]
    res["corr_max_nm"] = float(d_corr.max())
    res["steady_cycles"] = int(steady.sum())
    check(res["steady_cycles"] > 6000, f"only {res['steady_cycles']} steady cycles")
    check(res["corr_max_nm"] <= NUMERICS_BOUND_NM,
          f"correction differs from the reference by {res['corr_max_nm']:.1f} nm after fade-in")

    # Disable at 6000: fade out in the new fade time, no jump; zero after.
    fade2 = int(round(FADE_S_LATER / PERIOD_S))
    max_jump_ok(corr, target, fade2, 6000, 6600, "fade-out")
    check(np.all(corr[6000 + fade2 + 1:6600] == 0), "correction not zero after the fade-out")
    check(np.any(corr[6000 + fade2 // 2] != 0), "fade-out ended early (a jump)")
    res["fade_out_cycles"] = int(np.argmax(np.all(corr[6000:] == 0, axis=1)))
    check(res["fade_out_cycles"] <= fade2 + 1, f"fade-out took {res['fade_out_cycles']} cycles")
    # Enable at 6600: fade in again, no jump, reference after.
    max_jump_ok(corr, target, fade2, 6600, 7400, "second fade-in")
    check(steady[6600 + fade2 + 2], "second fade-in did not end after fade-s")

    # Rate limit on the counts everywhere (y: 0.5 mm/s from the change on).
    rate = np.full((N_MAIN - 1, 3), 1000.0)
    rate[k_change + 1:, 1] = RATE_Y_LATER * 1e3
    dc = np.abs(np.diff(counts, axis=0))
    check(np.all(dc <= rate), f"counts moved {dc.max():.0f} nm in a period")

    # Machine off at 7400: counts held, the correction fades out; machine on at
    # 7700: the port's LinuxCNC offset restarts at zero and catches up.
    check(np.all(counts[7400:7700] == counts[7400]), "counts changed while the machine was off")
    check(np.all(flags[7400:7700] & FLAG_HOLD), "hold flag missing while the machine was off")
    check(np.all(offset[7400:7700] == offset[7399]), "offset changed while the machine was off")
    check(np.all(offset[7700] == 0), "the port's LinuxCNC offset did not restart at machine-on")
    check(np.all(corr[7700 - 1] == 0), "correction did not fade out with the machine off")
    check(steady[7700 + fade + 2], "no fade-in after machine-on")
    res["wall_s"] = seen["wall_s"]
    return res


def test_f32(work: Path, table: Path, info: dict) -> dict:
    n = 3000
    pos = circle_positions(n)
    temp = temperatures(n, [(0, (21.5, 19.0, 24.0))])
    lev = levels(n, [(0, 1, 1, 1)])
    log(f"f32 run: {n} periods")
    seen = run_halrun(work, table, pos, temp, lev, "f32", changes=False)
    c = columns(seen["samples"])
    check_alignment(c, pos)
    ref_nm, _ = reference(table, info, pos, temp)
    corr = np.column_stack([nm(c[f"abbe.{a}.corr-mm"]) for a in "xyz"])
    target = np.column_stack([nm(c[f"abbe.{a}.target-mm"]) for a in "xyz"])
    flags = c["abbe.flags"].astype(np.int64)
    state = c["abbe.state"].astype(int)
    steady = (state == 1) & ((flags & (FLAG_FADING | FLAG_RATE_LIMITED)) == 0)
    res = {"target_max_nm": float(np.abs(target - ref_nm).max()),
           "corr_max_nm": float(np.abs(corr - ref_nm)[steady].max()),
           "steady_cycles": int(steady.sum())}
    check(res["steady_cycles"] > 2500, "f32: too few steady cycles")
    check(res["target_max_nm"] <= NUMERICS_BOUND_NM, f"f32 target off by {res['target_max_nm']:.1f} nm")
    check(res["corr_max_nm"] <= NUMERICS_BOUND_NM, f"f32 correction off by {res['corr_max_nm']:.1f} nm")
    return res


def test_bad_tables(work: Path, good: Path) -> None:
    blob = bytearray(good.read_bytes())
    damaged = bytearray(blob)
    damaged[300] ^= 0x01
    foreign = b"ABBF" + bytes(blob[4:])
    cases = [
        ("missing.bin", None, "cannot open: No such file or directory"),
        ("damaged.bin", bytes(damaged), "refused: table CRC-32 mismatch"),
        ("foreign.bin", foreign, "refused: bad magic: not an abbe table"),
        ("short.bin", bytes(blob[:100]), "refused: table truncated"),
    ]
    for name, content, expect in cases:
        path = work / name
        if content is not None:
            path.write_bytes(content)
            give(path)
        script = work / "bad.hal"
        script.write_text(f"loadrt abbe table={path}\n")
        give(script)
        hal_clean()
        res = subprocess.run(as_user(["halrun", "-f", str(script)]), cwd=work, capture_output=True,
                             text=True, stdin=subprocess.DEVNULL, timeout=60)
        text = res.stdout + res.stderr
        check(res.returncode != 0, f"{name}: the component loaded")
        check(f"abbe: table {path}" in text and expect in text,
              f"{name}: expected '{expect}' in:\n{text}")
        log(f"bad table {name}: refused ({expect})")
    # a five-axis table after a 3-axis one: the pins would mean axis and joint positions
    five = work / "five.bin"
    five.write_bytes((REPO / "host_tools/tests/exports/golden/trunnion5ax-fit/"
                      "model_five.bin").read_bytes())
    give(five)
    script = work / "bad.hal"
    script.write_text(f"loadrt abbe table={good},{five}\n")
    give(script)
    hal_clean()
    res = subprocess.run(as_user(["halrun", "-f", str(script)]), cwd=work, capture_output=True,
                         text=True, stdin=subprocess.DEVNULL, timeout=60)
    check(res.returncode != 0 and f"abbe: table {five}: kinematics 1" in res.stdout + res.stderr
          and "one kind for all tables" in res.stdout + res.stderr,
          f"a 3-axis and a five-axis table loaded together:\n{res.stdout}{res.stderr}")
    log("3-axis + five-axis tables: refused (one kind for all tables)")
    script = work / "bad.hal"
    script.write_text("loadrt abbe\n")
    give(script)
    res = subprocess.run(as_user(["halrun", "-f", str(script)]), cwd=work, capture_output=True,
                         text=True, stdin=subprocess.DEVNULL, timeout=60)
    check(res.returncode != 0 and "table=FILE is required" in res.stdout + res.stderr,
          "loadrt abbe without a table loaded")


def test_builtin(work: Path, table: Path, info: dict) -> dict:
    """A module built with the table compiled in (build.sh --builtin, from
    abbe table cgen of the same table): loads without table= and runs that
    table; a table= file given to it is still read and checked (a damaged one
    refuses the load)."""
    n = 1500
    pos = circle_positions(n)
    temp = temperatures(n, [(0, (20.5, 20.0, 19.5))])
    lev = levels(n, [(0, 1, 1, 1)])
    log(f"built-in table run: {n} periods")
    seen = run_halrun(work, None, pos, temp, lev, "q", changes=False)  # no table=
    check(seen.get("crc") == info["crc"], f"built-in model-crc 0x{seen.get('crc', 0):08X}, "
          f"table CRC 0x{info['crc']:08X}")
    c = columns(seen["samples"])
    check_alignment(c, pos)
    ref_nm, _ = reference(table, info, pos, temp)
    target = np.column_stack([nm(c[f"abbe.{a}.target-mm"]) for a in "xyz"])
    res = {"target_max_nm": float(np.abs(target - ref_nm).max())}
    check(res["target_max_nm"] <= NUMERICS_BOUND_NM, f"built-in: target off by {res['target_max_nm']:.1f} nm")
    damaged = bytearray(table.read_bytes())
    damaged[300] ^= 1
    bad = work / "damaged.bin"
    bad.write_bytes(bytes(damaged))
    give(bad)
    script = work / "bad.hal"
    script.write_text(f"loadrt abbe table={bad}\n")
    give(script)
    hal_clean()
    r = subprocess.run(as_user(["halrun", "-f", str(script)]), cwd=work, capture_output=True,
                       text=True, stdin=subprocess.DEVNULL, timeout=60)
    check(r.returncode != 0 and "table CRC-32 mismatch" in r.stdout + r.stderr,
          "built-in module: a damaged table= file did not refuse the load")
    return res


def main() -> None:
    import argparse
    ap = argparse.ArgumentParser()
    ap.add_argument("--builtin", action="store_true",
                    help="test a module built with the vmc500 table compiled in (run.sh does)")
    args = ap.parse_args()
    work = work_dir("abbe-halrun-")
    try:
        if args.builtin:
            table = make_table(REPO / "examples/vmc500/truth/true_table.json", work / "vmc500.bin")
            r = test_builtin(work, table, table_info(table))
            log(f"built-in table: target vs reference max {r['target_max_nm']:.1f} nm")
            log("halrun built-in table test: OK")
            return
        table = make_table(REPO / "examples/vmc500/truth/true_table.json", work / "vmc500.bin")
        info = table_info(table)
        log(f"table {table.name}: CRC 0x{info['crc']:08X}, take-up {info['takeup_mm']} mm, "
            f"backlash {info['backlash_um']} um, thermal {info['thermal']}")
        test_bad_tables(work, table)
        r = test_main(work, table, info)
        log(f"q: target vs reference max {r['target_max_nm']:.1f} nm; correction vs reference "
            f"max {r['corr_max_nm']:.1f} nm over {r['steady_cycles']} steady periods; "
            f"fade-out {r['fade_out_cycles']} periods; wall {r['wall_s']:.1f} s")
        r = test_f32(work, table, info)
        log(f"f32: target vs reference max {r['target_max_nm']:.1f} nm; correction max "
            f"{r['corr_max_nm']:.1f} nm over {r['steady_cycles']} steady periods")
        log("halrun test: OK")
    finally:
        hal_clean()
        cleanup(work)


if __name__ == "__main__":
    main_wrapper(main)
