"""Issue 35, third round (docs/thermal.md, "Issue 35, third round"): the variants R3a (the
input set chosen by cross-validation on hours 0-24) and R3b (R3a plus a ridge penalty
chosen by the same cross-validation), their choices made on hours 0-24 only, then scored
once on the held-out hours 24-46 beside the default and the static MLR on 16
temperatures. ``python -m cases.thermal_round3`` from host_tools/ (about a minute).

Printed first (hours 0-24 only): each variant's choices. Then the held-out table.
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

VARIANTS = {"default": {}, "R3a": {"inputs": "by_cv"},
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
        d = results["default"][k]
        cells = [f"{results[v][k].rms_comp:.2f} um ({100 * results[v][k].ratio:.0f} %)"
                 for v in VARIANTS]
        print(f"| {ch} | {d.rms_uncomp:.2f} um | {d.rms_mlr:.2f} um "
              f"({100 * d.rms_mlr / d.rms_uncomp:.0f} %) | " + " | ".join(cells) + " |")
    for v in ("R3a", "R3b"):
        base, new = results["default"], results[v]
        lowers = any(n.rms_comp < b.rms_comp - 1e-9 for b, n in zip(base, new))
        grows = [b.name for b, n in zip(base, new) if n.rms_comp > 1.05 * b.rms_comp]
        lost = [b.name for b, n in zip(base, new) if b.meets and not n.meets]
        ok = lowers and not grows and not lost
        print(f"{v}: lowers a channel {lowers}; grows > 5 %: {grows}; stops meeting: {lost}; "
              f"qualifies: {ok}; meets: {[n.name for n in new if n.meets]}; "
              f"largest ratio {max(n.ratio for n in new):.3f}")
    np.set_printoptions(precision=2)


if __name__ == "__main__":
    main()
