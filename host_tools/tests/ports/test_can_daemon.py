"""abbe-cand as an independent program, driven by a Python peer over a socketpair bus.

The peer (abbe.ports.can_tools.SocketpairBus) packs python-can Messages as struct
can_frame records. Checks: offsets along a circle against the float64
reference (abbe.model.reference.spatial_error) within the numerics bound plus one
increment of rounding; bad frames counted; the stale watchdog; model swap on
SIGHUP and on the RELOAD command, good and bad; configuration errors name
file/line/field; replay of a candump -l log reproduces the live session.

Needs the daemon: $ABBE_CAND, or build/bin/abbe-cand (cmake -DABBE_BUILD_PORTS=ON).
"""

from __future__ import annotations

import dataclasses
import math
import re
import shutil
import signal
import socket
import subprocess
import tomllib
import zlib
from pathlib import Path

import can
import numpy as np
import pytest

from abbe.formats.blob import read_blob, write_blob
from abbe.model.numerics import error_bound
from abbe.model.reference import spatial_error
from abbe.ports import can_tools as ct

DAEMON = ct.daemon_path()
if not DAEMON.is_file():
    pytest.skip(f"abbe-cand not built: {DAEMON} missing (cmake -DABBE_BUILD_PORTS=ON, or set ABBE_CAND)",
                allow_module_level=True)

REPO = Path(__file__).resolve().parents[3]
EXAMPLE = REPO / "examples" / "paper_table" / "model.bin"
FLAG_STALE = 0x0080
FLAG_INPUT_INVALID = 0x0200
FLAG_MODEL_SWAPPED = 0x0400

AXES = [ct.AxisScaling(10000.0), ct.AxisScaling(2000.0, sign=-1, origin_mm=-100.0),
        ct.AxisScaling(26214.4, correction_sign=-1)]
RPDO = (0x201, 0x202, 0x203)
STATUS, INFO, CMD = 0x1F0, 0x2F0, 0x270


@pytest.fixture()
def setup(tmp_path: Path) -> Path:
    """A configuration in tmp_path with its own copy of the example model."""
    shutil.copy(EXAMPLE, tmp_path / "model.bin")
    cfg = tmp_path / "can.toml"
    cfg.write_text(ct.config_text("model.bin", AXES, compensator="fade_cycles = 5\nstale_cycles = 3",
                                  axis_extra="rate_um_per_cycle = 1000\nwarn_um = 200\nlimit_um = 400"))
    return cfg


def circle(k: int, n: int = 150) -> np.ndarray:
    """Machine positions (mm) along a circle in XY with a Z wave, inside the example's travel."""
    a = 2 * math.pi * k / n
    return np.array([250 + 150 * math.cos(a), -200 + 150 * math.sin(a), -100 + 50 * math.sin(2 * a)])


def send_positions(bus: ct.SocketpairBus, incr: list[int], mask: int = 7) -> None:
    for j in range(3):
        if mask >> j & 1:
            bus.send(ct.tpdo(j + 1, incr[j]))


def offsets(ans: ct.Answer) -> list[int]:
    out = []
    for cid in RPDO:
        frames = ans.by_id(cid)
        assert len(frames) == 1, f"{len(frames)} frames 0x{cid:03X}"
        out.append(int.from_bytes(frames[0].data[:4], "little", signed=True))
    return out


def status(ans: ct.Answer) -> ct.Status:
    frames = ans.by_id(STATUS)
    assert len(frames) == 1
    return ct.decode_status(bytes(frames[0].data))


def info(ans: ct.Answer) -> ct.Info | None:
    frames = ans.by_id(INFO)
    return ct.decode_info(bytes(frames[0].data)) if frames else None


