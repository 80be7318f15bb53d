"""abbe-modbusd against docs/modbus-registers.md, by a client written from the docs alone.

The register map is read from the document's tables (addresses, types,
names, blocks), not from the port's header or abbe.ports.modbus_client;
requests go over a raw Modbus/TCP socket written here (MBAP + PDU), so
malformed requests can be sent too, and pymodbus checks that a standard
client gets the same answers. Every documented register, value range,
exception code, upload result (UP_RESULT), compensator state and flag is
exercised; what no request can reach is said where it is skipped.

Needs the server: $ABBE_MODBUSD, or a CMake build with -DABBE_BUILD_PORTS=ON
under <repo>/build*/ (skipped otherwise).
"""

from __future__ import annotations

import os
import re
import select
import signal
import socket
import struct
import subprocess
import time
import zlib
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]
DOC = REPO / "docs" / "modbus-registers.md"
PAPER = REPO / "examples" / "paper_table" / "model.bin"
MISMATCH = REPO / "fuzz" / "regressions" / "f32-coef-1e37-inconsistent-with-int32.bin"


# --------------------------------------------------------------------------- the document

@dataclass(frozen=True)
class Reg:
    """One documented value: address, registers it takes, signedness, name, section."""

    addr: int
    width: int          # registers: 1 (16-bit), 2 (32-bit), or the array length for "N x u16"
    signed: bool
    is32: bool
    name: str
    section: str


_ROW = re.compile(r"^\| (0x[0-9A-Fa-f]{4}) \| (?:(\d+) x )?([ui])(16|32) \| ([A-Z0-9_/]+) \|(.*)\|\s*$")


def _names(text: str) -> list[str]:
    """"IN_DIR_X/Y/Z" -> IN_DIR_X, IN_DIR_Y, IN_DIR_Z; "ID_FMT_MAJOR/MINOR" -> ID_FMT_MAJOR, ID_FMT_MINOR."""
    parts = text.split("/")
    first = parts[0]
    out = [first]
    for p in parts[1:]:
        out.append(first[:len(first) - len(first.split("_")[-1])] + p)
    return out


def parse_doc() -> list[Reg]:
    regs: list[Reg] = []
    section = ""
    for line in DOC.read_text().splitlines():
        if line.startswith("## "):
            section = line[3:].strip()
            continue
        m = _ROW.match(line)
        if not m:
            continue
        addr, count, sign, bits, names = int(m.group(1), 16), int(m.group(2) or 1), m.group(3), int(m.group(4)), m.group(5)
        names_l = _names(names)
        w = 2 if bits == 32 else 1
        if len(names_l) == count:            # "3 x i32 CT_WARN_X/Y/Z": one value each
            for k, n in enumerate(names_l):
                regs.append(Reg(addr + k * w, w, sign == "i", bits == 32, n, section))
        else:                                # "2 x u16 ID_MAGIC", "8192 x u16 STAGING": one array
            assert len(names_l) == 1, line
            regs.append(Reg(addr, count * w, sign == "i", bits == 32, names_l[0], section))
    return regs


REGS = parse_doc()
R = {r.name: r for r in REGS}
RO_SECTIONS = ("Identity (read only)", "Status and counters (read only)", "Outputs of the last cycle (read only)")


def blocks() -> dict[str, tuple[int, int]]:
    """Section -> (first address, register count), staging apart."""
    out: dict[str, tuple[int, int]] = {}
    for r in REGS:
        if r.name == "STAGING":
            continue
        lo, n = out.get(r.section, (r.addr, 0))
        lo2 = min(lo, r.addr)
        hi = max(lo + n, r.addr + r.width)
        out[r.section] = (lo2, hi - lo2)
    return out


def flag_bits() -> dict[int, str]:
    table = DOC.read_text().split("Flags (`ST_FLAGS`", 1)[1]
    return {int(m.group(1), 16): m.group(2) for m in re.finditer(r"^\| (0x[0-9A-F]{4}) \| ([A-Z_a-z]+) \|", table, re.M)}


def up_result_rows() -> list[tuple[int, int, str]]:
    """(low, high, name) of each row of the UP_RESULT table (low == high for one value)."""
    table = DOC.read_text().split("`UP_RESULT` values:", 1)[1].split("One session at a time", 1)[0]
    rows = []
    for m in re.finditer(r"^\| (-?\d+)(?: \.\. (-?\d+))? \| ([A-Z_*]+) \|", table, re.M):
        a, b = int(m.group(1)), int(m.group(2) or m.group(1))
        rows.append((min(a, b), max(a, b), m.group(3)))
    return rows


def up_results() -> dict[int, str]:
    return {v: name for lo, hi, name in up_result_rows() for v in {lo, hi}}


def documented_result(value: int) -> str | None:
    return next((name for lo, hi, name in up_result_rows() if lo <= value <= hi), None)


# --------------------------------------------------------------------------- no server

def test_doc_blocks_are_contiguous_and_apart():
    """Each section is one run of registers without gaps; blocks do not touch."""
    for section, (lo, n) in blocks().items():
        covered = set()
        for r in REGS:
            if r.section == section and r.name != "STAGING":
                span = set(range(r.addr, r.addr + r.width))
                assert not covered & span, f"{r.name} overlaps"
                covered |= span
        assert covered == set(range(lo, lo + n)), f"gap in {section}"
        assert n <= 125 or section.startswith("Table"), section
    spans = sorted(blocks().values())
    for (a, n), (b, _) in zip(spans, spans[1:]):
        assert a + n < b, "two blocks touch: a read across them would be legal"
    for r in REGS:
        if r.is32 and r.width == 2:
            assert r.addr % 2 == 0, f"{r.name}: a 32-bit value at an odd address"


