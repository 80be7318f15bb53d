"""docs/abbe.dbc describes every frame abbe-cand reads and sends (checked with cantools).

* the DBC's frame map equals the daemon's own (``abbe-cand --check``) for the
  default configuration (drives 1, 2, 3; compensator node 0x70);
* frames encoded from the DBC drive the daemon, and every frame it sends
  decodes with the DBC to the values the C code put there (offsets, state,
  flags, sequence, ages, counters, model CRC), cross-checked with
  abbe.ports.can_tools' own decoder.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import zlib
from pathlib import Path

import can
import pytest

cantools = pytest.importorskip("cantools")

from abbe.ports import can_tools as ct  # noqa: E402

DAEMON = ct.daemon_path()
if not DAEMON.is_file():
    pytest.skip(f"abbe-cand not built: {DAEMON} missing (cmake -DABBE_BUILD_PORTS=ON, or set ABBE_CAND)",
                allow_module_level=True)

REPO = Path(__file__).resolve().parents[3]
DBC = REPO / "docs" / "abbe.dbc"
EXAMPLE = REPO / "examples" / "paper_table" / "model.bin"
AXES = [ct.AxisScaling(10000.0), ct.AxisScaling(10000.0), ct.AxisScaling(10000.0)]
FLAG_SIGNALS = {0x0001: "FlagOutOfTravel", 0x0002: "FlagSaturated", 0x0010: "FlagWarn", 0x0020: "FlagLimit",
                0x0040: "FlagRateLimited", 0x0080: "FlagStale", 0x0100: "FlagFading",
                0x0200: "FlagInputInvalid", 0x0400: "FlagModelSwapped", 0x0800: "FlagNoModel",
                0x1000: "FlagAxisFault", 0x0004: "FlagReserved2", 0x0008: "FlagReserved3",
                0x2000: "FlagReserved13", 0x4000: "FlagReserved14", 0x8000: "FlagReserved15"}


@pytest.fixture(scope="module")
def db():
    return cantools.database.load_file(str(DBC))   # strict: overlapping signals would fail here


@pytest.fixture()
def config(tmp_path: Path) -> Path:
    shutil.copy(EXAMPLE, tmp_path / "model.bin")
    cfg = tmp_path / "can.toml"
    cfg.write_text(ct.config_text("model.bin", AXES, compensator="fade_cycles = 5\nstale_cycles = 3"))
    return cfg


def test_frame_map_matches_the_daemon(db, config: Path) -> None:
    r = subprocess.run([str(DAEMON), "-c", str(config), "--check"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    out = r.stdout
    ids = {"SYNC": int(re.search(r"^SYNC 0x([0-9A-F]+)", out, re.M).group(1), 16),
           "ABBE_STATUS": int(re.search(r"^status on 0x([0-9A-F]+)", out, re.M).group(1), 16),
           "ABBE_INFO": int(re.search(r"^info every \d+ cycles 0x([0-9A-F]+)", out, re.M).group(1), 16),
           "ABBE_COMMAND": int(re.search(r"^command on 0x([0-9A-F]+)", out, re.M).group(1), 16),
           "ABBE_TEMPERATURE": int(re.search(r"^temperature (?:on|off) 0x([0-9A-F]+)", out, re.M).group(1), 16)}
    th = int(re.search(r"^thermal (?:on|off) 0x([0-9A-F]+)\.\.", out, re.M).group(1), 16)
    ids.update({f"ABBE_THERMAL_{g}": th + g for g in range(5)})
    for m in re.finditer(r"^axis (\w) node \d+: TPDO 0x([0-9A-F]+) dlc (\d) .*-> RPDO 0x([0-9A-F]+) dlc (\d)",
                         out, re.M):
        ax = m.group(1)
        ids[f"DRIVE_{ax}_TPDO"] = int(m.group(2), 16)
        ids[f"DRIVE_{ax}_RPDO"] = int(m.group(4), 16)
        assert db.get_message_by_name(f"DRIVE_{ax}_TPDO").length == int(m.group(3))
        assert db.get_message_by_name(f"DRIVE_{ax}_RPDO").length == int(m.group(5))
    assert {msg.name: msg.frame_id for msg in db.messages} == ids
    assert db.get_message_by_name("SYNC").length == 0
    assert db.get_message_by_name("ABBE_STATUS").length == 8
    assert db.get_message_by_name("ABBE_INFO").length == 8
    assert db.get_message_by_name("ABBE_TEMPERATURE").length == 6
    for g in range(5):
        assert db.get_message_by_name(f"ABBE_THERMAL_{g}").length == 8


def _flag_defines() -> dict[str, int]:
    out = {}
    for h in ("error.h", "comp.h"):
        text = (REPO / "lib" / "include" / "abbe" / h).read_text()
        out.update({m.group(1): int(m.group(2), 16)
                    for m in re.finditer(r"#define ABBE_FLAG_(\w+) (0x[0-9A-Fa-f]+)u", text)})
    return out


def test_every_status_bit_is_named(db) -> None:
    """Each of the status frame's 64 bits belongs to exactly one DBC signal; every
    ABBE_FLAG_* of the library has its signal and its row in docs/can.md and
    docs/modbus-registers.md, and the other flag bits are named reserved."""
    msg = db.get_message_by_name("ABBE_STATUS")
    owner: dict[int, str] = {}
    for sig in msg.signals:
        assert sig.byte_order == "little_endian"
        for b in range(sig.start, sig.start + sig.length):
            assert b not in owner, f"bit {b}: {sig.name} and {owner[b]}"
            owner[b] = sig.name
    assert sorted(owner) == list(range(64))
    flags = _flag_defines()
    assert len(flags) >= 11 and all(v < 0x10000 for v in flags.values())
    can_md = (REPO / "docs" / "can.md").read_text()
    mb_md = (REPO / "docs" / "modbus-registers.md").read_text()
    for bit in range(16):
        value = 1 << bit
        name = next((n for n, v in flags.items() if v == value), None)
        sig = owner[8 + bit]
        if name is None:
            assert sig == f"FlagReserved{bit}"
            assert f"| {bit} | 0x{value:04X} | reserved |" in can_md
            assert f"| 0x{value:04X} | reserved |" in mb_md
        else:
            assert sig == FLAG_SIGNALS[value] and sig.lower() == "flag" + name.replace("_", "").lower()
            assert f"| {bit} | 0x{value:04X} | {name} |" in can_md
            assert f"| 0x{value:04X} | {name} |" in mb_md


def _c_enum(header: str, prefix: str) -> dict[str, int]:
    text = (REPO / header).read_text()
    return {m.group(1): int(m.group(2)) for m in re.finditer(rf"\b({prefix}\w+) = (-?\d+)", text)}


def test_load_status_names_every_status(db) -> None:
    """Every status a load can end with has its name in the DBC's LoadStatus value table."""
    choices = {int(k): str(v) for k, v in db.get_message_by_name("ABBE_INFO")
               .get_signal_by_name("LoadStatus").choices.items()}
    core = _c_enum("lib/include/abbe/status.h", "ABBE_E_")
    assert len(core) >= 18
    for name, code in core.items():
        assert choices.get(code) == name, f"{name} ({code}) missing from LoadStatus"
    port = _c_enum("port/socketcan/include/abbe_can.h", "ABBE_CAN_E_")
    for name in ("ABBE_CAN_E_IO", "ABBE_CAN_E_BUSY", "ABBE_CAN_E_TOO_BIG"):
        assert choices.get(port[name]) == name


