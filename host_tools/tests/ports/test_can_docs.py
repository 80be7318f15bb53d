"""abbe-cand against docs/can.md and docs/abbe.dbc, by a peer written from the docs alone.

The peer packs struct can_frame records itself (docs: 16 bytes, native byte
order), starts the daemon with --fd/--ready-fd as documented, encodes and
decodes every frame with docs/abbe.dbc (cantools), and takes configurations
from docs/can.md (its complete example, read with tomllib). Nothing here uses
the port's code or abbe.ports.can_tools. Each check is a sentence of the
docs: the frame map, the cycle and its latency, the scaling, every kind of
ignored frame and record, every bit of the status frame, the info frame,
commands, model reloads, the temperature frame, the log's cycle numbers, exit
statuses, and that tomllib and the daemon read the same numbers.

Needs the daemon ($ABBE_CAND, or build/bin/abbe-cand) and cantools.
"""

from __future__ import annotations

import os
import random
import re
import select
import signal
import socket
import struct
import subprocess
import tomllib
import zlib
from pathlib import Path

import pytest

cantools = pytest.importorskip("cantools")

REPO = Path(__file__).resolve().parents[3]
DOCS = REPO / "docs" / "can.md"
DBC = REPO / "docs" / "abbe.dbc"
PAPER = REPO / "examples" / "paper_table" / "model.bin"
DAEMON = Path(os.environ.get("ABBE_CAND", REPO / "build" / "bin" / "abbe-cand"))
if not DAEMON.is_file():
    pytest.skip(f"abbe-cand not built: {DAEMON} missing", allow_module_level=True)

DB = cantools.database.load_file(str(DBC))
MSG = {m.name: m for m in DB.messages}
ID = {m.name: m.frame_id for m in DB.messages}
RECORD = struct.Struct("=IB3x8s")          # struct can_frame: can_id, len, pad, res, len8_dlc, data[8]
EFF, RTR, ERR = 0x80000000, 0x40000000, 0x20000000
NO_READING = -32768


def docs_config() -> str:
    """The complete example configuration of docs/can.md."""
    text = DOCS.read_text()
    return next(b for b in re.findall(r"```toml\n(.*?)```", text, re.S) if "[axis.Z]" in b)


def config(tmp: Path, model: bytes = b"", **changes: str) -> Path:
    """The docs' example with its model in tmp and lines changed: changes["section.key"] = "value"
    (a key not in the example is added to its section)."""
    (tmp / "model.bin").write_bytes(model or PAPER.read_bytes())
    lines = docs_config().replace('"/etc/abbe/model.bin"', '"model.bin"').splitlines()
    section = ""
    done = set()
    out = []
    for line in lines:
        m = re.match(r"^\[(.+)\]$", line)
        if m:
            for k, v in changes.items():          # keys to add at the end of the previous section
                sec, key = k.rsplit(".", 1)
                if sec == section and k not in done:
                    out.append(f"{key} = {v}")
                    done.add(k)
            section = m.group(1)
        m = re.match(r"^#?\s*(\w+) = ", line)
        k = f"{section}.{m.group(1)}" if m else None
        if k in changes:
            out.append(f"{m.group(1)} = {changes[k]}")
            done.add(k)
        else:
            out.append(line)
    for k, v in changes.items():
        sec, key = k.rsplit(".", 1)
        if sec == section and k not in done:
            out.append(f"{key} = {v}")
            done.add(k)
    assert done == set(changes), set(changes) - done
    path = tmp / "can.toml"
    path.write_text("\n".join(out) + "\n")
    tomllib.loads(path.read_text())               # still TOML
    return path


