"""docs/concepts.md's sign convention of the five-axis tool error (issue 33): position and
orientation are both the tool relative to the workpiece. EC0C = +100 urad alone turns the
workpiece +100 urad about +Z, so the orientation error is -100 urad about Z and the
position error at u from the C line is W x u with the same W: in the exact form, the
linearised form and the C library; and the exact orientation is the documented
rotvec(R_tool R_nom R_act^T), computed here from the transforms."""

from __future__ import annotations

import numpy as np
import pytest

from abbe.formats.five_axis_blob import write_five_blob
from abbe.model import clib
from abbe.model.five_axis import (FiveAxisErrors, TrunnionGeometry, rotvec, table_transform,
                                  tool_error_exact, tool_error_linear)

GEOMS = [TrunnionGeometry("xyzac-trt", (10.0, 20.0, -300.0), (0.0, 30.0, -80.0), 100.0,
                          {"A": (-90.0, 90.0), "C": (-360.0, 360.0)}),
         TrunnionGeometry("xyzbc-trt", (-40.0, 15.0, -280.0), (25.0, 0.0, -60.0), 100.0,
                          {"B": (-90.0, 90.0), "C": (-360.0, 360.0)})]


def _at_u(g: TrunnionGeometry, u: np.ndarray, ang: np.ndarray) -> np.ndarray:
    """Joints of the workpiece point u (mm) from the C centre at angles ang."""
    T = table_transform(g, None, ang)
    w = np.asarray(g.rot_point_mm) + u
    return np.einsum("nij,j->ni", T[:, :3, :3], w) + T[:, :3, 3]


@pytest.mark.parametrize("g", GEOMS, ids=lambda g: g.kind)
def test_ec0c_alone_gives_one_sign(g: TrunnionGeometry) -> None:
    e = FiveAxisErrors({"EC0C": 100.0})
    ang = np.array([[0.0, 0.0], [0.0, 130.0]])
    q = _at_u(g, np.array([100.0, 0.0, 0.0]), ang[:1]).repeat(2, axis=0)
    q[1] = _at_u(g, np.array([100.0, 0.0, 0.0]), ang[1:])[0]
    forms = {"exact": tool_error_exact(g, e, q, ang), "linear": tool_error_linear(g, e, q, ang)}
    if clib.available():
        forms["C"] = clib.CFiveModel(write_five_blob(g, e)).error_f32(q, ang)[:2]
    for name, (pos, rot) in forms.items():
        assert rot[:, 2] == pytest.approx([-100.0, -100.0], abs=1e-3), name
        assert np.abs(rot[:, :2]).max() < 1e-3, name
        # position error = W x u, u the point's lever from the C line (machine frame)
        lever = q - np.asarray(g.rot_point_mm)
        lever[:, 2] = 0.0
        want = np.cross(rot * 1e-6, lever) * 1e3
        assert pos == pytest.approx(want, abs=2e-3), name
        assert pos[0, 1] == pytest.approx(-10.0, abs=2e-3), name  # -10 um along Y at 100 mm X


@pytest.mark.parametrize("g", GEOMS, ids=lambda g: g.kind)
def test_exact_orientation_is_the_documented_product(g: TrunnionGeometry) -> None:
    rng = np.random.default_rng(7)
    names = {"xyzac-trt": ["EB0A", "EC0A", "EA0A", "EA0C", "EB0C", "EC0C"],
             "xyzbc-trt": ["EA0B", "EC0B", "EB0B", "EA0C", "EB0C", "EC0C"]}[g.kind]
    e = FiveAxisErrors({n: float(rng.uniform(-80, 80)) for n in names})
    ang = np.column_stack([rng.uniform(-80, 80, 5), rng.uniform(0, 360, 5)])
    q = _at_u(g, np.array([60.0, -30.0, 40.0]), ang)
    _pos, rot = tool_error_exact(g, e, q, ang)
    Ra, Rn = table_transform(g, e, ang)[:, :3, :3], table_transform(g, None, ang)[:, :3, :3]
    doc = rotvec(Rn @ np.transpose(Ra, (0, 2, 1))) * 1e6  # R_tool = I: no linear errors
    assert rot == pytest.approx(doc, abs=1e-6)
    assert np.abs(rot).max() > 10.0