def test_circle_matches_reference(setup: Path) -> None:
    table = read_blob(EXAMPLE.read_bytes())
    bound_nm = error_bound(table).q_nm
    incrs, got = [], []
    with ct.SocketpairBus(setup) as bus:
        for k in range(300):
            incr = [a.incr_of_mm(p) for a, p in zip(AXES, circle(k))]
            send_positions(bus, incr)
            ans = bus.sync()
            st = status(ans)
            assert st.seq == k % 256 and st.fresh_mask == 7 and st.age == (0, 0, 0)
            incrs.append(incr)
            got.append(offsets(ans))
        assert bus.close() == 0
    want, corr_nm = ct.expected_offsets(table, AXES, np.array(incrs))
    got_a = np.array(got)[20:]           # after the 5-cycle fade-in
    want = want[20:]
    tol = np.array([math.floor(b * a.increments_per_mm / 1e6) + 1 for b, a in zip(bound_nm, AXES)])
    diff = np.abs(got_a - want)
    assert (diff <= tol).all(), f"max diff {diff.max(axis=0)} increments, allowed {tol}"
    assert (diff == 0).mean() > 0.9      # rounding boundaries are rare
    assert np.abs(corr_nm[20:]).max() > 5000, "the table should give corrections of several um"
    assert len({tuple(r) for r in got_a}) > 100   # the offsets follow the motion


def test_bad_frames_are_counted(setup: Path) -> None:
    incr = [a.incr_of_mm(p) for a, p in zip(AXES, circle(0))]
    with ct.SocketpairBus(setup) as bus:
        send_positions(bus, incr, mask=6)
        bus.send(can.Message(arbitration_id=0x181, is_extended_id=False, data=b"\1\2\3"))   # wrong DLC
        bus.send(can.Message(arbitration_id=0x181, is_extended_id=False, is_remote_frame=True, dlc=4))
        bus.send(can.Message(arbitration_id=0x181, is_extended_id=True, data=b"\0" * 4))   # 29-bit
        bus.send(can.Message(arbitration_id=0x123, is_extended_id=False, data=b"\0" * 4))  # unknown
        bus.send(can.Message(is_error_frame=True, arbitration_id=0x4, dlc=8, data=b"\0" * 8))
        bus.send(can.Message(arbitration_id=0x080, is_extended_id=False, data=b"\0\0"))   # SYNC DLC 2
        bus.send(can.Message(arbitration_id=CMD, is_extended_id=False, data=b"\x55"))     # bad command
        bus.send_raw(b"\0" * 10)                                                          # not a record
        bus.send_raw(b"")                                      # an empty record: not the end of the bus
        assert bus.recv_all(timeout=0.3) == []           # no cycle ran
        ans = bus.sync()
        st = status(ans)
        assert st.fresh_mask == 0b110 and st.age[0] == 1
        assert st.flags & FLAG_INPUT_INVALID
        assert st.ignored == 9
        inf = info(ans)   # the first cycle after the model load
        assert inf is not None and inf.ignored == 9 and inf.load_status == 0
        assert inf.model_crc == zlib.crc32(EXAMPLE.read_bytes()[:-4])
        assert bus.close() == 0
    summary = bus.wait_log("counters:")
    assert "bad DLC 2" in summary and "unknown id 2" in summary and "RTR 1" in summary
    assert "error frames 1" in summary and "bad command 1" in summary and "malformed 2" in summary


def test_log_names_the_cycle_of_each_event(setup: Path) -> None:
    """Log lines "cycle N: ..." carry the number of the cycle whose status frame
    has Seq N mod 256, also for frames sent in one burst (the daemon then reads
    many SYNCs at once) and from the very first SYNC on."""
    n = 30
    with ct.SocketpairBus(setup) as bus:
        for k in range(n):                 # one burst, no waiting for answers
            mask = 0b101 if 12 <= k < 20 else 0b111           # Y silent: stale from cycle 14
            send_positions(bus, [a.incr_of_mm(p) for a, p in zip(AXES, circle(k))], mask)
            if k == 24:
                bus.send(can.Message(arbitration_id=CMD, is_extended_id=False, data=bytes([ct.CMD_DISABLE])))
            bus.send(can.Message(arbitration_id=0x080, is_extended_id=False))
        statuses = [ct.decode_status(bytes(m.data)) for _ in range(n) for m in bus.recv_cycle().frames
                    if m.arbitration_id == STATUS]
        assert bus.close() == 0
    assert [s.seq for s in statuses] == list(range(n))
    log = "".join(bus.lines)
    events = {(int(m.group(1)), m.group(2)) for m in re.finditer(r"cycle (\d+): (.*)", log)}
    first_on = next(s.seq for s in statuses if s.state == 1)
    first_stale = next(s.seq for s in statuses if s.flags & FLAG_STALE)
    fresh_again = next(s.seq for s in statuses if s.seq > first_stale and not s.flags & FLAG_STALE)
    first_off = next(s.seq for s in statuses if s.seq > first_on and s.state == 0)
    assert (first_on, first_stale, fresh_again, first_off) == (0, 14, 20, 24)
    assert (first_on, "compensator OFF -> ON") in events
    assert (0, f"model 0x{zlib.crc32(EXAMPLE.read_bytes()[:-4]):08x} in use") in events
    assert any(c == first_stale and e.startswith("stale input") for c, e in events)
    assert (fresh_again, "positions fresh again: fading in") in events
    assert (first_off, "compensator ON -> OFF") in events


