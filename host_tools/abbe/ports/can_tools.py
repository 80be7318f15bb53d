"""Helpers for the CAN port (port/socketcan, docs/can.md): talk to ``abbe-cand``.

* :func:`pack_frame` / :func:`unpack_frame`: a python-can ``Message`` <-> one
  ``struct can_frame`` record (16 bytes, the SocketCAN layout), so a
  ``socketpair(AF_UNIX, SOCK_SEQPACKET)`` can stand in for a CAN bus;
* :class:`SocketpairBus`: start ``abbe-cand --fd N`` on one end of a socketpair
  and be the rest of the bus on the other end;
* the port's scaling between drive increments and machine positions, and the
  expected drive offsets from the float64 reference (:func:`expected_offsets`);
* :func:`decode_status` / :func:`decode_info`: the port's status and info frames
  (layout in docs/abbe.dbc).

Units: positions mm (nm where the name says so), corrections nm, offsets in
drive increments.
"""

from __future__ import annotations

import math
import os
import queue
import select
import signal
import socket
import struct
import subprocess
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import can
import numpy as np

CAN_EFF_FLAG = 0x80000000
CAN_RTR_FLAG = 0x40000000
CAN_ERR_FLAG = 0x20000000
RECORD = struct.Struct("=IB3x8s")   # struct can_frame: can_id, len, pad, res, len8_dlc, data[8]
assert RECORD.size == 16

CMD_ENABLE, CMD_DISABLE, CMD_RESET, CMD_RELOAD = 1, 2, 3, 4


def pack_frame(msg: can.Message) -> bytes:
    """python-can Message -> one struct can_frame record (native byte order, as the kernel)."""
    can_id = msg.arbitration_id
    if msg.is_error_frame:
        can_id |= CAN_ERR_FLAG
    if msg.is_extended_id:
        can_id |= CAN_EFF_FLAG
    if msg.is_remote_frame:
        can_id |= CAN_RTR_FLAG
    data = bytes(msg.data or b"")
    return RECORD.pack(can_id, msg.dlc, data.ljust(8, b"\0")[:8])


def unpack_frame(record: bytes, timestamp: float | None = None) -> can.Message:
    """One struct can_frame record -> python-can Message."""
    can_id, dlc, data = RECORD.unpack(record)
    return can.Message(
        arbitration_id=can_id & 0x1FFFFFFF, is_extended_id=bool(can_id & CAN_EFF_FLAG),
        is_remote_frame=bool(can_id & CAN_RTR_FLAG), is_error_frame=bool(can_id & CAN_ERR_FLAG),
        dlc=dlc, data=data[:min(dlc, 8)], timestamp=timestamp if timestamp is not None else 0.0)


def daemon_path() -> Path:
    """Where abbe-cand is: $ABBE_CAND, else <repo>/build/bin/abbe-cand."""
    env = os.environ.get("ABBE_CAND")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[3] / "build" / "bin" / "abbe-cand"


# --------------------------------------------------------------------------- scaling

def round_half_away(x: float) -> int:
    """Round half away from zero (the port's rounding, not Python's banker's round)."""
    return int(math.copysign(math.floor(abs(x) + 0.5), x))


def _sat32(v: int) -> int:
    return max(-2**31, min(2**31 - 1, v))


@dataclass(frozen=True)
class AxisScaling:
    """One axis' drive scaling (docs/can.md "Scaling")."""

    increments_per_mm: float
    sign: int = 1
    origin_mm: float = 0.0
    correction_sign: int = 1

    @property
    def origin_nm(self) -> int:
        return round_half_away(self.origin_mm * 1e6)

    def incr_of_mm(self, pos_mm: float) -> int:
        """Drive position (increments) of a machine position in mm."""
        return round_half_away((pos_mm - self.origin_mm) * self.increments_per_mm * self.sign)

    def nm_of_incr(self, incr: int) -> int:
        """Machine position in nm the port computes from a drive position."""
        return _sat32(round_half_away(self.origin_nm + self.sign * incr * 1e6 / self.increments_per_mm))

    def incr_of_corr(self, corr_nm: float) -> int:
        """Drive offset (increments) of a correction in nm."""
        return _sat32(round_half_away(corr_nm * self.increments_per_mm / 1e6)) * self.sign