def test_doc_flags_name_all_16_bits():
    bits = flag_bits()
    assert sorted(bits) == [1 << k for k in range(16)]


# --------------------------------------------------------------------------- the server

def _find_server() -> Path | None:
    env = os.environ.get("ABBE_MODBUSD")
    if env:
        return Path(env)
    found = sorted(REPO.glob("build*/port/modbus/abbe-modbusd"), key=lambda p: p.stat().st_mtime)
    return found[-1] if found else None


SERVER = _find_server()
needs_server = pytest.mark.skipif(SERVER is None or not SERVER.exists(),
                                  reason="abbe-modbusd not built (cmake -DABBE_BUILD_PORTS=ON), $ABBE_MODBUSD not set")


class Server:
    """abbe-modbusd on 127.0.0.1, port chosen by the system (--ready-fd, port 0), stopped by pid."""

    def __init__(self, *args: str) -> None:
        r, w = os.pipe()
        self.proc = subprocess.Popen([str(SERVER), "--tcp", "127.0.0.1:0", *args, "--ready-fd", str(w)],
                                     pass_fds=(w,), stderr=subprocess.DEVNULL)
        os.close(w)
        with os.fdopen(r) as f:
            ready, _, _ = select.select([f], [], [], 30)
            line = f.readline() if ready else ""
        m = re.match(r"ready tcp (\d+)", line)
        if not m:
            self.proc.kill()
            raise RuntimeError(f"no ready line: {line!r}")
        self.port = int(m.group(1))

    def stop(self) -> int:
        self.proc.send_signal(signal.SIGTERM)
        return self.proc.wait(timeout=30)


class MbException(Exception):
    def __init__(self, fc: int, code: int) -> None:
        super().__init__(f"exception {code:02d} to function {fc}")
        self.fc, self.code = fc, code


class Raw:
    """A Modbus/TCP client on a plain socket: MBAP header + PDU, unit 1."""

    def __init__(self, port: int) -> None:
        self.s = socket.create_connection(("127.0.0.1", port), timeout=10)
        self.tid = 0
        self.order = 0  # word order the client assumes: 0 high word first

    def close(self) -> None:
        self.s.close()

    def __enter__(self) -> "Raw":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _recv(self, n: int) -> bytes:
        out = b""
        while len(out) < n:
            chunk = self.s.recv(n - len(out))
            if not chunk:
                raise ConnectionError("server closed the connection")
            out += chunk
        return out

    def pdu(self, pdu: bytes) -> bytes:
        """Send one request PDU; return the answer PDU (function code first)."""
        self.tid = (self.tid + 1) & 0xFFFF
        self.s.sendall(struct.pack(">HHHB", self.tid, 0, len(pdu) + 1, 1) + pdu)
        tid, proto, length, _unit = struct.unpack(">HHHB", self._recv(7))
        assert tid == self.tid and proto == 0
        return self._recv(length - 1)

    def call(self, pdu: bytes) -> bytes:
        ans = self.pdu(pdu)
        if ans[0] & 0x80:
            assert ans[0] == pdu[0] | 0x80 and len(ans) == 2
            raise MbException(pdu[0], ans[1])
        assert ans[0] == pdu[0]
        return ans

    def read(self, addr: int, count: int, fc: int = 3) -> list[int]:
        ans = self.call(struct.pack(">BHH", fc, addr, count))
        assert ans[1] == 2 * count
        return list(struct.unpack(f">{count}H", ans[2:]))

    def write(self, addr: int, values: list[int]) -> None:
        vals = [v & 0xFFFF for v in values]
        ans = self.call(struct.pack(f">BHHB{len(vals)}H", 16, addr, len(vals), 2 * len(vals), *vals))
        assert struct.unpack(">HH", ans[1:5]) == (addr, len(vals))

    def write1(self, addr: int, value: int) -> None:
        ans = self.call(struct.pack(">BHH", 6, addr, value & 0xFFFF))
        assert struct.unpack(">HH", ans[1:5]) == (addr, value & 0xFFFF)

    def write_read(self, waddr: int, values: list[int], raddr: int, count: int) -> list[int]:
        vals = [v & 0xFFFF for v in values]
        ans = self.call(struct.pack(f">BHHHHB{len(vals)}H", 23, raddr, count, waddr, len(vals), 2 * len(vals), *vals))
        return list(struct.unpack(f">{count}H", ans[2:]))

    def code_of(self, pdu: bytes) -> int:
        """The exception code a request gets (0: a normal answer)."""
        try:
            self.call(pdu)
        except MbException as e:
            return e.code
        return 0

    # 32-bit values in the word order (docs: "Conventions")
    def p32(self, v: int) -> list[int]:
        u = v & 0xFFFFFFFF
        return [u >> 16, u & 0xFFFF] if self.order == 0 else [u & 0xFFFF, u >> 16]

    def u32(self, regs: list[int]) -> int:
        hi, lo = (regs[0], regs[1]) if self.order == 0 else (regs[1], regs[0])
        return hi << 16 | lo

    def i32(self, regs: list[int]) -> int:
        u = self.u32(regs)
        return u - (1 << 32) if u & 0x80000000 else u

    def get(self, name: str) -> int:
        r = R[name]
        v = self.read(r.addr, r.width)
        if r.width == 2 and r.is32:
            return self.i32(v) if r.signed else self.u32(v)
        x = v[0]
        return x - 0x10000 if r.signed and x & 0x8000 else x

    def put(self, name: str, value: int) -> None:
        r = R[name]
        self.write(r.addr, self.p32(value) if r.is32 else [value])


