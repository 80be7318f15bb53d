"""An output folder of abbe (or a JSON file it printed) -> a :class:`Campaign`, strictly.

Recognised by content, never by name alone (docs/history.md, "What `add` reads"):

* ``abbe fit -o OUT``: ``model.json`` with ``"format": "abbe-fit"`` and ``model.bin``
  beside it -> per axis the ISO 230-2 values, the backlash (reversal), the thermal
  terms, the squareness when observable, the peak-to-valley of every fitted term,
  the table blob; the measurement files' SHA-256 from its provenance.
* ``abbe diagnose -o OUT``: ``diagnose.json`` (effects, gap) -> every named effect
  with its 95 % interval, the gap before / after; the updated ``model.bin``.
* ``abbe demo -o OUT``: its ``fit/`` and ``diagnose/`` folders, as above.
* ``abbe ballbar ... --json > F.json``: ISO 230-4 G per direction, H, centre
  offset and radius deviation, per plane and feed.
* ``abbe iso230-2 FILE --json > F.json``: B, R, E, A, M bidirectional and E, R, A
  per direction; the axis is not in that JSON and comes from ``--axis``.
  (``abbe ballbar / iso230-2 -o DIR`` write the same documents into DIR.)
* ``abbe fit -o OUT`` on a five-axis file, ``abbe demo --five-axis``: ``five_axis.json``
  -> every identified location error with its 95 % interval, the sphere-centre
  dispersion before / after (fitted and held out).
* ``abbe diagnose -o OUT`` on a five-axis file: ``diagnose_five_axis.json`` -> the
  held-out dispersion before / after, every named effect's amplitude with its interval.
* ``abbe fit -o OUT`` on a ``[chain]`` file: ``chain_fit.json`` -> every identified
  location error and error motion coefficient with its 95 % interval, the RMS the fit
  leaves of each rotary ballbar test; ``abbe diagnose -o OUT`` on one:
  ``diagnose_chain.json`` -> the held-out RMS and gap before / after, every named
  effect's amplitude.
* ``abbe thermal evaluate -o OUT``: ``iso230_3.json`` -> the range of every channel
  and tilt, the envelope; ``abbe thermal fit -o OUT``: ``fit.json`` -> per signal the
  held-out RMS uncompensated, by the model and by the static regression;
  ``abbe thermal diagnose -o OUT``: ``diagnosis.json`` -> per channel the held-out gap
  before / after.
* ``abbe printer fit -o OUT``: ``printer_fit.json`` -> the held-out RMS (abbe, the
  firmware's mesh, uncorrected), the warp, the squareness with its interval.
* ``abbe predict -o OUT``: ``predict.json`` -> per ballbar test the prediction
  residual (max, RMS) and the ideal compensated roundness.
* ``abbe export TARGET -o OUT``: ``residual.json`` (three- or five-axis) -> |E| max and
  RMS that the controller's tables leave over the work volume, the ballbar circles or
  the tool-centre-point path, and the uncompensated figures beside them.

A folder is searched at its top and one level down; files it holds that are not
abbe outputs (plots, C sources, notes) are passed over, but a recognised file
with a bad value stops the whole campaign (file, line, field).
"""

from __future__ import annotations

import hashlib
from pathlib import Path
from typing import Any

import numpy as np

from abbe.errors import AbbeInputError, check_number
from abbe.formats.limits import BLOB_MAX_BYTES, TABLE_JSON_MAX_BYTES
from abbe.formats.text import read_bytes
from abbe.history.document import (ANGULAR_TERMS, AXES, VALUE_LIMIT, Campaign, Result,
                                   _Doc, _hash_named_file, _read, _set_machine)
from abbe.history.output_readers import READERS

__all__ = ["Campaign", "Result", "read_campaign"]

