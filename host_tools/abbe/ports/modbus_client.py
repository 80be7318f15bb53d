"""Host side of the abbe Modbus port (docs/modbus-registers.md), on pymodbus.

:class:`ModbusLink` talks to ``abbe-modbusd`` (or a drive running the same
register map) over Modbus TCP or RTU: identity and status, the compensation
cycle, and table upload with progress and CRC verification.

Units as on the bus: positions, corrections and errors in nm (int32), temperatures
in 0.01 degC (int16). Register numbers mirror
``port/modbus/include/abbe/modbus_regs.h`` (a test compares them).
"""

from __future__ import annotations

import re
import struct
import zlib
from dataclasses import dataclass, field
from typing import Any, Callable

from abbe.model.clib import STATUS_NAMES
from abbe.errors import AbbeInputError

REGMAP_VERSION = 1

# Register addresses (modbus_regs.h ABBE_MB_REG_*), by their C name without the prefix.
REG: dict[str, int] = {
    "ID_BASE": 0x0000, "ID_MAGIC": 0x0000, "ID_REGMAP": 0x0002, "ID_LIB_MAJOR": 0x0003,
    "ID_LIB_MINOR": 0x0004, "ID_LIB_PATCH": 0x0005, "ID_FMT_MAJOR": 0x0006, "ID_FMT_MINOR": 0x0007,
    "ID_SELFTEST": 0x0008, "ID_MODEL_CRC": 0x000A, "ID_MODEL_SIZE": 0x000C,
    "ID_PENDING_CRC": 0x000E, "ID_STAGING_MAX": 0x0010, "ID_MODEL_FEATURES": 0x0012,
    "ID_MAX_CLIENTS": 0x0013,
    "ST_BASE": 0x0020, "ST_STATE": 0x0020, "ST_FLAGS": 0x0021, "ST_CLIENTS": 0x0022,
    "ST_UPLOAD_STATE": 0x0023, "ST_CYCLES": 0x0024, "ST_REQUESTS": 0x0026,
    "ST_EXCEPTIONS": 0x0028, "ST_UPLOADS_OK": 0x002A, "ST_UPLOADS_REJECTED": 0x002C,
    "ST_INVALID_INPUTS": 0x002E, "ST_STALE_EVENTS": 0x0030, "ST_LIMIT_TRIPS": 0x0032,
    "ST_RATE_LIMITED": 0x0034, "ST_MODEL_SWAPS": 0x0036, "ST_CLIENTS_REFUSED": 0x0038,
    "ST_LAST_EXCEPTION": 0x003A,
    "UP_BASE": 0x0050, "UP_CMD": 0x0050, "UP_STATE": 0x0051, "UP_SESSION": 0x0052,
    "UP_RESULT": 0x0053, "UP_FILLED": 0x0054, "UP_COMMIT": 0x0056, "UP_COMMIT_LEN": 0x0056,
    "UP_COMMIT_CRC": 0x0058, "UP_RX_CRC": 0x005A, "UP_MODEL_CRC": 0x005C,
    "IN_BASE": 0x0100, "IN_POS_X": 0x0100, "IN_POS_Y": 0x0102, "IN_POS_Z": 0x0104,
    "IN_DIR_X": 0x0106, "IN_DIR_Y": 0x0107, "IN_DIR_Z": 0x0108, "IN_TEMP_X": 0x0109,
    "IN_TEMP_Y": 0x010A, "IN_TEMP_Z": 0x010B, "IN_AXIS_FAULT": 0x010C, "IN_CYCLE": 0x010D,
    "OUT_BASE": 0x0120, "OUT_CORR_X": 0x0120, "OUT_CORR_Y": 0x0122, "OUT_CORR_Z": 0x0124,
    "OUT_ERR_X": 0x0126, "OUT_ERR_Y": 0x0128, "OUT_ERR_Z": 0x012A, "OUT_FLAGS": 0x012C,
    "OUT_STATE": 0x012D, "OUT_CYCLE": 0x012E,
    "CT_BASE": 0x0200, "CT_ENABLE": 0x0200, "CT_RESET": 0x0201, "CT_WORD_ORDER": 0x0202,
    "CT_DIR_SOURCE": 0x0203, "CT_FADE_CYCLES": 0x0204, "CT_STALE_CYCLES": 0x0205,
    "CT_WARN_X": 0x0206, "CT_WARN_Y": 0x0208, "CT_WARN_Z": 0x020A, "CT_LIMIT_X": 0x020C,
    "CT_LIMIT_Y": 0x020E, "CT_LIMIT_Z": 0x0210, "CT_RATE_X": 0x0212, "CT_RATE_Y": 0x0214,
    "CT_RATE_Z": 0x0216, "CT_SIGN_X": 0x0218, "CT_SIGN_Y": 0x0219, "CT_SIGN_Z": 0x021A,
    "STAGING": 0x1000,
    # thermal inputs and state (tables of format 1.3 with a thermal block)
    "TIN_BASE": 0x0140, "IN_TH_0": 0x0140, "IN_TH_RESERVED": 0x0151, "IN_TH_DT_MS": 0x0152,
    "IN_TH_SAMPLE": 0x0154, "TOUT_BASE": 0x0160, "TH_FLAGS": 0x0160, "TH_SHAPE": 0x0161,
    "TH_INPUT_FAULTS": 0x0162, "TH_EVENTS": 0x0164, "TH_CHANNEL_0": 0x0166, "TH_SAMPLES": 0x0170,
    "TH_SAMPLE_ECHO": 0x0171,
}
# Block sizes (ABBE_MB_*_COUNT).
COUNT: dict[str, int] = {"ID": 0x14, "ST": 0x1B, "UP": 0x0E, "IN": 0x0E, "OUT": 0x0F, "CT": 0x1B,
                         "TIN": 0x15, "TOUT": 0x12}