def _encode(db, name: str, values: dict) -> can.Message:
    msg = db.get_message_by_name(name)
    return can.Message(arbitration_id=msg.frame_id, is_extended_id=False, data=msg.encode(values))


def test_daemon_frames_decode_with_the_dbc(db, config: Path) -> None:
    crc = zlib.crc32(EXAMPLE.read_bytes()[:-4])
    seen: set[str] = set()
    with ct.SocketpairBus(config) as bus:
        for k in range(40):
            pos_mm = (250.0 + k, -200.0 + 0.5 * k, -150.0)
            mask = 0b101 if 25 <= k < 30 else 0b111          # Y silent for 5 cycles
            for j, ax in enumerate("XYZ"):
                if mask >> j & 1:
                    bus.send(_encode(db, f"DRIVE_{ax}_TPDO", {f"PositionActualValue_{ax}": AXES[j].incr_of_mm(pos_mm[j])}))
            if k == 32:
                bus.send(_encode(db, "ABBE_COMMAND", {"Command": "DISABLE"}))
            if k == 10:
                bus.send(can.Message(arbitration_id=0x7EE, is_extended_id=False, data=b"\0"))  # unknown id
            ans = bus.sync()
            for m in ans.frames:
                dm = db.get_message_by_frame_id(m.arbitration_id)
                assert dm.length == m.dlc
                dec = dm.decode(bytes(m.data))
                seen.add(dm.name)
                if dm.name.endswith("_RPDO"):
                    ax = dm.name[6]
                    assert dec[f"PositionOffset_{ax}"] == int.from_bytes(m.data[:4], "little", signed=True)
                elif dm.name == "ABBE_STATUS":
                    st = ct.decode_status(bytes(m.data))
                    assert dec["Seq"] == k % 256 == st.seq
                    assert str(dec["State"]) == ("ON" if k < 32 else "OFF")   # DISABLE before SYNC 32
                    assert int(dec["State"].value if hasattr(dec["State"], "value") else dec["State"]) == st.state
                    assert dec["ModelLoaded"] == 1 and dec["LoadFailed"] == 0
                    assert (dec["FreshX"], dec["FreshY"], dec["FreshZ"]) == (1, int(mask >> 1 & 1), 1)
                    assert (dec["AgeX"], dec["AgeY"], dec["AgeZ"]) == st.age
                    assert dec["AgeY"] == (k - 24 if 25 <= k < 30 else 0)
                    flags = sum(bit for bit, name in FLAG_SIGNALS.items() if dec[name])
                    assert flags == st.flags
                    assert dec["FlagStale"] == (1 if 27 <= k < 30 else 0)
                    assert dec["IgnoredFrames"] == (1 if k >= 10 else 0)
                elif dm.name == "ABBE_INFO":
                    assert dec["ModelCrc"] == crc
                    assert str(dec["LoadStatus"]) == "OK"
                    assert dec["ModelSwaps"] == 1
                else:
                    pytest.fail(f"unexpected frame {dm.name}")
        assert bus.close() == 0
    assert seen == {"DRIVE_X_RPDO", "DRIVE_Y_RPDO", "DRIVE_Z_RPDO", "ABBE_STATUS", "ABBE_INFO"}


