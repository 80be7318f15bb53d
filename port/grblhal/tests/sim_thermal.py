#!/usr/bin/env python3
"""The grblHAL plugin's thermal block in the Simulator (docs/grblhal.md, "Temperatures").

A format 1.3 table (the fitted vmc500 table plus a small thermal block: two
temperatures and the spindle speed, channels dX and dZ, lags of 0 so the
expected thermal error is gain x rise) is uploaded as any table and stored;
temperatures arrive by ``$ABBET=...``; G-code runs as passes of short Y moves
(one segment each) with ``$ABBE`` after each, which reports the planner's
target of that segment end (STEPS) and the thermal part in use (OUT, um) with
the Simulator's clock at that segment end (APPLIED, ms).

Checked: the thermal error against the Python reference (abbe.model.thermal)
once faded in, both as OUT and as the planner's steps (the same pass without
temperatures is the baseline); an open circuit, a value out of range and
missing samples each raise their flag and fade their channels out by the
Simulator's clock, no segment end moving OUT by more than |part| x elapsed /
fade_s; the recovery fades back in; the stored table runs after a restart.
Then a stuck sensor (a second table, t_column with a stuck check of 1 min /
0.01 K): t_column alternates by 0.05 K, then repeats one value: FLAGS 80 (with
20 hold, FAULTS 1) once a minute of the Simulator's clock has passed, dX fades
out (dZ stays), and the flag clears when t_column moves again.
Figures in --json.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
import sys
import tempfile
import time
import zlib
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from sim_driver import STEPS_PER_MM, Checks, Sim  # noqa: E402

from abbe.formats.thermal_blob import block_size, write_thermal_blob  # noqa: E402
from abbe.model.thermal import (  # noqa: E402
    SPEED,
    ThermalChannel,
    ThermalInput,
    ThermalModel,
    ThermalTerm,
    evaluate,
    tool_tip_error,
)

FADE_S = 20.0
STUCK_S = 60.0            # the stuck check's time (whole minutes in the table)
MAX_GAP_S = 30.0
GOOD = (25.0, 24.0, 3000.0)   # deg C, deg C, rpm
N_MOVES = 50                  # Y moves per pass, 2 mm each
X_MM, Z_MM, Y0_MM = 50.0, -30.0, -40.0


def thermal_model() -> ThermalModel:
    inputs = (ThermalInput(name="t_column", reference=20.0, valid_min=-10.0, valid_max=90.0, max_step=30.0),
              ThermalInput(name="t_spindle", reference=20.0, valid_min=-10.0, valid_max=90.0, max_step=30.0),
              ThermalInput(name="spindle", kind=SPEED, reference=0.0, valid_min=0.0, valid_max=12000.0,
                           max_step=12000.0))
    channels = (ThermalChannel(name="dx", output="x", terms=(ThermalTerm(input=0, tau_s=0.0, gain=8.0),),
                               limit=150.0),
                ThermalChannel(name="dz", output="z", terms=(ThermalTerm(input=1, tau_s=0.0, gain=-6.0),
                                                            ThermalTerm(input=2, tau_s=0.0, gain=4.0)),
                               limit=150.0))
    return ThermalModel(inputs=inputs, channels=channels, max_gap_s=MAX_GAP_S, fade_s=FADE_S)


def expected_tip_um(model: ThermalModel, x: tuple[float, ...]) -> np.ndarray:
    """The reference's tool tip error (dX, dY, dZ), um, for steady inputs x (lags 0)."""
    out = evaluate(model, np.array([0.0, 1.0]), np.array([x, x], dtype=float))
    return tool_tip_error(model, out[-1], 0.0)


def info(sim: Sim) -> dict[str, str]:
    """$ABBE's main and THERMAL lines as one dict (THERMAL's fields prefixed T_)."""
    r, seen = sim.send("$ABBE")
    d: dict[str, str] = {}
    for ln in seen:
        if ln.startswith("[ABBE:") and "|SEGMENTS:" in ln:
            d.update(x.split(":", 1) for x in ln.strip("[]").split("|"))
        elif ln.startswith("[ABBE:THERMAL:"):
            parts = ln.strip("[]").split("|")
            d["THERMAL"] = parts[0].split(":", 2)[2]
            d.update(("T_" + k, v) for k, v in (x.split(":", 1) for x in parts[1:]))
    return d


