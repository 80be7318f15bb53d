"""Golden export files of examples/vmc500: regenerate and compare.

The golden directory holds, per model (``vmc500-fit``: ``abbe fit
examples/vmc500/machine.toml``; ``vmc500-demo``: the diagnosed model of ``abbe
demo``, ``demo-out/diagnose/model.bin``), the model itself and every target's files
(exported with ``--machine examples/vmc500/machine.toml``). They were reviewed by eye
once when written. Regenerate (after a deliberate change, then review the diff):

    cd host_tools && ../.venv/bin/python tests/exports/golden_compare.py --write

Comparison: the same files; text by tests/textnum.py (every character exactly, a number
within one unit of its last printed digit or 1e-9 relative, an integer within 1: float64
kernels differ between CPUs). residual.json is compared by its numbers with 2e-4 (its
values have 4 decimals).
"""

from __future__ import annotations

import json
import shutil
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
GOLDEN = HERE / "golden"
MACHINE = HERE.parents[2] / "examples" / "vmc500" / "machine.toml"
MODELS = ("vmc500-fit", "vmc500-demo")


def export_all(model_dir: Path, out_base: Path) -> None:
    from abbe.cli.entry import main
    from abbe.exports import TARGETS
    for t in TARGETS:
        rc = main(["export", str(model_dir / "model.bin"), "--format", t, "-o", str(out_base / t),
                   "--machine", str(MACHINE)])
        if rc != 0:
            raise SystemExit(f"export {t} failed ({rc})")


def compare_text(got: str, want: str, name: str) -> list[str]:
    """tests/textnum.py: characters exactly, numbers within one unit of the last printed
    digit (or 1e-9 relative), integers within 1."""
    from textnum import differences
    return [f"{name}: {d}" for d in differences(got, want)[:10]]


def compare_json(got, want, path: str) -> list[str]:
    if isinstance(want, dict):
        if not isinstance(got, dict) or set(got) != set(want):
            return [f"{path}: keys {sorted(got) if isinstance(got, dict) else got} != golden"]
        return [e for k in want for e in compare_json(got[k], want[k], f"{path}.{k}")]
    if isinstance(want, list):
        if not isinstance(got, list) or len(got) != len(want):
            return [f"{path}: length differs"]
        return [e for i, (g, w) in enumerate(zip(got, want)) for e in compare_json(g, w, f"{path}[{i}]")]
    if isinstance(want, bool) or not isinstance(want, (int, float)):
        if path.endswith(".model"):
            return []  # the model's path differs per run
        return [] if got == want else [f"{path}: {got!r} != golden {want!r}"]
    return [] if abs(float(got) - float(want)) <= 2e-4 + 1e-6 * abs(float(want)) else [
        f"{path}: {got} != golden {want}"]


def compare_dir(got: Path, want: Path) -> list[str]:
    gf = sorted(p.relative_to(got) for p in got.rglob("*") if p.is_file())
    wf = sorted(p.relative_to(want) for p in want.rglob("*") if p.is_file())
    if gf != wf:
        return [f"{want.name}: files {gf} != golden {wf}"]
    errs = []
    for rel in wf:
        if rel.name == "residual.json":
            errs += compare_json(json.loads((got / rel).read_text()),
                                 json.loads((want / rel).read_text()), str(rel))
        elif rel.suffix == ".bin":
            errs += compare_five_blob(got / rel, want / rel, str(rel))
        else:
            errs += compare_text((got / rel).read_text(), (want / rel).read_text(), str(rel))
    return errs


def compare_five_blob(got: Path, want: Path, name: str) -> list[str]:
    """A five-axis table by its decoded values: geometry within 1 nm, errors within 1e-6 um
    / urad (one count of the encoding is 4e-6 um; float64 kernels differ between CPUs)."""
    import numpy as np
    from abbe.formats.five_axis_blob import read_five_blob
    g, w = read_five_blob(got.read_bytes(), str(got)), read_five_blob(want.read_bytes(), str(want))
    if g.kind != w.kind or max(abs(a - b) for a, b in zip(g.rot_point_mm + g.offset_mm,
                                                          w.rot_point_mm + w.offset_mm)) > 1e-6:
        return [f"{name}: geometry {g.kind} {g.rot_point_mm} {g.offset_mm} != golden"]
    ge, we = g.errors, w.errors
    if set(ge.location) != set(we.location) or set(ge.motions) != set(we.motions):
        return [f"{name}: error names differ from golden"]
    d = [abs(ge.location[k] - we.location[k]) for k in we.location]
    d += [float(np.max(np.abs(np.asarray(ge.motions[k]) - np.asarray(we.motions[k]))))
          for k in we.motions if len(we.motions[k])]
    d += [abs(a - b) for a, b in zip(ge.squareness, we.squareness)]
    return [] if max(d, default=0.0) <= 1e-5 else [f"{name}: errors differ from golden by {max(d)}"]


def write() -> None:
    for m in MODELS:
        d = GOLDEN / m
        for t in [p for p in d.iterdir() if p.is_dir()]:
            shutil.rmtree(t)
        export_all(d, d)


if __name__ == "__main__":
    if sys.argv[1:] == ["--write"]:
        write()
    else:
        print(__doc__)