def test_temperature_frame_from_the_dbc(db, tmp_path: Path) -> None:
    """Temperature frames encoded from the DBC (NO_READING by its name) are taken;
    the status frame's TempStale, decoded with the DBC, says until when none came."""
    shutil.copy(EXAMPLE, tmp_path / "model.bin")
    cfg = tmp_path / "can.toml"
    cfg.write_text(ct.config_text("model.bin", AXES, extra="[temperature]\nenable = true\nstale_cycles = 3"))
    stale = []
    with ct.SocketpairBus(cfg) as bus:
        for k in range(12):
            if 2 <= k < 6:
                bus.send(_encode(db, "ABBE_TEMPERATURE", {"TemperatureX": 21.25, "TemperatureY": "NO_READING",
                                                          "TemperatureZ": -12.5}))
            for j, ax in enumerate("XYZ"):
                bus.send(_encode(db, f"DRIVE_{ax}_TPDO", {f"PositionActualValue_{ax}": AXES[j].incr_of_mm(100.0)}))
            frames = bus.sync().by_id(db.get_message_by_name("ABBE_STATUS").frame_id)
            stale.append(db.decode_message("ABBE_STATUS", bytes(frames[0].data))["TempStale"])
        assert bus.close() == 0
    assert stale == [1, 1, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1]   # the last frame at cycle 5: stale from 5 + 3
    assert "X 21.25, Y 20.00, Z -12.50 degC" in bus.wait_log("cycle 2: temperatures current")