def out_um(d: dict[str, str]) -> np.ndarray:
    return np.array([float(v) for v in d["T_OUT"].split(" ")[0].split(",")])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sim", type=Path, required=True)
    ap.add_argument("--table", type=Path, required=True, help="the compiled-in table (format 1.0 / 1.1)")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--stuck", action="store_true",
                    help="also the stuck sensor (2-3 min more: off in run.sh for CI time)")
    args = ap.parse_args()
    args.sim = args.sim.resolve()
    C = Checks()
    model = thermal_model()
    base_blob = args.table.read_bytes()
    blob = write_thermal_blob(base_blob, model)
    C.check(len(blob) == len(base_blob) + block_size(3, 2) == len(base_blob) + 16 + 20 * 3 + 56 * 2,
            f"thermal table {len(blob)} bytes = {len(base_blob)} + 16 + 20 x 3 + 56 x 2")
    tip = expected_tip_um(model, GOOD)
    summary: dict = {"table_bytes": len(blob), "expected_tip_um": tip.tolist(), "fade_s": FADE_S,
                     "max_gap_s": MAX_GAP_S}
    work = Path(tempfile.mkdtemp(prefix="abbe-gh-thermal-"))
    sim = Sim(args.sim, work, "thermal")
    try:
        d = info(sim)
        C.check(d.get("THERMAL") == "NONE", f"compiled-in 1.1 table: no thermal block ({d.get('THERMAL')})")
        r, seen = sim.send("$ABBET=20,20,0")
        C.check(r.startswith("error") and any("no thermal block" in s for s in seen),
                f"$ABBET without a thermal block refused: {r} {seen}")
        sim.ok("$ABBEU=A")
        # upload as any table (docs/grblhal.md "Table upload")
        sim.ok(f"$ABBEU=B,{len(blob)},{zlib.crc32(blob):08X}")
        for o in range(0, len(blob), 96):
            sim.ok(f"$ABBEU=D,{o},{blob[o:o + 96].hex().upper()}")
        seen = sim.ok("$ABBEU=C")
        C.check(any("table stored" in s for s in seen), f"the thermal table is stored: {seen}")
        sim.ok("G1 X%.3f Y%.3f Z%.3f F3000" % (X_MM, Y0_MM, Z_MM))
        d = info(sim)
        C.check(d.get("THERMAL", "").startswith("3 inputs,2 channels"), f"thermal block in use: {d.get('THERMAL')}")
        for bad, why in (("$ABBET=20,20", "2 values"), ("$ABBET=20,x,0", "not a number"),
                         ("$ABBET=20,20,0,1", "more values")):
            r, seen = sim.send(bad)
            C.check(r.startswith("error") and any(why in s for s in seen), f"{bad} refused ({why}): {seen}")
            sim.ok("$ABBET=CLEAR")  # a $ command that succeeds (grblHAL's error latch)

        def one_pass(name: str, sample, pause_s: float = 0.0) -> list[dict]:
            """Y moves of 2 mm (one segment each) from Y0 down, $ABBE after each; back to Y0.
            ``sample``: the $ABBET values before every move (a callable: of the move's index)."""
            rows = []
            for k in range(N_MOVES):
                if sample is not None:
                    sim.ok("$ABBET=" + (sample(k) if callable(sample) else sample))
                if pause_s and k % 10 == 9:
                    time.sleep(pause_s)
                sim.ok("G1 Y%.3f F600" % (Y0_MM - 2.0 * (k + 1)))
                d = info(sim)
                rows.append({"k": k, "steps": [int(v) for v in d["STEPS"].split(",")], "out": out_um(d).tolist(),
                             "applied_ms": int(d["T_APPLIED"].split(" ")[0]), "flags": int(d["T_FLAGS"], 16),
                             "events": int(d["T_EVENTS"], 16), "faults": int(d["T_FAULTS"], 16)})
            sim.ok("G1 Y%.3f F3000" % (Y0_MM + 1.0))
            sim.ok("G1 Y%.3f F3000" % Y0_MM)  # approach the pass's start from above, as every pass does
            print(f"  pass {name}: OUT {rows[0]['out']} -> {rows[-1]['out']} um, flags {rows[-1]['flags']:02X}, "
                  f"clock {rows[0]['applied_ms']} -> {rows[-1]['applied_ms']} ms")
            return rows

        def through_fade(rows: list[dict], name: str, sample, t0_ms: int) -> list[dict]:
            """``rows`` and more passes until FADE_S (+ 1 s: segment granularity) of the
            Simulator's clock has passed since ``t0_ms``: a pass's simulated duration is not
            fixed (the Simulator runs at -t x real time only when the host keeps up; on a
            loaded one it slows its clock, and two passes once took 13.5 s where the fade
            back from 3.3 um needed 18.3 s). At most 6 more passes."""
            for _ in range(6):
                if rows[-1]["applied_ms"] - t0_ms >= (FADE_S + 1.0) * 1000:
                    break
                rows = rows + one_pass(f"{name}, continued", sample)
            return rows

        def fade_steps(rows: list[dict], parts: np.ndarray, name: str) -> float:
            """Largest |change of OUT| per segment end, and the check against the fade rate."""
            worst, ratio = 0.0, 0.0
            for a, b in zip(rows, rows[1:]):
                dt = b["applied_ms"] - a["applied_ms"]
                dv = np.abs(np.array(b["out"]) - np.array(a["out"]))
                allowed = parts * dt / (FADE_S * 1000.0) + 0.002  # OUT is printed to 1 nm
                worst = max(worst, float(dv.max()))
                ratio = max(ratio, float(np.max(dv / allowed)))
            C.check(ratio <= 1.0, f"{name}: no segment end moves OUT faster than the fade "
                                  f"(largest {worst:.3f} um, {ratio:.2f} of the allowed)")
            return worst

        sim.ok("$ABBET=CLEAR")
        one_pass("warm-up: the compensator fades the new table in (32 segments)", None)
        base = one_pass("baseline (no sample yet)", None)
        C.check(all(r["out"] == [0.0, 0.0, 0.0] for r in base), "no sample yet: thermal part 0")
        base_steps = np.array([r["steps"] for r in base])
        good = ",".join(f"{v:g}" for v in GOOD)
        fade_in = one_pass("fade in", good)
        steady = one_pass("steady", good)
        parts = np.abs(tip)
        fade_steps(fade_in, parts, "fade in")
        last = steady[-1]
        C.check(np.allclose(last["out"], tip, atol=0.002), f"steady: OUT {last['out']} um = reference {tip} um")
        # where the thermal part is complete: planner steps - baseline = -tip x steps/mm, within
        # the two roundings to whole steps (1 step)
        full = [r for r in steady if np.allclose(r["out"], tip, atol=0.002)]
        th_steps = np.array([np.array(r["steps"]) - base_steps[r["k"]] for r in full])
        want = -tip * STEPS_PER_MM * 1e-3
        dev = np.abs(th_steps - want).max() if full else np.inf
        C.check(len(full) >= 10 and dev <= 1.0, f"steady: planner steps - baseline = -tip x steps/mm within 1 step "
                                                f"({len(full)} segment ends, largest {dev:.2f} steps; expected {want})")
        summary["steady_steps_vs_reference"] = float(dev)

        # open circuit of t_column: dX holds and fades out, dZ stays
        open_rows = one_pass("open circuit (t_column)", "-,%g,%g" % GOOD[1:])
        C.check(open_rows[0]["flags"] & 0x01 and open_rows[0]["flags"] & 0x20 and open_rows[0]["faults"] == 1,
                f"open circuit: FLAGS {open_rows[0]['flags']:02X} (01 open, 20 hold), FAULTS {open_rows[0]['faults']}")
        summary["open_worst_um_per_segment"] = fade_steps([steady[-1]] + open_rows, parts, "open circuit")
        open_rows = through_fade(open_rows, "open circuit", "-,%g,%g" % GOOD[1:], steady[-1]["applied_ms"])
        C.check(abs(open_rows[-1]["out"][0]) <= 0.001 and abs(open_rows[-1]["out"][2] - tip[2]) <= 0.002,
                f"open circuit: dX faded out, dZ kept ({open_rows[-1]['out']})")
        rec = through_fade(one_pass("recovery", good), "recovery", good, open_rows[-1]["applied_ms"])
        fade_steps(rec, parts, "recovery")
        C.check(np.allclose(rec[-1]["out"], tip, atol=0.002), f"recovered: OUT {rec[-1]['out']}")

        # out of range on t_spindle: dZ fades out
        hot = "%g,500,%g" % (GOOD[0], GOOD[2])
        rng_rows = through_fade(one_pass("out of range (t_spindle 500 deg C)", hot), "out of range", hot,
                                rec[-1]["applied_ms"])
        C.check(bool(rng_rows[0]["flags"] & 0x02) and rng_rows[0]["faults"] == 2,
                f"out of range: FLAGS {rng_rows[0]['flags']:02X} (02 range), FAULTS {rng_rows[0]['faults']}")
        summary["range_worst_um_per_segment"] = fade_steps([rec[-1]] + rng_rows, parts, "out of range")
        C.check(abs(rng_rows[-1]["out"][2]) <= 0.001 and abs(rng_rows[-1]["out"][0] - tip[0]) <= 0.002,
                f"out of range: dZ faded out, dX kept ({rng_rows[-1]['out']})")
        rec2 = through_fade(one_pass("recovery 2", good), "recovery 2", good, rng_rows[-1]["applied_ms"])
        C.check(np.allclose(rec2[-1]["out"], tip, atol=0.002), f"recovered: OUT {rec2[-1]['out']}")

        # missing samples: none for more than max_gap (the Simulator's clock runs at -t x real time)
        sim.ok("$ABBET=CLEAR")
        gap_rows = one_pass("missing samples", None, pause_s=0.5)
        while gap_rows[-1]["applied_ms"] - rec2[-1]["applied_ms"] < (MAX_GAP_S + FADE_S) * 1000 + 2000:
            gap_rows += one_pass("missing samples, continued", None, pause_s=0.5)
        C.check(any(r["events"] & 0x08 for r in gap_rows) and gap_rows[-1]["flags"] & 0x08,
                f"missing samples: GAP flag (FLAGS {gap_rows[-1]['flags']:02X})")
        summary["gap_worst_um_per_segment"] = fade_steps([rec2[-1]] + gap_rows, parts, "missing samples")
        C.check(np.allclose(gap_rows[-1]["out"], 0.0, atol=0.001), f"missing samples: faded out ({gap_rows[-1]['out']})")
        faded = [r for r in gap_rows if r["out"] == [0.0, 0.0, 0.0]]
        gap_steps = np.array([np.array(r["steps"]) - base_steps[r["k"]] for r in faded])
        C.check(len(faded) >= 5 and np.abs(gap_steps).max() <= 1,
                f"faded out: planner steps = baseline within 1 step ({len(faded)} segment ends, largest "
                f"{np.abs(gap_steps).max()})")
        worst_steps = 0
        for rows in (open_rows, rng_rows, gap_rows):
            st = np.array([r["steps"] for r in rows])
            b = np.tile(base_steps, (len(rows) // N_MOVES + 1, 1))[:len(rows)]
            th = st - b
            worst_steps = max(worst_steps, int(np.abs(np.diff(th, axis=0)).max()))
        summary["worst_thermal_steps_change_per_segment"] = worst_steps
        print(f"  largest change of the thermal part per segment end through the faults: {worst_steps} step(s)")
        sim.close()

        # the stored thermal table runs after a restart
        sim = Sim(args.sim, work, "thermal")
        d = info(sim)
        C.check(d.get("THERMAL", "").startswith("3 inputs,2 channels"),
                f"after a restart the stored thermal table runs: {d.get('THERMAL')}")

        if args.stuck:
            stuck_phase(sim, C, summary, one_pass, fade_steps, base_blob, model)
        sim.close()
    finally:
        for s in list(Sim.running):
            s.kill()
    summary["failed"] = C.failed
    if args.json:
        args.json.write_text(json.dumps(summary, indent=2))
    if C.failed:
        print(f"[grblhal thermal] outputs kept in {work}")
    else:
        shutil.rmtree(work, ignore_errors=True)
    print(f"[grblhal thermal] {'FAIL' if C.failed else 'ok'}: {len(C.failed)} failed")
    return 1 if C.failed else 0


def stuck_phase(sim: Sim, C: Checks, summary: dict, one_pass, fade_steps, base_blob: bytes,
                model: ThermalModel) -> None:
    """A stuck sensor: a table whose t_column has a stuck check (1 min, 0.01 K)."""
    t_start = time.monotonic()
    stuck_in = list(model.inputs)
    stuck_in[0] = dataclasses.replace(stuck_in[0], stuck_s=STUCK_S, stuck_resolution=0.01)
    stuck_blob = write_thermal_blob(base_blob, dataclasses.replace(model, inputs=tuple(stuck_in)))
    sim.ok("$ABBEU=A")
    sim.ok(f"$ABBEU=B,{len(stuck_blob)},{zlib.crc32(stuck_blob):08X}")
    for o in range(0, len(stuck_blob), 96):
        sim.ok(f"$ABBEU=D,{o},{stuck_blob[o:o + 96].hex().upper()}")
    sim.ok("$ABBEU=C")
    sim.ok("G1 X%.3f Y%.3f Z%.3f F3000" % (X_MM, Y0_MM, Z_MM))
    sim.ok("$ABBET=CLEAR")

    def moving(k: int) -> str:  # t_column alternates by 0.05 K: a live sensor
        return "%g,%g,%g" % (GOOD[0] + 0.05 * (k % 2), GOOD[1], GOOD[2])

    one_pass("stuck check: warm-up (the new table fades in)", moving)
    live = one_pass("stuck check: moving", moving) + one_pass("stuck check: moving, steady", moving)
    C.check(not any(r["flags"] & 0x80 for r in live), "a moving t_column is not stuck")
    frozen = moving(N_MOVES - 1)  # the live pass's last sample, repeated: no change from it
    held = one_pass("stuck: t_column repeats one value", frozen, pause_s=0.5)
    while held[-1]["applied_ms"] - live[-1]["applied_ms"] < (STUCK_S + FADE_S) * 1000 + 2000:
        held += one_pass("stuck, continued", frozen, pause_s=0.5)
    flagged = [r for r in held if r["flags"] & 0x80]
    C.check(bool(flagged) and all(r["flags"] & 0x20 and r["faults"] == 1 for r in flagged),
            f"stuck: FLAGS 80 with 20 hold, FAULTS 1 ({flagged[0]['flags'] if flagged else None})")
    if flagged:
        # t_column last changed at the last sample of the live pass (just before its last
        # row): the flag's first row comes a minute of the clock later
        t_flag = (flagged[0]["applied_ms"] - live[-1]["applied_ms"]) / 1000.0
        before = [r for r in held if r["applied_ms"] < flagged[0]["applied_ms"]]
        t_before = (before[-1]["applied_ms"] - live[-1]["applied_ms"]) / 1000.0 if before else 0.0
        print(f"  stuck: FLAGS 80 first at a segment end {t_flag:.1f} s after the last change "
              f"(the previous one {t_before:.1f} s, unflagged)")
        # within the planner's lag: a sample is taken when grblHAL reads its line, the
        # segment end that reports it executes later (seconds of the clock at -t 20)
        C.check(STUCK_S - 5.0 <= t_flag and t_before <= STUCK_S + 5.0,
                f"stuck: flagged about {STUCK_S:g} s after the last change ({t_before:.1f} .. {t_flag:.1f} s)")
        summary["stuck_flag_after_s"] = [t_before, t_flag]
    tip_live = expected_tip_um(model, tuple(float(v) for v in frozen.split(",")))
    C.check(abs(held[-1]["out"][0]) <= 0.001 and abs(held[-1]["out"][2] - tip_live[2]) <= 0.002,
            f"stuck: dX faded out, dZ kept ({held[-1]['out']})")
    summary["stuck_worst_um_per_segment"] = fade_steps([live[-1]] + held, np.abs(tip_live) + 0.4,
                                                       "stuck")
    back = one_pass("stuck: t_column moves again", moving)
    C.check(not back[0]["flags"] & 0x80 and bool(back[0]["events"] & 0x80),
            f"stuck: cleared by the first moving sample, kept in EVENTS ({back[0]['flags']:02X}, "
            f"{back[0]['events']:02X})")
    back += one_pass("stuck: recovery, steady", moving)
    C.check(not back[-1]["flags"] & 0xFF and abs(back[-1]["out"][0] - tip_live[0]) <= 0.41,
            f"stuck: recovered ({back[-1]['flags']:02X}, OUT {back[-1]['out']})")
    summary["stuck_wall_s"] = round(time.monotonic() - t_start, 1)
    print(f"  stuck sensor: {summary['stuck_wall_s']} s of wall time")


if __name__ == "__main__":
    sys.exit(main())
