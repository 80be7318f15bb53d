"""``abbe program MACHINE.toml --test five-axis-probing | five-axis-rtest --dialect linuxcnc
-o FILE``: the part program of a five-axis campaign for LinuxCNC's trt machines
(docs/programs.md, "Five-axis programs"). The machine file is the plan: its
``[probing.NAME]`` gives the sphere and the file the program logs the trigger points
to (the file ``abbe fit`` then reads), ``[rtest.NAME]`` the sphere the R-test holds."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from abbe.errors import AbbeInputError
from abbe.formats.machine import load_machine
from abbe.formats.output import Outputs
from abbe.programs.five_axis import (ProbingProgram, probing_gcode, rtest_gcode,
                                             rtest_path)
from abbe.model.table import AXES
from abbe.sim.five_axis import probing_positions


def _section(sections: dict, name: str | None, kind: str, path: str):
    if name is not None:
        if name not in sections:
            raise AbbeInputError(f"no [{kind}.{name}] section (have: "
                                 f"{', '.join(sorted(sections)) or 'none'})", file=path,
                                 field="--name")
        return name, sections[name]
    if len(sections) != 1:
        raise AbbeInputError(f"{'no' if not sections else 'several'} [{kind}.*] sections; "
                             "choose with --name" if sections else
                             f"a {kind} program needs a [{kind}.NAME] section (the sphere)",
                             file=path, field=kind)
    return next(iter(sections.items()))


def _relative_log(file: Path, machine: Path) -> str:
    """The probing file as the program names it: relative to the machine file's folder
    (where ``abbe fit`` reads it), so the program carries no path of the computer that
    wrote it; a file outside that folder keeps its absolute path (probing_gcode refuses a
    name that cannot go into the comment)."""
    base = Path(machine).resolve().parent
    try:
        text = Path(file).resolve().relative_to(base).as_posix()
    except ValueError:
        text = str(Path(file).resolve())
    return text


def _chain_program(args: argparse.Namespace, m) -> tuple[str, str]:  # noqa: ANN001 (Machine)
    """The program of a [chain] machine (abbe.programs.chain): (text, what it holds)."""
    from abbe.programs.chain import chain_probing_gcode, chain_rtest_gcode, chain_rtest_path
    from abbe.sim.chain import sphere_plan

    chain = m.extra["chain"]
    plans = m.extra["chain_plans"]
    travel = {a: s.travel_mm for a, s in m.axes.items()}
    missing = [a for a in AXES if a not in travel]
    if missing:
        raise AbbeInputError(f"a program needs the travel of every axis: no [axes.{missing[0]}]",
                             file=str(m.path), field=f"axes.{missing[0]}")
    r = chain.rotaries
    span = [chain.travel_deg[a][1] - chain.travel_deg[a][0] for a in r]
    turn = 1 if span[1] >= span[0] else 0  # the turning axis takes --c-positions
    try:
        if args.test == "five-axis-probing":
            name, pl = _section(plans.probing, args.name, "probing", str(m.path))
            counts = [args.tilt_positions, args.tilt_positions]
            counts[turn] = args.c_positions
            pos = sphere_plan(chain, counts[0], counts[1])
            for k, a in enumerate(r):  # a full turn of a +-180 deg axis: 270 is -90
                lo, hi = chain.travel_deg[a]
                pos[:, k] = np.where(pos[:, k] > hi, pos[:, k] - 360.0, pos[:, k])
            log_file = args.log_file or _relative_log(pl.file, m.path)
            prog = ProbingProgram(pl.sphere_mm, pl.sphere_radius_mm, pl.stylus_radius_mm, pos,
                                  n_points=args.points, probe_feed=args.probe_feed,
                                  safe_z_mm=args.safe_z_mm, log_file=log_file,
                                  fit_reads=_relative_log(pl.file, m.path))
            text = chain_probing_gcode(chain, prog, pl.tip_mm, travel,
                                       f"five-axis sphere probing {name} of {m.name}, "
                                       f"{chain.name}")
            return text, (f"{len(pos)} positions x {args.points} points, LOGOPEN {log_file} "
                          f"(abbe fit reads {pl.file})")
        name, rt = _section(plans.rtest, args.name, "rtest", str(m.path))
        path = chain_rtest_path(chain, args.step_deg)
        text = chain_rtest_gcode(chain, rt.sphere_mm, rt.tip_mm, path, travel,
                                 f"five-axis R-test {name} of {m.name}, {chain.name}",
                                 feed_deg_min=args.feed, safe_z_mm=args.safe_z_mm)
        return text, f"{len(path)} path points"
    except AbbeInputError as exc:
        if exc.file is None and exc.field and not exc.field.startswith("--"):
            exc.located(file=str(m.path), line=m.line_of(exc.field))
        raise


def run_five_axis(args: argparse.Namespace) -> int:
    if args.dialect != "linuxcnc":
        raise AbbeInputError("five-axis programs are written for LinuxCNC's trt kinematics "
                             "(M428 / M429 switchkins, G38.2, LOG); other dialects are not "
                             "built yet", field="--dialect")
    with Outputs() as outs:
        out = outs.file(args.out, option="--out")
        m = load_machine(args.machine)
        spec = m.five_axis
        if spec is None and "chain_plans" in m.extra:
            text, what = _chain_program(args, m)
            out.write_text(text, encoding="utf-8")
            print(f"abbe program: wrote {args.out} ({args.test}, linuxcnc, {what})")
            return 0
        if spec is None:
            raise AbbeInputError("a five-axis program needs a machine file with [rotary] or "
                                 "[chain]", file=str(m.path), field="rotary")
        travel = {a: s.travel_mm for a, s in m.axes.items()}
        missing = [a for a in AXES if a not in travel]
        if missing:
            raise AbbeInputError(f"a program needs the travel of every axis: no [axes.{missing[0]}]",
                                 file=str(m.path), field=f"axes.{missing[0]}")
        g = spec.geometry
        try:
            if args.test == "five-axis-probing":
                name, pl = _section(spec.probing, args.name, "probing", str(m.path))
                pos = probing_positions(g, args.tilt_positions, args.c_positions, args.passes)
                log_file = args.log_file or _relative_log(pl.file, m.path)
                prog = ProbingProgram(pl.sphere_mm, pl.sphere_radius_mm, pl.stylus_radius_mm,
                                      pos, n_points=args.points, probe_feed=args.probe_feed,
                                      safe_z_mm=args.safe_z_mm, log_file=log_file,
                                      fit_reads=_relative_log(pl.file, m.path))
                datum = ("" if pl.datum_u_um is None else
                         f", a datum sphere: its place declared to {pl.datum_u_um:g} um")
                text = probing_gcode(g, prog, travel, f"five-axis sphere probing {name} of "
                                     f"{m.name}, {g.kind}{datum}")
                what = (f"{len(pos)} positions x {args.points} points, LOGOPEN {log_file} "
                        f"(abbe fit reads {pl.file})")
            else:
                name, rt = _section(spec.rtest, args.name, "rtest", str(m.path))
                path = rtest_path(g, args.step_deg)
                text = rtest_gcode(g, rt.sphere_mm, path, travel,
                                   f"five-axis R-test {name} of {m.name}, {g.kind}",
                                   feed_deg_min=args.feed, safe_z_mm=args.safe_z_mm)
                what = f"{len(path)} path points"
        except AbbeInputError as exc:
            if exc.file is None and exc.field and not exc.field.startswith("--"):
                exc.located(file=str(m.path), line=m.line_of(exc.field))
            raise
        out.write_text(text, encoding="utf-8")
    print(f"abbe program: wrote {args.out} ({args.test}, linuxcnc, {what})")
    return 0