def _thermal_table():
    """The example table with thermal terms (expansion and offset per kelvin) on every axis."""
    t = read_blob(EXAMPLE.read_bytes())
    coef = {"X": (11.5, 0.8, 20.0), "Y": (10.0, -0.5, 20.0), "Z": (12.0, 1.5, 21.5)}
    axes = {a: dataclasses.replace(t.axes[a], thermal_expansion_ppm_per_k=c[0], thermal_offset_um_per_k=c[1],
                                   thermal_tref_c=c[2]) for a, c in coef.items()}
    return read_blob(write_blob(dataclasses.replace(t, axes=axes)))


def temperature_frame(cdegc: tuple[int, int, int], dlc: int = 6) -> can.Message:
    data = b"".join(int(v).to_bytes(2, "little", signed=True) for v in cdegc)
    return can.Message(arbitration_id=0x370, is_extended_id=False, data=data[:dlc])


NO_READING = -32768


def test_temperature_frame_feeds_the_thermal_term(tmp_path: Path) -> None:
    """Offsets along a circle with axis temperatures from the temperature frame
    match the float64 reference given the same temperatures; Z has no sensor
    (NO_READING) and keeps its temp_c; bad frames are counted and change
    nothing; TempStale until the first frame and after stale_cycles without."""
    table = _thermal_table()
    (tmp_path / "model.bin").write_bytes(write_blob(table))
    cfg = tmp_path / "can.toml"
    text = ct.config_text("model.bin", AXES, compensator="fade_cycles = 5\nstale_cycles = 3",
                          extra="[temperature]\nenable = true\nstale_cycles = 4",
                          axis_extra="rate_um_per_cycle = 1000\nwarn_um = 500\nlimit_um = 900")
    cfg.write_text(text.replace("[axis.Z]\n", "[axis.Z]\ntemp_c = 23.5\n"))
    n = 120
    rng = np.random.default_rng(3)
    walk = np.column_stack([2300 + np.cumsum(rng.integers(-40, 41, n)), 1800 + np.cumsum(rng.integers(-40, 41, n))])
    current = [20.0, 20.0, 23.5]                 # what the thermal term should use, degC
    incrs, got, used, stale = [], [], [], []
    with ct.SocketpairBus(cfg) as bus:
        for k in range(n):
            if k >= 2 and not 60 <= k < 70:       # none in the first 2 cycles, a gap of 10
                bus.send(temperature_frame((walk[k, 0], walk[k, 1], NO_READING)))
                current[:2] = walk[k] / 100.0
            if k == 30:
                bus.send(temperature_frame((2000, 15001, 2000)))    # 150.01 degC: the whole frame ignored
                bus.send(temperature_frame((2000, 2000, 2000), dlc=4))
            incr = [a.incr_of_mm(p) for a, p in zip(AXES, circle(k))]
            send_positions(bus, incr)
            ans = bus.sync()
            assert status(ans).ignored == (2 if k >= 30 else 0)
            stale.append(bytes(ans.by_id(STATUS)[0].data)[0] >> 7)
            incrs.append(incr)
            got.append(offsets(ans))
            used.append(list(current))
        assert bus.close() == 0
    assert stale == [1 if k < 2 or 63 <= k < 70 else 0 for k in range(n)]
    assert bus.wait_log("cycle 0: temperatures stale")
    assert "Z 23.50 degC" in bus.wait_log("cycle 2: temperatures current")
    assert "since the last reading X 4, Y 4, Z never" in bus.wait_log("cycle 63: temperatures stale")
    assert bus.wait_log("cycle 70: temperatures current")
    summary = bus.wait_log("counters:")
    assert "temperatures 108" in summary and "bad value 1" in summary and "bad DLC 1" in summary

    pos_mm = np.array([[a.nm_of_incr(int(v)) / 1e6 for a, v in zip(AXES, row)] for row in incrs])
    csign = np.array([a.correction_sign for a in AXES])

    def offsets_for(temp_c: np.ndarray) -> np.ndarray:
        corr_nm = -csign * spatial_error(table, pos_mm, None, temp_c) * 1e3
        return np.array([[a.incr_of_corr(c) for a, c in zip(AXES, row)] for row in corr_nm])

    want = offsets_for(np.array(used))[20:]
    got_a = np.array(got)[20:]
    bound_nm = error_bound(table).q_nm
    tol = np.array([math.floor(b * a.increments_per_mm / 1e6) + 1 for b, a in zip(bound_nm, AXES)])
    diff = np.abs(got_a - want)
    assert (diff <= tol).all(), f"max diff {diff.max(axis=0)} increments, allowed {tol}"
    at_20 = offsets_for(np.full((n, 3), 20.0))[20:]
    assert (np.abs(at_20 - want).max(axis=0) > 5 * tol).all()   # the temperatures matter on every axis