MAGIC = (0x4142, 0x4245)
SELFTEST = 0x12345678
UP_CMD_BEGIN, UP_CMD_ABORT = 1, 2
WORD_ORDER_HIGH_FIRST, WORD_ORDER_LOW_FIRST = 0, 1
MAX_WRITE_REGS = 123  # FC16: 246 data bytes per request

EX_ILLEGAL_FUNCTION, EX_ILLEGAL_ADDRESS, EX_ILLEGAL_VALUE = 1, 2, 3
EX_DEVICE_FAILURE, EX_BUSY = 4, 6
EXCEPTION_NAMES = {1: "illegal function (or not allowed now)", 2: "illegal data address",
                   3: "illegal data value", 4: "server device failure", 6: "server busy"}

UP_RESULT_NAMES: dict[int, str] = {
    1: "OK", 0: "NONE", -100: "INCOMPLETE", -101: "CRC_MISMATCH", -102: "LENGTH",
    -103: "ABORTED", -104: "DISCONNECTED", -105: "TIMEOUT",
}
COMP_STATES = {0: "OFF", 1: "ON", 2: "FAULT"}
FLAG_NAMES = {0x0001: "OUT_OF_TRAVEL", 0x0002: "SATURATED", 0x0010: "WARN", 0x0020: "LIMIT",
              0x0040: "RATE_LIMITED", 0x0080: "STALE", 0x0100: "FADING",
              0x0200: "INPUT_INVALID", 0x0400: "MODEL_SWAPPED", 0x0800: "NO_MODEL",
              0x1000: "AXIS_FAULT"}


def result_name(code: int) -> str:
    """Name of an UP_RESULT value (``OK``, ``CRC_MISMATCH``, ``ABBE_E_MAGIC``, ...)."""
    if code in UP_RESULT_NAMES:
        return UP_RESULT_NAMES[code]
    return STATUS_NAMES.get(code, f"result {code}")


def flag_names(flags: int) -> list[str]:
    """Names of the set ABBE_FLAG_* bits; a set bit without a name (reserved in
    docs/modbus-registers.md, maybe defined by a newer server) as its hex value."""
    names = [n for bit, n in FLAG_NAMES.items() if flags & bit]
    unknown = flags & 0xFFFF & ~sum(FLAG_NAMES)
    return names + [f"0x{1 << b:04X}" for b in range(16) if unknown >> b & 1]


