"""``abbe program MACHINE --test T [--axis A | --plane P] --dialect D -o FILE``: the part
program of a measurement (docs/programs.md)."""

from __future__ import annotations

import argparse

from abbe.cli.conventions import examples
from abbe.cli.options import in_range, int_range
from abbe.errors import AbbeInputError
from abbe.formats.machine import load_machine
from abbe.formats.output import Outputs
from abbe.programs.dialects import DIALECTS, render
from abbe.programs.five_axis import FIVE_AXIS_TESTS
from abbe.programs.plan import SEQUENCES, TESTS, ballbar_program, line_program
from abbe.programs.thermal import DEFAULT_SPEEDS_RPM, THERMAL_TESTS, spindle_program
from abbe.model.geometry import PLANES
from abbe.model.table import AXES


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "program", help="write the part program of a measurement (ISO 230-2, lines, ballbar; "
                        "five-axis sphere probing and R-test)",
        description="Write the part program for a test of the machine file: ISO 230-2 "
                    "positioning of an axis (targets per ISO 230-2, not evenly spaced; "
                    "overrun; a dwell at each target; bidirectional runs; linear or pendulum "
                    "sequence), a straightness or angular line (the same motion), or a ballbar "
                    "circle (feed-in and feed-out arcs, CCW then CW, the machine file's feed "
                    "and radius). Positions in machine coordinates, mm (docs/programs.md).",
        epilog=examples("abbe program MACHINE.toml --test positioning --axis X "
                        "--dialect linuxcnc -o x_iso230.ngc",
                        "abbe program MACHINE.toml --test ballbar --plane XY --dialect fanuc "
                        "-o O0001.nc"))
    p.add_argument("machine", help="machine file (TOML)")
    p.add_argument("--test", required=True, choices=TESTS + FIVE_AXIS_TESTS + THERMAL_TESTS)
    g = p.add_mutually_exclusive_group()
    g.add_argument("--axis", choices=AXES, help="the line's axis ([laser.A] of the machine file)")
    g.add_argument("--plane", choices=PLANES, help="the ballbar test's plane ([ballbar.*])")
    p.add_argument("--name", help="the [ballbar.NAME] section when several share the plane; "
                   "five-axis: the [probing.NAME] / [rtest.NAME] section")
    p.add_argument("--dialect", required=True, choices=DIALECTS)
    p.add_argument("-o", "--out", required=True, help="program file to write")
    p.add_argument("--feed", type=in_range(1.0, 100000.0, "mm/min"), default=1000.0,
                   help="feed of the line tests, mm/min; of the five-axis R-test's rotary "
                        "moves, deg/min (default 1000)")
    p.add_argument("--dwell-s", type=in_range(0.0, 600.0, "s"), default=4.0,
                   help="dwell at each target for the capture, s (default 4)")
    p.add_argument("--overrun-mm", type=in_range(0.0, 100.0, "mm"), default=5.0,
                   help="overrun past the end targets (and each side in a pendulum), mm (5)")
    p.add_argument("--runs", type=int_range(1, 20), default=5,
                   help="bidirectional runs (ISO 230-2: 5)")
    p.add_argument("--sequence", choices=SEQUENCES, default="linear")
    p.add_argument("--targets", type=int_range(2, 1000), default=None,
                   help="targets (default: ISO 230-2, >= 5 per metre and >= 5)")
    p.add_argument("--seed", type=int_range(0, 2**31 - 1), default=0,
                   help="seed of the targets' random offsets (default 0)")
    p.add_argument("--feed-arc-deg", type=in_range(1.0, 180.0, "deg"), default=45.0,
                   help="ballbar feed-in and feed-out arcs, deg (default 45)")
    p.add_argument("--pause-s", type=in_range(0.0, 600.0, "s"), default=2.0,
                   help="ballbar pause between the CCW and the CW run, s (default 2)")
    p.add_argument("--tilt-positions", type=int_range(1, 50), default=4,
                   help="five-axis probing: tilt positions, over 80 %% of its travel (4)")
    p.add_argument("--c-positions", type=int_range(1, 72), default=8,
                   help="five-axis probing: C positions round its travel (8)")
    p.add_argument("--passes", type=int_range(1, 4), default=1,
                   help="five-axis probing: runs of the grid; 2 = the diagnosis plan (the grid "
                        "again backwards, C half a step on: a drift is told from the geometry "
                        "and C seen at twice the angles; `abbe diagnose`) (1)")
    p.add_argument("--points", type=int_range(4, 25), default=5,
                   help="five-axis probing: points per sphere (the pole and a ring; 5)")
    p.add_argument("--probe-feed", type=in_range(1.0, 5000.0, "mm/min"), default=100.0,
                   help="five-axis probing: the G38.2 feed, mm/min (100)")
    p.add_argument("--safe-z-mm", type=in_range(5.0, 500.0, "mm"), default=50.0,
                   help="five-axis: the safe height above the highest place the sphere takes "
                        "(probing) or above the ball (R-test), mm (50)")
    p.add_argument("--log-file", metavar="PATH",
                   help="five-axis probing: the file LOGOPEN names, as given (LinuxCNC opens a "
                        "relative path in its configuration folder, the INI file's); default: "
                        "the [probing.NAME] file relative to the machine file's folder")
    p.add_argument("--step-deg", type=in_range(0.5, 90.0, "deg"), default=10.0,
                   help="five-axis R-test: angle step of the path, deg (10)")
    p.add_argument("--speeds", type=_speeds, default=list(DEFAULT_SPEEDS_RPM),
                   help="iso230-3-spindle: the speeds, rpm, comma-separated "
                        "(default 1250,2500,3750,5000,3500)")
    p.add_argument("--on-h", type=in_range(0.001, 100.0, "h"), default=4.0,
                   help="iso230-3-spindle: hours at each speed (4)")
    p.add_argument("--off-h", type=in_range(0.0, 100.0, "h"), default=4.0,
                   help="iso230-3-spindle: hours stopped after each speed (4)")
    p.add_argument("--reading-s", type=in_range(1.0, 3600.0, "s"), default=60.0,
                   help="iso230-3-spindle: the reading interval, s (60)")
    p.set_defaults(func=run)