def test_stale_watchdog_fades_out(setup: Path) -> None:
    with ct.SocketpairBus(setup) as bus:
        for k in range(15):
            send_positions(bus, [a.incr_of_mm(p) for a, p in zip(AXES, circle(k))])
            ans = bus.sync()
        assert any(o != 0 for o in offsets(ans))
        flags = []
        for k in range(15, 30):
            send_positions(bus, [a.incr_of_mm(p) for a, p in zip(AXES, circle(k))], mask=0b101)
            ans = bus.sync()
            st = status(ans)
            flags.append(bool(st.flags & FLAG_STALE))
            assert st.age[1] == k - 14
        assert flags[:2] == [False, False] and all(flags[2:])
        assert offsets(ans) == [0, 0, 0]
        bus.wait_log("stale input")
        for k in range(30, 45):
            send_positions(bus, [a.incr_of_mm(p) for a, p in zip(AXES, circle(k))])
            ans = bus.sync()
        assert not status(ans).flags & FLAG_STALE
        assert any(o != 0 for o in offsets(ans))
        bus.wait_log("positions fresh again")
        assert bus.close() == 0


def _variant(src: bytes, shift_nm: int) -> bytes:
    """The example table with its reference X shifted, CRC recomputed."""
    b = bytearray(src)
    ref = int.from_bytes(b[24:28], "little", signed=True) + shift_nm
    b[24:28] = ref.to_bytes(4, "little", signed=True)
    b[-4:] = zlib.crc32(bytes(b[:-4])).to_bytes(4, "little")
    return bytes(b)


