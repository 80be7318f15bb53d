"""The thermal results' U (k = 2) on the real spindle record (third_party/spindle-thermal):
first order, degree-5 cubature (the stated analytic U) and the Monte Carlo (GUM S1) for the
largest predicted drift and the held-out RMS of every channel and tilt, as a markdown table
(docs/uncertainty.md, "Thermal results"); with ``--profile`` also the profile-likelihood
95 % interval of every time constant beside the Wald interval of log tau.

    python host_tools/bench/bench_thermal_uncertainty.py [--draws 1000] [--seeds 1 2 3] [--profile]

Profile likelihood: for log tau of one term on a grid, the other time constants refitted
(``least_squares``, inside the identification's bounds) and the gains solved linearly;
D = (SSE - SSE_min) / s^2 with s^2 the identification's (serial correlation inflated, as
the covariance); the interval is where D <= 3.84 (chi^2, 1 degree of freedom, 95 %),
searched from 0.01 s to 1e8 s. "<" / "+": the interval reaches the end of that range.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from abbe.analysis.thermal import uncertainty as tu  # noqa: E402
from abbe.analysis.thermal.identify import TAU_BOUNDS_S, candidates_of  # noqa: E402
from abbe.analysis.thermal.pipeline import fit_record  # noqa: E402
from abbe.formats.machine import load_machine  # noqa: E402
from abbe.formats.thermal_record import read_thermal_xlsx  # noqa: E402
from abbe.model.thermal import lag_states  # noqa: E402
from thermal_helpers import REAL_MACHINE, REAL_XLSX  # noqa: E402


def _table(res, draws: int, seeds: list[int]) -> None:
    runs = []
    for s in seeds:
        t0 = time.perf_counter()
        runs.append(tu.thermal_uncertainty(res, draws=draws, seed=s))
        print(f"seed {s}: {draws} draws, {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    print("| signal | figure | value | U first order | U cubature | U MC (seeds "
          + " / ".join(map(str, seeds)) + ") | first order: U_MC / U - 1 | cubature: U_MC / U - 1 |")
    print("|---|---|---|---|---|---|---|---|")
    agree_fo = [0] * len(seeds)
    agree_cu = [0] * len(seeds)
    for i, sig in enumerate(runs[0]["signals"]):
        for key in ("drift", "heldout_rms"):
            d0 = sig[key]
            mcs = [r["signals"][i][key]["U_mc"] for r in runs]
            fo = [m / d0["U_first_order"] - 1 for m in mcs]
            cu = [m / d0["U"] - 1 for m in mcs]
            for k in range(len(seeds)):
                agree_fo[k] += abs(fo[k]) <= tu.AGREEMENT
                agree_cu[k] += abs(cu[k]) <= tu.AGREEMENT
            what = f"drift at {d0['hours']:.1f} h" if key == "drift" else "held-out RMS"
            print(f"| {sig['name']} | {what} | {d0['value']:.2f} | {d0['U_first_order']:.3f} | "
                  f"{d0['U']:.3f} | " + " / ".join(f"{m:.3f}" for m in mcs) + " | "
                  + " / ".join(f"{v:+.1%}" for v in fo) + " | "
                  + " / ".join(f"{v:+.1%}" for v in cu) + " |")
    print(f"| | within 10 % | | | | | {' / '.join(map(str, agree_fo))} of 14 | "
          f"{' / '.join(map(str, agree_cu))} of 14 |")


def _profile(res) -> None:
    rec = res.record
    t = rec.time_s
    cands = candidates_of(rec.temps_c, list(rec.temp_names), rec.speed_rpm)
    mask = res.ident_mask
    lo_b, hi_b = np.log(TAU_BOUNDS_S)
    print("\n| signal | input | tau (s) | Wald 95 % (log tau) | profile 95 % |")
    print("|---|---|---|---|---|")
    for sig in res.channels + [s for s in res.outputs if s.unit == "urad"]:
        fit, y = sig.fit, sig.measured
        if not fit.terms:
            continue
        p, C = tu.covariance(t, y, cands, fit, mask)
        ng = len(fit.terms) + 1
        dyn = [j for j, tt in enumerate(fit.terms) if tt.tau_s > 0]

        def resid(lts: np.ndarray) -> np.ndarray:
            taus = [tt.tau_s for tt in fit.terms]
            for j, lt in zip(dyn, lts):
                taus[j] = float(np.exp(lt))
            S = np.column_stack([np.ones(t.size)] + [lag_states(cands[tt.input].rise, t, tau)
                                                     for tt, tau in zip(fit.terms, taus)])[mask]
            return y[mask] - S @ np.linalg.lstsq(S, y[mask], rcond=None)[0]

        r0 = resid(p[ng:])
        n = r0.size
        rho = float(np.clip(np.corrcoef(r0[:-1], r0[1:])[0, 1], 0.0, 0.999))
        n_eff = max(n * (1 - rho) / (1 + rho), p.size + 1.0)
        s2 = float(r0 @ r0) / max(n - p.size, 1) * (n / n_eff)
        for k, j in enumerate(dyn):
            lt0, sd = p[ng + k], float(np.sqrt(C[ng + k, ng + k]))
            others = [i for i in range(len(dyn)) if i != k]

            def D(lt: float) -> float:
                def f(z: np.ndarray) -> np.ndarray:
                    v = p[ng:].copy()
                    v[k] = lt
                    v[others] = z
                    return resid(v)
                r = (least_squares(f, p[ng:][others], bounds=(lo_b, hi_b), diff_step=1e-4).fun
                     if others else f(np.empty(0)))
                return (float(r @ r) - float(r0 @ r0)) / s2

            grid = np.unique(np.concatenate([np.linspace(-3, 3, 25) * min(sd, 1.0),
                                             np.linspace(-12, 12, 17)]))
            grid = grid[(lt0 + grid >= np.log(0.01)) & (lt0 + grid <= np.log(1e8))]
            ok = np.array([D(lt0 + g) <= 3.84 for g in grid])
            c = int(np.argmin(np.abs(grid)))
            a = b = c
            while a > 0 and ok[a - 1]:
                a -= 1
            while b < grid.size - 1 and ok[b + 1]:
                b += 1
            tau = float(np.exp(lt0))
            print(f"| {sig.name} | {res.input_names[fit.terms[j].input]} | {tau:.0f} | "
                  f"{tau * np.exp(-1.96 * sd):.3g} .. {tau * np.exp(1.96 * sd):.3g} | "
                  f"{'< ' if a == 0 else ''}{np.exp(lt0 + grid[a]):.3g} .. "
                  f"{np.exp(lt0 + grid[b]):.3g}{' +' if b == grid.size - 1 else ''} |", flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--draws", type=int, default=1000)
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--profile", action="store_true")
    a = ap.parse_args()
    spec = load_machine(REAL_MACHINE).extra["thermal"]
    res = fit_record(read_thermal_xlsx(REAL_XLSX), spec)
    _table(res, a.draws, a.seeds)
    if a.profile:
        _profile(res)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
