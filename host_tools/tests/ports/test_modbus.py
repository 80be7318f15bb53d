"""abbe-modbusd end to end with pymodbus as an independent client, plus the host
tools (abbe upload / abbe modbus-status) and the register-map mirror.

The server binary comes from $ABBE_MODBUSD or a CMake build with
-DABBE_BUILD_PORTS=ON under <repo>/build*/; without one the end-to-end tests
skip. The server starts with port 0 and a ready pipe and is stopped by pid;
its exit status must be 0.
"""

from __future__ import annotations

import os
import re
import select
import shutil
import signal
import subprocess
import time
import zlib
from pathlib import Path

import numpy as np
import pytest

from abbe import cli
from abbe.errors import AbbeInputError
from abbe.formats.golden import golden_tables
from abbe.ports.modbus_client import (COUNT, EX_BUSY, REG, ModbusError, ModbusLink, UploadRefused,
                                parse_endpoint)
from abbe.model.reference import spatial_error
from abbe.formats.blob import blob_crc, read_blob

REPO = Path(__file__).resolve().parents[3]
HEADER = REPO / "port" / "modbus" / "include" / "abbe" / "modbus_regs.h"
PAPER = REPO / "examples" / "paper_table" / "model.bin"


def _find_server() -> Path | None:
    env = os.environ.get("ABBE_MODBUSD")
    if env:
        return Path(env)
    found = sorted(REPO.glob("build*/port/modbus/abbe-modbusd"), key=lambda p: p.stat().st_mtime)
    return found[-1] if found else None


SERVER = _find_server()
needs_server = pytest.mark.skipif(SERVER is None or not SERVER.exists(),
                                  reason="abbe-modbusd not built (cmake -DABBE_BUILD_PORTS=ON) "
                                         "and $ABBE_MODBUSD not set")


class Server:
    """abbe-modbusd started with a ready pipe, stopped by pid."""

    def __init__(self, *args: str, log: Path | None = None) -> None:
        r, w = os.pipe()
        self.log = open(log, "w") if log is not None else None
        self.proc = subprocess.Popen([str(SERVER), *args, "--ready-fd", str(w)], pass_fds=(w,),
                                     stderr=self.log)
        os.close(w)
        with os.fdopen(r) as f:
            ready, _, _ = select.select([f], [], [], 30)
            line = f.readline() if ready else ""
        m = re.match(r"ready (tcp (\d+)|rtu)", line)
        if not m:
            self.stop()
            raise RuntimeError(f"abbe-modbusd did not get ready: {line!r}")
        self.port = int(m.group(2)) if m.group(2) else None

    def stop(self) -> int:
        self.proc.send_signal(signal.SIGTERM)
        rc = self.proc.wait(timeout=30)
        if self.log is not None:
            self.log.close()
        return rc


@pytest.fixture
def server():
    srv = Server("--tcp", "127.0.0.1:0", "--max-clients", "4")
    yield srv
    assert srv.stop() == 0


def _link(srv: Server) -> ModbusLink:
    return ModbusLink(parse_endpoint(f"tcp://127.0.0.1:{srv.port}")).connect()


def _full_blob() -> bytes:
    return next(g.blob for g in golden_tables() if g.name == "full")


# --------------------------------------------------------------------------- no server

def test_register_map_mirrors_c_header():
    text = HEADER.read_text()
    c_regs = {m.group(1): int(m.group(2), 16)
              for m in re.finditer(r"#define ABBE_MB_REG_(\w+) (0x[0-9A-Fa-f]+)u", text)}
    c_counts = {m.group(1): int(m.group(2), 16)
                for m in re.finditer(r"#define ABBE_MB_(\w+)_COUNT (0x[0-9A-Fa-f]+)u", text)}
    assert c_regs == REG
    assert c_counts == COUNT
    results = {int(m.group(2)): m.group(1)
               for m in re.finditer(r"#define ABBE_MB_UP_(\w+) \(?(-?\d+)\)?\s", text)}
    from abbe.ports.modbus_client import UP_RESULT_NAMES
    assert results == UP_RESULT_NAMES