def test_model_swap_on_sighup_and_command(setup: Path) -> None:
    model = setup.parent / "model.bin"
    original = model.read_bytes()
    crc0 = zlib.crc32(original[:-4])
    pos = [a.incr_of_mm(p) for a, p in zip(AXES, circle(3))]
    with ct.SocketpairBus(setup) as bus:
        for _ in range(10):
            send_positions(bus, pos)
            before = offsets(bus.sync())

        good = _variant(original, 40_000_000)
        model.write_bytes(good)
        bus.signal(signal.SIGHUP)
        bus.wait_log("loaded: CRC-32")
        send_positions(bus, pos)
        ans = bus.sync()
        st, inf = status(ans), info(ans)
        assert st.flags & FLAG_MODEL_SWAPPED and not st.load_failed
        assert inf is not None and inf.model_crc == zlib.crc32(good[:-4]) and inf.model_swaps == 2
        for _ in range(10):
            send_positions(bus, pos)
            after = offsets(bus.sync())
        assert after != before                     # the new model is in use

        bad = bytearray(original)
        bad[400] ^= 0x10                           # damaged: the CRC no longer matches
        model.write_bytes(bytes(bad))
        bus.signal(signal.SIGHUP)
        line = bus.wait_log("refused")
        assert "ABBE_E_CRC" in line and f"running model 0x{zlib.crc32(good[:-4]):08x} kept" in line
        send_positions(bus, pos)
        ans = bus.sync()
        st, inf = status(ans), info(ans)
        assert st.load_failed and not st.flags & FLAG_MODEL_SWAPPED
        assert inf is not None and inf.load_status == -7 and inf.model_crc == zlib.crc32(good[:-4])
        assert offsets(ans) == after               # still the good model

        model.write_bytes(b"ABBE")                 # truncated
        bus.send(can.Message(arbitration_id=CMD, is_extended_id=False, data=bytes([ct.CMD_RELOAD])))
        line = bus.wait_log("refused")
        assert "ABBE_E_TRUNCATED" in line

        model.write_bytes(original)                # the RELOAD command takes the good one
        bus.send(can.Message(arbitration_id=CMD, is_extended_id=False, data=bytes([ct.CMD_RELOAD])))
        send_positions(bus, pos)
        ans = bus.sync()                           # loaded before this SYNC is handled
        inf = info(ans)
        assert inf is not None and inf.model_crc == crc0 and inf.load_status == 0
        assert status(ans).flags & FLAG_MODEL_SWAPPED
        assert bus.close() == 0


def test_commands_disable_enable(setup: Path) -> None:
    pos = [a.incr_of_mm(p) for a, p in zip(AXES, circle(7))]
    with ct.SocketpairBus(setup) as bus:
        for _ in range(10):
            send_positions(bus, pos)
            on = offsets(bus.sync())
        bus.send(can.Message(arbitration_id=CMD, is_extended_id=False, data=bytes([ct.CMD_DISABLE])))
        for _ in range(10):
            send_positions(bus, pos)
            ans = bus.sync()
        assert offsets(ans) == [0, 0, 0] and status(ans).state == 0
        bus.send(can.Message(arbitration_id=CMD, is_extended_id=False, data=bytes([ct.CMD_ENABLE])))
        for _ in range(10):
            send_positions(bus, pos)
            ans = bus.sync()
        assert offsets(ans) == on and status(ans).state == 1
        assert bus.close() == 0


@pytest.mark.parametrize("line, text, field", [
    ("sign = -1", "sign = 3", "axis.Y.sign"),
    ('path = "model.bin"', 'path = 5', "model.path"),
    ("node_id = 2", "node_id = 0x70", "axis.Y.tpdo_cob_id"),  # = the compensator's: TPDO1 is its status
])
def test_config_errors_name_file_line_field(setup: Path, line: str, text: str, field: str) -> None:
    lines = setup.read_text().splitlines()
    # the occurrence in [axis.Y] for axis keys, else the first
    start = lines.index("[axis.Y]") if field.startswith("axis.Y") else 0
    idx = next(i for i in range(start, len(lines)) if lines[i] == line)
    lines[idx] = text
    setup.write_text("\n".join(lines) + "\n")
    r = subprocess.run([str(DAEMON), "-c", str(setup), "--check"], capture_output=True, text=True)
    assert r.returncode == 2
    if field == "axis.Y.tpdo_cob_id":   # derived from node_id: reported at the section header
        idx = start
    assert r.stderr.startswith(f"{setup}:{idx + 1}: field '{field}': "), r.stderr


def test_bad_model_at_start_exits_2(setup: Path) -> None:
    (setup.parent / "model.bin").write_bytes(b"not a table")
    r = subprocess.run([str(DAEMON), "-c", str(setup), "--check"], capture_output=True, text=True)
    assert r.returncode == 2 and "refused" in r.stderr and "ABBE_E_" in r.stderr


def test_socketcan_unavailable_is_clear(setup: Path) -> None:
    try:
        socket.socket(socket.PF_CAN, socket.SOCK_RAW, socket.CAN_RAW).close()
    except OSError:
        r = subprocess.run([str(DAEMON), "-c", str(setup)], capture_output=True, text=True, timeout=10)
        assert r.returncode == 1 and "no SocketCAN" in r.stderr
        return
    pytest.skip("this kernel has SocketCAN: test_can_socket (CTest) covers the real socket")