class Bus:
    """abbe-cand on one end of socketpair(AF_UNIX, SOCK_SEQPACKET) (docs: --fd), this peer on the other."""

    def __init__(self, cfg: Path, tmp: Path) -> None:
        self.peer, child = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        r, w = os.pipe()
        self.log_path = tmp / "cand.log"
        self.log = open(self.log_path, "w")
        self.proc = subprocess.Popen([str(DAEMON), "-c", str(cfg), "--fd", str(child.fileno()), "--ready-fd", str(w)],
                                     pass_fds=(child.fileno(), w), stderr=self.log, stdout=subprocess.DEVNULL)
        child.close()
        os.close(w)
        ready, _, _ = select.select([r], [], [], 30)
        got = os.read(r, 16) if ready else b""
        os.close(r)
        assert got == b"ready\n", self.text()

    def text(self) -> str:
        if not self.log.closed:
            self.log.flush()
        return self.log_path.read_text()

    def send(self, can_id: int, data: bytes = b"", dlc: int | None = None) -> None:
        self.peer.send(RECORD.pack(can_id, len(data) if dlc is None else dlc, data.ljust(8, b"\0")[:8]))

    def send_msg(self, name: str, **values) -> None:
        self.send(ID[name], MSG[name].encode(values))

    def sync(self) -> dict[str, list]:
        """SYNC, then every frame up to the status frame (the last of the cycle): name -> [(dlc, decoded, raw)]."""
        self.send(ID["SYNC"])
        out: dict[str, list] = {}
        while True:
            r, _, _ = select.select([self.peer], [], [], 10)
            assert r, "no status frame"
            rec = self.peer.recv(64)
            assert len(rec) == RECORD.size
            can_id, dlc, data = RECORD.unpack(rec)
            msg = DB.get_message_by_frame_id(can_id)
            assert msg.length == dlc, msg.name
            out.setdefault(msg.name, []).append((dlc, msg.decode(data[:dlc], decode_choices=False), data[:dlc]))
            if msg.name == "ABBE_STATUS":
                return out

    def status(self, ans: dict) -> dict:
        (frame,) = ans["ABBE_STATUS"]
        return frame[1]

    def close(self) -> int:
        self.peer.close()
        rc = self.proc.wait(timeout=30)
        self.log.close()
        return rc


def tpdos(bus: Bus, x: int, y: int, z: int) -> None:
    for ax, v in zip("XYZ", (x, y, z)):
        bus.send_msg(f"DRIVE_{ax}_TPDO", **{f"PositionActualValue_{ax}": v})


def offsets(ans: dict) -> tuple[int, int, int]:
    return tuple(ans[f"DRIVE_{ax}_RPDO"][0][1][f"PositionOffset_{ax}"] for ax in "XYZ")


POS = (2_500_000, -1_000_000, -500_000)   # increments: 250, -100, -50 mm at 10000 increments/mm
# fade in one cycle, no rate limit: an output follows its target at once
FAST = {"compensator.fade_cycles": "1", **{f"axis.{a}.rate_um_per_cycle": "1000" for a in "XYZ"}}


# --------------------------------------------------------------------------- frame map, cycle