def test_flag_names_show_unknown_bits():
    from abbe.ports.modbus_client import flag_names
    assert flag_names(0x0081) == ["OUT_OF_TRAVEL", "STALE"]
    assert flag_names(0x2010) == ["WARN", "0x2000"]   # a reserved bit is shown, not dropped


@pytest.mark.parametrize("text, want", [
    ("tcp://plc.local:1502", ("tcp", "plc.local", 1502)),
    ("tcp://10.0.0.2", ("tcp", "10.0.0.2", 502)),
    ("rtu:/dev/ttyUSB0:115200", ("rtu", "/dev/ttyUSB0", 115200)),
])
def test_parse_endpoint(text, want):
    ep = parse_endpoint(text)
    assert (ep.kind, ep.host or ep.device, ep.port if ep.kind == "tcp" else ep.baud) == want


def test_parse_endpoint_framing():
    ep = parse_endpoint("rtu:/dev/ttyS1:9600:E72")
    assert (ep.parity, ep.bytesize, ep.stopbits) == ("E", 7, 2)


@pytest.mark.parametrize("text", ["udp://x:1", "tcp://", "tcp://h:0", "rtu:/dev/x", "rtu:/dev/x:96k"])
def test_parse_endpoint_rejects(text):
    with pytest.raises(AbbeInputError) as ei:
        parse_endpoint(text)
    assert ei.value.field == "modbus"


def test_upload_bad_file_names_file_and_field(tmp_path, capsys):
    bad = tmp_path / "short.bin"
    bad.write_bytes(PAPER.read_bytes()[:1000])
    rc = cli.main(["upload", "--modbus", "tcp://127.0.0.1:1", str(bad)])
    err = capsys.readouterr().err
    assert rc == 2
    assert f"{bad}" in err and "field 'total_size'" in err and "ABBE_E_TRUNCATED" in err


def test_upload_unreachable_server(capsys):
    rc = cli.main(["upload", "--modbus", "tcp://127.0.0.1:1", "-q", str(PAPER)])
    assert rc == 1
    assert "cannot connect" in capsys.readouterr().err


# --------------------------------------------------------------------------- end to end (TCP)

@needs_server
def test_cli_upload_and_status(server, capsys):
    url = f"tcp://127.0.0.1:{server.port}"
    assert cli.main(["upload", "--modbus", url, str(PAPER)]) == 0
    out, err = capsys.readouterr()
    crc = f"0x{blob_crc(PAPER.read_bytes()):08X}"
    assert f"table CRC-32 {crc} = file {crc}" in out and "queued" in out
    assert "(100%)" in err
    assert cli.main(["modbus-status", "--modbus", url]) == 0
    out = capsys.readouterr().out
    assert f"queued {crc}" in out and "1 ok, 0 rejected" in out and "last result OK" in out


@needs_server
@pytest.mark.parametrize("name", ["paper", "full"])
def test_stream_matches_python_reference(server, name):
    """Corrections and spatial error from the server against abbe.model.reference
    (float64) on the quantized table: within 3 nm (2 nm bound + rounding)."""
    g = next(g for g in golden_tables() if g.name == name)
    table = read_blob(g.blob)
    rng = np.random.default_rng(7)
    lo = np.array([table.axes[a].travel_mm[0] for a in "XYZ"])
    hi = np.array([table.axes[a].travel_mm[1] for a in "XYZ"])
    n = 150
    pos_nm = np.round((lo + (hi - lo) * rng.random((n, 3))) * 1e6).astype(np.int64)
    temp_cdeg = rng.integers(1800, 2600, size=(n, 3))
    with _link(server) as link:
        link.set_limits(warn_nm=10**9, limit_nm=2 * 10**9, rate_nm_per_cycle=2 * 10**9,
                        fade_cycles=1, stale_cycles=5)
        res = link.upload(g.blob)
        assert res.model_crc == blob_crc(g.blob)
        link.enable()
        got_err = np.zeros((n, 3))
        for k in range(n):
            out = link.cycle(tuple(int(v) for v in pos_nm[k]), k,
                             temp_cdegc=tuple(int(t) for t in temp_cdeg[k]))
            assert out.cycle == k and out.state == "ON"
            got_err[k] = out.err_nm
            assert out.corr_nm == tuple(-e for e in out.err_nm)  # sign +1, fade 1, no clipping
        assert link.read32(REG["ID_MODEL_CRC"]) == res.model_crc
    want_nm = spatial_error(table, pos_nm / 1e6, None, temp_cdeg / 100.0) * 1e3
    assert np.max(np.abs(got_err - want_nm)) <= 3.0
    assert np.max(np.abs(want_nm)) > 1000.0  # the comparison is not of zeros


