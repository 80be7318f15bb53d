"""What ``abbe diagnose`` records of every candidate it tests (moved from
:mod:`abbe.diagnose.selection`): the summary of a candidate's test (``DiagnoseResult.tested``:
significance, evidence, held-out gain, value, redundancy) and what is read from that record
once the effects are named: a companion "A alone, or A + B" (docs/effects.md §3,
"Undecided is an answer").
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from abbe.diagnose.backlash_pair import scan_entries
from abbe.diagnose.candidates import Cand, Engine
from abbe.diagnose.results import DiagnoseOptions
from abbe.diagnose.candidate_eval import heldout_need


def _summ(st: dict[str, Any], c: Cand, opts: DiagnoseOptions) -> dict[str, Any]:
    d = {"significant": bool(st.get("ok") and st["log_evidence"] >= opts.evidence_log_min),
         "qualifies": bool(st.get("qualifies")), "why_not": st.get("why_not", "")}
    if st.get("ok"):
        d.update({"p_value": float(f"{st['p_eff']:.3g}"), "delta_bic": round(st["dbic"], 2),
                  "F": round(st["F"], 3), "heldout_gain": (None if not np.isfinite(st["heldout"]["gain"])
                                                            else round(st["heldout"]["gain"], 2)),
                  "contribution_rms_um": round(st["contrib_rms_um"], 4),
                  "log_evidence": (None if not np.isfinite(st["log_evidence"])
                                   else round(st["log_evidence"], 2))})
        lt = st["evidence"].get("log_evidence_typical")
        if lt is not None and np.isfinite(lt):
            d["log_evidence_typical"] = round(float(lt), 2)
        d["heldout_need"] = round(heldout_need(st, opts), 2)
        if st["k"]:
            d["value"] = round(float(st["coef"][0]), 6)
            d["unit"] = c.spec.params[c.param_idx[0]].unit
            sd = st["evidence"].get("theta_sd")
            if sd and np.isfinite(sd[0]):
                d["ci95"] = [round(float(st["coef"][0]) - 1.96 * sd[0], 6),
                             round(float(st["coef"][0]) + 1.96 * sd[0], 6)]
        d["k"] = int(st["k"])
        d["log_lr"] = round(float(st["evidence"].get("log_lr", 0.0)), 3)
        d["observable_rms_um"] = round(float(st["observable_rms_um"]), 4)
        if c.scan_value is not None:
            d["scan"] = {k: round(v, 4) for k, v in
                         scan_entries(c.scan_value, c.spec.scan or "scan").items()}
        d["heldout_in_time"] = bool(st.get("heldout_in_time"))
        if st.get("redundant_with"):
            d["redundancy"] = round(float(st["redundancy"]), 4)
            d["redundant_with"] = st["redundant_with"]
    return d
def _companions(eng: Engine, effects: list[Any], tested: dict[str, dict[str, Any]],
                by_key_spec: dict[str, Any]) -> None:
    """"A alone, or A + B" (docs/effects.md §3, "Undecided is an answer"): a candidate B not
    named whose held-out gain passes the arbiter, that a named effect A reproduces more
    than it leaves (redundancy >= 0.5), and whose evidence ratio the prior decides: strong
    against for any plausible size (the selection's prior), not strong against for an
    effect of typical size (log K_typical > -log 19). The data then cannot say whether B
    is present beside A; the named effect's entry becomes undecided with both. A drift
    qualifies only when its held-out gain comes from a split in time (a check with
    repeated runs, ``heldout_in_time``): a split by angle sectors has not checked that it
    changes in time."""
    from abbe.diagnose.describe import _unit, companion_undecided
    lo = eng.opts.evidence_log_min
    by_key = {e.key: e for e in effects}
    for k, v in tested.items():
        a = by_key.get(v.get("redundant_with") or "")
        if a is None or v.get("selected") or k in by_key or v.get("value") is None:
            continue
        spec = by_key_spec[k]
        if not _held_out_below_threshold(v, spec, lo) or v["log_evidence_typical"] <= -lo \
                or v.get("redundancy", 0.0) < 0.5:
            continue
        if any(x.get("key") == k for x in (a.undecided or {}).get("alternatives", [])):
            continue
        lk, lt = v["log_evidence"], v["log_evidence_typical"]
        if {spec.kind, by_key_spec[a.key].kind} == {"thermal", "scale"} and spec.axis == a.axis:
            test = (f"the laser line of {spec.axis} again in the reverse time order of its runs "
                    "and targets, or after a dwell of about the warm-up time (a scale error "
                    "depends on the position only, a drift on when the reading is taken)")
        else:
            test = f"a test that sees {k} apart from {a.key} (docs/effects.md §3, Ambiguity)"
        companion_undecided(a, k, v["value"], _unit(v.get("unit", ""), spec, eng), test, lk, lt)


def possibly_present(eng: Engine, effects: list[Any], tested: dict[str, dict[str, Any]],
                     by_key_spec: dict[str, Any]) -> list[dict[str, Any]]:
    """"Nothing, or B" (docs/effects.md §3, "Possibly present"): a candidate B not named,
    that no named effect reproduces (else it is a companion, :func:`_companions`), whose
    held-out gain passes the arbiter, whose size the checks see above ``min_effect_um``,
    and whose evidence ratio the prior alone decides the other way: below the threshold
    for any plausible size (the selection's prior), at or above it for an effect of
    typical size (``log_evidence_typical``). The data then cannot say whether B is present;
    it is reported with its value, never named and never written into the table (a
    correction is made only on the evidence the selection requires), with how much more of
    the same data would decide it: for a change theta of k parameters the evidence grows
    with n times the data as log K(n) = log K + (n - 1) q / 2 - k log(n) / 2, q = 2 log LR
    (exact for the white part; the table's and the model's own error do not average out,
    so it is a lower bound of what is needed). A declared quantity (the tool offset) is
    judged by its own prior only; a drift needs a held-out split in time."""
    lo = eng.opts.evidence_log_min
    named = {e.key for e in effects}
    for e in effects:
        named |= {a["key"] for a in (e.undecided or {}).get("alternatives", [])}
        named |= {c.get("key") for c in e.components or []}
    out: list[dict[str, Any]] = []
    for k, v in tested.items():
        if k in named or v.get("selected") or v.get("value") is None:
            continue
        spec = by_key_spec[k]
        if not _held_out_below_threshold(v, spec, lo) \
                or v["log_evidence_typical"] < lo \
                or v.get("observable_rms_um", 0.0) < eng.opts.min_effect_um:
            continue
        if v.get("redundant_with") and v.get("redundancy", 0.0) >= 0.5:
            continue   # reproduced by a named effect: "A alone, or A + B" (_companions)
        lk, lt, g = v["log_evidence"], v["log_evidence_typical"], v["heldout_gain"]
        q = 2.0 * float(v.get("log_lr", 0.0))
        kk = max(int(v.get("k", 1)), 1)
        n_more = _data_factor(lk, q, kk, lo)
        entry = {"key": k, "id": spec.family, "value": v["value"], "unit": v.get("unit", ""),
                 "ci95": v.get("ci95"), "contribution_rms_um": v.get("contribution_rms_um"),
                 "log_evidence": lk, "log_evidence_typical": lt, "heldout_gain": g,
                 "heldout_need": v["heldout_need"], "data_factor": n_more,
                 "statement": (
                     f"{k} possibly present ({v.get('contribution_rms_um', 0.0):.3f} um RMS): the "
                     f"evidence depends on the prior: log K {lk:.1f} for any plausible size, "
                     f"{lt:.1f} for a typical one (threshold {lo:.2f}); the held-out data "
                     f"prefer it (gain {g:.1f} >= {v['heldout_need']:.1f}). Not named and not "
                     "in the table"),
                 "test": ("repeat the checks that see it, "
                          + (f"about {n_more:.0f} x their runs in all" if n_more is not None
                             else "many times over")
                          + ": if it is real its evidence grows to the threshold with that much "
                          "data; if it is not, it falls")}
        out.append(entry)
    return sorted(out, key=lambda d: -float(d["log_evidence_typical"]))


def _held_out_below_threshold(v: dict[str, Any], spec: Any, lo: float) -> bool:
    """What a companion and a possibly present candidate share (docs/effects.md §3): the
    record ``v`` has both evidence ratios and a held-out gain, its evidence is below the
    threshold ``lo`` under the selection's prior, the held-out gain passes the arbiter; a
    declared quantity (the tool offset) is judged by its own prior only, never "maybe", and
    a drift's held-out gain must come from a split in time (early / late runs)."""
    lk, lt, g = v.get("log_evidence"), v.get("log_evidence_typical"), v.get("heldout_gain")
    if lk is None or lt is None or g is None or not lk < lo or not g >= v["heldout_need"]:
        return False
    if spec.kind == "tool_offset":
        return False
    return not (spec.kind == "thermal" and not v.get("heldout_in_time"))


def _data_factor(log_k: float, q: float, k: int, lo: float) -> float | None:
    """The smallest n (>= 1, a whole number) with log K + (n - 1) q / 2 - k log(n) / 2 >= lo
    (:func:`possibly_present`), or None when q is not positive or n exceeds 1000."""
    if not q > 0:
        return None
    for n in range(1, 1001):
        if log_k + 0.5 * (n - 1) * q - 0.5 * k * math.log(n) >= lo:
            return float(n)
    return None
