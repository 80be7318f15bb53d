"""Every command as a fuzz target: its argument line, the file it reads that gets mutated,
and the outputs whose promises the harness checks.

A :class:`Target` is built against a :class:`fuzzing.seeds.Workspace`; ``mutated`` is
the input file that is replaced by mutated bytes for one case (None: only the
option values are mutated), ``outputs`` the paths the command may write.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from fuzzing.seeds import Workspace


@dataclass
class Target:
    name: str
    argv: list[str]
    mutated: Path | None
    outputs: list[Path] = field(default_factory=list)
    allowed: set[int] = field(default_factory=lambda: {0, 2, 3})
    json_stdout: bool = False
    needs_clib: bool = False
    budget_s: float = 60.0


def targets(ws: Workspace, out: Path, fit_model: Path | None = None) -> list[Target]:
    """The fuzz targets; ``out`` is a folder for outputs, ``fit_model`` a blob fitted from
    the workspace's machine file (for predict / diagnose)."""
    o = lambda n: out / n  # noqa: E731
    s = [str(x) for x in (ws.machine, ws.laser, ws.ballbar, ws.dat, ws.blob, ws.table_json)]
    mach, _, _, dat, blob, tjson = s
    fit = ["fit", mach, "-o", str(o("fit")), "--no-clib-check", "--no-report", "-q"]
    t = [
        Target("table info", ["table", "info", blob], ws.blob),
        Target("table eval", ["table", "eval", blob, "100", "-200", "-100", "--dir", "1", "-1", "0"],
               ws.blob),
        Target("table from-json", ["table", "from-json", tjson, "-o", str(o("m.bin"))],
               ws.table_json, [o("m.bin")]),
        Target("table to-json", ["table", "to-json", blob, "-o", str(o("m.json"))], ws.blob,
               [o("m.json")]),
        Target("table cgen", ["table", "cgen", blob, "-o", str(o("cgen"))], ws.blob, [o("cgen")]),
        Target("iso230-2 dat", ["iso230-2", dat, "--json"], ws.dat, json_stdout=True),
        Target("iso230-2 csv", ["iso230-2", str(ws.laser), "--json"], ws.laser, json_stdout=True),
        Target("fit machine", fit, ws.machine, [o("fit")]),
        Target("fit laser", fit, ws.laser, [o("fit")]),
        Target("fit declared", ["fit", str(ws.declared_machine), "-o", str(o("fitd")),
                                "--no-clib-check", "--no-report", "-q"], ws.declared_laser,
               [o("fitd")]),
        Target("simulate", ["simulate", str(ws.spec), "-o", str(o("sim"))], ws.spec, [o("sim")],
               budget_s=120.0),
        Target("ballbar machine", ["ballbar", mach, "circle1", "--json", "--plot",
                                   str(o("bb.png"))], ws.machine, [o("bb.png")], json_stdout=True),
        Target("ballbar csv", ["ballbar", mach, "circle1", "--no-plot", "--json"], ws.ballbar,
               json_stdout=True),
        Target("diagnose iso230-2", ["diagnose", "--iso230-2", dat, "--axis", "X", "-o",
                                     str(o("diag")), "--json", str(o("diag.json")), "--no-plots",
                                     "--backend", "reference"], ws.dat,
               [o("diag"), o("diag.json")], budget_s=120.0),
        Target("upload", ["upload", "--modbus", "tcp://127.0.0.1:9", "--timeout", "0.2", "-q",
                          blob], ws.blob, allowed={0, 1, 2, 3}),
    ]
    if fit_model is not None:
        fm = str(fit_model)
        t += [
            Target("predict", ["predict", mach, "--model", fm, "--ballbar", "circle1", "--json",
                               "-o", str(o("pred"))], ws.ballbar, [o("pred")], json_stdout=True,
                   needs_clib=True),
            Target("diagnose machine", ["diagnose", mach, "--model", fm, "--ballbar", "circle1",
                                        "-o", str(o("diag2")), "--no-plots", "--backend",
                                        "reference"], ws.ballbar, [o("diag2")], budget_s=120.0),
            Target("diagnose model", ["diagnose", mach, "--model", fm, "--ballbar", "circle1",
                                      "-o", str(o("diag3")), "--no-plots", "--backend",
                                      "reference"], Path(fm), [o("diag3")], budget_s=120.0),
        ]
    return t


#: Option values to put in place of a number on an argument line.
OPTION_VALUES = ("nan", "inf", "-1", "0", "1e400", "1_0", "\u0663", "", "-0", "1e-320",
                 "99999999999999999999999", "2", "0.5", "X", "--", "-o")
