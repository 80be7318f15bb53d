"""The fitted table's U (k = 2) against the Monte Carlo (GUM S1) on the vmc500 example and,
when present, the real ESS X record: value / U / MC U per kind of result, as a markdown table.

    python host_tools/bench/bench_fit_uncertainty.py [--draws 2000] [--reselect-draws 200]

Kinds: a term along its axis (at the position of its largest U, and the worst U_MC / U - 1
over the travel where U >= 10 % of its max), dX dY dZ at machine points, the compensated
residual's max |r| and RMS. ``--reselect-draws`` also re-runs the whole automatic selection
on each draw (period, orders): what the fixed-structure U leaves out.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from abbe.analysis.fit import uncertainty as fu_mod  # noqa: E402
from abbe.analysis.fit.pipeline import fit_machine, options_from_machine  # noqa: E402
from abbe.formats.machine import load_machine  # noqa: E402
from abbe.model.table import basis_matrix  # noqa: E402
from cases.ess_case import write_ess_case  # noqa: E402
from real_data import ESS_DAT  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
POINTS = np.array([[250.0, -200.0, -150.0], [0.0, 0.0, 0.0], [500.0, -400.0, -300.0],
                   [100.0, -350.0, -50.0]])


def rows(name: str, machine: Path, draws: int, resel: int, points: np.ndarray | None) -> list[str]:
    m = load_machine(machine)
    t0 = time.perf_counter()
    res = fit_machine(m, options_from_machine(m))
    t_fit = time.perf_counter() - t0
    fu = res.uncertainty
    t0 = time.perf_counter()
    mc = fu_mod.monte_carlo(res, fu, draws=draws, seed=11, points_mm=points)
    t_mc = time.perf_counter() - t0
    mcr = fu_mod.monte_carlo(res, fu, draws=resel, seed=12, reselect=True) if resel else None
    out = []
    for a, d in mc["axes"].items():
        for t, v in d.items():
            i = int(np.argmax(v["U"]))
            val = float((basis_matrix(res.table.axes[a], v["grid_mm"][i:i + 1])
                         @ res.table.axes[a].coef[t])[0])
            w = fu_mod.worst_ratio(v["U_mc"], v["U"])
            rs = ""
            if mcr is not None:
                rs = f"{mcr['axes'][a][t]['U_mc'][i]:.4g}"
            unit = fu.terms[a][t].unit
            c = fu.compensated[a][t]
            out.append(
                f"| {name} | {a} {t} ({unit}) at {v['grid_mm'][i]:.1f} mm | {val:.4g} | "
                f"{v['U'][i]:.4g} | {v['U_mc'][i]:.4g} | {w * 100:.1f} % | {rs} | "
                f"{c['max_abs']:.4g} / {c['max_abs_U']:.4g} / {v['compensated_max_abs_U_mc']:.4g} | "
                f"{c['rms']:.4g} / {c['rms_U']:.4g} / {v['compensated_rms_U_mc']:.4g} |")
    if points is not None:
        val = fu_mod.spatial_error(res.table, points)
        for p, e, U, Um in zip(points, val, mc["points_U"], mc["points_U_mc"]):
            out.append(f"| {name} | point {tuple(float(x) for x in p)} dX dY dZ (um) | "
                       + " ".join(f"{x:.3f}" for x in e) + " | " + " ".join(f"{x:.3f}" for x in U)
                       + " | " + " ".join(f"{x:.3f}" for x in Um)
                       + f" | {fu_mod.worst_ratio(Um, U, floor=0.0) * 100:.1f} % | | | |")
    print(f"{name}: fit {t_fit:.2f} s (with the covariances), Monte Carlo {draws} draws "
          f"{t_mc:.2f} s", file=sys.stderr)
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=2000)
    ap.add_argument("--reselect-draws", type=int, default=0)
    a = ap.parse_args()
    print("| data | result | value | U (k = 2) | U MC | worst over the travel | U MC, "
          "re-selected | compensated max abs r / U / U MC | compensated RMS / U / U MC |")
    print("|---|---|---|---|---|---|---|---|---|")
    lines = rows("vmc500", REPO / "examples" / "vmc500" / "machine.toml", a.draws,
                 a.reselect_draws, POINTS)
    if ESS_DAT.is_file():
        with tempfile.TemporaryDirectory() as td:
            lines += rows("ESS X (real)", write_ess_case(ESS_DAT, Path(td)), a.draws,
                          a.reselect_draws, None)
    else:
        print(f"ESS record absent ({ESS_DAT}): real-data rows left out", file=sys.stderr)
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