@needs_server
def test_bad_uploads_leave_running_model(server):
    paper = PAPER.read_bytes()
    full = _full_blob()
    with _link(server) as a, _link(server) as b:
        a.upload(paper)
        a.write(REG["IN_CYCLE"], [1])  # cycle boundary: paper runs
        running = a.read32(REG["ID_MODEL_CRC"])
        assert running == blob_crc(paper)

        def untouched(result: str) -> None:
            st = a.status()
            assert not st.upload_open
            from abbe.ports.modbus_client import result_name
            assert result_name(st.upload_result) == result
            a.write(REG["IN_CYCLE"], [2])
            assert a.read32(REG["ID_MODEL_CRC"]) == running
            assert a.read32(REG["ID_PENDING_CRC"]) == 0

        # damaged in transit: the server's CRC of the received bytes differs
        a.write(REG["UP_CMD"], [1])
        data = bytearray(full)
        data[100] ^= 0xFF
        for off in range(0, len(data), 246):
            part = bytes(data[off:off + 246])
            a.write(REG["STAGING"] + off // 2,
                    [int.from_bytes(part[i:i + 2], "big") for i in range(0, len(part), 2)])
        with pytest.raises(ModbusError) as ei:
            a.write(REG["UP_COMMIT"], a.pack32(len(full)) + a.pack32(zlib.crc32(full)))
        assert ei.value.exception_code == 3
        untouched("CRC_MISMATCH")

        # intact transfer of a broken table: the library's status
        bad = bytearray(full)
        bad[4000] ^= 1
        with pytest.raises(UploadRefused) as er:
            a.upload(bytes(bad))
        assert er.value.result == -7
        untouched("ABBE_E_CRC")

        # a second client interleaving: busy, and the first upload goes through
        a.write(REG["UP_CMD"], [1])
        with pytest.raises(ModbusError) as eb:
            b.upload(paper)
        assert eb.value.exception_code == EX_BUSY
        with pytest.raises(ModbusError) as eb:
            b.write(REG["STAGING"], [0x4142, 0x4245])
        assert eb.value.exception_code == EX_BUSY
        a.write(REG["UP_CMD"], [2])  # abort
        untouched("ABORTED")

    # a client disconnecting mid-upload
    with _link(server) as c:
        c.write(REG["UP_CMD"], [1])
        c.write(REG["STAGING"], [0x4142, 0x4245])
    with _link(server) as d:
        for _ in range(2000):  # until the server has seen the close
            if not d.status().upload_open:
                break
        st = d.status()
        assert not st.upload_open and st.upload_result == -104
        assert d.read32(REG["ID_MODEL_CRC"]) == running
        assert st.counters["uploads_rejected"] == 5


@needs_server
def test_exception_codes_pymodbus(server):
    with _link(server) as link:
        cl = link._client
        assert cl.read_coils(0, count=1).exception_code == 1
        assert cl.read_holding_registers(0x0014, count=1).exception_code == 2
        assert cl.read_holding_registers(0x0FFF, count=2).exception_code == 2
        assert cl.write_register(0x0000, 1).exception_code == 2
        assert cl.write_register(REG["CT_ENABLE"], 2).exception_code == 3
        assert cl.write_register(REG["IN_POS_X"], 1).exception_code == 2  # half of an int32
        assert cl.write_registers(REG["STAGING"], [1, 2]).exception_code == 1  # no session
        assert not cl.read_input_registers(REG["ID_SELFTEST"], count=2).isError()
        assert link.status().counters["exceptions"] == 7