def expected_offsets(table, axes: list[AxisScaling], incr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Float64 reference of the steady-state offsets for drive positions ``incr`` (N, 3).

    Returns (offsets in increments (N, 3) int, corrections in nm (N, 3) float):
    the port turns increments into nm, the model gives the spatial error
    (abbe.model.reference.spatial_error, no backlash/thermal), the correction is
    ``-correction_sign * error`` and the offset its rounded increments.
    """
    from abbe.model.reference import spatial_error

    incr = np.asarray(incr, dtype=np.int64).reshape(-1, 3)
    pos_mm = np.array([[axes[j].nm_of_incr(int(v)) / 1e6 for j, v in enumerate(row)] for row in incr])
    err_um = spatial_error(table, pos_mm)
    corr_nm = -np.array([a.correction_sign for a in axes]) * err_um * 1e3
    off = np.array([[axes[j].incr_of_corr(c) for j, c in enumerate(row)] for row in corr_nm], dtype=np.int64)
    return off, corr_nm


# --------------------------------------------------------------------------- status frames

@dataclass
class Status:
    """The status frame (docs/abbe.dbc ABBE_STATUS)."""

    state: int
    model_loaded: bool
    load_failed: bool
    fresh_mask: int
    flags: int
    seq: int
    age: tuple[int, int, int]
    ignored: int


@dataclass
class Info:
    """The info frame (docs/abbe.dbc ABBE_INFO)."""

    model_crc: int
    load_status: int
    model_swaps: int
    ignored: int


def decode_status(data: bytes) -> Status:
    if len(data) != 8:
        raise ValueError(f"status frame has {len(data)} bytes, expected 8")
    b0 = data[0]
    return Status(state=b0 & 3, model_loaded=bool(b0 & 4), load_failed=bool(b0 & 8),
                  fresh_mask=(b0 >> 4) & 7, flags=int.from_bytes(data[1:3], "little"), seq=data[3],
                  age=(data[4], data[5], data[6]), ignored=data[7])


def decode_info(data: bytes) -> Info:
    if len(data) != 8:
        raise ValueError(f"info frame has {len(data)} bytes, expected 8")
    return Info(model_crc=int.from_bytes(data[0:4], "little"),
                load_status=int.from_bytes(data[4:5], "little", signed=True), model_swaps=data[5],
                ignored=int.from_bytes(data[6:8], "little"))


# --------------------------------------------------------------------------- the bus

@dataclass
class Answer:
    """What the daemon sent after one SYNC."""

    frames: list[can.Message] = field(default_factory=list)

    def by_id(self, can_id: int) -> list[can.Message]:
        return [m for m in self.frames if m.arbitration_id == can_id]


class SocketpairBus:
    """abbe-cand on one end of socketpair(AF_UNIX, SOCK_SEQPACKET), the test on the other.

    The daemon gets its end with ``--fd N`` and signals readiness on ``--ready-fd M``;
    its stderr is collected line by line (:meth:`wait_log`).
    """

    def __init__(self, config: Path, daemon: Path | None = None, extra: list[str] | None = None,
                 status_id: int = 0x1F0) -> None:
        self.status_id = status_id
        self.peer, child = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        ready_r, ready_w = os.pipe()
        exe = str(daemon or daemon_path())
        args = [exe, "-c", str(config), "--fd", str(child.fileno()), "--ready-fd", str(ready_w),
                *(extra or [])]
        self.proc = subprocess.Popen(args, pass_fds=(child.fileno(), ready_w), stderr=subprocess.PIPE,
                                     stdout=subprocess.DEVNULL, text=True)
        child.close()
        os.close(ready_w)
        self.lines: list[str] = []
        self._cursor = 0
        self._q: queue.Queue[str] = queue.Queue()
        self._reader = threading.Thread(target=self._read_stderr, daemon=True)
        self._reader.start()
        ready, _, _ = select.select([ready_r], [], [], 30.0)
        got = os.read(ready_r, 16) if ready else b""
        os.close(ready_r)
        if got != b"ready\n":
            self.proc.kill()
            self.proc.wait()
            raise RuntimeError(f"abbe-cand did not start: {''.join(self.lines)}")
        self.peer.setblocking(False)
        self.wait_log("running:")   # consumes the start-up lines (model loaded, ...)

    def _read_stderr(self) -> None:
        assert self.proc.stderr is not None
        for line in self.proc.stderr:
            self._q.put(line)

    def _drain_log(self) -> None:
        while True:
            try:
                self.lines.append(self._q.get_nowait())
            except queue.Empty:
                return

    def wait_log(self, text: str, timeout: float = 10.0) -> str:
        """Wait for a stderr line containing ``text`` that no earlier call returned
        (lines before it are consumed too); returns the line."""
        end = time.monotonic() + timeout
        while True:
            self._drain_log()
            for i in range(self._cursor, len(self.lines)):
                if text in self.lines[i]:
                    self._cursor = i + 1
                    return self.lines[i]
            left = end - time.monotonic()
            if left <= 0:
                raise TimeoutError(f"no log line with {text!r}; log so far:\n{''.join(self.lines)}")
            try:
                self.lines.append(self._q.get(timeout=left))
            except queue.Empty:
                pass

    def send(self, msg: can.Message) -> None:
        self.peer.send(pack_frame(msg))

    def send_raw(self, record: bytes) -> None:
        self.peer.send(record)

    def recv_all(self, timeout: float = 0.3) -> list[can.Message]:
        """Every frame that arrives within ``timeout`` s (to check that nothing was sent)."""
        out: list[can.Message] = []
        end = time.monotonic() + timeout
        while True:
            r, _, _ = select.select([self.peer], [], [], max(0.0, end - time.monotonic()))
            if not r:
                return out
            rec = self.peer.recv(64)
            if not rec:
                return out
            out.append(unpack_frame(rec, time.monotonic()))

    def recv_cycle(self, timeout: float = 5.0) -> Answer:
        """Frames of one cycle: everything up to and including the status frame,
        which the port sends last."""
        ans = Answer()
        end = time.monotonic() + timeout
        while True:
            r, _, _ = select.select([self.peer], [], [], max(0.0, end - time.monotonic()))
            if not r:
                raise TimeoutError(f"no status frame 0x{self.status_id:03X} within {timeout} s "
                                   f"(got {len(ans.frames)} frames)")
            rec = self.peer.recv(64)
            if not rec:
                raise ConnectionError("abbe-cand closed the bus")
            msg = unpack_frame(rec, time.monotonic())
            ans.frames.append(msg)
            if msg.arbitration_id == self.status_id and not msg.is_extended_id:
                return ans

    def sync(self, counter: int | None = None) -> Answer:
        """Send a SYNC (0x080, optionally with the counter byte) and collect the cycle's frames."""
        data = b"" if counter is None else bytes([counter])
        self.send(can.Message(arbitration_id=0x080, is_extended_id=False, data=data))
        return self.recv_cycle()

    def signal(self, sig: int = signal.SIGHUP) -> None:
        self.proc.send_signal(sig)

    def close(self, timeout: float = 20.0) -> int:
        """Close the bus; the daemon exits on its own. Returns its exit status."""
        self.peer.close()
        try:
            rc = self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            rc = self.proc.wait()
        self._reader.join(5.0)
        self._drain_log()
        return rc

    def __enter__(self) -> "SocketpairBus":
        return self

    def __exit__(self, *exc: object) -> None:
        if self.proc.poll() is None:
            self.close()


def tpdo(node_id: int, incr: int, statusword: int | None = None, cob_id: int | None = None) -> can.Message:
    """A drive's position TPDO in the default layout (INT32 at byte 0), or
    statusword (UINT16, byte 0) + position (byte 2) when ``statusword`` is given."""
    pos = int(incr).to_bytes(4, "little", signed=True)
    data = pos if statusword is None else statusword.to_bytes(2, "little") + pos + b"\0\0"
    return can.Message(arbitration_id=cob_id if cob_id is not None else 0x180 + node_id,
                       is_extended_id=False, data=data)


def config_text(model_path: str, axes: list[AxisScaling], node_ids: tuple[int, int, int] = (1, 2, 3),
                extra: str = "", compensator: str = "", axis_extra: str = "") -> str:
    """A configuration file (docs/can.md) for the given axes."""
    lines = ['[bus]', 'interface = "can0"', '', '[model]', f'path = "{model_path}"', '',
             '[compensator]', compensator, '', extra, '']
    for name, nid, a in zip("XYZ", node_ids, axes):
        lines += [f"[axis.{name}]", f"node_id = {nid}", f"increments_per_mm = {a.increments_per_mm!r}",
                  f"sign = {a.sign}", f"origin_mm = {a.origin_mm!r}", f"correction_sign = {a.correction_sign}",
                  axis_extra, ""]
    return "\n".join(lines)
