"""The dynamic thermal model: what identification produces and the runtime evaluates.

This module is the contract between the thermal identification (``abbe thermal``,
``abbe.analysis.thermal``), the table's thermal block (``abbe.formats``) and the C
runtime (``lib/``): one data structure and one reference evaluator, the
discretisation the C library implements. Everything else (fitting, selection,
reports, the binary layout) lives elsewhere.

The model, per output channel c (a displacement of the tool relative to the
workpiece, ISO 230-3):

    y_c(t) = sum_k g_ck * s_ck(t)                              [um, or urad for tilts]
    s_ck[n] = s_ck[n-1] + dt_n / (tau_ck + dt_n) * (u_k[n] - s_ck[n-1])
    u_k[n]  = x_k[n] - ref_k                                     (the input's rise)

x_k is an input: a temperature (deg C) or the spindle speed (rpm, used as
krpm = rpm / 1000, its heat input's proxy). Each term is the input through a
first-order lag of time constant tau (s), discretised by backward Euler, which
needs no exp() and takes any sample spacing dt_n > 0 (the C library has no libm);
tau = 0 is a static term (s = u). At the first sample every state starts at its
input's rise (the machine taken in equilibrium with its sensors); ``ref_k`` is
the input's reference value (a cold machine's temperature; 0 rpm), at which the
thermal error is zero.

Outputs (``ThermalChannel.output``): ``"x" | "y" | "z"`` add to dX, dY, dZ (um);
``"a" | "b"`` are the spindle's tilts about X and Y (urad), which move the tool
tip by the tool offset t_z (mm) as dY -= a * t_z * 1e-3, dX += b * t_z * 1e-3 (um).

Units: time s, temperatures deg C, speed rpm, gains um/K, um/krpm (urad/... for
tilts), time constants s.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from abbe.errors import AbbeInputError

#: Input kinds.
TEMPERATURE = "temperature"
SPEED = "speed"
INPUT_KINDS = (TEMPERATURE, SPEED)

#: Output components a channel may drive.
OUTPUTS = ("x", "y", "z", "a", "b")

#: Limits the runtime's block holds (the C library's arrays are sized by them).
MAX_INPUTS = 16 + 1
MAX_CHANNELS = 5
#: The stuck check's limits in the table (one byte of minutes, 16 bits of milli-units).
STUCK_MAX_MIN = 255
STUCK_RESOLUTION_CAP_MILLI = 65535
MAX_TERMS_PER_CHANNEL = 4

#: Speed inputs enter in krpm (a gain is um per krpm).
RPM_PER_KRPM = 1000.0


@dataclass(frozen=True)
class ThermalInput:
    """One input of the thermal model.

    ``name``: the sensor's name in the machine file / record (``"t3"``, ``"spindle"``).
    ``kind``: ``"temperature"`` (deg C) or ``"speed"`` (rpm).
    ``reference``: the value at which the thermal error is zero (deg C; rpm, usually 0).
    ``valid_min`` / ``valid_max``: a reading outside is a sensor fault (open circuit,
    short): deg C or rpm.
    ``max_step``: the largest credible change between two samples (deg C or rpm per
    sample); a larger one is a fault.
    ``stuck_s``: a sensor whose readings stay within ``stuck_resolution`` (deg C or rpm)
    of one value for this long (s, whole minutes, at most 255 min) is stuck (a frozen
    converter repeats a value a live sensor's noise would not); 0: no stuck check (the
    spindle speed legitimately holds a value for hours).
    """

    name: str
    kind: str = TEMPERATURE
    reference: float = 20.0
    valid_min: float = -20.0
    valid_max: float = 120.0
    max_step: float = 5.0
    stuck_s: float = 0.0
    stuck_resolution: float = 0.0

    def rise(self, value: np.ndarray | float) -> np.ndarray:
        """The input's rise u = x - ref, in the model's units (K, or krpm for speed)."""
        u = np.asarray(value, dtype=float) - self.reference
        return u / RPM_PER_KRPM if self.kind == SPEED else u


@dataclass(frozen=True)
class ThermalTerm:
    """One lagged input in a channel: ``gain`` x first-order lag(``input``, ``tau_s``).

    ``input``: index into :attr:`ThermalModel.inputs`; ``tau_s``: time constant, s
    (0 = static); ``gain``: um per K (um per krpm for speed; urad per ... for tilts).
    ``gain_u95`` / ``tau_u95_s``: the half-widths of their 95 % intervals (None if not
    computed).
    """

    input: int
    tau_s: float
    gain: float
    gain_u95: float | None = None
    tau_u95_s: float | None = None


@dataclass(frozen=True)
class ThermalChannel:
    """One modelled displacement: its output component and its terms.

    ``name``: the record's channel (``"ch5"``); ``output``: one of :data:`OUTPUTS`;
    ``limit``: the largest thermal correction the runtime applies on this channel
    (um, urad for tilts); beyond it the value is clamped and a flag raised.
    """

    name: str
    output: str
    terms: tuple[ThermalTerm, ...]
    limit: float = 200.0


@dataclass(frozen=True)
class ThermalModel:
    """A dynamic thermal model: inputs, channels, and the runtime's fault handling.

    ``max_gap_s``: a sample later than this after the previous one is a missing-sample
    fault; ``fade_s``: how long the thermal part takes to fade out after a fault (and
    back in after recovery), s.
    """

    inputs: tuple[ThermalInput, ...]
    channels: tuple[ThermalChannel, ...]
    max_gap_s: float = 60.0
    fade_s: float = 30.0
    notes: tuple[str, ...] = field(default_factory=tuple)

    def validate(self) -> None:
        """Refuse a model the runtime cannot hold (AbbeInputError naming the field)."""
        if not 1 <= len(self.inputs) <= MAX_INPUTS:
            raise AbbeInputError(f"{len(self.inputs)} inputs: expected 1..{MAX_INPUTS}",
                                 field="thermal.inputs")
        if not 1 <= len(self.channels) <= MAX_CHANNELS:
            raise AbbeInputError(f"{len(self.channels)} channels: expected 1..{MAX_CHANNELS}",
                                 field="thermal.channels")
        for i, inp in enumerate(self.inputs):
            where = f"thermal.inputs[{i}] ({inp.name})"
            if inp.kind not in INPUT_KINDS:
                raise AbbeInputError(f"kind {inp.kind!r}: expected one of {INPUT_KINDS}",
                                     field=where)
            vals = (inp.reference, inp.valid_min, inp.valid_max, inp.max_step)
            if not all(np.isfinite(vals)):
                raise AbbeInputError("a non-finite value", field=where)
            if not inp.valid_min < inp.valid_max or inp.max_step <= 0:
                raise AbbeInputError("expected valid_min < valid_max and max_step > 0",
                                     field=where)
            st, res = inp.stuck_s, inp.stuck_resolution
            res_cap = STUCK_RESOLUTION_CAP_MILLI / (1.0 if inp.kind == SPEED else 1000.0)
            if not (np.isfinite(st) and np.isfinite(res)) or not (
                    (st == 0.0 and res == 0.0)
                    or (st % 60.0 == 0.0 and 60.0 <= st <= STUCK_MAX_MIN * 60.0
                        and 0.0 <= res <= res_cap)):
                raise AbbeInputError(
                    f"stuck_s {st}, stuck_resolution {res}: expected both 0 (no stuck check) "
                    f"or stuck_s whole minutes in 60..{STUCK_MAX_MIN * 60} s and "
                    f"0 <= stuck_resolution <= {res_cap:g}", field=where)
        outs = [c.output for c in self.channels]
        if len(set(outs)) != len(outs):
            raise AbbeInputError(f"two channels drive the same output: {outs}",
                                 field="thermal.channels")
        for c in self.channels:
            where = f"thermal channel {c.name}"
            if c.output not in OUTPUTS:
                raise AbbeInputError(f"output {c.output!r}: expected one of {OUTPUTS}",
                                     field=where)
            if not 1 <= len(c.terms) <= MAX_TERMS_PER_CHANNEL:
                raise AbbeInputError(f"{len(c.terms)} terms: expected 1..{MAX_TERMS_PER_CHANNEL}",
                                     field=where)
            if not (np.isfinite(c.limit) and c.limit > 0):
                raise AbbeInputError(f"limit {c.limit}: expected > 0", field=where)
            for t in c.terms:
                if not 0 <= t.input < len(self.inputs):
                    raise AbbeInputError(f"term input {t.input} out of range", field=where)
                if not (np.isfinite(t.tau_s) and t.tau_s >= 0 and np.isfinite(t.gain)):
                    raise AbbeInputError(f"term tau {t.tau_s} s, gain {t.gain}: expected "
                                         "finite, tau >= 0", field=where)
        if not (self.max_gap_s > 0 and self.fade_s > 0):
            raise AbbeInputError("expected max_gap_s > 0 and fade_s > 0", field="thermal")


def lag_states(u: np.ndarray, t_s: np.ndarray, tau_s: float) -> np.ndarray:
    """First-order lag of the rise ``u`` (one value per sample at times ``t_s``, s).

    Backward Euler, the runtime's discretisation: s[0] = u[0];
    s[n] = s[n-1] + dt/(tau+dt) (u[n] - s[n-1]). tau = 0 returns u.
    """
    u = np.asarray(u, dtype=float)
    t = np.asarray(t_s, dtype=float)
    if tau_s == 0.0 or u.size == 0:
        return u.copy()
    dt = np.diff(t)
    if np.any(dt <= 0):
        raise AbbeInputError("sample times must increase", field="time")
    from scipy.signal import lfilter  # local: the module stays importable without scipy's cost

    w = dt / (tau_s + dt)
    if np.allclose(w, w[0], rtol=1e-12, atol=0.0):
        # a constant step: an IIR filter, s[n] = (1-w) s[n-1] + w u[n], started at u[0]
        a = 1.0 - w[0]
        out, _ = lfilter([w[0]], [1.0, -a], u[1:], zi=[a * u[0]])
        return np.concatenate(([u[0]], out))
    s = np.empty_like(u)
    s[0] = u[0]
    for n in range(1, u.size):
        s[n] = s[n - 1] + w[n - 1] * (u[n] - s[n - 1])
    return s


def evaluate(model: ThermalModel, t_s: np.ndarray, inputs: np.ndarray) -> np.ndarray:
    """The model's outputs over a record, one column per channel (um / urad).

    ``inputs``: shape (n_samples, len(model.inputs)) in the inputs' own units
    (deg C, rpm). No fault handling (the runtime's; a record with a fault is
    refused by its reader). The reference the C library's golden vectors are
    checked against.
    """
    x = np.asarray(inputs, dtype=float)
    if x.ndim != 2 or x.shape[1] != len(model.inputs):
        raise AbbeInputError(f"inputs of shape {x.shape}: expected (n, {len(model.inputs)})",
                             field="inputs")
    out = np.zeros((x.shape[0], len(model.channels)))
    for j, c in enumerate(model.channels):
        for term in c.terms:
            u = model.inputs[term.input].rise(x[:, term.input])
            out[:, j] += term.gain * lag_states(u, t_s, term.tau_s)
    return out


def tool_tip_error(model: ThermalModel, outputs_row: np.ndarray,
                   tool_z_mm: float) -> np.ndarray:
    """(dX, dY, dZ) in um of one sample's channel outputs, the tilts through the tool.

    dX += b t_z, dY -= a t_z with a, b in urad and t_z in mm (urad x mm = 1e-3 um).
    """
    d = np.zeros(3)
    for c, v in zip(model.channels, np.asarray(outputs_row, dtype=float)):
        if c.output in ("x", "y", "z"):
            d["xyz".index(c.output)] += v
        elif c.output == "a":
            d[1] -= v * tool_z_mm * 1e-3
        else:
            d[0] += v * tool_z_mm * 1e-3
    return d


#: ``thermal.json``'s format name and version (docs/thermal.md).
JSON_FORMAT = "abbe-thermal-model"
JSON_VERSION = 1


def _input_dict(i: ThermalInput) -> dict:
    d = {"name": i.name, "kind": i.kind, "reference": i.reference, "valid_min": i.valid_min,
         "valid_max": i.valid_max, "max_step": i.max_step}
    if i.stuck_s:  # written only when set: files without a stuck check stay as they were
        d.update(stuck_s=i.stuck_s, stuck_resolution=i.stuck_resolution)
    return d


def as_dict(model: ThermalModel) -> dict:
    """The model as the plain data of ``thermal.json`` (units in the keys' docs)."""
    return {
        "format": JSON_FORMAT, "version": JSON_VERSION,
        "max_gap_s": model.max_gap_s, "fade_s": model.fade_s,
        "inputs": [_input_dict(i) for i in model.inputs],
        "channels": [{"name": c.name, "output": c.output, "limit": c.limit,
                      "terms": [{"input": t.input, "tau_s": t.tau_s, "gain": t.gain,
                                 "gain_u95": t.gain_u95, "tau_u95_s": t.tau_u95_s}
                                for t in c.terms]} for c in model.channels],
        "notes": list(model.notes),
    }


def _num(d: dict, key: str, where: str, *, optional: bool = False) -> float | None:
    v = d.get(key)
    if v is None and optional:
        return None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
        raise AbbeInputError(f"{key} = {v!r}: expected a finite number", field=f"{where}.{key}")
    return float(v)


def from_dict(d: object) -> ThermalModel:
    """A :class:`ThermalModel` from ``thermal.json``'s data, validated (AbbeInputError
    naming the field otherwise)."""
    if not isinstance(d, dict) or d.get("format") != JSON_FORMAT:
        raise AbbeInputError(f"expected an object with format = {JSON_FORMAT!r}", field="format")
    if d.get("version") != JSON_VERSION:
        raise AbbeInputError(f"version {d.get('version')!r}: expected {JSON_VERSION}",
                             field="version")
    try:
        inputs = tuple(
            ThermalInput(name=str(i["name"]), kind=str(i["kind"]),
                         reference=_num(i, "reference", f"inputs[{k}]"),
                         valid_min=_num(i, "valid_min", f"inputs[{k}]"),
                         valid_max=_num(i, "valid_max", f"inputs[{k}]"),
                         max_step=_num(i, "max_step", f"inputs[{k}]"),
                         stuck_s=_num(i, "stuck_s", f"inputs[{k}]", optional=True) or 0.0,
                         stuck_resolution=_num(i, "stuck_resolution", f"inputs[{k}]",
                                               optional=True) or 0.0)
            for k, i in enumerate(d["inputs"]))
        channels = tuple(
            ThermalChannel(name=str(c["name"]), output=str(c["output"]),
                           limit=_num(c, "limit", f"channels[{j}]"),
                           terms=tuple(ThermalTerm(
                               input=int(t["input"]),
                               tau_s=_num(t, "tau_s", f"channels[{j}].terms[{n}]"),
                               gain=_num(t, "gain", f"channels[{j}].terms[{n}]"),
                               gain_u95=_num(t, "gain_u95", f"channels[{j}].terms[{n}]",
                                             optional=True),
                               tau_u95_s=_num(t, "tau_u95_s", f"channels[{j}].terms[{n}]",
                                              optional=True))
                               for n, t in enumerate(c["terms"])))
            for j, c in enumerate(d["channels"]))
        model = ThermalModel(inputs=inputs, channels=channels,
                             max_gap_s=_num(d, "max_gap_s", "thermal"),
                             fade_s=_num(d, "fade_s", "thermal"),
                             notes=tuple(str(n) for n in d.get("notes", ())))
    except (KeyError, TypeError, ValueError) as exc:
        raise AbbeInputError(f"a missing or malformed entry ({exc})", field="thermal") from exc
    model.validate()
    return model