@needs_server
def test_temperature_registers(server):
    """IN_TEMP_*: 0x8000 keeps an axis' temperature, out of -50..150 degC is
    exception 03 and the request (cycle trigger included) changes nothing; the
    thermal term follows the written temperatures (full table, vs abbe.model.reference)."""
    g = next(g for g in golden_tables() if g.name == "full")
    table = read_blob(g.blob)
    pos = (400_000_000, -600_000_000, -250_000_000)
    with _link(server) as link:
        link.set_limits(warn_nm=10**9, limit_nm=2 * 10**9, rate_nm_per_cycle=2 * 10**9,
                        fade_cycles=1, stale_cycles=5)
        link.upload(g.blob)
        link.enable()
        out = link.cycle(pos, 1, temp_cdegc=(3000, 1500, 2500))
        assert link.read(REG["IN_TEMP_X"], 3) == [3000, 1500, 2500]
        kept = link.cycle(pos, 2, temp_cdegc=(0x8000, 1600, 0x8000))
        assert link.read(REG["IN_TEMP_X"], 3) == [3000, 1600, 2500]
        for bad in (-5001, 15001, 0x7FFF):
            with pytest.raises(ModbusError) as ei:
                link.cycle(pos, 3, temp_cdegc=(2000, bad, 2000))
            assert ei.value.exception_code == 3
        assert link.read(REG["IN_TEMP_X"], 3) == [3000, 1600, 2500]
        assert link.read(REG["OUT_CYCLE"], 1) == [2]
    for o, temps in ((out, (30.0, 15.0, 25.0)), (kept, (30.0, 16.0, 25.0))):
        want = spatial_error(table, np.array([pos]) / 1e6, None, np.array([temps]))[0] * 1e3
        assert np.max(np.abs(np.array(o.err_nm) - want)) <= 3.0
    at_20 = spatial_error(table, np.array([pos]) / 1e6, None, np.full((1, 3), 20.0))[0] * 1e3
    assert np.max(np.abs(np.array(out.err_nm) - at_20)) > 1000.0   # the temperatures matter


@needs_server
def test_verbose_log_names_connections_and_sessions(tmp_path):
    """-v logs each connection (opened, refused, closed with the reason) and each
    upload session with its own number and result, also when one BEGIN ends the
    previous session and when a refused BEGIN leaves the open one alone."""
    log = tmp_path / "server.log"
    srv = Server("--tcp", "127.0.0.1:0", "--max-clients", "2", "-v", log=log)
    try:
        paper = PAPER.read_bytes()
        with _link(srv) as a, _link(srv) as b:
            a.upload(paper)                                    # session 1: OK
            a.write(REG["IN_CYCLE"], [9])
            a.write(REG["UP_CMD"], [1])                        # session 2
            with pytest.raises(ModbusError):
                b.write(REG["UP_CMD"], [1])                    # busy
            a.write(REG["UP_CMD"], [1])                        # 2 aborted, 3 begun
            with pytest.raises(ModbusError):
                ModbusLink(parse_endpoint(f"tcp://127.0.0.1:{srv.port}"), timeout_s=1).connect()
        # a and b closed with session 3 open; the server notices the closes when it
        # next polls them, so a new client may be refused (2 of 2 open) for a moment
        c = None
        for _ in range(100):
            try:
                c = _link(srv).connect()
                break
            except ModbusError:
                time.sleep(0.05)
        assert c is not None, "no connection accepted after a and b closed"
        with c:
            for _ in range(2000):
                if not c.status().upload_open:
                    break
    finally:
        assert srv.stop() == 0
    text = log.read_text()
    crc = f"0x{blob_crc(paper):08X}"
    want = [r"connection 1 from 127\.0\.0\.1:\d+ opened \(1 of 2 open\)",
            r"connection 2 from 127\.0\.0\.1:\d+ opened \(2 of 2 open\)",
            r"upload session 1 begun by connection 1",
            rf"upload session 1 \(connection 1\) ended: OK, table CRC-32 {crc}, {len(paper)} bytes",
            rf"table CRC-32 {crc} \({len(paper)} bytes\) in use from the cycle with IN_CYCLE 9",
            r"upload session 2 begun by connection 1",
            r"upload BEGIN from connection 2 refused: session 2 of connection 1 is open \(busy\)",
            r"upload session 2 \(connection 1\) ended: ABORTED \(-103\)",
            r"upload session 3 begun by connection 1",
            r"connection from 127\.0\.0\.1:\d+ refused: all connections in use \(2 of 2 open\)"]
    pos = 0
    for pattern in want:
        m = re.compile(r"^abbe-modbusd: (?:" + pattern + ")", re.M).search(text, pos)
        assert m, f"no line {pattern!r} after offset {pos} in:\n{text}"
        pos = m.end()
    # After the refusal the server sees the closes of a and b and the new client c
    # in the order it polls them; each pair is ordered, the pairs are not.
    for first, then in (
            (r"connection 1 from 127\.0\.0\.1:\d+ closed: closed by the client",
             r"upload session 3 \(connection 1\) ended: DISCONNECTED \(-104\)"),
            (r"connection 2 from 127\.0\.0\.1:\d+ closed: closed by the client", None),
            (r"connection 3 from 127\.0\.0\.1:\d+ opened",
             r"connection 3 from 127\.0\.0\.1:\d+ closed: (?:server stopping|closed by the client)")):
        m = re.compile(r"^abbe-modbusd: (?:" + first + ")", re.M).search(text, pos)
        assert m, f"no line {first!r} after offset {pos} in:\n{text}"
        if then is not None:
            assert re.compile(r"^abbe-modbusd: (?:" + then + ")", re.M).search(text, m.end()), \
                f"no line {then!r} after {first!r} in:\n{text}"
    assert text.count("ended:") == 3