class ModbusError(Exception):
    """The server refused a request (a Modbus exception), or did not answer."""

    def __init__(self, message: str, exception_code: int | None = None) -> None:
        self.exception_code = exception_code
        super().__init__(message)


class UploadRefused(ModbusError):
    """The server refused the table; ``result`` is the UP_RESULT code."""

    def __init__(self, message: str, result: int) -> None:
        self.result = result
        super().__init__(message)


# --------------------------------------------------------------------------- addresses

@dataclass(frozen=True)
class Endpoint:
    """Where the server is: ``tcp://HOST:PORT`` or ``rtu:DEVICE:BAUD[:PDS]``."""

    kind: str            # "tcp" or "rtu"
    host: str = ""
    port: int = 502
    device: str = ""
    baud: int = 19200
    parity: str = "N"
    bytesize: int = 8
    stopbits: int = 1
    unit: int = 1


_TCP_RE = re.compile(r"^tcp://(\[[^\]]+\]|[^:/]+)(?::(\d+))?/?$")
_RTU_RE = re.compile(r"^rtu:(.+?):(\d+)(?::([NEO])([5-8])([12]))?$")


def parse_endpoint(text: str, unit: int = 1) -> Endpoint:
    """Parse ``tcp://HOST:PORT`` (port 502 if omitted) or ``rtu:/dev/ttyX:BAUD[:E81]``.

    Raises AbbeInputError (field 'modbus') for anything else.
    """
    m = _TCP_RE.match(text)
    if m:
        port = int(m.group(2)) if m.group(2) else 502
        if not 0 < port < 65536:
            raise AbbeInputError(f"TCP port {port} not in 1..65535", field="modbus")
        return Endpoint("tcp", host=m.group(1).strip("[]"), port=port, unit=unit)
    m = _RTU_RE.match(text)
    if m:
        baud = int(m.group(2))
        if baud <= 0:
            raise AbbeInputError(f"baud rate {baud} must be > 0", field="modbus")
        if m.group(3):
            return Endpoint("rtu", device=m.group(1), baud=baud, parity=m.group(3),
                            bytesize=int(m.group(4)), stopbits=int(m.group(5)), unit=unit)
        return Endpoint("rtu", device=m.group(1), baud=baud, unit=unit)
    raise AbbeInputError(f"{text!r}: want tcp://HOST:PORT or rtu:DEVICE:BAUD[:PDS] "
                         "(e.g. rtu:/dev/ttyUSB0:115200:E81)", field="modbus")


# --------------------------------------------------------------------------- results

@dataclass
class Identity:
    """ID block: versions, the running and queued tables (CRC-32), staging size (bytes)."""

    regmap: int
    lib_version: str
    table_format: str
    word_order: str        # "high" (high word first) or "low"
    model_crc: int         # 0: no model running
    model_size: int
    pending_crc: int       # 0: nothing queued
    staging_max: int
    model_features: int
    max_clients: int


@dataclass
class Status:
    """ST and UP blocks: compensator state and flags, counters, upload session."""

    state: str
    flags: int
    clients: int
    upload_open: bool
    counters: dict[str, int] = field(default_factory=dict)
    last_exception: int = 0
    upload_session: int = 0
    upload_result: int = 0
    upload_filled: int = 0


@dataclass
class UploadResult:
    """Outcome of a successful upload: the table's CRC as the server reports it and
    whether it already runs or waits for the next cycle boundary."""

    session: int
    size: int
    model_crc: int
    running: bool
    requests: int


@dataclass
class CycleOutput:
    """OUT block of one cycle: corrections and spatial error in nm."""

    corr_nm: tuple[int, int, int]
    err_nm: tuple[int, int, int]
    flags: int
    state: str
    cycle: int


def _i32(u: int) -> int:
    return u - (1 << 32) if u & 0x80000000 else u


def _i16(u: int) -> int:
    return u - (1 << 16) if u & 0x8000 else u


def _u16(v: int) -> int:
    return v & 0xFFFF


