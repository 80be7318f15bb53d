"""The ``abbe`` command line: one sub-command per module in COMMANDS.

Each command module exposes ``register(subparsers)`` which adds its parser and
sets ``func`` (taking the parsed args, returning an exit status).

Exit statuses (docs/formats.md, "Exit statuses"): 0 done; 2 bad input or usage
(``FILE:LINE: field 'F': message``, nothing written); 3 the C library is not
built; 4 the C library and the reference disagree (``abbe fit``); 1 a port's
server refused or could not be reached; 70 an internal error -- a bug: one line
on stderr naming a log file with the traceback (:func:`abbe.cli.guard.run_guarded`);
130 interrupted.
"""

from __future__ import annotations

import argparse
import importlib
import sys

from abbe import __version__
from abbe.cli import conventions
from abbe.cli.conventions import examples

# Modules providing sub-commands, in help order.
COMMANDS: list[str] = [
    "abbe.cli.table",
    "abbe.cli.iso230_2",
    "abbe.cli.fit",
    "abbe.cli.simulate",
    "abbe.cli.ballbar",
    "abbe.cli.diagnose",
    "abbe.cli.predict",
    "abbe.cli.program",
    "abbe.cli.export",
    "abbe.cli.import_cmd",
    "abbe.cli.demo",
    "abbe.cli.modbus",
    "abbe.cli.history",
    "abbe.cli.thermal",
    "abbe.cli.printer",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="abbe", description="abbe: measure, model and compensate the geometric and "
        "thermal errors of machine tools -- three-axis machines, five-axis trunnions "
        "(table-table A/C, B/C), printers and routers -- from laser, ballbar, probing, "
        "R-test and thermal records (ISO 230-2/-3/-4/-7), with each result's uncertainty, "
        "and write the tables a C library applies in the controller (LinuxCNC, grblHAL, "
        "Klipper, CAN and Modbus drives) or a controller's own compensation format. "
        "Every command that evaluates writes an output folder (-o DIR) that abbe history "
        "add reads; --json FILE writes its JSON document, --json - prints it (docs/cli.md). "
        "Exit status: 0 success, 1 a device or server refused, "
        "2 bad input, 3 C library missing, 4 C library and reference disagree, "
        "70 internal error (a bug: the message names a log file) "
        "(docs/formats.md, \"Exit status\").",
        epilog=examples("abbe demo -o abbe-demo", "abbe demo --five-axis -o abbe-demo5",
                        "abbe fit MACHINE.toml -o fit-out",
                        "abbe iso230-2 x.csv --machine MACHINE.toml --axis X -o iso-x",
                        "abbe thermal fit MACHINE.toml -o thermal-out",
                        "abbe COMMAND --help"))
    parser.add_argument("--version", action="version", version=f"abbe {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMANDS:
        importlib.import_module(name).register(sub)
    return conventions.apply(parser)


def main(argv: list[str] | None = None) -> int:
    from abbe.cli.guard import run_guarded

    parser = build_parser()
    args = conventions.clean(parser.parse_args(argv))
    return run_guarded(f"abbe {args.command}", lambda: int(args.func(args) or 0), argv)


if __name__ == "__main__":
    sys.exit(main())
