"""A laser line's readings from whatever files the machine file names: abbe's 6D laser CSV
(or a declared export), one Renishaw ``.rtl`` file, or one ``.rtl`` file per channel
(``files = { linear = "x.rtl", pitch = "x_pitch.rtl" }``).

Every path gives the same :class:`abbe.formats.laser_csv.LaserData`; the linear channel
is normalised to 20 deg C when the file says how (:mod:`abbe.formats.thermal20`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from abbe.errors import AbbeInputError
from abbe.formats import renishaw_rtl, thermal20
from abbe.formats.laser_csv import TARGET_TOL_MM, LaserData, read_laser_csv
from abbe.formats.machine import LaserLine

#: abbe channel -> the .rtl measurement type that can give it.
CHANNEL_KIND = {"linear": "linear", "straight_h": "straightness", "straight_v": "straightness",
                "pitch": "angular", "yaw": "angular", "roll": "angular"}


def csv_normalisation(d: LaserData, linear: np.ndarray
                      ) -> tuple[thermal20.Normalisation | None, np.ndarray]:
    """20 deg C for a laser CSV: with ``temp_c`` and ``expansion_ppm_per_k`` the linear
    readings (n, 2, T) are corrected (returned corrected); with ``temp_c`` alone the
    status says why not."""
    if d.temp_c is None:
        return None, linear
    span = float(d.targets_mm[-1] - d.targets_mm[0])
    t_mean = float(np.mean(d.temp_c))
    if d.expansion_ppm_per_k is None:
        return thermal20.Normalisation(
            thermal20.NOT_APPLIED, "the file has temp_c but no expansion_ppm_per_k column",
            material_temp_c=t_mean, span_mm=span), linear
    a = d.expansion_ppm_per_k
    pos = np.broadcast_to(d.targets_mm, linear.shape)
    corr = thermal20.correction_um(pos, float(d.targets_mm[0]), d.temp_c, a)
    return thermal20.Normalisation(
        thermal20.APPLIED, "temp_c and expansion_ppm_per_k of the file, per reading, about "
        "the first target", material_temp_c=t_mean, expansion_ppm_per_k=a, span_mm=span,
        nominal_differential_expansion_um=thermal20.nominal_expansion_um(a, t_mean, span)
    ), linear - corr


def rtl_normalisation(r: renishaw_rtl.RtlFile) -> thermal20.Normalisation | None:
    """20 deg C for an ``.rtl`` file: Renishaw's software compensates the material
    expansion when its coefficient is not 0 (docs/formats.md, assumption R7), so abbe
    reports the nominal differential expansion and applies nothing."""
    t = r.material_temp_c()
    if "Exp coeff" not in r.environment:
        return None
    span = float(abs(r.targets_mm[-1] - r.targets_mm[0]))
    a = float(np.mean(r.environment["Exp coeff"]))
    if a == 0.0:
        return thermal20.Normalisation(
            thermal20.NOT_APPLIED, "the file's expansion coefficient is 0: material "
            "compensation was off, and the material's coefficient is not known",
            material_temp_c=t, span_mm=span)
    if t is None:
        return thermal20.Normalisation(
            thermal20.NOT_APPLIED, "no material temperature sensor connected",
            expansion_ppm_per_k=a, span_mm=span)
    return thermal20.Normalisation(
        thermal20.BY_INSTRUMENT, "the .rtl file has an expansion coefficient and material "
        "temperatures: the laser software normalised the readings",
        material_temp_c=t, expansion_ppm_per_k=a, span_mm=span,
        nominal_differential_expansion_um=thermal20.nominal_expansion_um(a, t, span))


def _check_range(r: renishaw_rtl.RtlFile, lim: tuple[float, float] | None, what: str) -> None:
    if lim is None:
        return
    lo, hi = min(lim), max(lim)
    bad = np.flatnonzero((r.targets_mm < lo - TARGET_TOL_MM) | (r.targets_mm > hi + TARGET_TOL_MM))
    if bad.size:
        raise AbbeInputError(f"target {r.targets_mm[bad[0]]:.6g} mm is outside {what} "
                             f"[{lo:g}, {hi:g}] mm", file=r.file, line=r.key_lines.get("Targets"),
                             field="Targets")


def read_rtl_channels(files: dict[str, Path], *, travel_mm: tuple[float, float] | None = None,
                      span_mm: tuple[float, float] | None = None) -> LaserData:
    """One ``.rtl`` file per channel, merged into one :class:`LaserData`: each file's
    measurement type must give its channel, and every file must have the same
    targets and runs."""
    first: renishaw_rtl.RtlFile | None = None
    chans: dict[str, np.ndarray] = {}
    lines = None
    norm = None
    for ch, path in files.items():
        r = renishaw_rtl.read_rtl(path)
        if CHANNEL_KIND[ch] != r.kind:
            raise AbbeInputError(f"measurement type {r.owner!r} cannot give channel {ch!r} "
                                 f"(it needs a {CHANNEL_KIND[ch]} measurement)", file=str(path),
                                 line=r.key_lines.get("Owner"), field="Owner")
        _check_range(r, travel_mm, "the axis travel")
        _check_range(r, span_mm, "the line's start..end")
        if first is None:
            first = r
        elif (r.targets_mm.size != first.targets_mm.size
              or np.any(np.abs(r.targets_mm - first.targets_mm) > TARGET_TOL_MM)):
            raise AbbeInputError(f"other targets than {first.file}: every channel of a line "
                                 "must be measured at the same targets", file=str(path),
                                 line=r.key_lines.get("Targets"), field="Targets")
        elif r.n_runs != first.n_runs:
            raise AbbeInputError(f"{r.n_runs} runs, {first.file} has {first.n_runs}: every "
                                 "channel of a line needs the same runs", file=str(path),
                                 line=r.key_lines.get("Run-count"), field="Run-count")
        targets, up, down, ln = r.by_direction()
        chans[ch] = np.stack([up, down], axis=1)
        if lines is None:
            lines = ln
        if ch == "linear":
            norm = rtl_normalisation(r)
    assert first is not None and lines is not None
    main = next(iter(files.values()))
    return LaserData(file=Path(main), targets_mm=np.sort(first.targets_mm), channels=chans,
                     time_s=None, temp_c=None, line_no=lines, sha256=first.sha256,
                     normalisation=norm)


def read_laser_line(line: LaserLine, *, channels: tuple[str, ...],
                    travel_mm: tuple[float, float] | None = None,
                    span_mm: tuple[float, float] | None = None) -> LaserData:
    """The readings of a machine file's laser line, from a CSV, one ``.rtl`` file (a
    linear measurement) or one ``.rtl`` file per channel (``files``)."""
    if line.files:
        missing = [c for c in channels if c not in line.files]
        if missing:
            raise AbbeInputError(f"the machine file maps channel {missing[0]!r} but names no "
                                 f"file for it in 'files'", file=str(line.file), field=missing[0])
        return read_rtl_channels(line.files, travel_mm=travel_mm, span_mm=span_mm)
    if renishaw_rtl.looks_like_rtl(line.file):
        r = renishaw_rtl.read_rtl(line.file)
        if r.kind != "linear" or set(channels) - {"linear"}:
            raise AbbeInputError(
                f"one .rtl file holds one channel (this one: {r.owner!r}); name a file per "
                f"channel with files = {{ linear = ..., pitch = ... }} in [laser.{line.axis}]",
                file=str(line.file), line=r.key_lines.get("Owner"), field="Owner")
        return read_rtl_channels({"linear": line.file}, travel_mm=travel_mm, span_mm=span_mm)
    d = read_laser_csv(line.file, channels=channels, travel_mm=travel_mm, span_mm=span_mm,
                       columns=line.columns)
    if "linear" in d.channels:
        d.normalisation, d.channels["linear"] = csv_normalisation(d, d.channels["linear"])
    return d
