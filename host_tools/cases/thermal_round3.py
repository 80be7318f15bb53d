"""Issue 35, third round (docs/thermal.md, "Issue 35, third round"): the variants R3a (the
input set chosen by cross-validation on hours 0-24) and R3b (R3a plus a ridge penalty
chosen by the same cross-validation), their choices made on hours 0-24 only, then scored
once on the held-out hours 24-46 beside the default and the static MLR on 16
temperatures. ``python -m cases.thermal_round3`` from host_tools/ (about a minute).

Printed first (hours 0-24 only): each variant's choices. Then the held-out table. Then,
labelled POST HOC, the diagnostics computed after that table (ch2 against ch1, and every
channel on every other channel's term set): they were looked at after the held-out hours,
so no figure of them is a held-out result, and nothing of them is the default.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from abbe.analysis.thermal import pipeline
from abbe.analysis.thermal.identify import candidates_of
from abbe.formats.machine import load_machine
from abbe.formats.thermal_record import read_thermal_xlsx

ROOT = Path(__file__).resolve().parents[2]
REAL_XLSX = ROOT / "third_party" / "spindle-thermal" / "data.xlsx"
REAL_MACHINE = ROOT / "examples" / "spindle_thermal" / "machine.toml"

VARIANTS = {"all inputs": {}, "R3a": {"inputs": "by_cv"},
            "R3b": {"inputs": "by_cv", "ridge": True}}


def main() -> None:
    spec = load_machine(REAL_MACHINE).extra["thermal"]
    rec = read_thermal_xlsx(REAL_XLSX)
    h = rec.hours
    ident = (h >= spec.identify_hours[0]) & (h < spec.identify_hours[1])
    valid = (h >= spec.validate_hours[0]) & (h <= spec.validate_hours[1])
    cands = candidates_of(rec.temps_c, list(rec.temp_names), rec.speed_rpm)
    names = [c.name for c in cands]
    cycle_s = spec.cycle_hours * 3600.0
    results: dict[str, list] = {}
    for v, kw in VARIANTS.items():
        results[v] = []
        for k, ch in enumerate(rec.channel_names):
            y = rec.disp_um[:, k] - rec.disp_um[0, k]
            s = pipeline._signal(ch, "um", y, rec, cands, ident, valid, cycle_s, **kw)
            results[v].append(s)
            terms = "; ".join(f"{names[t.input]} {t.tau_s / 60:.0f} min {t.gain:+.2f}"
                              for t in s.fit.terms)
            print(f"[hours 0-24] {v} {ch}: CV {s.fit.cv_rms_um:.2f} um (selection "
                  f"{s.fit.selection_cv_um:.2f}), lambda {s.fit.ridge_lambda:g}, fit "
                  f"{s.rms_comp_ident:.2f} um; {terms}")
    print("\nheld-out hours 24-46 (computed once):")
    print("| channel | uncompensated | MLR on 16 T | " + " | ".join(VARIANTS) + " |")
    for k, ch in enumerate(rec.channel_names):
        d = results["all inputs"][k]
        cells = [f"{results[v][k].rms_comp:.2f} um ({100 * results[v][k].ratio:.0f} %)"
                 for v in VARIANTS]
        print(f"| {ch} | {d.rms_uncomp:.2f} um | {d.rms_mlr:.2f} um "
              f"({100 * d.rms_mlr / d.rms_uncomp:.0f} %) | " + " | ".join(cells) + " |")
    for v in ("R3a", "R3b"):
        base, new = results["all inputs"], results[v]
        lowers = any(n.rms_comp < b.rms_comp - 1e-9 for b, n in zip(base, new))
        grows = [b.name for b, n in zip(base, new) if n.rms_comp > 1.05 * b.rms_comp]
        lost = [b.name for b, n in zip(base, new) if b.meets and not n.meets]
        ok = lowers and not grows and not lost
        print(f"{v}: lowers a channel {lowers}; grows > 5 %: {grows}; stops meeting: {lost}; "
              f"qualifies: {ok}; meets: {[n.name for n in new if n.meets]}; "
              f"largest ratio {max(n.ratio for n in new):.3f}")
    post_hoc(rec, cands, ident, valid, cycle_s, results["R3a"])


def _rms(v: np.ndarray) -> float:
    return float(np.sqrt(np.mean(v ** 2)))


def post_hoc(rec, cands, ident, valid, cycle_s, fits) -> None:
    """After the held-out table: ch2 against ch1, and each channel on each channel's term set
    (inputs and time constants of R3a, gains refitted on hours 0-24) with its leave-one-
    cycle-out CV on hours 0-24 and its held-out ratio. POST HOC: not a held-out result."""
    from abbe.analysis.thermal.identify import _cv_rms, cycles_of
    from abbe.model.thermal import lag_states
    h = rec.hours
    y = rec.disp_um - rec.disp_um[0]
    d = y[:, 1] - y[:, 0]
    print("\nPOST HOC (computed after the held-out table; not held-out results):")
    for what, m in (("hours 0-24", ident), ("hours 24-46", valid)):
        print(f"  {what}: ch1 RMS {_rms(y[m, 0]):.2f} um, ch2 {_rms(y[m, 1]):.2f} um, "
              f"correlation {np.corrcoef(y[m, 0], y[m, 1])[0, 1]:.3f}; ch2 - ch1 RMS "
              f"{_rms(d[m]):.2f} um, peak to peak {np.ptp(d[m]):.2f} um")
    t = rec.temps_c - rec.temps_c[0]
    corr = {n: np.corrcoef(t[valid, j], d[valid])[0, 1] for j, n in enumerate(rec.temp_names)}
    print("  hours 24-46, correlation of ch2 - ch1 with each temperature: "
          + ", ".join(f"{n} {c:+.2f}" for n, c in corr.items()))
    r2 = y[:, 1] - fits[1].predicted
    for lo, hi in ((24, 32), (32, 40), (40, 46.1)):
        m = valid & (h >= lo) & (h < hi)
        print(f"  R3a ch2 residual {lo}-{hi} h: RMS {_rms(r2[m]):.2f} um, mean {np.mean(r2[m]):+.2f}")
    cyc = cycles_of(rec.time_s, ident, cycle_s)
    sets = [np.column_stack([lag_states(cands[t.input].rise, rec.time_s, t.tau_s)
                             for t in f.fit.terms]) for f in fits]
    for c, ch in enumerate(rec.channel_names):
        cells = []
        for s, other in enumerate(rec.channel_names):
            x = np.column_stack([np.ones(h.size), sets[s]])
            g = np.linalg.lstsq(x[ident], y[ident, c], rcond=None)[0]
            cells.append(f"{other}'s set CV {_cv_rms(sets[s], y[:, c], cyc):.2f} um, held-out "
                         f"{100 * _rms((y[:, c] - x @ g)[valid]) / _rms(y[valid, c]):.0f} %")
        print(f"  {ch}: " + " | ".join(cells))


if __name__ == "__main__":
    main()