def _kind_of(data: Any) -> str | None:
    """What produced this JSON value (None: not an abbe output add reads)."""
    if not isinstance(data, dict):
        return None
    if data.get("format") == "abbe-fit":
        return "fit"
    if "effects" in data and "gap" in data and "lack_of_fit" in data:
        return "diagnose"
    if isinstance(data.get("standard"), str) and data["standard"].startswith("ISO 230-2"):
        return "iso230-2"
    if {"plane", "bidirectional", "H_um", "feed_mm_min"} <= set(data):
        return "ballbar"
    fmt = data.get("format")
    if isinstance(fmt, str):
        return FORMATS.get(fmt.rsplit(" ", 1)[0])
    if CHAIN_FIT_KEYS <= set(data):  # chain_fit.json written before it had its format tag
        return "chain fit"
    return None


#: What a ``chain_fit.json`` without its "format" tag (abbe before it had one) holds.
CHAIN_FIT_KEYS = frozenset({"chain", "kind", "rank", "unknowns", "location", "setup_um"})


#: The "format" tag of an output (without its version) -> its kind.
FORMATS = {"abbe-five-axis": "five-axis", "abbe-five-axis-diagnose": "five-axis diagnose",
           "abbe-iso230-3": "thermal evaluate", "abbe-thermal-fit": "thermal fit",
           "abbe-thermal-diagnose": "thermal diagnose", "abbe-printer-fit": "printer fit",
           "abbe-predict": "predict", "abbe-export-residual": "export",
           "abbe-export-residual-five-axis": "export", "abbe-chain-fit": "chain fit",
           "abbe-chain-diagnose": "chain diagnose"}


# --------------------------------------------------------------------------- readers
def _read_table(c: Campaign, blob_path: Path, source: str, expect_crc: str | None,
                doc: _Doc | None, crc_field: str) -> Any:
    """model.bin beside a fit / diagnose JSON: validated blob, CRC checked; the table."""
    from abbe.formats.blob import blob_crc, read_blob
    if not blob_path.is_file():
        raise AbbeInputError(f"missing: {source} writes model.bin beside its JSON",
                             file=str(blob_path))
    raw = read_bytes(blob_path, what="table blob", max_bytes=BLOB_MAX_BYTES)
    table = read_blob(raw, source=str(blob_path))
    crc = blob_crc(raw)
    if expect_crc is not None and doc is not None:
        try:
            want = int(expect_crc, 16)
        except ValueError:
            raise doc.err(crc_field, f"expected a hexadecimal CRC-32, got {expect_crc!r}") from None
        if want != crc:
            raise doc.err(crc_field, f"{expect_crc} does not match model.bin beside it "
                                     f"(CRC 0x{crc:08X}): the folder mixes two results")
    size = int.from_bytes(raw[8:12], "little")
    blob = raw[:size]
    c.tables.append((source, blob, crc))
    c.inputs.append((f"{source}:model.bin", str(blob_path), hashlib.sha256(blob).hexdigest()))
    c.parts.append((f"{source}:model.bin", hashlib.sha256(blob).hexdigest()))
    return table


def _term_pv(table: Any) -> list[tuple[str, str, float]]:
    """Peak-to-valley of every fitted term over its axis' travel (201 points): (axis, term, pv)."""
    from abbe.model.table import basis_matrix
    out = []
    for a in AXES:
        ax = table.axes.get(a)
        if ax is None:
            continue
        p = np.linspace(ax.travel_mm[0], ax.travel_mm[1], 201)
        basis = basis_matrix(ax, p)
        for term in ax.present_terms():
            v = basis @ np.asarray(ax.coef[term], dtype=np.float64)
            out.append((a, term, float(v.max() - v.min())))
    return out


def _k(doc: _Doc, dotted: str) -> float:
    """The coverage factor a producer states at ``dotted`` (every abbe output: 2)."""
    k = doc.num(dotted, optional=True, lo=1.0, hi=10.0)
    return 2.0 if k is None else float(k)


