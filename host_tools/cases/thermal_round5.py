"""Issue 35, fifth round (docs/thermal.md, "Issue 35, fifth round"): candidates R5a-R5d,
every choice made on hours 0-24 only, then scored once on the held-out hours 24-46 beside
the previous default (R4d) and the static MLR on 16 temperatures, and the pre-written
adoption rule applied.

* **R5a, the nest's pairs**: a paired channel (ch1/ch2: X at two heights; ch3/ch4: Y) is
  predicted either by its own model (R4d) or as its partner's model plus (upper) or minus
  (lower) the model of the pair's difference (the tilt signal's R4d fit, the tilt times the
  spacing); per channel the partner + difference only if both its leave-one-cycle-out and
  its forward-chaining RMS on hours 0-24 are lower (:func:`structure.prefers_partner`).
* **R5b, the room term decided**: a channel whose R4d run took a room-sensor term keeps it
  only if every such term passes the bound rule (:func:`identify.bounded`); otherwise the
  channel falls back to R3a (the run R4d was compared with).
* **R5c, every term decided**: each signal's R4d terms (5 channels, 2 tilts) pruned once by
  the bound rule (:func:`identify.prune`), the rest refined; a signal left with no term
  keeps its R4d terms.
* **R5d, R5a on R5c**: R5a's choice and composition with every model (direct, partner,
  difference) R5c's.

``python -m cases.thermal_round5 --identification-only`` from host_tools/ prints the choices
on hours 0-24 and the costs and computes nothing on hours 24-46. Without the flag it also
prints the held-out table and the rule's verdict (about 25 s).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from abbe.analysis.thermal import structure as s4
from abbe.analysis.thermal.identify import (bounded, candidates_of, cycles_of, heated_inputs,
                                            mlr_baseline, prune)
from abbe.analysis.thermal.iso230_3 import tilt_signal
from abbe.analysis.thermal.pipeline import TARGET_RATIO
from abbe.formats.machine import load_machine
from abbe.formats.thermal_record import read_thermal_xlsx
from abbe.model.thermal import MAX_TERMS_PER_CHANNEL

ROOT = Path(__file__).resolve().parents[2]
REAL_XLSX = ROOT / "third_party" / "spindle-thermal" / "data.xlsx"
REAL_MACHINE = ROOT / "examples" / "spindle_thermal" / "machine.toml"

CANDIDATES = ("R5a", "R5b", "R5c", "R5d")


def _rms(v: np.ndarray) -> float:
    return float(np.sqrt(np.mean(v ** 2)))


def _pred(t, cands, fit) -> np.ndarray:
    """A fit's prediction over the record (its sensor zero offset included), um / urad."""
    if not fit.terms:
        return np.full(t.size, fit.offset_um)
    return fit.offset_um + s4.states_of(t, cands, fit.terms) @ np.array(
        [tt.gain for tt in fit.terms])


class Ctx:
    """The record, its masks and signals: channels (um from start) and the pairs'
    differences (upper - lower, um) with their tilt signals (urad)."""

    def __init__(self, rec, spec) -> None:
        self.rec, self.spec = rec, spec
        h = rec.hours
        self.t = rec.time_s
        self.ident = (h >= spec.identify_hours[0]) & (h < spec.identify_hours[1])
        self.valid = (h >= spec.validate_hours[0]) & (h <= spec.validate_hours[1])
        self.cycle_s = spec.cycle_hours * 3600.0
        self.cyc = cycles_of(self.t, self.ident, self.cycle_s)
        self.cands = candidates_of(rec.temps_c, list(rec.temp_names), rec.speed_rpm)
        self.names = list(rec.channel_names)
        self.ys = {n: rec.disp_um[:, k] - rec.disp_um[0, k] for k, n in enumerate(self.names)}
        self.pairs = spec.tilt_pairs()
        self.tilts = {f"tilt_{p.output}": tilt_signal(rec, p) for p in self.pairs}
        # um of difference (upper - lower) per urad of the tilt signal
        self.um_per_urad = {f"tilt_{p.output}": (1.0 if p.output == "b" else -1.0)
                            * p.spacing_mm * 1e-3 for p in self.pairs}


def r4d(ctx: Ctx, name: str, y: np.ndarray):
    """The previous default (fit_record's run): R3a, then R4d's room term by LOCO CV."""
    d = s4.default_fit(name, ctx.t, y, ctx.cands, ctx.ident, ctx.cycle_s)
    return d, s4.with_room_term(name, ctx.t, y, ctx.cands, ctx.ident, ctx.cycle_s, d)


