"""From a record and its ``[thermal]`` section to an identified, validated model.

:func:`fit_record` identifies every displacement channel (for the per-channel table) and the
runtime's outputs (x, y from the tool-side channel of each pair, z, and the tilts a, b fitted
on the pairs' tilt signals), on the identification hours only; predicts the whole record;
and scores the held-out hours against the uncompensated drift and the static multi-linear
regression on every temperature (trained on the same hours).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from abbe.analysis.thermal.identify import (ChannelFit, candidates_of, cycles_of,
                                            identify_channel, inputs_of, mlr_baseline)
from abbe.analysis.thermal.iso230_3 import tilt_signal
from abbe.analysis.thermal.structure import prefers_partner, with_room_term
from abbe.formats.thermal_machine import ThermalSpec
from abbe.formats.thermal_record import ThermalRecord
from abbe.model.thermal import (MAX_TERMS_PER_CHANNEL, ThermalChannel, ThermalModel, evaluate,
                                lag_states)

#: The done-when ratio: compensated RMS at most this fraction of the uncompensated RMS.
TARGET_RATIO = 0.20


@dataclass
class SignalResult:
    """One modelled signal (a channel, or a tilt) and its scores on the held-out hours."""

    name: str
    unit: str
    measured: np.ndarray
    predicted: np.ndarray
    mlr: np.ndarray
    fit: ChannelFit
    rms_uncomp: float = 0.0
    rms_comp: float = 0.0
    rms_mlr: float = 0.0
    rms_comp_ident: float = 0.0
    #: a channel predicted as its partner's model plus ``scale`` times the pair's tilt
    #: model (round 5, R5a): (partner, tilt signal, scale um per urad); None: its own model
    composed: tuple[str, str, float] | None = None
    #: the channel's own model when ``composed`` (kept for the report and the CV figures)
    direct: ChannelFit | None = None

    @property
    def ratio(self) -> float:
        return self.rms_comp / self.rms_uncomp if self.rms_uncomp > 0 else float("inf")

    @property
    def meets(self) -> bool:
        return self.ratio <= TARGET_RATIO and self.rms_comp < self.rms_mlr

    def row(self, input_names: list[str]) -> dict:
        return {"name": self.name, "unit": self.unit, "rms_uncompensated": self.rms_uncomp,
                "rms_model": self.rms_comp, "rms_mlr": self.rms_mlr,
                "ratio_model": self.ratio, "ratio_mlr": self.rms_mlr / self.rms_uncomp,
                "rms_model_identification_hours": self.rms_comp_ident,
                "meets_target": self.meets, "cv_rms": self.fit.cv_rms_um,
                "input_set": self.fit.input_set,
                "composed_of": (None if self.composed is None else
                                {"partner": self.composed[0], "tilt": self.composed[1],
                                 "um_per_urad": self.composed[2]}),
                "terms": [{"input": input_names[t.input], "tau_s": t.tau_s, "gain": t.gain,
                           "gain_u95": t.gain_u95, "tau_u95_s": t.tau_u95_s}
                          for t in self.fit.terms],
                "selection": [{"added": s[0], "tau_s": s[1], "cv_rms": s[2],
                               "max_vif": s[3], "rivals": list(s[4])}
                              for s in (self.direct or self.fit).steps]}


@dataclass
class FitResult:
    """Everything :func:`fit_record` found (the CLI writes it and reports it)."""

    record: ThermalRecord
    spec: ThermalSpec
    ident_mask: np.ndarray
    valid_mask: np.ndarray
    channels: list[SignalResult]
    outputs: list[SignalResult]
    model: ThermalModel
    input_names: list[str]
    notes: list[str] = field(default_factory=list)


def _rms(v: np.ndarray) -> float:
    return float(np.sqrt(np.mean(v ** 2))) if v.size else float("nan")


def _signal(name: str, unit: str, y: np.ndarray, rec: ThermalRecord, cands, ident, valid,
            cycle_s: float, **kw) -> SignalResult:
    t = rec.time_s
    kw = dict(kw)
    kw.pop("partner", None)
    room = kw.pop("room_term", False)
    fit = identify_channel(name, t, y, cands, ident, cycle_s, **kw)
    if room:
        fit = with_room_term(name, t, y, cands, ident, cycle_s, fit)
    pred = np.full_like(y, fit.offset_um)  # the sensor's zero, then the model
    for term in fit.terms:
        pred += term.gain * lag_states(cands[term.input].rise, t, term.tau_s)
    mlr = mlr_baseline(rec.temps_c, y, ident)
    return SignalResult(name, unit, y, pred, mlr, fit, _rms(y[valid]), _rms((y - pred)[valid]),
                        _rms((y - mlr)[valid]), _rms((y - pred)[ident]))


def fit_record(rec: ThermalRecord, spec: ThermalSpec, **kw) -> FitResult:
    """Identify on ``spec.identify_hours``, score on ``spec.validate_hours`` (module docs).

    Every signal's input set is chosen by cross-validation on the identification hours
    (``inputs="by_cv"``: all inputs, or the speed and the temperatures the spindle heats;
    docs/thermal.md, "Issue 35, third round"), then kept or replaced by the heated inputs
    plus one room-sensor term, by the same cross-validation (``room_term=True``,
    :func:`~abbe.analysis.thermal.structure.with_room_term`; "Issue 35, fourth round");
    then every channel of a tilt pair is predicted directly or as its partner's model plus
    the pair's difference (the tilt's model times the spacing), by the cross-validation of
    round 5 (``partner=True``, :func:`_nest_pairs`; "Issue 35, fifth round").
    ``kw`` goes to :func:`~abbe.analysis.thermal.identify.identify_channel` and may
    override them."""
    kw.setdefault("inputs", "by_cv")
    kw.setdefault("room_term", True)
    h = rec.hours
    ident = (h >= spec.identify_hours[0]) & (h < spec.identify_hours[1])
    valid = (h >= spec.validate_hours[0]) & (h <= spec.validate_hours[1])
    cands = candidates_of(rec.temps_c, list(rec.temp_names), rec.speed_rpm)
    names = [c.name for c in cands]
    cycle_s = spec.cycle_hours * 3600.0
    chans = []
    for k, n in enumerate(rec.channel_names):
        y = rec.disp_um[:, k] - rec.disp_um[0, k]
        chans.append(_signal(n, "um", y, rec, cands, ident, valid, cycle_s, **kw))
    pairs = spec.tilt_pairs()
    tilts = {}
    for p in pairs:
        y = tilt_signal(rec, p)
        tilts[p.output] = _signal(f"tilt_{p.output}", "urad", y, rec, cands, ident, valid,
                                  cycle_s, **kw)
    direct = {c.name: c for c in chans}
    if kw.get("partner", True):
        chans = _nest_pairs(chans, tilts, pairs, rec, cands, ident, valid, cycle_s)
    by_name = {c.name: c for c in chans}
    outputs: list[SignalResult] = []
    model_channels: list[ThermalChannel] = []
    lowers = {p.lower for p in pairs}
    used: set[str] = set()
    for d in ("x", "y", "z"):
        cs = [c for c in spec.channels.values() if c.direction == d]
        pick = [c for c in cs if c.name in lowers] or sorted(cs, key=lambda c: c.nest_z_mm)
        if pick and pick[0].name in by_name and pick[0].name not in used:
            s = by_name[pick[0].name]
            if len(s.fit.terms) > MAX_TERMS_PER_CHANNEL:  # composed beyond the runtime's terms
                s = direct[s.name]
            used.add(s.name)
            outputs.append(s)
            if s.fit.terms:
                model_channels.append(ThermalChannel(s.name, d, tuple(s.fit.terms),
                                                     limit=_limit(s.measured)))
    for p in pairs:
        s = tilts[p.output]
        outputs.append(s)
        if s.fit.terms:
            model_channels.append(ThermalChannel(s.name, p.output, tuple(s.fit.terms),
                                                 limit=_limit(s.measured)))
    notes = [f"identified on hours {spec.identify_hours[0]:g}-{spec.identify_hours[1]:g} of "
             f"{rec.file.rsplit('/', 1)[-1]}, validated on hours {spec.validate_hours[0]:g}-"
             f"{spec.validate_hours[1]:g}"]
    if spec.note:
        notes.append(spec.note)
    if not model_channels:
        from abbe.errors import AbbeInputError
        raise AbbeInputError("no input explains any channel on the identification hours "
                             "(every candidate term lowered the cross-validated RMS by less "
                             "than the threshold): no model to write", file=rec.file)
    model = ThermalModel(inputs=inputs_of(cands, rec.temps_c, rec.speed_rpm),
                         channels=tuple(model_channels), notes=tuple(notes))
    model.validate()
    return FitResult(rec, spec, ident, valid, chans, outputs, model, names, notes)


def _nest_pairs(chans: list[SignalResult], tilts: dict[str, SignalResult], pairs,
                rec: ThermalRecord, cands, ident: np.ndarray, valid: np.ndarray,
                cycle_s: float) -> list[SignalResult]:
    """Round 5's R5a (docs/thermal.md, "Issue 35, fifth round"): each channel of a tilt pair
    keeps its own model, or is predicted as its partner's model plus (upper) or minus
    (lower) the pair's difference, the tilt's model times the spacing, when that has both
    the lower leave-one-cycle-out and the lower forward-chaining RMS on the identification
    hours (:func:`~abbe.analysis.thermal.structure.prefers_partner`). The composed channel's
    terms are the two models' terms summed (the same input and time constant merged)."""
    t = rec.time_s
    cyc = cycles_of(t, ident, cycle_s)
    by = {c.name: c for c in chans}
    out = dict(by)
    for p in pairs:
        tilt = tilts.get(p.output)
        if tilt is None or p.lower not in by or p.upper not in by:
            continue
        k = (1.0 if p.output == "b" else -1.0) * p.spacing_mm * 1e-3  # um per urad
        y_diff = by[p.upper].measured - by[p.lower].measured
        for me, partner, sign in ((p.upper, p.lower, 1.0), (p.lower, p.upper, -1.0)):
            mine, other = by[me], by[partner]
            use, figs = prefers_partner(t, mine.measured, cands, mine.fit.terms,
                                        other.fit.terms, other.measured, tilt.fit.terms,
                                        y_diff, sign, cyc)
            if not use:
                continue
            scale = sign * k
            pred = other.predicted + scale * tilt.predicted
            terms = _merged(list(other.fit.terms), [replace(tt, gain=scale * tt.gain,
                                                            gain_u95=None if tt.gain_u95 is None
                                                            else abs(scale) * tt.gain_u95)
                                                    for tt in tilt.fit.terms])
            resid = mine.measured - pred
            fit = ChannelFit(me, terms, figs["loco_partner"], [],
                             fit_rms_um=_rms(resid[ident]),
                             offset_um=other.fit.offset_um + scale * tilt.fit.offset_um,
                             selection_cv_um=figs["loco_partner"],
                             input_set="partner+difference")
            out[me] = replace(mine, predicted=pred, fit=fit, rms_comp=_rms(resid[valid]),
                              rms_comp_ident=_rms(resid[ident]),
                              composed=(partner, tilt.name, scale), direct=mine.fit)
    return [out[c.name] for c in chans]