def _ci(value: float, se: float | None) -> tuple[float | None, float | None]:
    if se is None:
        return None, None
    return value - 1.959964 * se, value + 1.959964 * se


def read_fit(c: Campaign, doc: _Doc) -> None:
    """``model.json`` of ``abbe fit`` (docs/formats.md, "model.json") and its model.bin."""
    c.kinds.append("fit")
    c.parts.append(("fit", doc.sha256))
    c.inputs.append(("fit:model.json", str(doc.path), doc.sha256))
    name = doc.get("machine.name", str)
    _set_machine(c, name, doc, "machine.name")
    for role, entry in sorted(doc.get("provenance.inputs").items()):
        where = f"provenance.inputs.{role}"
        if not isinstance(entry, dict):
            raise doc.err(where, "expected an object with file and sha256")
        sha = entry.get("sha256")
        if not isinstance(sha, str) or len(sha) != 64 or any(ch not in "0123456789abcdef"
                                                              for ch in sha):
            raise doc.err(f"{where}.sha256", "expected 64 lower-case hexadecimal digits")
        c.inputs.append((f"measurement:{role}", str(entry.get("file", "")), sha))
    for a, _ax in sorted(doc.get("axes").items()):
        if a not in AXES:
            raise doc.err(f"axes.{a}", f"unknown axis {a!r} (expected X, Y or Z)")
        base = f"axes.{a}"
        iso = doc.get(f"{base}.iso230_2", dict, optional=True)
        if iso is not None:
            k = _k(doc, f"{base}.iso230_2.U_k")
            for q in ("B", "R", "E", "A", "M"):
                v = doc.num(f"{base}.iso230_2.{q}_um")
                U = doc.num(f"{base}.iso230_2.{q}_U_um", optional=True, lo=0)
                c.results.append(Result(f"iso230-2 {q} {a} bi", "fit", f"iso230-2 {q}", v, "um",
                                        axis=a, direction="bi", U=U, k=k))
        bl = doc.get(f"{base}.backlash", dict, optional=True)
        if bl is not None:
            v = doc.num(f"{base}.backlash.mean_reversal_um")
            lo, hi = _ci(v, doc.num(f"{base}.backlash.se_um", optional=True, lo=0))
            c.results.append(Result(f"fit backlash {a}", "fit", "backlash (mean reversal)", v,
                                    "um", axis=a, ci_low=lo, ci_high=hi))
        th = doc.get(f"{base}.thermal", dict, optional=True)
        if th is not None:
            t = doc.num(f"{base}.thermal.tref_c", optional=True, lo=-50, hi=150)
            if t is not None:
                c.temperatures.append((f"fit: laser {a} (mean logged)", t))
            for key, q, unit in (("offset_um_per_k", "thermal offset", "um/K"),
                                 ("expansion_ppm_per_k", "thermal expansion", "ppm/K")):
                v = doc.num(f"{base}.thermal.{key}", optional=True)
                if v is None:
                    continue
                se = doc.num(f"{base}.thermal.se_{key}", optional=True, lo=0)
                lo, hi = _ci(v, se)
                c.results.append(Result(f"fit {q} {a}", "fit", q, v, unit, axis=a,
                                        ci_low=lo, ci_high=hi))
    sq = doc.get("squareness", dict, optional=True)
    if sq is not None and sq.get("observable") is True:
        for pl in ("xy", "xz", "yz"):
            v = doc.num(f"squareness.S_{pl}_urad")
            c.results.append(Result(f"fit squareness {pl}", "fit", "squareness", v, "urad",
                                    plane=pl.upper()))
    crc = doc.get("table.crc32", str, optional=True)
    table = _read_table(c, doc.path.parent / "model.bin", "fit", crc, doc, "table.crc32")
    for a, term, pv in _term_pv(table):
        unit = "urad" if term in ANGULAR_TERMS else "um"
        c.results.append(Result(f"fit term {a} {term} pv", "fit", f"term {term} peak-to-valley",
                                pv, unit, axis=a))


