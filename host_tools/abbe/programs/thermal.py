"""The ISO 230-3 spindle thermal test as a program (docs/programs.md, docs/thermal.md).

The spindle sits at the test position (the nest of displacement sensors against a test
mandrel) and runs a speed schedule: each speed for ``on_s`` seconds, then stopped for
``off_s`` seconds (the real record of third_party/spindle-thermal: 1250, 2500, 3750, 5000,
3500 rpm, 4 h on, 4 h off). The program dwells in steps of the reading interval (the data
logger reads the sensors and the temperatures at that interval; a ``Comment`` marks every
step's first reading), so a controller whose dwell is limited (Fanuc ``G04 X`` up to
9999.999 s) runs it as written.
"""

from __future__ import annotations

from abbe.errors import AbbeInputError
from abbe.programs.plan import Comment, Dwell, Move, Program, Spindle

THERMAL_TESTS: tuple[str, ...] = ("iso230-3-spindle",)
#: The shared record's schedule (rpm).
DEFAULT_SPEEDS_RPM: tuple[float, ...] = (1250.0, 2500.0, 3750.0, 5000.0, 3500.0)
MAX_SPEED_RPM = 100_000.0


def spindle_program(speeds_rpm: list[float], on_s: float, off_s: float, reading_s: float,
                    position_mm: tuple[float, float, float], feed: float = 1000.0) -> Program:
    """The schedule as a :class:`Program`: move to the test position, then per speed:
    spindle on, dwell ``on_s`` in ``reading_s`` steps, spindle off, dwell ``off_s``."""
    if not speeds_rpm:
        raise AbbeInputError("expected at least one speed", field="--speeds")
    for v in speeds_rpm:
        if not 0.0 < v <= MAX_SPEED_RPM:
            raise AbbeInputError(f"speed {v:g} rpm: expected (0, {MAX_SPEED_RPM:g}] rpm",
                                 field="--speeds")
    if reading_s > min(on_s, off_s if off_s > 0 else on_s):
        raise AbbeInputError(f"reading interval {reading_s:g} s longer than a phase",
                             field="--reading-s")
    prog = Program(title="ISO 230-3 spindle thermal test", plane="XY")
    prog.params = {"speeds_rpm": " ".join(f"{v:g}" for v in speeds_rpm), "on_s": on_s,
                   "off_s": off_s, "reading_s": reading_s}
    prog.steps.append(Comment("start the data logger: temperatures and displacements every "
                              f"{reading_s:g} s"))
    prog.steps.append(Move(tuple(float(x) for x in position_mm), feed))

    def hold(seconds: float, what: str) -> None:
        n_full, rest = divmod(seconds, reading_s)
        prog.steps.append(Comment(what))
        prog.steps.extend(Dwell(reading_s) for _ in range(int(n_full)))
        if rest > 1e-9:
            prog.steps.append(Dwell(rest))

    for k, v in enumerate(speeds_rpm):
        prog.steps.append(Spindle(v))
        hold(on_s, f"step {k + 1}: {v:g} rpm for {on_s / 3600:g} h")
        prog.steps.append(Spindle(0.0))
        if off_s > 0:
            hold(off_s, f"step {k + 1}: stopped for {off_s / 3600:g} h")
    return prog