def _merged(a: list, b: list) -> list:
    """Terms a then b, a term of b with the same input and time constant as one of a added
    into it (gains summed, their 95 % half-widths in quadrature: the two fits' errors taken
    as independent)."""
    out = list(a)
    for tt in b:
        j = next((i for i, u in enumerate(out)
                  if u.input == tt.input and u.tau_s == tt.tau_s), None)
        if j is None:
            out.append(tt)
            continue
        u = out[j]
        g_u = (None if u.gain_u95 is None or tt.gain_u95 is None
               else float(np.hypot(u.gain_u95, tt.gain_u95)))
        out[j] = replace(u, gain=u.gain + tt.gain, gain_u95=g_u)
    return out


def _limit(y: np.ndarray) -> float:
    """The runtime's clamp: twice the largest drift seen, at least 10 (um / urad)."""
    return float(max(10.0, 2.0 * np.max(np.abs(y))))


def check_model(res: FitResult) -> float:
    """Largest difference (um / urad) between the reference evaluator on the model and the
    pipeline's own predictions: the written model is the one scored."""
    x = np.column_stack([res.record.temps_c] + ([res.record.speed_rpm[:, None]]
                                                if res.record.speed_rpm is not None else []))
    out = evaluate(res.model, res.record.time_s, x)
    by = {s.name: s for s in res.outputs}
    return float(max(np.max(np.abs(out[:, j] + by[c.name].fit.offset_um
                                   - by[c.name].predicted))
                     for j, c in enumerate(res.model.channels)))