def read_diagnose(c: Campaign, doc: _Doc, with_table: bool) -> None:
    """``diagnose.json`` of ``abbe diagnose`` (docs/formats.md, "diagnose JSON")."""
    c.kinds.append("diagnose")
    c.parts.append(("diagnose", doc.sha256))
    c.inputs.append(("diagnose:diagnose.json", str(doc.path), doc.sha256))
    effects = doc.get("effects", list)
    for i, e in enumerate(effects):
        w = f"effects[{i}]"
        if not isinstance(e, dict):
            raise doc.err(w, "expected an object")
        key = e.get("key")
        unit = e.get("unit")
        if not isinstance(key, str) or not key or len(key) > 80:
            raise doc.err(f"{w}.key", "expected the effect's key (a string)")
        if not isinstance(unit, str) or not unit or len(unit) > 20:
            raise doc.err(f"{w}.unit", "expected the unit (a string)")
        v = _num_at(doc, e.get("value"), f"{w}.value")
        lo = hi = None
        ci = e.get("ci95")
        if ci is not None:
            if not isinstance(ci, list) or len(ci) != 2:
                raise doc.err(f"{w}.ci95", "expected [low, high] or null")
            lo = None if ci[0] is None else _num_at(doc, ci[0], f"{w}.ci95[0]")
            hi = None if ci[1] is None else _num_at(doc, ci[1], f"{w}.ci95[1]")
        axis = e.get("axis") if isinstance(e.get("axis"), str) else None
        plane = e.get("plane") if isinstance(e.get("plane"), str) else None
        U = None if e.get("U") is None else _num_at(doc, e.get("U"), f"{w}.U")
        if U is not None and U < 0:
            raise doc.err(f"{w}.U", f"expected U >= 0, got {U!r}")
        c.results.append(Result(f"diagnose {key}", "diagnose", key, v, unit, axis=axis,
                                plane=plane, ci_low=lo, ci_high=hi, U=U,
                                k=_k(doc, "uncertainty.k")))
    for when in ("before", "after"):
        v = doc.num(f"gap.{when}.rms_um", lo=0)
        U = doc.num(f"gap.{when}.rms_U_um", optional=True, lo=0)
        c.results.append(Result(f"diagnose gap rms {when}", "diagnose", f"gap rms {when}", v,
                                "um", U=U, k=_k(doc, "uncertainty.k")))
    inp = doc.get("input", dict, optional=True) or {}
    _hash_named_file(c, inp.get("machine"), "measurement:machine", doc.path)
    if with_table:
        _read_table(c, doc.path.parent / "model.bin", "diagnose", None, None, "")


def _num_at(doc: _Doc, v: Any, where: str) -> float:
    try:
        return check_number(v, file=str(doc.path), field=where, lo=-VALUE_LIMIT, hi=VALUE_LIMIT)
    except AbbeInputError as exc:
        raise doc.err(where, exc.message) from None


