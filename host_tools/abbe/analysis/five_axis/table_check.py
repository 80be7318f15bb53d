"""What the written five-axis table achieves on the campaign it was fitted from.

The fit's "after" dispersion is the identified model's, computed in Python with
every set-up unknown of the plan. A controller compensates with the *table*
(``model_five.bin``), evaluated by the C library: this module re-predicts the
probed sphere centres through that table and reports their dispersion, so the
report's "after" is what the table achieves (issue 33: a table that left out
the C line's position in the fit's convention reproduced none of the campaign
while the fit reported 0.5 um).

The table gives the tool tip's error relative to the workpiece at joint
positions, ``E(q, angles) = q + e_lin - T_act T_nom^-1 q`` (um,
:func:`abbe.model.five_axis.tool_error_exact`). A probe that touches the
sphere at ``s`` (workpiece coordinates) reads the machine position where the
sphere actually is, ``T_act s - e_lin = q - E`` with ``q = T_nom s``. So each
measured centre ``m_i`` should equal ``T_nom,i s - E_i``. The sphere's place
``s`` is the one unknown a table cannot hold (a workpiece datum): it is
refitted per probing, with the table fixed, in closed form (every ``R_i`` is a
rotation), twice so that ``E`` is evaluated where the refitted sphere is.
Units: mm in, um out.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from abbe.analysis.five_axis.problem import Block
from abbe.model.five_axis import TrunnionGeometry, table_transform


def _evaluator(blob: bytes):
    """(error function (q mm (N, 3), angles deg (N, 2)) -> (N, 3) um, its name): the C
    library's ``abbe_five_error_eval_f32``, or the float64 reference of the same table
    when the library is not there (the report says which)."""
    from abbe.model import clib

    if clib.available():
        try:
            model = clib.CFiveModel(blob, "model_five.bin")
            return (lambda q, a: model.error_f32(q, a)[0]), "C library (abbe_five_error_eval_f32)"
        except clib.LibraryNotFound:
            pass
    from abbe.formats.five_axis_blob import five_reference, read_five_blob

    table = read_five_blob(blob, "model_five.bin")
    return (lambda q, a: five_reference(table, q, a)[0]), \
        "Python reference (abbe.formats.five_axis_blob.five_reference; C library not found)"


def centre_residuals(g: TrunnionGeometry, b: Block, error_um, iterations: int = 2
                     ) -> np.ndarray:
    """Measured minus table-predicted sphere centres of probe block ``b`` (M, 3) um, the
    sphere's place refitted (module docstring). ``error_um`` None: no compensation (the
    "before" of the same computation)."""
    T = table_transform(g, None, b.angles_deg)
    R, t = T[:, :3, :3], T[:, :3, 3]
    m = np.asarray(b.obs, dtype=np.float64)
    s = np.asarray(b.sphere_mm, dtype=np.float64)
    E = np.zeros_like(m)
    for _ in range(iterations if error_um is not None else 1):
        if error_um is not None:
            E = np.asarray(error_um(np.einsum("nij,j->ni", R, s) + t, b.angles_deg)) * 1e-3
        s = np.mean(np.einsum("nji,nj->ni", R, m + E - t), axis=0)
    pred = np.einsum("nij,j->ni", R, s) + t - E
    return (m - pred) * 1e3


def repredict(g: TrunnionGeometry, blocks: list[Block], blob: bytes) -> dict[str, Any] | None:
    """The table's dispersion on the plan's probing (um, RMS 3-D length over every probed
    position), with and without the table, and who evaluated it; None without probing."""
    probes = [b for b in blocks if b.kind == "probe"]
    if not probes:
        return None
    fn, who = _evaluator(blob)
    after = np.vstack([centre_residuals(g, b, fn) for b in probes])
    before = np.vstack([centre_residuals(g, b, None) for b in probes])

    def rms(r: np.ndarray) -> float:
        return float(np.sqrt(np.mean(np.sum(r ** 2, axis=1))))

    return {"before": rms(before), "after": rms(after), "evaluated_by": who,
            "positions": int(after.shape[0]),
            "note": "the probed sphere centres re-predicted through model_five.bin, the "
                    "sphere's place refitted per probing (a workpiece datum)"}