def test_frame_map_of_the_docs_table(tmp_path):
    """--check of the docs' example prints the frame map of the docs' table and of the DBC."""
    cfg = config(tmp_path)
    r = subprocess.run([str(DAEMON), "-c", str(cfg), "--check"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    table = DOCS.read_text().split("## Frame map", 1)[1].split("`docs/abbe.dbc`", 1)[0]
    ids = {int(m.group(1), 16) for m in re.finditer(r"^\| (0x[0-9A-F]{3})(?:\.\.0x[0-9A-F]{3})? \|", table, re.M)}
    ids |= {int(m.group(1), 16) for m in re.finditer(r"\.\.(0x[0-9A-F]{3}) \|", table)}
    assert ids == {0x080, 0x181, 0x183, 0x201, 0x203, 0x1F0, 0x2F0, 0x270, 0x370, 0x3F0, 0x3F4}
    for want in ("SYNC 0x080", "status on 0x1F0", "info every 100 cycles 0x2F0", "command on 0x270",
                 "temperature off 0x370", "thermal off 0x3F0..0x3F4", "TPDO 0x181 dlc 4", "RPDO 0x203 dlc 4"):
        assert want in r.stdout
    assert set(ID.values()) == {0x080, 0x181, 0x182, 0x183, 0x201, 0x202, 0x203, 0x1F0, 0x2F0, 0x270, 0x370,
                                0x3F0, 0x3F1, 0x3F2, 0x3F3, 0x3F4}


def test_cycle_latency_scaling_and_signs(tmp_path):
    """Offsets come at each SYNC from the positions since the previous one; an axis with
    sign = -1 and its origin gets the same correction, negated in increments (docs: Scaling)."""
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    cfg_a = config(tmp_path / "a", **FAST)
    cfg_b = config(tmp_path / "b", **FAST, **{"axis.Y.sign": "-1", "axis.Y.origin_mm": "-50.0"})
    got = {}
    for name, cfg in (("a", cfg_a), ("b", cfg_b)):
        bus = Bus(cfg, cfg.parent)
        y = POS[1] if name == "a" else -(POS[1] + 500_000)       # the same machine position: -100 mm
        first = offsets(bus.sync())                             # no position yet
        tpdos(bus, POS[0], y, POS[2])
        ans = bus.sync()
        st = bus.status(ans)
        assert (st["FreshX"], st["FreshY"], st["FreshZ"]) == (1, 1, 1)
        got[name] = [offsets(bus.sync()) for _ in range(3)][-1]  # positions held: not fresh, same offsets
        assert bus.close() == 0
        assert first == (0, 0, 0)
    assert got["a"][0] == got["b"][0] and got["a"][2] == got["b"][2]
    assert got["b"][1] == -got["a"][1] and got["a"][1] != 0


# --------------------------------------------------------------------------- ignored frames

def test_every_ignored_kind_is_counted_once(tmp_path):
    """Each kind the docs list ("Ignored frames") adds exactly one to IgnoredFrames and to the
    info frame's IgnoredTotal; the daemon goes on; a position in a bad frame is not fresh."""
    cfg = config(tmp_path, **{"status.info_period_cycles": "1", "temperature.enable": "true"})
    bus = Bus(cfg, tmp_path)
    kinds = [
        ("TPDO with DLC 3", lambda: bus.send(ID["DRIVE_X_TPDO"], b"\1\2\3")),
        ("TPDO with DLC 5", lambda: bus.send(ID["DRIVE_X_TPDO"], b"\1\2\3\4\5")),
        ("SYNC with 2 bytes", lambda: bus.send(ID["SYNC"], b"\0\0")),
        ("command of 0 bytes", lambda: bus.send(ID["ABBE_COMMAND"], b"")),
        ("command of 2 bytes", lambda: bus.send(ID["ABBE_COMMAND"], b"\1\0")),
        ("temperature frame of 5 bytes", lambda: bus.send(ID["ABBE_TEMPERATURE"], b"\0" * 5)),
        ("unknown id", lambda: bus.send(0x555, b"\0")),
        ("29-bit id", lambda: bus.send(ID["DRIVE_X_TPDO"] | EFF, b"\0" * 4)),
        ("remote request", lambda: bus.send(ID["DRIVE_X_TPDO"] | RTR, b"", dlc=4)),
        ("error frame", lambda: bus.send(ERR | 0x4, b"\0" * 8)),
        ("unknown command", lambda: bus.send(ID["ABBE_COMMAND"], b"\x09")),
        ("temperature out of range", lambda: bus.send(ID["ABBE_TEMPERATURE"], struct.pack("<hhh", 2000, 15001, 2000))),
        ("temperature 0x7FFF", lambda: bus.send(ID["ABBE_TEMPERATURE"], struct.pack("<hhh", 0x7FFF, 2000, 2000))),
        ("record of 10 bytes", lambda: bus.peer.send(b"\0" * 10)),
        ("record of 72 bytes (CAN FD size)", lambda: bus.peer.send(b"\0" * 72)),
        ("empty record", lambda: bus.peer.send(b"")),
    ]
    tpdos(bus, *POS)
    before = bus.status(bus.sync())["IgnoredFrames"]
    assert before == 0
    for k, (what, send) in enumerate(kinds, 1):
        send()
        ans = bus.sync()
        st = bus.status(ans)
        assert st["IgnoredFrames"] == k, what
        assert ans["ABBE_INFO"][0][1]["IgnoredTotal"] == k, what
        assert st["FreshX"] == 0, what                          # the bad TPDOs did not count
    assert bus.close() == 0
    counters = bus.text().rsplit("counters:", 1)[1]
    for part in ("bad DLC 6", "unknown id 2", "RTR 1", "error frames 1", "bad command 1", "bad value 2",
                 "malformed 3"):
        assert part in counters, (part, counters)


# --------------------------------------------------------------------------- status and info frames

def test_status_frame_every_bit(tmp_path):
    """Every bit of ABBE_STATUS is one DBC signal; reserved flag bits and TempStale (frame off)
    stay 0; Seq counts cycles from 0 and wraps; ages count per axis and saturate at 255."""
    owner = {}
    for sig in MSG["ABBE_STATUS"].signals:
        for bit in range(sig.start, sig.start + sig.length):
            assert bit not in owner
            owner[bit] = sig.name
    assert sorted(owner) == list(range(64))
    reserved = [s.name for s in MSG["ABBE_STATUS"].signals if "Reserved" in s.name]
    assert len(reserved) == 5
    cfg = config(tmp_path, **{"compensator.stale_cycles": "3", "compensator.fade_cycles": "2"})
    bus = Bus(cfg, tmp_path)
    for k in range(300):
        if k < 2 or k >= 290:
            tpdos(bus, *POS)
        else:
            bus.send_msg("DRIVE_X_TPDO", PositionActualValue_X=POS[0])    # Y and Z silent
        st = bus.status(bus.sync())
        assert st["Seq"] == k % 256
        assert all(st[r] == 0 for r in reserved) and st["TempStale"] == 0
        assert st["ModelLoaded"] == 1 and st["LoadFailed"] == 0
        if 2 <= k < 290:
            assert st["AgeY"] == min(k - 1, 255) and st["AgeX"] == 0 and st["FreshX"] == 1 and st["FreshY"] == 0
            assert st["FlagInputInvalid"] == 1 and st["FlagStale"] == (1 if k >= 4 else 0)
        if k >= 290:
            assert st["AgeY"] == 0 and st["FlagStale"] == 0
    assert bus.close() == 0


def test_info_frame_commands_and_reloads(tmp_path):
    """Info every info_period_cycles and after each load attempt (CRC = the file's last 4 bytes,
    LoadStatus, ModelSwaps); ENABLE/DISABLE/RESET/RELOAD; SIGHUP reloads; a bad file is refused
    and the running model goes on."""
    paper = PAPER.read_bytes()
    crc = struct.unpack("<I", paper[-4:])[0]
    cfg = config(tmp_path, **FAST, **{"status.info_period_cycles": "5"})
    bus = Bus(cfg, tmp_path)
    infos = []
    for k in range(12):
        tpdos(bus, *POS)
        ans = bus.sync()
        if "ABBE_INFO" in ans:
            infos.append(k)
            info = ans["ABBE_INFO"][0][1]
            assert info["ModelCrc"] == crc and info["LoadStatus"] == 0 and info["ModelSwaps"] == 1
    assert infos == [0, 4, 9]                              # after the start-up load, then every 5th
    on = offsets(ans)
    assert any(on)
    bus.send_msg("ABBE_COMMAND", Command=2)                 # DISABLE
    ans = bus.sync()
    assert bus.status(ans)["State"] == 0 and offsets(ans) == (0, 0, 0)
    bus.send_msg("ABBE_COMMAND", Command=1)                 # ENABLE
    tpdos(bus, *POS)
    ans = bus.sync()
    assert bus.status(ans)["State"] == 1 and offsets(ans) == on
    # RELOAD of a changed file: the next SYNC runs it
    other = bytearray(paper)
    struct.pack_into("<i", other, 24, struct.unpack_from("<i", other, 24)[0] + 20_000_000)   # reference X + 20 mm
    total = struct.unpack_from("<I", other, 8)[0]
    struct.pack_into("<I", other, total - 4, zlib.crc32(bytes(other[:total - 4])))
    (tmp_path / "model.bin").write_bytes(bytes(other))
    bus.send_msg("ABBE_COMMAND", Command=4)
    tpdos(bus, *POS)
    ans = bus.sync()                                         # "handled before any SYNC queued behind it"
    info = ans["ABBE_INFO"][0][1]
    assert info["ModelCrc"] == struct.unpack("<I", other[-4:])[0] and info["ModelSwaps"] == 2
    assert bus.status(ans)["FlagModelSwapped"] == 1
    # SIGHUP with a damaged file: refused (-7), the running model goes on
    bad = bytearray(other)
    bad[300] ^= 0x55
    (tmp_path / "model.bin").write_bytes(bytes(bad))
    bus.proc.send_signal(signal.SIGHUP)
    for _ in range(500):
        if "refused" in bus.text():
            break
        select.select([], [], [], 0.01)
    tpdos(bus, *POS)
    ans = bus.sync()
    info = ans["ABBE_INFO"][0][1]
    assert info["LoadStatus"] == -7 and info["ModelCrc"] == struct.unpack("<I", other[-4:])[0]
    assert MSG["ABBE_INFO"].get_signal_by_name("LoadStatus").choices[-7] == "ABBE_E_CRC"
    assert bus.status(ans)["LoadFailed"] == 1
    # RESET: clears a latched fault and disables
    bus.send_msg("ABBE_COMMAND", Command=3)
    assert bus.status(bus.sync())["State"] == 0
    assert bus.close() == 0
    assert "refused: table CRC-32 mismatch (ABBE_E_CRC); running model 0x%08x kept" % info["ModelCrc"] in bus.text()


def test_limit_fault_and_reset(tmp_path):
    cfg = config(tmp_path, **FAST, **{"axis.X.warn_um": "0.5", "axis.X.limit_um": "1.0"})
    bus = Bus(cfg, tmp_path)
    tpdos(bus, *POS)
    st = bus.status(bus.sync())
    assert st["State"] == 2 and st["FlagLimit"] == 1 and st["FlagWarn"] == 1       # FAULT, latched
    bus.send_msg("ABBE_COMMAND", Command=1)
    tpdos(bus, *POS)
    assert bus.status(bus.sync())["State"] == 2
    assert bus.close() == 0
    assert "correction over the error limit" in bus.text()


# --------------------------------------------------------------------------- temperatures

def _thermal_paper() -> tuple[bytes, int]:
    """docs/table-format.md: THERMAL = features bit 3; X record (at 64): expansion 2^-50/mK at +36,
    offset 2^-16 nm/mK at +40, reference m°C at +44; CRC-32 of [0, total - 4) at the end."""
    b = bytearray(PAPER.read_bytes())
    struct.pack_into("<I", b, 20, struct.unpack_from("<I", b, 20)[0] | 8)
    struct.pack_into("<iii", b, 64 + 36, 13_510_799, 65_536, 20_000)   # 12 ppm/K, 1 um/K, 20 degC
    total = struct.unpack_from("<I", b, 8)[0]
    struct.pack_into("<I", b, total - 4, zlib.crc32(bytes(b[:total - 4])))
    return bytes(b), struct.unpack_from("<i", b, 24)[0]


def test_temperature_frame(tmp_path):
    """The temperature frame feeds the thermal term (alpha dT (x - ref) + o dT), NO_READING keeps an
    axis' temperature (temp_c until its first reading), out-of-range frames are ignored, and
    TempStale says when readings stop."""
    blob, ref_x_nm = _thermal_paper()
    cfg = config(tmp_path, blob, **FAST, **{"temperature.enable": "true", "temperature.stale_cycles": "3",
                                            "axis.X.warn_um": "500", "axis.X.limit_um": "900"})
    bus = Bus(cfg, tmp_path)
    x_nm = POS[0] * 100                                       # 10000 increments/mm: 100 nm each

    def cycle(temps=None):
        if temps is not None:
            bus.send_msg("ABBE_TEMPERATURE", **{f"Temperature{a}": t for a, t in zip("XYZ", temps)})
        tpdos(bus, *POS)
        ans = bus.sync()
        return offsets(ans)[0], bus.status(ans)["TempStale"]

    off20, stale = cycle()
    assert stale == 1                                         # none yet: temp_c (20 degC)
    off20b, stale = cycle((20.0, "NO_READING", "NO_READING"))
    assert stale == 0 and off20b == off20
    off30, _ = cycle((30.0, "NO_READING", "NO_READING"))
    want_nm = 12e-6 * 10 * (x_nm - ref_x_nm) + 1000 * 10
    assert abs(abs(off30 - off20) - want_nm / 100) <= 2, (off30 - off20, want_nm / 100)
    bus.send(ID["ABBE_TEMPERATURE"], struct.pack("<hhh", 2000, 2000, 15001))    # ignored as a whole
    assert cycle()[0] == off30
    assert cycle(("NO_READING", 25.0, "NO_READING"))[0] == off30                 # X kept 30 degC
    assert cycle((30.0, 25.0, "NO_READING"))[1] == 0
    stales = [cycle()[1] for _ in range(5)]
    assert stales == [0, 0, 1, 1, 1]                          # stale_cycles = 3 without a frame
    assert bus.close() == 0
    log = bus.text()
    assert "temperatures stale" in log and "temperatures current: X 20.00, Y 20.00, Z 20.00 degC" in log


# --------------------------------------------------------------------------- log, exit statuses

def test_log_cycle_numbers_are_the_status_seq(tmp_path):
    """"cycle N" in the log is the cycle whose status frame has Seq = N mod 256, from the first SYNC,
    also when the frames come in one burst."""
    cfg = config(tmp_path, **{"compensator.stale_cycles": "2"})
    bus = Bus(cfg, tmp_path)
    n = 20
    for k in range(n):
        if not 6 <= k < 12:
            tpdos(bus, *POS)
        bus.send(ID["SYNC"])
    seqs, stale = [], []
    while len(seqs) < n:
        r, _, _ = select.select([bus.peer], [], [], 10)
        assert r
        can_id, dlc, data = RECORD.unpack(bus.peer.recv(64))
        if can_id == ID["ABBE_STATUS"]:
            st = MSG["ABBE_STATUS"].decode(data[:dlc], decode_choices=False)
            seqs.append(st["Seq"])
            stale.append(st["FlagStale"])
    assert bus.close() == 0
    assert seqs == list(range(n))
    log = bus.text()
    first_stale = stale.index(1)
    assert re.search(rf"cycle {first_stale}: stale input", log), log
    assert re.search(r"cycle 0: compensator OFF -> ON", log) and re.search(r"cycle 0: model 0x[0-9a-f]{8} in use", log)
    assert re.search(rf"cycle {stale.index(0, first_stale)}: positions fresh again", log)


def test_exit_statuses_and_config_errors(tmp_path):
    cfg = config(tmp_path)
    text = cfg.read_text().splitlines()
    i = next(k for k, line in enumerate(text) if line.startswith("sign = "))
    text[i] = "sign = 2"
    cfg.write_text("\n".join(text) + "\n")
    r = subprocess.run([str(DAEMON), "-c", str(cfg), "--check"], capture_output=True, text=True)
    assert r.returncode == 2 and r.stderr.startswith(f"{cfg}:{i + 1}: field 'axis.X.sign': ")
    cfg = config(tmp_path, b"ABBE")                            # a model that does not load: exit 2
    r = subprocess.run([str(DAEMON), "-c", str(cfg), "--check"], capture_output=True, text=True)
    assert r.returncode == 2 and "refused" in r.stderr
    r = subprocess.run([str(DAEMON), "--bogus"], capture_output=True, text=True)
    assert r.returncode == 2
    cfg = config(tmp_path)
    bus = Bus(cfg, tmp_path)
    assert bus.close() == 0                                    # the peer closed the fd: exit 0


# --------------------------------------------------------------------------- numbers: tomllib and the daemon

def _spellings(rng: random.Random) -> list[str]:
    """Number spellings, TOML-valid or not, around the forms docs/can.md names."""
    digits = lambda n: "".join(rng.choice("0123456789") for _ in range(n))  # noqa: E731
    out = ["10000", "1_0000", "1e4", "1E4", "1.0e4", "+10000", "10000.0", "0x2710", "0x27_10", "010000",
           "1__0000", "_10000", "10000_", ".5e5", "5.", "5.e4", "1e", "1e+4", "1e-4", "0.0001e8", "-0",
           "0x", "0X2710", "-0x10", "1_000.000_1", "1.5_", "inf", "nan", "+inf", "1e400", "9" * 25,
           "0.5", "00.5", "1_e4", "1e_4", "0x1p4", "1,5", "1 0", "١٠", "２"]
    for _ in range(150):
        int_part = rng.choice(["0", digits(1), digits(3), f"{digits(1)}_{digits(2)}", "0" + digits(2)])
        s = rng.choice(["", "+", "-"]) + int_part
        if rng.random() < 0.5:
            s += "." + rng.choice([digits(2), f"{digits(1)}_{digits(1)}", ""])
        if rng.random() < 0.4:
            s += rng.choice("eE") + rng.choice(["", "+", "-"]) + rng.choice([digits(1), digits(2), ""])
        out.append(s)
    return out


def test_numbers_read_as_tomllib_reads_them(tmp_path):
    """docs/can.md: the file is TOML that tomllib reads too. For each spelling of
    increments_per_mm and node_id, the daemon accepts exactly what tomllib accepts as a number
    in the documented range, and reads the same value."""
    rng = random.Random(15)
    base = config(tmp_path).read_text()
    collide: set[int] = set()   # the example sets axis X's COB-IDs itself: any node id fits
    for s in _spellings(rng):
        for key in ("increments_per_mm", "node_id"):
            line = re.search(rf"^{key} = .*$", base.split("[axis.X]", 1)[1], re.M).group(0)
            text = base.replace(line, f"{key} = {s}", 1)
            try:
                value = tomllib.loads(text)["axis"]["X"][key]
                toml_ok = isinstance(value, (int, float)) and not isinstance(value, bool)
            except tomllib.TOMLDecodeError:
                toml_ok, value = False, None
            cfg = tmp_path / "n.toml"
            cfg.write_text(text)
            r = subprocess.run([str(DAEMON), "-c", str(cfg), "--check"], capture_output=True, text=True)
            if key == "node_id":
                in_range = toml_ok and isinstance(value, int) and 1 <= value <= 127 and value not in collide
            else:
                in_range = toml_ok and 0 < value <= 1e9
            if r.returncode == 0:
                assert in_range, (key, s, value)
                got = re.search(r"^axis X node (\d+): .* ([0-9.e+-]+) increments/mm", r.stdout, re.M)
                assert got, r.stdout
                if key == "node_id":
                    assert int(got.group(1)) == value, (s, got.group(1))
                else:
                    assert got.group(2) == f"{value:.6g}", (s, got.group(2), value)
            else:
                assert r.returncode == 2, (s, r.stderr)
                assert not in_range, (key, s, value, r.stderr)
                if not (key == "node_id" and value in collide):
                    assert f"field 'axis.X.{key}': " in r.stderr, (s, r.stderr)