def read_ballbar(c: Campaign, doc: _Doc) -> None:
    """The JSON ``abbe ballbar ... --json`` prints (ISO 230-4)."""
    c.kinds.append("ballbar")
    c.parts.append(("ballbar", doc.sha256))
    c.inputs.append(("ballbar:json", str(doc.path), doc.sha256))
    name = doc.get("machine_name", str, optional=True)  # abbe ballbar writes it (not "machine")
    if name:
        _set_machine(c, name, doc, "machine_name")
    plane = doc.get("plane", str)
    if plane not in ("XY", "ZX", "YZ", "XZ"):
        raise doc.err("plane", f"expected XY, ZX or YZ, got {plane!r}")
    feed = doc.num("feed_mm_min", lo=0, hi=1e6)
    tag = f"{plane} F{feed:g}"
    def U_of(name: str) -> dict[str, float | None]:
        """The U (k) abbe ballbar states for ``name`` (uncertainty.results), if any."""
        U = doc.num(f"uncertainty.results.{name}.U_um", optional=True, lo=0)
        return {"U": U, "k": _k(doc, f"uncertainty.results.{name}.k")}

    for d in ("ccw", "cw", "bidirectional"):
        v = doc.num(f"{d}.G_um", lo=0)
        short = "bi" if d == "bidirectional" else d
        c.results.append(Result(f"ballbar G {tag} {short}", "ballbar", "iso230-4 G", v, "um",
                                direction=short, plane=plane, feed_mm_min=feed, **U_of(f"G_{d}")))
    c.results.append(Result(f"ballbar H {tag}", "ballbar", "iso230-4 H", doc.num("H_um", lo=0),
                            "um", plane=plane, feed_mm_min=feed, **U_of("H")))
    c.results.append(Result(f"ballbar radius deviation {tag}", "ballbar", "radius deviation",
                            doc.num("bidirectional.radius_dev_um"), "um", plane=plane,
                            feed_mm_min=feed, **U_of("radius_dev")))
    for k in sorted(doc.get("bidirectional")):
        if k.startswith("center_") and k.endswith("_um"):
            ax = k[len("center_"):-3].upper()
            c.results.append(Result(f"ballbar centre {ax} {tag}", "ballbar", "centre offset",
                                    doc.num(f"bidirectional.{k}"), "um", axis=ax, plane=plane,
                                    feed_mm_min=feed))
    _hash_named_file(c, doc.data.get("file"), "measurement:ballbar", doc.path)


def read_iso230_2(c: Campaign, doc: _Doc, axis: str) -> None:
    """The JSON ``abbe iso230-2 FILE --json`` prints, for ``axis``."""
    c.kinds.append("iso230-2")
    c.parts.append((f"iso230-2 {axis}", doc.sha256))
    c.inputs.append((f"iso230-2:json {axis}", str(doc.path), doc.sha256))
    name = doc.get("machine", str, optional=True)  # with --machine: the machine file's name
    if name:
        _set_machine(c, name, doc, "machine")
    for q in ("B", "R", "E", "A", "M"):
        c.results.append(Result(f"iso230-2 {q} {axis} bi", "iso230-2", f"iso230-2 {q}",
                                doc.num(f"{q}_um"), "um", axis=axis, direction="bi",
                                U=doc.num(f"uncertainty.results.{q}.U_um", optional=True, lo=0),
                                k=_k(doc, f"uncertainty.results.{q}.k")))
    uni = doc.get("unidirectional", dict, optional=True)
    if uni is not None:
        for d in ("up", "down"):
            for q in ("E", "R", "A"):
                c.results.append(Result(f"iso230-2 {q} {axis} {d}", "iso230-2", f"iso230-2 {q}",
                                        doc.num(f"unidirectional.{d}.{q}_um"), "um", axis=axis,
                                        direction=d))
    _hash_named_file(c, doc.data.get("file"), f"measurement:iso230-2 {axis}", doc.path)


# --------------------------------------------------------------------------- folders
def _candidates(path: Path) -> list[Path]:
    """JSON files of a folder and of its direct subfolders, in a fixed order."""
    out = sorted(p for p in path.glob("*.json") if p.is_file())
    for sub in sorted(q for q in path.iterdir() if q.is_dir() and not q.name.startswith(".")):
        out += sorted(p for p in sub.glob("*.json") if p.is_file())
    return out