# --------------------------------------------------------------------------- RTU over socat ptys

@needs_server
@pytest.mark.skipif(shutil.which("socat") is None, reason="socat not installed")
def test_rtu_over_pty_pair(tmp_path):
    pytest.importorskip("serial", reason="pyserial not installed (pymodbus RTU needs it)")
    a, b = tmp_path / "ttyA", tmp_path / "ttyB"
    socat = subprocess.Popen(["socat", "-d", "-d", f"pty,raw,echo=0,link={a}",
                              f"pty,raw,echo=0,link={b}"], stderr=subprocess.PIPE, text=True)
    try:
        for _ in range(50):  # ready signal: socat reports the transfer loop
            ready, _, _ = select.select([socat.stderr], [], [], 10)
            line = socat.stderr.readline() if ready else ""
            if not line or "starting data transfer loop" in line:
                break
        assert a.exists() and b.exists()
        srv = Server("--rtu", f"{a}:115200:N81", "--unit", "3")
        try:
            # (no parity on a pty: pyserial cannot set it twice there)
            link = ModbusLink(parse_endpoint(f"rtu:{b}:115200:N81", unit=3), timeout_s=5)
            with link:
                assert link.identity().max_clients == 1
                link.set_limits(warn_nm=10**8, limit_nm=2 * 10**8, rate_nm_per_cycle=10**8,
                                fade_cycles=1, stale_cycles=5)
                res = link.upload(PAPER.read_bytes())
                assert res.model_crc == blob_crc(PAPER.read_bytes())
                link.enable()
                table = read_blob(PAPER.read_bytes())
                pos = [(100_000_000 + 3_000_000 * k, -50_000_000 - 2_000_000 * k,
                        -20_000_000 - 1_000_000 * k) for k in range(40)]
                errs = [link.cycle(p, k).err_nm for k, p in enumerate(pos)]
                want = spatial_error(table, np.array(pos) / 1e6, None,
                                     np.full((40, 3), 20.0)) * 1e3
                assert np.max(np.abs(np.array(errs) - want)) <= 3.0
                assert link.read32(REG["ID_MODEL_CRC"]) == res.model_crc
        finally:
            assert srv.stop() == 0
    finally:
        socat.terminate()
        socat.wait(timeout=10)