@pytest.fixture
def srv():
    s = Server("--max-clients", "3", "--upload-timeout-ms", "400")
    yield s
    assert s.stop() == 0


def closed_by_server(sock: socket.socket) -> bool:
    """The server closed the connection (an orderly close, or a reset when data was unread)."""
    try:
        return sock.recv(1) == b""
    except ConnectionResetError:
        return True


def _ex(c: Raw, fn, *args) -> int:
    try:
        fn(*args)
    except MbException as e:
        return e.code
    return 0


def _fixed_crc(blob: bytearray) -> bytes:
    """docs/table-format.md: total_size at byte 8 (u32 LE), CRC-32 of [0, total_size - 4) in the last 4 bytes."""
    total = struct.unpack_from("<I", blob, 8)[0]
    struct.pack_into("<I", blob, total - 4, zlib.crc32(bytes(blob[:total - 4])))
    return bytes(blob)


def upload(c: Raw, blob: bytes, commit_len: int | None = None, commit_crc: int | None = None,
           chunk_regs: int = 123) -> int:
    """The documented protocol: BEGIN, chunks, COMMIT (one FC16 of 4 registers). Returns UP_RESULT."""
    c.write1(R["UP_CMD"].addr, 1)
    padded = blob + (b"\0" if len(blob) % 2 else b"")
    for off in range(0, len(padded), 2 * chunk_regs):
        part = padded[off:off + 2 * chunk_regs]
        c.write(R["STAGING"].addr + off // 2, list(struct.unpack(f">{len(part) // 2}H", part)))
    n = len(blob) if commit_len is None else commit_len
    crc = zlib.crc32(blob[:n]) if commit_crc is None else commit_crc
    _ex(c, c.write, R["UP_COMMIT_LEN"].addr, c.p32(n) + c.p32(crc))
    return c.get("UP_RESULT")


def cycle_block(c: Raw, pos_nm, cyc: int, dirs=(0, 0, 0), temps=(2000, 2000, 2000), fault=0) -> list[int]:
    """The controller's cycle of the docs: FC23 writing 0x0100..0x010D, reading 0x0120..0x012E."""
    w = []
    for p in pos_nm:
        w += c.p32(p)
    w += list(dirs) + list(temps) + [fault, cyc]
    assert len(w) == 14
    return c.write_read(R["IN_POS_X"].addr, w, R["OUT_CORR_X"].addr, 15)


def set_limits(c: Raw, fade=1, stale=10, warn=10**8, limit=2 * 10**8, rate=10**8, signs=(1, 1, 1)) -> None:
    v = [fade, stale]
    for x in (warn, limit, rate):
        for _ in range(3):
            v += c.p32(x)
    v += list(signs)
    c.write(R["CT_FADE_CYCLES"].addr, v)


# --------------------------------------------------------------------------- registers and blocks

@needs_server
def test_every_documented_register_reads(srv):
    """Each block in one request (FC03 and FC04), and each documented value alone."""
    with Raw(srv.port) as c:
        for section, (lo, n) in blocks().items():
            whole = c.read(lo, n)
            if not section.startswith("Status"):                  # counters move between two reads
                assert c.read(lo, n, fc=4) == whole
        for r in REGS:
            if r.name == "STAGING":
                assert _ex(c, c.read, r.addr, 4) == 1          # no upload session: wrong state
                continue
            c.read(r.addr, r.width)


@needs_server
def test_block_edges_gaps_and_staging_end(srv):
    with Raw(srv.port) as c:
        for section, (lo, n) in blocks().items():
            assert _ex(c, c.read, lo, n + 1) == 2, section      # one past the end
            assert _ex(c, c.read, lo + n, 1) == 2, section      # the first unmapped address
            if lo > 0:
                assert _ex(c, c.read, lo - 1, 2) == 2, section  # across the start
        st = R["STAGING"]
        assert _ex(c, c.read, st.addr + st.width, 1) == 2
        assert _ex(c, c.read, 0xFFFF, 1) == 2


@needs_server
def test_read_only_registers_refuse_writes(srv):
    with Raw(srv.port) as c:
        for r in REGS:
            if r.section in RO_SECTIONS:
                vals = [0] * (2 if r.is32 else 1)
                assert _ex(c, c.write, r.addr, vals) == 2, r.name
                if not r.is32:
                    assert _ex(c, c.write1, r.addr, 0) == 2, r.name


@needs_server
def test_identity(srv):
    text = (REPO / "docs" / "table-format.md").read_text()
    fmt_minor = int(re.search(r"\| 6 \| u16 \| version_minor \| (\d+)\.", text).group(1))
    with Raw(srv.port) as c:
        assert c.read(R["ID_MAGIC"].addr, 2) == [0x4142, 0x4245]
        assert c.get("ID_REGMAP") == 1                            # "Register map version **1**"
        assert (c.get("ID_FMT_MAJOR"), c.get("ID_FMT_MINOR")) == (1, fmt_minor)
        assert c.read(R["ID_SELFTEST"].addr, 2) == [0x1234, 0x5678]
        assert c.get("ID_STAGING_MAX") == 16384
        assert c.get("ID_MAX_CLIENTS") == 3                       # --max-clients 3
        assert (c.get("ID_MODEL_CRC"), c.get("ID_MODEL_SIZE"), c.get("ID_PENDING_CRC")) == (0, 0, 0)
        assert c.get("ID_MODEL_FEATURES") == 0
        blob = PAPER.read_bytes()
        assert upload(c, blob) == 1
        assert c.get("ID_PENDING_CRC") == struct.unpack("<I", blob[-4:])[0]
        c.write1(R["IN_CYCLE"].addr, 1)
        assert c.get("ID_MODEL_CRC") == struct.unpack("<I", blob[-4:])[0]   # "its last 4 bytes"
        assert c.get("ID_MODEL_SIZE") == len(blob)
        assert c.get("ID_PENDING_CRC") == 0
        features = struct.unpack_from("<I", blob, 20)[0]
        assert c.get("ID_MODEL_FEATURES") == features


def golden_blob(name: str) -> bytes:
    """A golden table's bytes as tests/golden/golden_data.c spells them."""
    text = (REPO / "tests" / "golden" / "golden_data.c").read_text()
    body = re.search(rf"golden_blob_{name}\[\d+\][^=]*= \{{(.*?)\}};", text, re.S).group(1)
    return bytes(int(v, 16) for v in re.findall(r"0x([0-9A-F]{2})", body))


@needs_server
def test_format_1_1_table_runs(srv):
    """A table with reversal blocks (format 1.1, feature bit 16) uploads and runs; the
    identity shows its features (the server reads format 1.1: ID_FMT_MINOR)."""
    blob = golden_blob("reversal")
    assert struct.unpack_from("<H", blob, 6)[0] == 1
    with Raw(srv.port) as c:
        assert c.get("ID_FMT_MINOR") >= 1
        assert upload(c, blob) == 1
        c.write1(R["IN_CYCLE"].addr, 1)
        assert c.get("ID_MODEL_CRC") == struct.unpack("<I", blob[-4:])[0]
        assert c.get("ID_MODEL_FEATURES") == struct.unpack_from("<I", blob, 20)[0] & 0xFFFF
        assert c.get("ID_MODEL_FEATURES") & 16


@needs_server
def test_word_order(srv):
    with Raw(srv.port) as c, Raw(srv.port) as d:
        c.put("CT_WARN_X", 123456)
        c.write1(R["CT_WORD_ORDER"].addr, 1)
        c.order = 1
        assert c.read(R["ID_SELFTEST"].addr, 2) == [0x5678, 0x1234]
        assert d.read(R["ID_SELFTEST"].addr, 2) == [0x5678, 0x1234]     # "for every client at once"
        assert c.get("CT_WARN_X") == 123456 and c.read(R["CT_WARN_X"].addr, 2) == [123456 & 0xFFFF, 123456 >> 16]
        # one request writing CT_WORD_ORDER = 0 and CT_WARN_X: its values in the order before it (low first)
        a = R["CT_WORD_ORDER"].addr
        v = [0, 0, 1000, 10] + c.p32(333333)          # word order, dir source, fade, stale, warn X
        c.write(a, v)
        c.order = 0
        assert c.read(R["ID_SELFTEST"].addr, 2) == [0x1234, 0x5678]
        assert c.get("CT_WARN_X") == 333333


@needs_server
def test_write_rules_and_ranges(srv):
    """Half a 32-bit value: 02; every documented range: 03; and a refused write changes nothing."""
    with Raw(srv.port) as c:
        def snapshot() -> list[int]:
            return [x for name in ("Inputs", "Control") for sec, (lo, n) in blocks().items()
                    if sec.startswith(name) for x in c.read(lo, n)]
        before = snapshot()
        for name in ("IN_POS_X", "IN_POS_Z", "CT_WARN_Y", "CT_RATE_Z"):
            a = R[name].addr
            assert _ex(c, c.write, a + 1, [0]) == 2, name            # starts in the middle
            assert _ex(c, c.write, a - 1, [0, 0]) == 2 or R[name].addr - 1 < blocks()[R[name].section][0], name
        assert _ex(c, c.write, R["IN_DIR_Z"].addr, [0, 2000]) == 0    # IN_DIR_Z, IN_TEMP_X: 16-bit, fine
        bad = {"IN_DIR_X": [2, -2, 0x7FFF], "IN_TEMP_Y": [-5001, 15001, 0x7FFF, -32767],
               "IN_AXIS_FAULT": [8, 0xFFFF], "CT_ENABLE": [2], "CT_RESET": [2], "CT_WORD_ORDER": [2],
               "CT_DIR_SOURCE": [2], "CT_FADE_CYCLES": [0], "CT_STALE_CYCLES": [0], "CT_SIGN_Y": [0, 2, -2]}
        for name, values in bad.items():
            for v in values:
                assert _ex(c, c.write, R[name].addr, [v]) == 3, (name, v)
        for name, values in {"CT_WARN_X": [0, -5], "CT_RATE_Y": [0], "CT_LIMIT_Z": [99_999]}.items():  # limit < warn
            for v in values:
                assert _ex(c, c.write, R[name].addr, c.p32(v)) == 3, (name, v)
        assert snapshot() == before                                   # nothing changed
        # the limits only while OFF with zero output: 01
        c.write1(R["CT_ENABLE"].addr, 1)
        assert _ex(c, c.write1, R["CT_FADE_CYCLES"].addr, 5) == 1
        assert _ex(c, set_limits, c) == 1
        c.write1(R["CT_ENABLE"].addr, 0)
        c.write1(R["IN_CYCLE"].addr, 1)                              # no table: output stays zero
        c.write1(R["CT_FADE_CYCLES"].addr, 5)
        assert c.get("CT_FADE_CYCLES") == 5
        # the whole control block in one FC16: reset, then limits, then enable
        v = [1, 1, 0, 0, 7, 3]
        for x in (50_000, 100_000, 2_000):
            for _ in range(3):
                v += c.p32(x)
        v += [1, 0xFFFF, 1]
        c.write(R["CT_ENABLE"].addr, v)
        assert c.get("CT_ENABLE") == 1 and c.get("CT_RESET") == 0 and c.get("CT_SIGN_Y") == -1
        assert (c.get("CT_FADE_CYCLES"), c.get("CT_LIMIT_Z"), c.get("CT_RATE_X")) == (7, 100_000, 2_000)


# --------------------------------------------------------------------------- the cycle

@needs_server
def test_cycle_trigger_fresh_and_stale(srv):
    blob = PAPER.read_bytes()
    pos = (100_000_000, -100_000_000, -50_000_000)
    with Raw(srv.port) as c:
        assert upload(c, blob) == 1
        set_limits(c, fade=1, stale=3)
        c.write1(R["CT_ENABLE"].addr, 1)
        cycles0 = c.get("ST_CYCLES")
        w = []
        for p in pos:
            w += c.p32(p)
        c.write(R["IN_POS_X"].addr, w)                            # positions only: no cycle
        assert c.get("ST_CYCLES") == cycles0
        out = cycle_block(c, pos, 4242)                          # the docs' FC23 cycle
        assert out[14] == 4242 and c.get("ST_CYCLES") == cycles0 + 1
        flags = out[12]
        assert flags & 0x0400                                     # MODEL_SWAPPED: the upload took effect
        assert not flags & 0x0200                                 # fresh
        corr = [c.i32(out[2 * j:2 * j + 2]) for j in range(3)]
        err = [c.i32(out[6 + 2 * j:8 + 2 * j]) for j in range(3)]
        assert corr == [-e for e in err] and any(err)             # OUT_CORR = sign x (-OUT_ERR), fade 1
        assert out[13] == 1 and c.get("ST_STATE") == 1            # ON
        # positions in several requests count as fresh; X and Z only do not
        c.write(R["IN_POS_X"].addr, c.p32(pos[0]))
        c.write(R["IN_POS_Y"].addr, c.p32(pos[1]) + c.p32(pos[2]))
        c.write1(R["IN_CYCLE"].addr, 1)
        assert not c.get("OUT_FLAGS") & 0x0200
        invalid0 = c.get("ST_INVALID_INPUTS")
        for k in range(4):
            c.write(R["IN_POS_X"].addr, c.p32(pos[0]))
            c.write1(R["IN_CYCLE"].addr, 10 + k)
            f = c.get("OUT_FLAGS")
            assert f & 0x0200                                     # INPUT_INVALID
            assert bool(f & 0x0080) == (k >= 2)                   # STALE after CT_STALE_CYCLES = 3
            assert [c.get(f"OUT_ERR_{a}") for a in "XYZ"] == err  # the last evaluation kept
        assert c.get("ST_INVALID_INPUTS") == invalid0 + 4 and c.get("ST_STALE_EVENTS") == 1
        cycle_block(c, pos, 99)
        assert not c.get("OUT_FLAGS") & 0x0280


@needs_server
def test_direction_from_position(srv):
    """CT_DIR_SOURCE = 1: the direction is the sign of the position change; IN_DIR is then ignored."""
    blob = bytearray(PAPER.read_bytes())
    struct.pack_into("<I", blob, 20, struct.unpack_from("<I", blob, 20)[0] | 4)   # BACKLASH
    struct.pack_into("<ii", blob, 64 + 28, 20_000 * 256, 1_000)                   # X: B = 20 um, take-up 1 um
    blob = _fixed_crc(blob)
    with Raw(srv.port) as c:
        assert upload(c, blob) == 1
        set_limits(c, fade=1)
        c.write1(R["CT_ENABLE"].addr, 1)

        def err_after(xs: list[int], dirs: tuple[int, int, int] = (0, 0, 0)) -> int:
            for k, x in enumerate(xs):
                out = cycle_block(c, (x, -100_000_000, -50_000_000), k, dirs=dirs)
            return c.i32(out[6:8])

        base = 200_000_000
        up = err_after([base - 50_000 + 10_000 * k for k in range(6)], dirs=(1, 0, 0))
        down = err_after([base + 50_000 - 10_000 * k for k in range(6)], dirs=(-1, 0, 0))
        assert abs(abs(up - down) - 20_000) <= 5                  # the reversal, driven by IN_DIR
        c.write1(R["CT_ENABLE"].addr, 0)
        for k in range(3):
            c.write1(R["IN_CYCLE"].addr, 50 + k)
        c.write1(R["CT_DIR_SOURCE"].addr, 1)
        c.write1(R["CT_ENABLE"].addr, 1)
        up2 = err_after([base - 50_000 + 10_000 * k for k in range(6)], dirs=(-1, 0, 0))   # IN_DIR ignored
        down2 = err_after([base + 50_000 - 10_000 * k for k in range(6)], dirs=(1, 0, 0))
        assert abs(up2 - up) <= 2 and abs(down2 - down) <= 2


@needs_server
def test_temperatures(srv):
    """IN_TEMP_*: 0.01 degC into the thermal term (docs/table-format.md), 0x8000 keeps, 2000 until written."""
    blob = bytearray(PAPER.read_bytes())
    struct.pack_into("<I", blob, 20, struct.unpack_from("<I", blob, 20)[0] | 8)   # THERMAL
    alpha_q50, offset_q16, tref = 13_510_799, 65_536, 20_000                      # 12 ppm/K, 1 um/K, 20 degC
    struct.pack_into("<iii", blob, 64 + 36, alpha_q50, offset_q16, tref)          # X only
    blob = _fixed_crc(blob)
    ref_x_nm = struct.unpack_from("<i", blob, 24)[0]
    x = 150_000_000
    with Raw(srv.port) as c:
        assert [c.get(f"IN_TEMP_{a}") for a in "XYZ"] == [2000, 2000, 2000]
        assert upload(c, blob) == 1
        set_limits(c, fade=1)
        c.write1(R["CT_ENABLE"].addr, 1)
        e20 = c.i32(cycle_block(c, (x, -100_000_000, -50_000_000), 1, temps=(2000, 2000, 2000))[6:8])
        e30 = c.i32(cycle_block(c, (x, -100_000_000, -50_000_000), 2, temps=(3000, 0x8000, 2000))[6:8])
        want = 12e-6 * 10 * (x - ref_x_nm) + 1000 * 10                           # alpha dT (p - ref) + o dT, nm
        assert abs(abs(e30 - e20) - abs(want)) <= 3, (e30 - e20, want)
        assert [c.get(f"IN_TEMP_{a}") for a in "XYZ"] == [3000, 2000, 2000]      # Y kept its 2000
        e_kept = c.i32(cycle_block(c, (x, -100_000_000, -50_000_000), 3, temps=(0x8000, 0x8000, 0x8000))[6:8])
        assert e_kept == e30
        for v in (-5000, 15000):                                                  # the range ends
            cycle_block(c, (x, -100_000_000, -50_000_000), 4, temps=(v, v, v))
            assert c.get("IN_TEMP_X") == v


# --------------------------------------------------------------------------- upload

@needs_server
def test_upload_results_every_documented_value(srv):
    """Each UP_RESULT of the docs' table, the counters, and the running table kept throughout."""
    documented = up_results()
    paper = PAPER.read_bytes()
    crc_paper = struct.unpack("<I", paper[-4:])[0]
    seen: dict[int, str] = {}
    with Raw(srv.port) as c:
        assert c.get("UP_RESULT") == 0 and c.get("UP_STATE") == 0
        seen[0] = "NONE"
        assert upload(c, paper) == 1
        seen[1] = "OK"
        assert c.get("UP_MODEL_CRC") == crc_paper and c.get("UP_RX_CRC") == zlib.crc32(paper)
        c.write1(R["IN_CYCLE"].addr, 1)

        def refused(blob: bytes, want: int, **kw) -> None:
            assert upload(c, blob, **kw) == want
            seen[want] = documented.get(want, "ABBE_E_*")
            assert c.get("UP_STATE") == 0 and c.get("ST_UPLOAD_STATE") == 0
            c.write1(R["IN_CYCLE"].addr, 2)
            assert c.get("ID_MODEL_CRC") == crc_paper and c.get("ID_PENDING_CRC") == 0

        refused(paper, -100, commit_len=len(paper) + 2)                            # INCOMPLETE
        refused(paper, -101, commit_crc=zlib.crc32(paper) ^ 1)                      # CRC_MISMATCH
        assert c.get("UP_RX_CRC") == zlib.crc32(paper)                             # what arrived
        refused(paper, -102, commit_len=0)                                          # LENGTH
        big = paper + bytes(16384 - len(paper))
        refused(big, -102, commit_len=16386, commit_crc=0)
        bad = bytearray(paper)
        bad[0] = ord("X")
        refused(bytes(bad), -3)                                                     # MAGIC
        bad = bytearray(paper)
        bad[500] ^= 1
        refused(bytes(bad), -7)                                                     # the table's own CRC
        refused(paper[:200], -2)                                                    # TRUNCATED
        refused(_fixed_crc(bytearray(MISMATCH.read_bytes())), -17)                  # MISMATCH
        # ABORT, and BEGIN again
        c.write1(R["UP_CMD"].addr, 1)
        assert c.get("UP_STATE") == 1 and c.get("UP_RESULT") == 0
        s = c.get("UP_SESSION")
        c.write1(R["UP_CMD"].addr, 2)
        assert c.get("UP_RESULT") == -103 and c.get("UP_SESSION") == s
        c.write1(R["UP_CMD"].addr, 1)
        c.write1(R["UP_CMD"].addr, 1)
        assert c.get("UP_RESULT") == 0 and c.get("UP_SESSION") == s + 2
        seen[-103] = "ABORTED"
        # the session ends with its connection: DISCONNECTED
    with Raw(srv.port) as d:
        for _ in range(200):
            if d.get("UP_STATE") == 0:
                break
            time.sleep(0.01)
        assert d.get("UP_RESULT") == -104
        seen[-104] = "DISCONNECTED"
        # no upload request for --upload-timeout-ms 400: TIMEOUT
        d.write1(R["UP_CMD"].addr, 1)
        for _ in range(500):
            if d.get("UP_STATE") == 0:
                break
            time.sleep(0.01)
        assert d.get("UP_RESULT") == -105
        seen[-105] = "TIMEOUT"
        assert d.get("ID_MODEL_CRC") == crc_paper
        # counters: 1 ok; refused: 8 commits, abort, BEGIN again, disconnect, timeout
        assert d.get("ST_UPLOADS_OK") == 1 and d.get("ST_UPLOADS_REJECTED") == 12
    named = {v for k, v in documented.items() if k > -100 and k < 0}
    assert named == {"ABBE_E_*"}
    for value in seen:                                   # every result that came is documented
        assert documented_result(value) is not None, f"UP_RESULT {value} is not in the docs' table"
    for code, name in documented.items():
        if name != "ABBE_E_*":
            assert code in seen, f"UP_RESULT {code} {name} not reached"


@needs_server
def test_upload_protocol_rules(srv):
    paper = PAPER.read_bytes()
    regs = list(struct.unpack(f">{len(paper) // 2}H", paper))
    st = R["STAGING"].addr
    with Raw(srv.port) as a, Raw(srv.port) as b:
        assert _ex(a, a.write, st, regs[:4]) == 1                      # no session: 01
        assert _ex(a, a.write, R["UP_COMMIT_LEN"].addr, [0, 4, 0, 0]) == 1
        assert _ex(a, a.write1, R["UP_CMD"].addr, 2) == 1
        assert _ex(a, a.write1, R["UP_CMD"].addr, 3) == 3               # not a command
        assert a.read(R["UP_CMD"].addr, 1) == [0]                       # reads 0
        a.write1(R["UP_CMD"].addr, 1)
        assert a.read(st, 4) == [0, 0, 0, 0]                            # cleared
        a.write(st, regs[:100])
        assert a.get("UP_FILLED") == 200
        assert _ex(a, a.write, st + 101, regs[101:110]) == 2            # a gap
        a.write(st + 50, regs[50:150])                                  # overlapping, in order: fine
        assert a.get("UP_FILLED") == 300 and a.read(st + 10, 5) == regs[10:15]
        assert _ex(a, a.write, st + 8191, [0, 0]) == 2                  # past the staging area
        assert _ex(a, a.write, R["UP_COMMIT_LEN"].addr, [0, 4]) == 2    # the commit as 2 registers
        # another connection: busy for everything of the session
        for fn, args in ((b.write1, (R["UP_CMD"].addr, 1)), (b.write, (st, regs[:4])), (b.read, (st, 4)),
                         (b.write, (R["UP_COMMIT_LEN"].addr, [0, 4, 0, 0])), (b.write1, (R["UP_CMD"].addr, 2))):
            assert _ex(b, fn, *args) == 6
        assert a.get("UP_STATE") == 1 and a.get("UP_FILLED") == 300     # undisturbed
        # FC23 touching the staging area: 02
        assert a.code_of(struct.pack(">BHHHHBH", 23, st, 1, R["IN_CYCLE"].addr, 1, 2, 0)) == 2
        assert a.code_of(struct.pack(">BHHHHBH", 23, R["OUT_CYCLE"].addr, 1, st, 1, 2, 0)) == 2
        for off in range(300, len(paper), 246):
            part = paper[off:off + 246]
            a.write(st + off // 2, list(struct.unpack(f">{len(part) // 2}H", part)))
        a.write(R["UP_COMMIT_LEN"].addr, a.p32(len(paper)) + a.p32(zlib.crc32(paper)))
        assert a.get("UP_RESULT") == 1
        # a later commit before the cycle replaces the queued table
        other = bytearray(paper)
        struct.pack_into("<i", other, 24, struct.unpack_from("<i", other, 24)[0] + 1000)
        other = _fixed_crc(other)
        assert upload(b, other) == 1
        assert b.get("ID_PENDING_CRC") == struct.unpack("<I", other[-4:])[0]
        b.write1(R["IN_CYCLE"].addr, 1)
        assert b.get("ID_MODEL_CRC") == struct.unpack("<I", other[-4:])[0]


# --------------------------------------------------------------------------- exceptions, counters

@needs_server
def test_exception_code_table(srv):
    with Raw(srv.port) as c:
        for fc in (1, 2, 5, 15, 0x2B, 0x41):                           # other function codes: 01
            assert c.code_of(bytes([fc, 0, 0, 0, 1])) == 1, fc
        assert c.code_of(struct.pack(">BHH", 3, 0, 0)) == 3             # count 0
        assert c.code_of(struct.pack(">BHH", 3, 0x1000, 126)) == 3      # over 125
        assert c.code_of(struct.pack(">BHH", 4, 0, 126)) == 3
        assert c.code_of(struct.pack(">BHHB", 16, R["CT_ENABLE"].addr, 1, 2) + b"\0\0\0") == 3  # byte count
        assert c.code_of(struct.pack(">BHHB", 16, R["CT_ENABLE"].addr, 0, 0)) == 3
        # over 123 (FC16) or 121 (FC23) registers: a count field above the maximum; the data
        # of so many would not fit a Modbus frame (253 PDU bytes)
        n = 123
        assert c.code_of(struct.pack(f">BHHB{n}H", 16, 0x1000, n + 1, 2 * n, *([0] * n))) == 3
        n = 121
        assert c.code_of(struct.pack(f">BHHHHB{n}H", 23, 0x120, 1, 0x100, n + 1, 2 * n, *([0] * n))) == 3
        assert c.code_of(struct.pack(">BHHHHB", 23, 0x120, 126, 0x10D, 1, 2) + b"\0\0") == 3
        assert c.code_of(struct.pack(">BHH", 6, 0x0000, 1)) == 2        # read only
        ex0 = c.get("ST_EXCEPTIONS")
        req0 = c.get("ST_REQUESTS")
        assert c.code_of(struct.pack(">BHH", 6, R["CT_ENABLE"].addr, 9)) == 3
        assert c.get("ST_LAST_EXCEPTION") == (6 << 8) | 3               # function << 8 | code
        assert c.get("ST_EXCEPTIONS") == ex0 + 1
        assert c.get("ST_REQUESTS") == req0 + 3                         # the three reads before this one
    with Raw(srv.port) as c:                                            # a frame longer than Modbus/TCP allows
        n = 124
        c.s.sendall(struct.pack(f">HHHBBHHB{n}H", 1, 0, 7 + 2 * n, 1, 16, 0x1000, n, 2 * n, *([0] * n)))
        assert closed_by_server(c.s)                                    # closes that connection


@needs_server
def test_pymodbus_gets_the_same_answers(srv):
    """A standard client: FC03, FC16, FC23 and an exception, as the raw client sees them."""
    from pymodbus.client import ModbusTcpClient

    cl = ModbusTcpClient("127.0.0.1", port=srv.port, timeout=5, retries=1)
    assert cl.connect()
    try:
        assert list(cl.read_holding_registers(R["ID_MAGIC"].addr, count=2).registers) == [0x4142, 0x4245]
        assert not cl.write_registers(R["IN_POS_X"].addr, [0, 5, 0, 6, 0, 7]).isError()
        rsp = cl.readwrite_registers(read_address=R["OUT_CORR_X"].addr, read_count=15,
                                     write_address=R["IN_CYCLE"].addr, values=[31])
        assert list(rsp.registers)[14] == 31
        assert cl.write_register(R["CT_ENABLE"].addr, 2).exception_code == 3
        assert cl.read_coils(0, count=1).exception_code == 1
    finally:
        cl.close()


# --------------------------------------------------------------------------- states and flags

@needs_server
def test_states_flags_and_their_counters(srv):
    """OFF/ON/FAULT and every flag a request can cause, with the counters that go with them;
    the reserved flag bits stay 0. (SATURATED needs a table whose fixed point overflows; none here.)"""
    bits = {name: bit for bit, name in flag_bits().items()}
    reserved = sum(bit for bit, name in flag_bits().items() if name == "reserved")
    paper = PAPER.read_bytes()
    pos = (100_000_000, -100_000_000, -50_000_000)
    seen = 0
    with Raw(srv.port) as c:
        def step(p=pos, cyc=0, fault=0) -> int:
            nonlocal seen
            out = cycle_block(c, p, cyc, fault=fault)
            assert out[12] & reserved == 0
            seen |= out[12]
            return out[12]

        assert step() & bits["NO_MODEL"] and c.get("ST_STATE") == 0
        assert upload(c, paper) == 1
        set_limits(c, fade=4, stale=2, warn=1_000, limit=10**8, rate=100)
        c.write1(R["CT_ENABLE"].addr, 1)
        f = step()
        assert f & bits["MODEL_SWAPPED"] and c.get("ST_MODEL_SWAPS") == 1
        assert step() & bits["FADING"]
        for _ in range(300):
            f = step()
        assert f & bits["WARN"] and c.get("ST_RATE_LIMITED") > 0 and seen & bits["RATE_LIMITED"]
        assert step(fault=2) & bits["AXIS_FAULT"]
        assert step(p=(10**9, pos[1], pos[2])) & bits["OUT_OF_TRAVEL"]
        c.write(R["IN_POS_X"].addr, c.p32(pos[0]))
        c.write1(R["IN_CYCLE"].addr, 7)
        c.write1(R["IN_CYCLE"].addr, 8)
        f = c.get("OUT_FLAGS")
        seen |= f
        assert f & bits["INPUT_INVALID"] and f & bits["STALE"]
        # FAULT: an error limit below the correction
        c.write1(R["CT_ENABLE"].addr, 0)
        for k in range(2000):                                            # until faded out (rate-limited)
            step(cyc=k)
            if c.read(R["OUT_CORR_X"].addr, 6) == [0] * 6:
                break
        set_limits(c, fade=1, stale=2, warn=10, limit=20, rate=10**8)
        c.write1(R["CT_ENABLE"].addr, 1)
        f = step()
        assert f & bits["LIMIT"] and c.get("ST_STATE") == 2 and c.get("OUT_STATE") == 2
        assert c.get("ST_LIMIT_TRIPS") == 1
        c.write1(R["CT_ENABLE"].addr, 1)
        assert step() & bits["LIMIT"] and c.get("ST_STATE") == 2      # latched until CT_RESET
        c.write1(R["CT_RESET"].addr, 1)                               # clears it and disables ...
        assert c.get("CT_ENABLE") == 0
        assert step() & bits["LIMIT"] and c.get("ST_LIMIT_TRIPS") == 2  # ... the table still asks too much
        # one FC16 of the whole control block: reset, then wider limits, then enable
        v = [1, 1, 0, 0, 1, 2]
        for x in (10**8, 2 * 10**8, 10**8):
            for _ in range(3):
                v += c.p32(x)
        c.write(R["CT_ENABLE"].addr, v + [1, 1, 1])
        assert not step() & bits["LIMIT"] and c.get("ST_STATE") == 1
    unreached = {name for name, bit in bits.items() if name != "reserved" and not seen & bit}
    assert unreached == {"SATURATED"}


@needs_server
def test_clients_and_refused_connections(srv):
    with Raw(srv.port) as a, Raw(srv.port) as b, Raw(srv.port) as c:
        assert a.get("ST_CLIENTS") == 3
        d = socket.create_connection(("127.0.0.1", srv.port), timeout=5)
        assert closed_by_server(d)                                      # accepted and closed at once
        d.close()
        for _ in range(100):
            if a.get("ST_CLIENTS_REFUSED") == 1:
                break
            time.sleep(0.01)
        assert a.get("ST_CLIENTS_REFUSED") == 1
        b.close()
        for _ in range(100):
            if a.get("ST_CLIENTS") == 2:
                break
            time.sleep(0.01)
        assert a.get("ST_CLIENTS") == 2
        # a frame that is not Modbus/TCP (protocol id 1) closes only its own connection
        c.s.sendall(struct.pack(">HHHB", 1, 1, 6, 1) + struct.pack(">BHH", 3, 0, 1))
        assert closed_by_server(c.s)
        assert a.read(R["ID_MAGIC"].addr, 2) == [0x4142, 0x4245]
