"""The ESS target's ISO 230-2 X record (../shared/data, not carried) as a one-line `abbe fit`
case: a laser CSV with the linear channel only and a machine file declaring its
triangulation sensor's budget (``[uncertainty.laser] instrument = "laser_triangulation"``)."""

from __future__ import annotations

from pathlib import Path

from abbe.formats.positioning import load_positioning


def write_ess_case(dat: Path, d: Path) -> Path:
    """Write ``x.csv`` and ``machine.toml`` into ``d`` from the ``.dat`` file; returns the
    machine file. Deviations um, targets mm (as the file gives them)."""
    pd = load_positioning(dat)
    rows = ["run,direction,target_mm,linear_um"]
    for r in range(pd.up_um.shape[0]):
        rows += [f"{r + 1},+,{t:.4f},{v:.4f}" for t, v in zip(pd.targets_mm, pd.up_um[r])]
        rows += [f"{r + 1},-,{t:.4f},{v:.4f}"
                 for t, v in zip(pd.targets_mm[::-1], pd.down_um[r][::-1])]
    (d / "x.csv").write_text("\n".join(rows) + "\n")
    lo, hi = float(pd.targets_mm[0]), float(pd.targets_mm[-1])
    (d / "machine.toml").write_text(f"""[machine]
name = "ess-target-x"
[axes.X]
travel_mm = [{lo}, {hi}]
[axes.Y]
travel_mm = [0.0, 1.0]
[axes.Z]
travel_mm = [0.0, 1.0]
[reference]
point_mm = [0.0, 0.0, 0.0]
[laser.X]
file = "x.csv"
start_mm = [{lo}, 0.0, 0.0]
end_mm = [{hi}, 0.0, 0.0]
map = {{ linear = "+dx" }}
[uncertainty.laser]
instrument = "laser_triangulation"
""")
    return d / "machine.toml"
