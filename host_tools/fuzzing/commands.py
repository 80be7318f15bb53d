"""Every command as a fuzz target: its argument line, the file it reads that gets mutated,
and the outputs whose promises the harness checks.

A :class:`Target` is built against a :class:`fuzzing.seeds.Workspace`; ``mutated`` is
the input file that is replaced by mutated bytes for one case (None: only the
option values are mutated), ``outputs`` the paths the command may write.
"""

from __future__ import annotations

import re
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
    #: every number of the mutated file is data: one replaced by a hostile number
    #: (fuzzing.mutate.replace_number) must make the command refuse it (exit 2)
    hostile_numbers: bool = False


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
        Target("iso230-2 dat", ["iso230-2", dat, "--json", "-"], ws.dat, json_stdout=True),
        Target("iso230-2 csv", ["iso230-2", str(ws.laser), "--json", "-"], ws.laser, json_stdout=True,
               hostile_numbers=True),
        Target("fit machine", fit, ws.machine, [o("fit")]),
        Target("fit laser", fit, ws.laser, [o("fit")], hostile_numbers=True),
        Target("fit declared", ["fit", str(ws.declared_machine), "-o", str(o("fitd")),
                                "--no-clib-check", "--no-report", "-q"], ws.declared_laser,
               [o("fitd")]),
        Target("simulate", ["simulate", str(ws.spec), "-o", str(o("sim"))], ws.spec, [o("sim")],
               budget_s=120.0),
        Target("ballbar machine", ["ballbar", mach, "circle1", "--json", "-", "--plot",
                                   str(o("bb.png"))], ws.machine, [o("bb.png")], json_stdout=True),
        Target("ballbar csv", ["ballbar", mach, "circle1", "--no-plot", "--json", "-"], ws.ballbar,
               json_stdout=True, hostile_numbers=True),
        Target("diagnose iso230-2", ["diagnose", "--iso230-2", dat, "--axis", "X", "-o",
                                     str(o("diag")), "--json", str(o("diag.json")), "--no-plots",
                                     "--backend", "reference"], ws.dat,
               [o("diag"), o("diag.json")], budget_s=120.0),
        Target("upload", ["upload", "--modbus", "tcp://127.0.0.1:9", "--timeout", "0.2", "-q",
                          blob], ws.blob, allowed={0, 1, 2, 3}),
        Target("iso230-2 rtl", ["iso230-2", str(ws.rtl), "--json", "-"], ws.rtl, json_stdout=True,
               hostile_numbers=True),
        Target("fit rtl", ["fit", str(ws.renishaw_machine), "-o", str(o("fitr")),
                           "--no-clib-check", "--no-report", "-q"], ws.rtl, [o("fitr")],
               hostile_numbers=True),
        Target("ballbar b5r", ["ballbar", str(ws.renishaw_machine), "circle1", "--no-plot",
                               "--json", "-"], ws.b5r, json_stdout=True, hostile_numbers=True),
        Target("program positioning", ["program", mach, "--test", "positioning", "--axis", "X",
                                       "--dialect", "fanuc", "-o", str(o("p.nc"))], ws.machine,
               [o("p.nc")]),
        Target("program ballbar", ["program", mach, "--test", "ballbar", "--plane", "XY",
                                   "--dialect", "heidenhain", "-o", str(o("bb.h"))], ws.machine,
               [o("bb.h")]),
        Target("ballbar renishaw machine", ["ballbar", str(ws.renishaw_machine), "circle1",
                                            "--no-plot"], ws.renishaw_machine),
    ]
    if ws.rtl_windows is not None and ws.b5r_ballbar20 is not None:
        # The independent writer's shapes: a cp1250 .rtl with an EQUIPMENT:: section, a
        # Ballbar 20-layout .b5r (text numbers outside the data: no hostile-number rule).
        t += [
            Target("iso230-2 rtl cp1250", ["iso230-2", str(ws.rtl_windows), "--json", "-"],
                   ws.rtl_windows, json_stdout=True),
            Target("iso230-2 rtl declared", ["iso230-2", str(ws.rtl_windows), "--encoding",
                                             "cp1252", "--json", "-"], ws.rtl_windows,
                   json_stdout=True),
            Target("ballbar b5r ballbar20", ["ballbar", str(ws.renishaw20_machine), "circle1",
                                             "--no-plot", "--json", "-"], ws.b5r_ballbar20,
                   json_stdout=True),
        ]
    # Five-axis: the example trunnion's machine file (its [rotary] sections) and the probing,
    # R-test and indexer files it names, each read by `abbe fit`.
    f5 = str(ws.five_axis_machine)
    fit5 = ["fit", f5, "-o", str(o("fit5")), "--no-report", "-q"]
    t += [
        Target("fit five-axis machine", fit5, ws.five_axis_machine, [o("fit5")]),
        Target("fit five-axis probe", fit5, ws.five_axis_probe, [o("fit5")],
               hostile_numbers=True),
        Target("fit five-axis rtest", fit5, ws.five_axis_rtest, [o("fit5")],
               hostile_numbers=True),
        Target("fit five-axis indexer", fit5, ws.five_axis_indexer, [o("fit5")],
               hostile_numbers=True),
    ]  # abbe diagnose on this plan takes minutes: tests/cli/test_fuzz_five_axis.py fuzzes it
    ref = ["163.626", "-212.772", "-290.704"]

    def export(fmt: str, model: str, *extra: str) -> list[str]:
        return ["export", model, "--format", fmt, "-o", str(o(f"exp-{fmt}")), *extra]

    t += [
        Target("export isg-csv", export("isg-csv", blob, "--machine", mach), ws.blob,
               [o("exp-isg-csv")]),
        Target("export sinumerik-lec", export("sinumerik-lec", tjson, "--set", "points=64"),
               ws.table_json, [o("exp-sinumerik-lec")]),
        Target("export sinumerik-cec", export("sinumerik-cec", blob, "--machine", mach, "--set",
                                              "tables=8", "points=50"), ws.machine,
               [o("exp-sinumerik-cec")]),
        Target("export heidenhain-com", export("heidenhain-com", blob, "--set", "points=64",
                                               "axis_names=X=X,Y=Y"), ws.blob,
               [o("exp-heidenhain-com")]),
        Target("export fanuc-pitch", export("fanuc-pitch", tjson, "--machine", mach, "--set",
                                            "points=32", "reference=X=0,Y=-400,Z=-300",
                                            "--json", "-"), ws.table_json,
               [o("exp-fanuc-pitch")], json_stdout=True),
        Target("export klipper-skew", export("klipper-skew", blob), ws.blob,
               [o("exp-klipper-skew")]),
        Target("export marlin", export("marlin", tjson, "--set", "skew_z=0"), ws.table_json,
               [o("exp-marlin")]),
        Target("export linuxcnc-comp", export("linuxcnc-comp", blob, "--machine", mach, "--set",
                                              "points=100"), ws.machine, [o("exp-linuxcnc-comp")]),
        Target("export linuxcnc-matrixkins", export("linuxcnc-matrixkins", blob), ws.blob,
               [o("exp-linuxcnc-matrixkins")]),
        Target("import isg-csv", ["import", str(ws.isg_csv), "-o", str(o("imp-csv")),
                                  "--reference", *ref, "--max-points", "60"], ws.isg_csv,
               [o("imp-csv")], budget_s=120.0, hostile_numbers=True),
        Target("import isg-lis", ["import", str(ws.isg_lis), "-o", str(o("imp-lis")),
                                  "--machine", mach], ws.isg_lis, [o("imp-lis")], budget_s=120.0),
        Target("import etalon", ["import", str(ws.etalon), "-o", str(o("imp-etalon")),
                                 "--reference", *ref, "--tool-offset", "0", "0", "150",
                                 "--no-unfold"], ws.etalon, [o("imp-etalon")], budget_s=120.0,
               hostile_numbers=True),
        Target("import machine", ["import", str(ws.isg_lis), "-o", str(o("imp-machine")),
                                  "--machine", mach], ws.machine, [o("imp-machine")],
               budget_s=120.0),
    ]
    if fit_model is not None:
        fm = str(fit_model)
        fj = fit_model.with_name("model.json")  # the fit's model.json: a wrapped table
        t.append(Target("export fit-json", ["export", str(fj), "--format", "isg-csv", "-o",
                                            str(o("exp-fit-json")), "--set", "max_records=500"],
                        fj, [o("exp-fit-json")]))
        t += [
            Target("predict", ["predict", mach, "--model", fm, "--ballbar", "circle1", "--json",
                               "-", "-o", str(o("pred"))], ws.ballbar, [o("pred")], json_stdout=True,
                   needs_clib=True),
            Target("diagnose machine", ["diagnose", mach, "--model", fm, "--ballbar", "circle1",
                                        "-o", str(o("diag2")), "--no-plots", "--backend",
                                        "reference"], ws.ballbar, [o("diag2")], budget_s=120.0),
            Target("diagnose model", ["diagnose", mach, "--model", fm, "--ballbar", "circle1",
                                      "-o", str(o("diag3")), "--no-plots", "--backend",
                                      "reference"], Path(fm), [o("diag3")], budget_s=120.0),
        ]
    return t