def _speeds(text: str) -> list[float]:
    """argparse type: comma-separated speeds, each in [1, 100000] rpm, at most 100."""
    parts = text.split(",")
    if len(parts) > 100:
        raise argparse.ArgumentTypeError(f"{len(parts)} speeds: at most 100")
    one = in_range(1.0, 100000.0, "rpm")
    return [one(v) for v in parts]


def run(args: argparse.Namespace) -> int:
    if args.test in THERMAL_TESTS:
        return _run_thermal(args)
    if args.test in FIVE_AXIS_TESTS:
        from abbe.cli.program_five_axis import run_five_axis
        return run_five_axis(args)
    with Outputs() as outs:
        out = outs.file(args.out, option="--out")
        m = load_machine(args.machine)
        travel = {a: s.travel_mm for a, s in m.axes.items()}
        missing = [a for a in AXES if a not in travel]
        if missing:
            raise AbbeInputError(f"a program needs the travel of every axis: no [axes.{missing[0]}]",
                                 file=str(m.path), field=f"axes.{missing[0]}")
        try:
            if args.test == "ballbar":
                if args.axis:
                    raise AbbeInputError("a ballbar test is chosen with --plane (and --name)",
                                         field="--axis")
                cands = {n: b for n, b in m.ballbar.items()
                         if (args.plane is None or b.plane == args.plane)
                         and (args.name is None or n == args.name)}
                if len(cands) != 1:
                    what = "no" if not cands else "several"
                    raise AbbeInputError(
                        f"{what} [ballbar.*] sections match (plane {args.plane or 'any'}, name "
                        f"{args.name or 'any'}): {', '.join(sorted(m.ballbar)) or 'none'}; "
                        "choose with --plane / --name", file=str(m.path), field="ballbar")
                name, bt = next(iter(cands.items()))
                prog = ballbar_program(name, bt.plane, bt.center_mm, bt.radius_mm,
                                       bt.feed_mm_min, travel, feed_arc_deg=args.feed_arc_deg,
                                       pause_s=args.pause_s)
            else:
                if not args.axis:
                    raise AbbeInputError(f"--test {args.test} needs --axis", field="--axis")
                if args.axis not in m.laser:
                    raise AbbeInputError(f"no [laser.{args.axis}] section: the program takes the "
                                         "line's ends (start_mm, end_mm) from it",
                                         file=str(m.path), field=f"laser.{args.axis}")
                line = m.laser[args.axis]
                prog = line_program(args.test, args.axis, line.start_mm, line.end_mm, travel,
                                    feed=args.feed, dwell_s=args.dwell_s,
                                    overrun_mm=args.overrun_mm, runs=args.runs,
                                    sequence=args.sequence, n_targets=args.targets,
                                    seed=args.seed)
        except AbbeInputError as exc:
            if exc.file is None and exc.field and not exc.field.startswith("--"):
                exc.located(file=str(m.path), line=m.line_of(exc.field))
            raise
        prog.params = {"machine": m.name, "dialect": args.dialect, **prog.params}
        out.write_text(render(prog, args.dialect), encoding="utf-8")
    print(f"abbe program: wrote {args.out} ({prog.title}, {args.dialect}, "
          f"{len(prog.steps)} steps)")
    return 0


def _run_thermal(args: argparse.Namespace) -> int:
    with Outputs() as outs:
        out = outs.file(args.out, option="--out")
        m = load_machine(args.machine)
        prog = spindle_program(args.speeds, args.on_h * 3600.0, args.off_h * 3600.0,
                               args.reading_s, m.reference_mm)
        prog.params = {"machine": m.name, "dialect": args.dialect, **prog.params}
        out.write_text(render(prog, args.dialect), encoding="utf-8")
    print(f"abbe program: wrote {args.out} ({prog.title}, {args.dialect}, "
          f"{len(prog.steps)} steps)")
    return 0