def _session_frames(k_cycles: int) -> list[tuple[float, can.Message]]:
    """A recorded session: positions, SYNCs, a few bad frames, timestamps 1 ms apart."""
    t = 1_700_000_000.0
    out: list[tuple[float, can.Message]] = []
    for k in range(k_cycles):
        incr = [a.incr_of_mm(p) for a, p in zip(AXES, circle(k))]
        for j in range(3):
            if not (k in (40, 41, 42, 43) and j == 1):       # Y drops out: stale
                out.append((t + k * 1e-3 + j * 1e-5, ct.tpdo(j + 1, incr[j])))
        if k == 10:
            out.append((t + k * 1e-3 + 4e-5, can.Message(arbitration_id=0x555, is_extended_id=False, data=b"\1")))
            out.append((t + k * 1e-3 + 5e-5, can.Message(arbitration_id=0x182, is_extended_id=False,
                                                          is_remote_frame=True)))
        out.append((t + k * 1e-3 + 9e-5, can.Message(arbitration_id=0x080, is_extended_id=False)))
    for ts, m in out:
        m.timestamp = ts
        m.channel = "can0"
    return out


def test_replay_round_trip(setup: Path, tmp_path: Path) -> None:
    session = _session_frames(80)
    log_in = tmp_path / "session.log"
    with can.CanutilsLogWriter(str(log_in), channel="can0") as w:   # python-can writes candump -l
        for _, m in session:
            w.on_message_received(m)
    # the live run of the same frames
    live: list[can.Message] = []
    with ct.SocketpairBus(setup) as bus:
        for _, m in session:
            bus.send(m)
            if m.arbitration_id == 0x080:
                live += bus.recv_cycle().frames
        assert bus.close() == 0
    out = tmp_path / "sent.log"
    r = subprocess.run([str(DAEMON), "-c", str(setup), "--replay", str(log_in), "-o", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "counters: cycles 80," in r.stderr
    replayed = list(can.CanutilsLogReader(str(out)))                  # and reads it back
    assert [(m.arbitration_id, bytes(m.data)) for m in replayed] == \
        [(m.arbitration_id, bytes(m.data)) for m in live]
    syncs = [m.timestamp for m in can.CanutilsLogReader(str(log_in)) if m.arbitration_id == 0x080]
    assert sorted({m.timestamp for m in replayed}) == syncs           # stamped with their SYNC
    assert all(m.channel == "can0" for m in replayed)
    stale = [ct.decode_status(bytes(m.data)).flags & FLAG_STALE for m in replayed if m.arbitration_id == STATUS]
    assert any(stale)
    # the same replay to stdout is byte-identical (reproducible output)
    r2 = subprocess.run([str(DAEMON), "-c", str(setup), "--replay", str(log_in)], capture_output=True, text=True)
    assert r2.returncode == 0 and r2.stdout == out.read_text()


def test_replay_bad_line_names_it(setup: Path, tmp_path: Path) -> None:
    log_in = tmp_path / "bad.log"
    log_in.write_text("(1700000000.000000) can0 181#00000000\n(1700000000.001000) can0 18#00\n")
    out = tmp_path / "out.log"
    r = subprocess.run([str(DAEMON), "-c", str(setup), "--replay", str(log_in), "-o", str(out)],
                       capture_output=True, text=True)
    assert r.returncode == 2 and f"{log_in}:2: not a candump -l line" in r.stderr
    assert not out.exists()                                           # no partial output


def test_docs_example_config_is_valid(tmp_path: Path) -> None:
    """The complete example in docs/can.md parses with tomllib and with abbe-cand --check."""
    text = (REPO / "docs" / "can.md").read_text()
    block = next(b for b in re.findall(r"```toml\n(.*?)```", text, re.S) if "[axis.Z]" in b)
    data = tomllib.loads(block)
    assert data["axis"]["X"]["increments_per_mm"] == 10000
    cfg = tmp_path / "can.toml"
    cfg.write_text(block.replace('"/etc/abbe/model.bin"', f'"{EXAMPLE}"'))
    r = subprocess.run([str(DAEMON), "-c", str(cfg), "--check"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "status on 0x1F0" in r.stdout and "TPDO 0x181" in r.stdout and "RPDO 0x203" in r.stdout