#: Option values to put in place of a number on an argument line (or of the value of a
#: ``--set NAME=VALUE``).
OPTION_VALUES = ("nan", "inf", "-1", "0", "1e400", "1_0", "\u0663", "", "-0", "1e-320",
                 "99999999999999999999999", "2", "0.5", "X", "--", "-o", "1e9", "10001", "3.5",
                 "../x", "a b", "X=nan", "X=1,X=2", "Q=1", "\n", "\uff11")


def without_comments(data: bytes) -> bytes:
    """The seed without its ``//`` comment lines (a number in a comment is text)."""
    return b"\n".join(ln for ln in data.split(b"\n") if not ln.lstrip().startswith(b"//"))


def option_slots(argv: list[str]) -> list[int]:
    """Indices of the option values that may be replaced: numbers, and ``NAME=VALUE``
    settings (``--set``)."""
    out = []
    for i, a in enumerate(argv):
        if a.lstrip("-").replace(".", "").isdigit() and i > 0 and not argv[i - 1].startswith(
                ("-o", "--out", "--json", "--plot")):
            out.append(i)
        elif re.fullmatch(r"[a-z_]+=.+", a):
            out.append(i)
    return out


def with_option_value(argv: list[str], i: int, value: str) -> list[str]:
    """``argv`` with the option value at ``i`` replaced by ``value``."""
    a = list(argv)
    name, eq, _ = a[i].partition("=")
    a[i] = f"{name}={value}" if eq and not a[i].lstrip("-").replace(".", "").isdigit() else value
    return a