def compose(ctx: Ctx, fits: dict, tag: str) -> tuple[dict, dict, dict]:
    """R5a's choice per paired channel with the models ``fits`` (name -> fit, channels and
    tilts): returns (predictions of the channels, um; the choice per channel; the
    identification-hour figures)."""
    preds = {n: _pred(ctx.t, ctx.cands, fits[n]) for n in ctx.names}
    choice, figs = {}, {}
    for p in ctx.pairs:
        tn = f"tilt_{p.output}"
        k = ctx.um_per_urad[tn]
        y_diff = ctx.ys[p.upper] - ctx.ys[p.lower]
        diff_pred = k * _pred(ctx.t, ctx.cands, fits[tn])
        for me, partner, sign in ((p.upper, p.lower, 1.0), (p.lower, p.upper, -1.0)):
            use, f = s4.prefers_partner(ctx.t, ctx.ys[me], ctx.cands, fits[me].terms,
                                        fits[partner].terms, ctx.ys[partner],
                                        fits[tn].terms, y_diff, sign, ctx.cyc)
            choice[me], figs[me] = use, f
            if use:
                preds[me] = _pred(ctx.t, ctx.cands, fits[partner]) + sign * diff_pred
    return preds, choice, figs


def identify_all(ctx: Ctx):
    """Every candidate's predictions per channel (hours 0-24 choices), the costs (s) and
    the printed choices."""
    t, cands, ident, cyc = ctx.t, ctx.cands, ctx.ident, ctx.cyc
    sigs = {**ctx.ys, **ctx.tilts}
    t0 = time.perf_counter()
    r3a, prev = {}, {}
    for n, y in sigs.items():
        r3a[n], prev[n] = r4d(ctx, n, y)
    cost = {"R4d": time.perf_counter() - t0}
    preds = {"R4d": {n: _pred(t, cands, prev[n]) for n in ctx.names}}
    lines = []

    for n in sigs:
        f = prev[n]
        y = sigs[n]
        terms = "; ".join(
            f"{cands[tt.input].name} {tt.tau_s / 60:.1f} min {tt.gain:+.3g} +/- "
            f"{tt.gain_u95 if tt.gain_u95 is not None else float('inf'):.2g} (tau +/- "
            f"{(tt.tau_u95_s or float('inf')) / 60:.2g} min){'' if bounded(tt) else ' UNDECIDED'}"
            for tt in f.terms)
        lines.append(f"[hours 0-24] R4d {n} ({f.input_set}): LOCO "
                     f"{s4.loco_rms(t, y, cands, f.terms, cyc):.2f}, forward chain "
                     f"{s4.forward_chain_rms(t, y, cands, f.terms, cyc):.2f}; {terms}")

    t0 = time.perf_counter()
    preds["R5a"], choice_a, figs_a = compose(ctx, prev, "R5a")
    cost["R5a"] = time.perf_counter() - t0
    for n in choice_a:
        f = figs_a[n]
        lines.append(f"[hours 0-24] R5a {n}: direct LOCO {f['loco_direct']:.2f} / forward "
                     f"{f['forward_direct']:.2f} um; partner+difference LOCO "
                     f"{f['loco_partner']:.2f} / forward {f['forward_partner']:.2f} um -> "
                     + ("partner+difference" if choice_a[n] else "direct"))

    t0 = time.perf_counter()
    heated = heated_inputs(t, cands, ident)
    fits_b = {}
    for n in ctx.names:
        f = prev[n]
        room = [tt for tt in f.terms if tt.input not in heated]
        undecided = f.input_set == "heated+room" and any(not bounded(tt) for tt in room)
        fits_b[n] = r3a[n] if undecided else f
        if f.input_set == "heated+room":
            lines.append(f"[hours 0-24] R5b {n}: room term(s) "
                         + ", ".join(f"{cands[tt.input].name} {'decided' if bounded(tt) else 'undecided'}"
                                     for tt in room)
                         + (" -> R3a" if undecided else " -> kept"))
    preds["R5b"] = {n: _pred(t, cands, fits_b[n]) for n in ctx.names}
    cost["R5b"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    fits_c = {}
    for n, y in sigs.items():
        f = prev[n]
        kept, dropped = prune(t, y, cands, [(tt.input, tt.tau_s) for tt in f.terms], ident)
        if not kept:
            fits_c[n] = f
            note = "nothing decided: keeps R4d"
        elif dropped:
            fits_c[n] = s4._finish(n, t, y, cands, kept, ident, cyc, f.input_set + "+pruned")
            note = "kept " + ", ".join(f"{cands[i].name} {tau / 60:.1f} min" for i, tau in kept)
        else:
            fits_c[n] = f
            note = "every term decided"
        g = fits_c[n]
        lines.append(f"[hours 0-24] R5c {n}: dropped {dropped or 'none'}; {note}; LOCO "
                     f"{s4.loco_rms(t, y, cands, g.terms, cyc):.2f}, forward chain "
                     f"{s4.forward_chain_rms(t, y, cands, g.terms, cyc):.2f}")
    preds["R5c"] = {n: _pred(t, cands, fits_c[n]) for n in ctx.names}
    cost["R5c"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    preds["R5d"], choice_d, figs_d = compose(ctx, fits_c, "R5d")
    cost["R5d"] = time.perf_counter() - t0 + cost["R5c"]
    for n in choice_d:
        f = figs_d[n]
        lines.append(f"[hours 0-24] R5d {n}: direct LOCO {f['loco_direct']:.2f} / forward "
                     f"{f['forward_direct']:.2f} um; partner+difference LOCO "
                     f"{f['loco_partner']:.2f} / forward {f['forward_partner']:.2f} um -> "
                     + ("partner+difference" if choice_d[n] else "direct"))

    # the runtime's outputs x, y are the lower channels: a lower channel taking the
    # partner + difference needs both models' terms in one runtime channel
    runtime = {}
    for v, fits, choice in (("R5a", prev, choice_a), ("R5d", fits_c, choice_d)):
        need = []
        for p in ctx.pairs:
            if choice.get(p.lower):
                keys = {(tt.input, tt.tau_s) for tt in fits[p.upper].terms} | \
                    {(tt.input, tt.tau_s) for tt in fits[f"tilt_{p.output}"].terms}
                if len(keys) > MAX_TERMS_PER_CHANNEL:
                    need.append(f"{p.lower}: {len(keys)} terms > {MAX_TERMS_PER_CHANNEL}")
        runtime[v] = need
    lines.append(f"[runtime] lower channels beyond the C block's terms: {runtime}")
    for v, c in cost.items():
        lines.append(f"[cost] {v}: {c:.1f} s")
    return preds, cost, runtime, lines


def held_out(ctx: Ctx, preds: dict, cost: dict, runtime: dict) -> None:
    rec = ctx.rec
    print("\nheld-out hours 24-46 (computed once):")
    print("| channel | uncompensated | MLR on 16 T | " + " | ".join(preds) + " |")
    res: dict[str, list[tuple[float, bool, float]]] = {v: [] for v in preds}
    for n in ctx.names:
        y = ctx.ys[n]
        unc = _rms(y[ctx.valid])
        mlr = _rms((y - mlr_baseline(rec.temps_c, y, ctx.ident))[ctx.valid])
        cells = []
        for v in preds:
            r = _rms((y - preds[v][n])[ctx.valid])
            res[v].append((r, r / unc <= TARGET_RATIO and r < mlr, r / unc))
            cells.append(f"{r:.2f} um ({100 * r / unc:.0f} %)"
                         + (" met" if res[v][-1][1] else ""))
        print(f"| {n} | {unc:.2f} um | {mlr:.2f} um ({100 * mlr / unc:.0f} %) | "
              + " | ".join(cells) + " |")
    base = res["R4d"]
    qual = []
    for v in CANDIDATES:
        new = res[v]
        lowers = any(b_[0] - n_[0] > 1e-9 for b_, n_ in zip(base, new))
        grows = [ctx.names[k] for k, (b_, n_) in enumerate(zip(base, new))
                 if n_[0] > 1.05 * b_[0]]
        lost = [ctx.names[k] for k, (b_, n_) in enumerate(zip(base, new)) if b_[1] and not n_[1]]
        ok = lowers and not grows and not lost
        meets = sum(n_[1] for n_ in new)
        largest = max(n_[2] for n_ in new)
        blocked = runtime.get(v) or []
        print(f"{v}: lowers a channel {lowers}; grows > 5 %: {grows}; stops meeting: {lost}; "
              f"qualifies: {ok}; meets {meets}/5; largest ratio {largest:.3f}; "
              f"cost {cost[v]:.1f} s" + (f"; needs the C block: {blocked}" if blocked else ""))
        if ok and not blocked:
            qual.append((-meets, round(largest, 6), cost[v], v))
    print("qualifying, in the rule's order:", [q[3] for q in sorted(qual)] or "none")


def main() -> None:
    spec = load_machine(REAL_MACHINE).extra["thermal"]
    rec = read_thermal_xlsx(REAL_XLSX)
    ctx = Ctx(rec, spec)
    preds, cost, runtime, lines = identify_all(ctx)
    print("\n".join(lines))
    if "--identification-only" in sys.argv:
        return
    held_out(ctx, preds, cost, runtime)


if __name__ == "__main__":
    main()