def read_campaign(paths: list[str], axes: dict[str, str], machine: str | None) -> Campaign:
    """Read every output ``paths`` names into one campaign.

    ``axes``: the axis of each ISO 230-2 JSON (file name -> X|Y|Z, or "" -> the axis
    when there is one such file); ``machine``: ``--machine`` (checked against the
    name a fit output carries)."""
    c = Campaign(machine=machine)
    docs: list[tuple[str, _Doc, bool]] = []  # kind, doc, explicit
    for text in paths:
        p = Path(text)
        if not p.exists():
            raise AbbeInputError("no such file or folder", file=text)
        if p.is_file():
            doc = _read(p, "abbe output JSON")
            kind = _kind_of(doc.data)
            if kind is None:
                raise AbbeInputError("not an output abbe history reads (expected the JSON of "
                                     "abbe ballbar --json, abbe iso230-2 --json, a fit's "
                                     "model.json, five_axis.json or chain_fit.json, a "
                                     "diagnose.json or an "
                                     "output of abbe thermal, printer fit, predict or export)",
                                     file=text)
            docs.append((kind, doc, True))
            continue
        found = 0
        for f in _candidates(p):
            if f.stat().st_size > TABLE_JSON_MAX_BYTES:
                continue
            doc = _read(f, "abbe output JSON")
            kind = _kind_of(doc.data)
            if kind is not None:
                docs.append((kind, doc, False))
                found += 1
        if not found:
            raise AbbeInputError("no abbe output here: expected the -o folder of an abbe "
                                 "command that evaluates (fit, diagnose, demo, ballbar, "
                                 "iso230-2, thermal, printer fit, predict, export) or its "
                                 "JSON",
                                 file=text)
    seen: dict[tuple[str, str], tuple[_Doc, bool]] = {}
    for kind, doc, _explicit in docs:
        has_bin = (doc.path.parent / "model.bin").is_file()
        key = (kind, doc.sha256)
        if key in seen:  # the demo writes diagnose.json twice: keep the one beside its table
            if has_bin and not seen[key][1]:
                seen[key] = (doc, has_bin)
            continue
        seen[key] = (doc, has_bin)
    iso_docs = [d for (k, _), (d, _) in seen.items() if k == "iso230-2"]
    for (kind, _), (doc, has_bin) in seen.items():
        if kind == "fit":
            read_fit(c, doc)
        elif kind == "diagnose":
            read_diagnose(c, doc, with_table=has_bin)
        elif kind == "ballbar":
            read_ballbar(c, doc)
        elif kind in READERS:
            READERS[kind](c, doc)
    used = set()
    for doc in iso_docs:
        axis = axes.get(doc.path.name) or axes.get(str(doc.path))
        if axis is None and "" in axes and len(iso_docs) == 1:
            axis = axes[""]
        if axis is None:
            raise AbbeInputError("the ISO 230-2 JSON does not say its axis: give --axis X "
                                 "(one such file) or --axis FILE=X", file=str(doc.path))
        used.add(doc.path.name)
        read_iso230_2(c, doc, axis)
    extra = [k for k in axes if k and k not in used and not any(str(d.path) == k for d in iso_docs)]
    if extra:
        raise AbbeInputError(f"no ISO 230-2 JSON named {extra[0]!r} among the inputs",
                             field="--axis")
    if "" in axes and len(iso_docs) != 1:
        raise AbbeInputError(f"--axis {axes['']} without a file name needs exactly one ISO "
                             f"230-2 JSON among the inputs, found {len(iso_docs)}",
                             field="--axis")
    if c.machine is None:
        raise AbbeInputError("these outputs do not name their machine: give --machine NAME",
                             field="--machine")
    # ISO 230-2 values of an axis given both by a fit and by abbe iso230-2: the latter
    # (it also has the values per direction) is kept
    iso_axes = {r.series for r in c.results if r.source == "iso230-2"}
    c.results = [r for r in c.results if not (r.source == "fit" and r.series in iso_axes)]
    series = [r.series for r in c.results]
    dup = {s for s in series if series.count(s) > 1}
    if dup:
        raise AbbeInputError(f"two outputs of this campaign give {sorted(dup)[0]!r}: add them "
                             "as separate campaigns", file=paths[0])
    c.kinds = sorted(set(c.kinds))
    return c
