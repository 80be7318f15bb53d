"""``abbe upload`` and ``abbe modbus-status``: a table to a Modbus server, and its state.

* ``upload --modbus tcp://HOST:PORT MODEL.bin`` (or ``rtu:/dev/ttyX:BAUD[:E81]``):
  checks the table locally, uploads it in chunks with progress, commits it with
  its length and CRC-32 and verifies the table CRC the server reports;
* ``modbus-status --modbus URL``: identity (versions, running and queued table
  CRC) and status (compensator state, flags, counters, last upload).

Exit status: 0 done, 1 the server refused or could not be reached, 2 bad input.
Register map: docs/modbus-registers.md.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from abbe.cli.conventions import examples
from abbe.errors import AbbeInputError
from abbe.cli.options import in_range, int_range
from abbe.formats.blob import blob_crc, read_blob_file
from abbe.model.table import feature_names
from abbe.ports.modbus_client import (
    REGMAP_VERSION,
    ModbusError,
    ModbusLink,
    flag_names,
    parse_endpoint,
    result_name,
)


def _add_endpoint(p: argparse.ArgumentParser) -> None:
    p.add_argument("--modbus", required=True, metavar="URL",
                   help="tcp://HOST:PORT or rtu:DEVICE:BAUD[:PDS] (e.g. rtu:/dev/ttyUSB0:115200:E81)")
    p.add_argument("--unit", type=int_range(0, 247), default=1,
                   help="Modbus unit id, 0..247 (default 1)")
    p.add_argument("--timeout", type=in_range(0.0, 600.0, "s", lo_open=True), default=3.0,
                   metavar="S", help="response timeout in seconds, (0, 600] (default 3)")


def register(subparsers: argparse._SubParsersAction) -> None:
    up = subparsers.add_parser("upload", help="upload a table to a drive or gateway (Modbus)",
                               description=__doc__.splitlines()[0],
                               epilog=examples("abbe upload --modbus tcp://127.0.0.1:1502 "
                                               "fit-out/model.bin",
                                               "abbe upload --modbus rtu:/dev/ttyUSB0:115200 "
                                               "fit-out/model.bin"))
    _add_endpoint(up)
    up.add_argument("model", type=Path, help="the table (model.bin)")
    up.add_argument("--chunk", type=int_range(1, 123), default=123, metavar="REGS",
                    help="registers per write request, 1..123 (default 123)")
    up.add_argument("-q", "--quiet", action="store_true", help="no progress display")
    up.set_defaults(func=run_upload)

    st = subparsers.add_parser("modbus-status", help="identity and status of a Modbus server",
                               epilog=examples("abbe modbus-status --modbus tcp://127.0.0.1:1502"))
    _add_endpoint(st)
    st.set_defaults(func=run_status)


def _link(args: argparse.Namespace) -> ModbusLink:
    if not 0 <= args.unit <= 247:
        raise AbbeInputError(f"unit id {args.unit} not in 0..247", field="unit")
    return ModbusLink(parse_endpoint(args.modbus, unit=args.unit), timeout_s=args.timeout)


def _progress(quiet: bool):  # type: ignore[no-untyped-def]
    tty = sys.stderr.isatty()
    shown = {"last": -1}

    def show(done: int, total: int) -> None:
        if quiet:
            return
        pct = 100 * done // total if total else 100
        if tty:
            print(f"\rupload: {done}/{total} bytes ({pct}%)", end="", file=sys.stderr, flush=True)
            if done >= total:
                print(file=sys.stderr)
        elif pct // 25 != shown["last"]:  # logs: 0, 25, 50, 75, 100 %
            shown["last"] = pct // 25
            print(f"upload: {done}/{total} bytes ({pct}%)", file=sys.stderr, flush=True)

    return show


def run_upload(args: argparse.Namespace) -> int:
    path: Path = args.model
    data, _ = read_blob_file(path)  # the server would refuse a bad table: say why here
    total = int.from_bytes(data[8:12], "little")
    data = data[:total]
    if not 1 <= args.chunk <= 123:
        raise AbbeInputError(f"{args.chunk} not in 1..123", field="chunk")
    link = _link(args)
    t0 = time.monotonic()
    try:
        with link:
            ident = link.identity()
            if ident.regmap != REGMAP_VERSION:
                print(f"abbe upload: error: server register map version {ident.regmap}, "
                      f"this tool speaks {REGMAP_VERSION}", file=sys.stderr)
                return 1
            if not ident.table_format.startswith("1."):
                print(f"abbe upload: error: server reads table format {ident.table_format}, "
                      "the file is 1.0", file=sys.stderr)
                return 1
            if len(data) > ident.staging_max:
                print(f"abbe upload: error: {len(data)} bytes exceed the server's staging area "
                      f"({ident.staging_max} bytes)", file=sys.stderr)
                return 1
            res = link.upload(data, progress=_progress(args.quiet), chunk_regs=args.chunk)
    except ModbusError as exc:
        print(f"abbe upload: error: {exc}", file=sys.stderr)
        return 1
    dt = time.monotonic() - t0
    where = "running" if res.running else "queued: takes effect at the next cycle"
    print(f"{path}: {res.size} bytes in {res.requests} requests, {dt:.2f} s; server reports "
          f"table CRC-32 0x{res.model_crc:08X} = file 0x{blob_crc(data):08X} ({where}), "
          f"session {res.session}")
    return 0


def run_status(args: argparse.Namespace) -> int:
    link = _link(args)
    try:
        with link:
            ident = link.identity()
            st = link.status()
    except ModbusError as exc:
        print(f"abbe modbus-status: error: {exc}", file=sys.stderr)
        return 1
    crc = f"0x{ident.model_crc:08X}" if ident.model_crc else "none"
    pending = f"0x{ident.pending_crc:08X}" if ident.pending_crc else "none"
    feats = ", ".join(feature_names(ident.model_features)) or "none"
    c = st.counters
    lines = [
        f"server: abbe {ident.lib_version}, table format {ident.table_format}, "
        f"register map {ident.regmap}, word order {ident.word_order} word first",
        f"model: CRC-32 {crc}, {ident.model_size} bytes, features {feats}; queued {pending}",
        f"staging area: {ident.staging_max} bytes; clients {st.clients}/{ident.max_clients}",
        f"compensator: {st.state}, flags 0x{st.flags:04X} " + (" ".join(flag_names(st.flags)) or "-"),
        f"counters: cycles {c['cycles']}, requests {c['requests']}, exceptions {c['exceptions']}, "
        f"invalid inputs {c['invalid_inputs']}, stale events {c['stale_events']}, "
        f"limit trips {c['limit_trips']}, rate limited {c['rate_limited']}, "
        f"model swaps {c['model_swaps']}, clients refused {c['clients_refused']}",
        f"uploads: {c['uploads_ok']} ok, {c['uploads_rejected']} rejected; session "
        f"{st.upload_session} " + ("open, " + f"{st.upload_filled} bytes received"
                                   if st.upload_open else f"last result {result_name(st.upload_result)}"),
    ]
    if st.last_exception:
        lines.append(f"last exception: function 0x{st.last_exception >> 8:02X} "
                     f"code {st.last_exception & 0xFF}")
    print("\n".join(lines))
    return 0