# --------------------------------------------------------------------------- the link

class ModbusLink:
    """A connection to an abbe Modbus server (pymodbus, synchronous).

    The word order is read from the self-test register on connect. Every call
    raises :class:`ModbusError` when the server answers with an exception or not
    at all.
    """

    def __init__(self, endpoint: Endpoint, timeout_s: float = 3.0) -> None:
        from pymodbus.client import ModbusSerialClient, ModbusTcpClient

        self.endpoint = endpoint
        self.unit = endpoint.unit
        if endpoint.kind == "tcp":
            self._client: Any = ModbusTcpClient(endpoint.host, port=endpoint.port,
                                                timeout=timeout_s, retries=1)
        else:
            self._client = ModbusSerialClient(endpoint.device, baudrate=endpoint.baud,
                                              parity=endpoint.parity, bytesize=endpoint.bytesize,
                                              stopbits=endpoint.stopbits, timeout=timeout_s,
                                              retries=1)
        self.word_order = WORD_ORDER_HIGH_FIRST
        self.requests = 0

    # -- connection
    def connect(self) -> "ModbusLink":
        """Open the connection, check the identity magic, learn the word order."""
        where = (f"{self.endpoint.host}:{self.endpoint.port}" if self.endpoint.kind == "tcp"
                 else self.endpoint.device)
        try:
            ok = self._client.connect()
        except Exception as exc:  # pymodbus wraps serial errors differently by version
            raise ModbusError(f"cannot connect to {where}: {exc}") from None
        if not ok:
            raise ModbusError(f"cannot connect to {where}")
        head = self.read(REG["ID_MAGIC"], 2)
        if tuple(head) != MAGIC:
            raise ModbusError(f"{where} is not an abbe Modbus server (magic {head})")
        st = self.read(REG["ID_SELFTEST"], 2)
        if st == [0x1234, 0x5678]:
            self.word_order = WORD_ORDER_HIGH_FIRST
        elif st == [0x5678, 0x1234]:
            self.word_order = WORD_ORDER_LOW_FIRST
        else:
            raise ModbusError(f"self-test register reads {st[0]:#06x} {st[1]:#06x}, "
                              "want 0x1234 0x5678 in either order")
        return self

    def close(self) -> None:
        self._client.close()

    def __enter__(self) -> "ModbusLink":
        return self.connect()

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- raw register access
    def _check(self, rsp: Any, what: str) -> Any:
        self.requests += 1
        if rsp is None or rsp.isError():
            code = getattr(rsp, "exception_code", None)
            name = EXCEPTION_NAMES.get(code, "no valid answer") if code else "no valid answer"
            raise ModbusError(f"{what}: {name}" + (f" (exception {code})" if code else ""), code)
        return rsp

    def _call(self, what: str, fn: Callable[..., Any], *args: Any, **kw: Any) -> Any:
        from pymodbus.exceptions import ModbusException

        try:
            rsp = fn(*args, device_id=self.unit, **kw)
        except ModbusException as exc:
            self.requests += 1
            raise ModbusError(f"{what}: {exc}") from None
        except OSError as exc:  # the server reset or closed the connection mid-request
            self.requests += 1
            raise ModbusError(f"{what}: connection lost ({exc.strerror or exc})") from None
        return self._check(rsp, what)

    def read(self, addr: int, count: int) -> list[int]:
        """FC03: ``count`` registers from ``addr``."""
        rsp = self._call(f"read {count} at {addr:#06x}", self._client.read_holding_registers,
                         addr, count=count)
        return list(rsp.registers)

    def write(self, addr: int, values: list[int]) -> None:
        """FC16 (FC06 for a single register)."""
        vals = [_u16(v) for v in values]
        if len(vals) == 1:
            self._call(f"write {addr:#06x}", self._client.write_register, addr, vals[0])
        else:
            self._call(f"write {len(vals)} at {addr:#06x}", self._client.write_registers,
                       addr, vals)

    def write_read(self, waddr: int, values: list[int], raddr: int, count: int) -> list[int]:
        """FC23: write ``values`` at ``waddr``, then read ``count`` from ``raddr``."""
        rsp = self._call("write/read", self._client.readwrite_registers, read_address=raddr,
                         read_count=count, write_address=waddr,
                         values=[_u16(v) for v in values])
        return list(rsp.registers)

    # -- 32-bit values
    def pack32(self, value: int) -> list[int]:
        """Two registers for an (unsigned or signed) 32-bit value in the word order."""
        u = value & 0xFFFFFFFF
        hi, lo = u >> 16, u & 0xFFFF
        return [hi, lo] if self.word_order == WORD_ORDER_HIGH_FIRST else [lo, hi]

    def unpack32(self, regs: list[int]) -> int:
        """Unsigned 32-bit value from two registers in the word order."""
        hi, lo = (regs[0], regs[1]) if self.word_order == WORD_ORDER_HIGH_FIRST else (regs[1], regs[0])
        return (hi << 16) | lo

    def read32(self, addr: int) -> int:
        return self.unpack32(self.read(addr, 2))

    # -- blocks
    def identity(self) -> Identity:
        r = self.read(REG["ID_BASE"], COUNT["ID"])

        def u32(a: str) -> int:
            return self.unpack32(r[REG[a]:REG[a] + 2])

        return Identity(
            regmap=r[REG["ID_REGMAP"]],
            lib_version=f"{r[3]}.{r[4]}.{r[5]}",
            table_format=f"{r[6]}.{r[7]}",
            word_order="high" if self.word_order == WORD_ORDER_HIGH_FIRST else "low",
            model_crc=u32("ID_MODEL_CRC"), model_size=u32("ID_MODEL_SIZE"),
            pending_crc=u32("ID_PENDING_CRC"), staging_max=u32("ID_STAGING_MAX"),
            model_features=r[REG["ID_MODEL_FEATURES"]], max_clients=r[REG["ID_MAX_CLIENTS"]])

    def status(self) -> Status:
        s = self.read(REG["ST_BASE"], COUNT["ST"])
        u = self.read(REG["UP_BASE"], COUNT["UP"])
        base = REG["ST_BASE"]

        def u32(name: str) -> int:
            a = REG[name] - base
            return self.unpack32(s[a:a + 2])

        names = ["cycles", "requests", "exceptions", "uploads_ok", "uploads_rejected",
                 "invalid_inputs", "stale_events", "limit_trips", "rate_limited",
                 "model_swaps", "clients_refused"]
        return Status(
            state=COMP_STATES.get(s[0], str(s[0])), flags=s[1], clients=s[2],
            upload_open=bool(s[3]),
            counters={n: u32("ST_" + n.upper()) for n in names},
            last_exception=s[REG["ST_LAST_EXCEPTION"] - base],
            upload_session=u[REG["UP_SESSION"] - REG["UP_BASE"]],
            upload_result=_i16(u[REG["UP_RESULT"] - REG["UP_BASE"]]),
            upload_filled=self.unpack32(u[4:6]))

    # -- the cycle
    def cycle(self, pos_nm: tuple[int, int, int], cycle: int,
              dir: tuple[int, int, int] = (0, 0, 0),
              temp_cdegc: tuple[int, int, int] = (2000, 2000, 2000),
              axis_fault: int = 0) -> CycleOutput:
        """One compensation cycle with FC23: write positions (nm), direction
        (-1/0/+1), temperatures (0.01 degC), fault mask and the cycle counter (the
        trigger), read the outputs."""
        w: list[int] = []
        for p in pos_nm:
            w += self.pack32(int(p))
        w += [_u16(int(d)) for d in dir] + [_u16(int(t)) for t in temp_cdegc]
        w += [axis_fault & 0xFFFF, cycle & 0xFFFF]
        r = self.write_read(REG["IN_BASE"], w, REG["OUT_BASE"], COUNT["OUT"])
        corr = tuple(_i32(self.unpack32(r[2 * j:2 * j + 2])) for j in range(3))
        err = tuple(_i32(self.unpack32(r[6 + 2 * j:8 + 2 * j])) for j in range(3))
        return CycleOutput(corr_nm=corr, err_nm=err, flags=r[12],  # type: ignore[arg-type]
                           state=COMP_STATES.get(r[13], str(r[13])), cycle=r[14])

    def set_limits(self, warn_nm: int, limit_nm: int, rate_nm_per_cycle: int,
                   fade_cycles: int, stale_cycles: int,
                   axis_sign: tuple[int, int, int] = (1, 1, 1)) -> None:
        """Write the CT limits (one request; the compensator must be off with zero output)."""
        v = [fade_cycles, stale_cycles]
        for x in (warn_nm, limit_nm, rate_nm_per_cycle):
            for _ in range(3):
                v += self.pack32(x)
        v += [_u16(s) for s in axis_sign]
        self.write(REG["CT_FADE_CYCLES"], v)

    def enable(self, on: bool = True) -> None:
        self.write(REG["CT_ENABLE"], [1 if on else 0])

    # -- upload
    def upload(self, blob: bytes, progress: Callable[[int, int], None] | None = None,
               chunk_regs: int = MAX_WRITE_REGS) -> UploadResult:
        """Upload a table: begin, chunks into the staging area, commit (length and the
        CRC-32 of the bytes), then check the server's report.

        Raises ModbusError (busy: another client is uploading) or UploadRefused with
        the server's reason (CRC_MISMATCH, ABBE_E_MAGIC, ...), or ModbusError if the
        CRC the server reports is not the table's.
        """
        if not 1 <= chunk_regs <= MAX_WRITE_REGS:
            raise ValueError(f"chunk_regs {chunk_regs} not in 1..{MAX_WRITE_REGS}")
        n = len(blob)
        try:
            self.write(REG["UP_CMD"], [UP_CMD_BEGIN])
        except ModbusError as exc:
            if exc.exception_code == EX_BUSY:
                up = self.read(REG["UP_SESSION"], 1)[0]
                raise ModbusError(f"staging area busy: another client is uploading "
                                  f"(session {up})", EX_BUSY) from None
            raise
        session = self.read(REG["UP_SESSION"], 1)[0]
        padded = blob + (b"\0" if n % 2 else b"")
        step = 2 * chunk_regs
        if progress:
            progress(0, n)
        for off in range(0, len(padded), step):
            part = padded[off:off + step]
            regs = list(struct.unpack(f">{len(part) // 2}H", part))
            self.write(REG["STAGING"] + off // 2, regs)
            if progress:
                progress(min(off + step, n), n)
        crc = zlib.crc32(blob) & 0xFFFFFFFF
        commit_error: ModbusError | None = None
        try:
            self.write(REG["UP_COMMIT"], self.pack32(n) + self.pack32(crc))
        except ModbusError as exc:
            commit_error = exc  # the result register says why (or that a retry came late)
        up = self.read(REG["UP_BASE"], COUNT["UP"])
        result = _i16(up[REG["UP_RESULT"] - REG["UP_BASE"]])
        if up[REG["UP_SESSION"] - REG["UP_BASE"]] != session or result != 1:
            reason = result_name(result)
            rx = self.unpack32(up[10:12])
            detail = (f"; server computed CRC-32 0x{rx:08X}, sent 0x{crc:08X}"
                      if result == -101 else "")
            if commit_error is not None and result == 0:
                raise commit_error
            raise UploadRefused(f"upload refused: {reason}{detail}", result)
        model_crc = self.unpack32(up[12:14])
        want = struct.unpack_from("<I", blob, n - 4)[0] if n >= 4 else -1
        if n >= 12:
            total = struct.unpack_from("<I", blob, 8)[0]
            if 4 <= total <= n:
                want = struct.unpack_from("<I", blob, total - 4)[0]
        if model_crc != want:
            raise ModbusError(f"server reports table CRC 0x{model_crc:08X}, the file has "
                              f"0x{want:08X}")
        running = self.read32(REG["ID_MODEL_CRC"]) == model_crc and \
            self.read32(REG["ID_PENDING_CRC"]) != model_crc
        return UploadResult(session=session, size=n, model_crc=model_crc, running=running,
                            requests=self.requests)
