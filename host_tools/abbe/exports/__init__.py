"""Exports of an abbe table to controllers' native compensation formats.

One module per target (``TARGETS``); the shared machinery: the work volume and
circles (:mod:`.volume`), the model as per-axis functions and named parts
(:mod:`.terms`), grid choice (:mod:`.grids`), the target interface and the "not
held" report (:mod:`.target`), the residual (:mod:`.residual`). docs/exports.md
describes every target with its sources.
"""

from __future__ import annotations

import importlib
import json
from pathlib import Path
from types import ModuleType
from typing import Any

from abbe.exports.target import Context, Export, parse_options
from abbe.exports.volume import work_volume

#: target name -> module (in help order).
TARGETS: dict[str, str] = {
    "isg-csv": "abbe.exports.isg_csv",
    "sinumerik-lec": "abbe.exports.sinumerik_lec",
    "sinumerik-cec": "abbe.exports.sinumerik_cec",
    "heidenhain-com": "abbe.exports.heidenhain_com",
    "fanuc-pitch": "abbe.exports.fanuc_pitch",
    "klipper-skew": "abbe.exports.klipper_skew",
    "klipper-twist": "abbe.exports.klipper_twist",
    "marlin": "abbe.exports.marlin",
    "rrf-m556": "abbe.exports.rrf_m556",
    "linuxcnc-comp": "abbe.exports.linuxcnc_comp",
    "linuxcnc-matrixkins": "abbe.exports.linuxcnc_matrixkins",
}
#: five-axis targets (rotary geometry of a format 1.2 table; :mod:`.five_axis`).
FIVE_AXIS_TARGETS: dict[str, str] = {
    "linuxcnc-trt": "abbe.exports.linuxcnc_trt",
    "grblhal-rtcp-ac": "abbe.exports.grblhal_rtcp",
    "sinumerik-carr": "abbe.exports.sinumerik_carr",
    "isg-kin91": "abbe.exports.isg_kin91",
}

#: kinematic-chain targets (a fitted ``[chain]``: abbe fit's chain_fit.json; :mod:`.chain_kins`).
CHAIN_TARGETS: dict[str, str] = {
    "linuxcnc-5axiskins": "abbe.exports.linuxcnc_5axiskins",
    "linuxcnc-maxkins": "abbe.exports.linuxcnc_maxkins",
    "linuxcnc-xyzab-tdr": "abbe.exports.linuxcnc_xyzab_tdr",
}

RESIDUAL_FILE = "residual.json"


def target_module(name: str) -> ModuleType:
    """The module of target ``name`` (KeyError if unknown)."""
    for table in (TARGETS, FIVE_AXIS_TARGETS):
        if name in table:
            return importlib.import_module(table[name])
    return importlib.import_module(CHAIN_TARGETS[name])


def run_chain_export(model: Path, target: str, options: list[str] | None = None, machine=None
                     ) -> tuple[Any, dict[str, Any]]:
    """:func:`run_export` of a kinematic-chain target: ``model`` abbe fit's chain_fit.json,
    ``machine`` the parsed ``[chain]`` machine file it was fitted from."""
    from abbe.exports.chain_kins import evaluate, load_chain_context

    mod = target_module(target)
    opts = parse_options(target, mod.OPTIONS, list(options or []))
    for k, o in mod.OPTIONS.items():  # X=..,Y=..,Z=.. values arrive as checked text
        if o.kind == "axes" and o.item == "float":
            opts[k] = {a: float(v) for a, v in opts[k].items()}
    ctx = load_chain_context(model, machine, opts)
    exp = mod.build(ctx)
    report = evaluate(ctx, exp)
    report["options"] = {k: v for k, v in opts.items()}
    return exp, report


def run_five_export(model: Path, target: str, options: list[str] | None = None, machine=None
                    ) -> tuple[Any, dict[str, Any]]:
    """:func:`run_export` of a five-axis target: ``model`` a format 1.2 table file,
    ``machine`` the parsed machine file with its ``[rotary]`` section."""
    from abbe.exports.five_axis import evaluate, load_five_context

    mod = target_module(target)
    opts = parse_options(target, mod.OPTIONS, list(options or []))
    for k, o in mod.OPTIONS.items():  # X=..,Y=..,Z=.. values arrive as checked text
        if o.kind == "axes" and o.item == "float":
            opts[k] = {a: float(v) for a, v in opts[k].items()}
    ctx = load_five_context(model, machine, opts)
    exp = mod.build(ctx)
    report = evaluate(ctx, exp)
    report["options"] = {k: v for k, v in opts.items()}
    return exp, report


def run_export(table, target: str, options: list[str] | None = None, machine=None,
               model_source: str = "") -> tuple[Export, dict[str, Any]]:
    """Build ``target`` for ``table`` and evaluate its residual.

    Returns the export (files in memory) and the residual report; nothing is
    written. ``options``: ``NAME=VALUE`` strings (``--set``).
    """
    from abbe.exports.residual import evaluate

    mod = target_module(target)
    opts = parse_options(target, mod.OPTIONS, list(options or []))
    ctx = Context(table=table, volume=work_volume(table, machine), options=opts,
                  model_source=model_source)
    exp = mod.build(ctx)
    report = evaluate(ctx, exp)
    report["options"] = {k: v for k, v in opts.items()}
    return exp, report


def files_to_write(out_dir: Path, exp: Export, report: dict[str, Any]) -> dict[Path, bytes]:
    """Every output file (the target's and residual.json) by its path. The names are
    plain file names (a target's options cannot name a path); residual.json is strict
    JSON (a NaN or Infinity would be a bug: ValueError)."""
    files: dict[Path, bytes] = {}
    for name, data in exp.files.items():
        if not name or name in (".", "..", RESIDUAL_FILE) or "/" in name or "\\" in name \
                or "\0" in name:
            raise ValueError(f"export {exp.target}: not a plain output file name: {name!r}")
        files[out_dir / name] = data
    files[out_dir / RESIDUAL_FILE] = (json.dumps(report, indent=2, allow_nan=False)
                                      + "\n").encode()
    return files


def write_files(staging: Path, exp: Export, report: dict[str, Any]) -> None:
    """Write the export into ``staging`` (the folder :class:`abbe.formats.output.Outputs`
    gave for OUT)."""
    for path, data in files_to_write(staging, exp, report).items():
        path.write_bytes(data)
