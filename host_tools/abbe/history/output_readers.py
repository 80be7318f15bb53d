"""Readers of the outputs added after the laser fit's: the five-axis fit and diagnose (the
trunnions' and any kinematic chain's),
the thermal evaluation / fit / diagnosis, the printer fit, predict and export (their
"format" tag names them; docs/history.md lists the series each stores)."""

from __future__ import annotations

from abbe.history.document import (Campaign, Result, _begin, _Doc, _entry_num, _entry_str,
                                   _list, _unit)

#: the coverage factor of every U abbe's outputs state (docs/uncertainty.md)
K = 2.0

def read_five_axis(c: Campaign, doc: _Doc) -> None:
    """``five_axis.json`` of ``abbe fit`` on a five-axis file: the identified location
    errors (value, 95 % interval) and the sphere-centre dispersion."""
    _begin(c, doc, "five-axis")
    for i, p in enumerate(_list(doc, "parameters")):
        where = f"parameters[{i}]"
        if not isinstance(p, dict) or p.get("kind") != "location" or p.get("observable") is not True:
            continue
        name = _entry_str(doc, p, "name", where)
        v = _entry_num(doc, p, "value", where)
        ci = _entry_num(doc, p, "ci95", where, lo=0)
        U = _entry_num(doc, p, "U", where, lo=0, optional=True)
        assert v is not None and ci is not None
        c.results.append(Result(f"five-axis {name}", "five-axis", "location error", v,
                                _unit(doc, p.get("unit"), f"{where}.unit"), axis=name[-1],
                                ci_low=v - ci, ci_high=v + ci, U=U, k=K))
    for key in ("before", "after", "heldout_before", "heldout_after"):
        v = doc.num(f"dispersion_um.{key}", optional=True, lo=0)
        if v is not None:
            c.results.append(Result(f"five-axis dispersion {key.replace('_', ' ')}", "five-axis",
                                    "sphere-centre dispersion RMS", v, "um"))


def read_five_axis_diagnose(c: Campaign, doc: _Doc) -> None:
    """``diagnose_five_axis.json``: held-out dispersion before / after, named effects."""
    _begin(c, doc, "five-axis diagnose")
    for key in ("heldout_before_um", "heldout_after_um"):
        v = doc.num(key, lo=0)
        assert v is not None
        c.results.append(Result(f"five-axis diagnose {key[:-3].replace('_', ' ')}",
                                "five-axis diagnose", "held-out dispersion RMS", v, "um"))
    for i, n in enumerate(_list(doc, "named")):
        where = f"named[{i}]"
        eff = _entry_str(doc, n, "effect", where)
        v = _entry_num(doc, n, "amplitude", where)
        ci = _entry_num(doc, n, "amplitude_ci95", where, lo=0, optional=True)
        assert v is not None
        c.results.append(Result(f"five-axis diagnose {eff} amplitude", "five-axis diagnose",
                                "effect amplitude", v, "um",
                                ci_low=None if ci is None else v - ci,
                                ci_high=None if ci is None else v + ci))


def read_thermal_evaluate(c: Campaign, doc: _Doc) -> None:
    """``iso230_3.json`` of ``abbe thermal evaluate -o``: range per channel and tilt."""
    _begin(c, doc, "thermal evaluate")
    for key, unit in (("channels", "um"), ("tilts", "urad")):
        for i, d in enumerate(_list(doc, key)):
            where = f"{key}[{i}]"
            name = _entry_str(doc, d, "name", where)
            v = _entry_num(doc, d, "range", where, lo=0)
            U = _entry_num(doc, d, "U", where, lo=0, optional=True)
            assert v is not None
            c.results.append(Result(f"iso230-3 range {name}", "thermal evaluate",
                                    "thermal drift range", v, unit, U=U, k=K))
    v = doc.num("envelope.range_um", lo=0)
    assert v is not None
    c.results.append(Result("iso230-3 envelope", "thermal evaluate", "thermal drift envelope",
                            v, "um", U=doc.num("envelope.U_um", optional=True, lo=0), k=K))


def read_thermal_fit(c: Campaign, doc: _Doc) -> None:
    """``fit.json`` of ``abbe thermal fit``: held-out RMS per signal."""
    _begin(c, doc, "thermal fit")
    for i, s in enumerate(_list(doc, "signals")):
        where = f"signals[{i}]"
        name = _entry_str(doc, s, "name", where)
        unit = _unit(doc, s.get("unit"), f"{where}.unit")
        for key, q in (("rms_uncompensated", "uncompensated"), ("rms_model", "model"),
                       ("rms_mlr", "static regression")):
            v = _entry_num(doc, s, key, where, lo=0)
            assert v is not None
            c.results.append(Result(f"thermal fit {name} held-out rms {q}", "thermal fit",
                                    f"held-out RMS, {q}", v, unit))


def read_thermal_diagnose(c: Campaign, doc: _Doc) -> None:
    """``diagnosis.json`` of ``abbe thermal diagnose``: the held-out gap per channel."""
    _begin(c, doc, "thermal diagnose")
    for i, ch in enumerate(_list(doc, "channels")):
        where = f"channels[{i}]"
        name = _entry_str(doc, ch, "channel", where)
        for key, q in (("gap_heldout_um", "before"), ("after_heldout_um", "after")):
            v = _entry_num(doc, ch, key, where, lo=0, optional=True)
            if v is not None:
                c.results.append(Result(f"thermal diagnose {name} held-out gap {q}",
                                        "thermal diagnose", f"held-out gap, {q}", v, "um"))


def read_printer_fit(c: Campaign, doc: _Doc) -> None:
    """``printer_fit.json`` of ``abbe printer fit``."""
    _begin(c, doc, "printer fit")
    for key, q in (("heldout.abbe_rms_um", "held-out RMS, abbe"),
                   ("heldout.firmware_mesh_rms_um", "held-out RMS, firmware mesh"),
                   ("heldout.uncorrected_rms_um", "held-out RMS, uncorrected"),
                   ("nonseparable_rms_um", "warp RMS (not held by axis terms)")):
        v = doc.num(key, optional=True, lo=0)
        if v is not None:
            c.results.append(Result(f"printer {q}", "printer fit", q, v, "um"))
    sq = doc.get("squareness_urad", dict, optional=True) or {}
    for plane in sorted(sq):
        v = doc.num(f"squareness_urad.{plane}")
        u = doc.num(f"squareness_u95_urad.{plane}", optional=True, lo=0)
        U = doc.num(f"squareness_U_urad.{plane}", optional=True, lo=0)
        assert v is not None
        c.results.append(Result(f"printer squareness {plane}", "printer fit", "squareness", v,
                                "urad", plane=plane[:8], ci_low=None if u is None else v - u,
                                ci_high=None if u is None else v + u, U=U, k=K))


def read_predict(c: Campaign, doc: _Doc) -> None:
    """``predict.json`` of ``abbe predict -o``: residual per ballbar test."""
    _begin(c, doc, "predict")
    for i, p in enumerate(_list(doc, "predictions")):
        where = f"predictions[{i}]"
        name = _entry_str(doc, p, "ballbar", where)
        for key, q in (("residual_max_um", "prediction residual max"),
                       ("residual_rms_um", "prediction residual RMS"),
                       ("ideal_roundness_um", "ideal compensated roundness")):
            v = _entry_num(doc, p, key, where, lo=0)
            U = _entry_num(doc, p, key[:-3] + "_U_um", where, lo=0, optional=True)
            assert v is not None
            c.results.append(Result(f"predict {name} {q}", "predict", q, v, "um", U=U, k=K))


def read_export(c: Campaign, doc: _Doc) -> None:
    """``residual.json`` of ``abbe export -o``: what the controller's tables leave, |E| max
    and RMS over the work volume (and the ballbar circles or the TCP path), with the
    uncompensated figures beside it."""
    _begin(c, doc, "export", names_machine=False)
    target = doc.get("target", str)
    keys = ["volume"] + (["tcp_path"] if "tcp_path" in doc.data else [])
    keys += [f"circles.{n}" for n in sorted(doc.get("circles", dict, optional=True) or {})]
    for key in keys:
        for state in ("residual", "uncompensated"):
            for stat in ("max_um", "rms_um"):
                v = doc.num(f"{key}.{state}.norm.{stat}", lo=0)
                assert v is not None
                what = key.replace("circles.", "circle ").replace("_", " ")
                c.results.append(Result(
                    f"export {target} {what} {state} |E| {stat[:-3]}", "export",
                    f"{state} |E| {stat[:-3]} after the export", v, "um"))


def _rotary_axis(name: str) -> str:
    """The rotary axis an ISO 230-7 name belongs to: ``EX0C`` -> C, ``EXC(C) sin2`` -> C."""
    return name.split("(")[1][0] if "(" in name else name[-1]


def read_chain_fit(c: Campaign, doc: _Doc) -> None:
    """``chain_fit.json`` of ``abbe fit`` on a ``[chain]`` machine file (head-head,
    head-table, dual-rotary table, a trunnion as a chain): every identified location error
    and error motion coefficient (value, 95 % interval; the ones the plan cannot see are
    not stored, never as 0) and what the fit leaves of each rotary ballbar test (RMS)."""
    _begin(c, doc, "chain fit")
    doc.get("chain", str)
    for key, quantity in (("location", "location error"),
                          ("motions", "error motion coefficient")):
        for i, p in enumerate(_list(doc, key) if key in doc.data else []):
            where = f"{key}[{i}]"
            if not isinstance(p, dict):
                raise doc.err(where, "expected an object")
            if p.get("status") != "identified":
                continue
            name = _entry_str(doc, p, "name", where)
            v = _entry_num(doc, p, "value", where)
            u = _entry_num(doc, p, "u95", where, lo=0)
            U = _entry_num(doc, p, "U", where, lo=0, optional=True)
            assert v is not None and u is not None
            c.results.append(Result(f"chain {name}", "chain fit", quantity, v,
                                    _unit(doc, p.get("unit"), f"{where}.unit"),
                                    axis=_rotary_axis(name), ci_low=v - u, ci_high=v + u,
                                    U=U, k=K))
    tests = doc.get("rotary_ballbar", dict, optional=True) or {}
    for n in sorted(tests):
        v = doc.num(f"rotary_ballbar.{n}.left_rms_um", lo=0)
        assert v is not None
        c.results.append(Result(f"chain ballbar {n} left RMS", "chain fit",
                                "rotary ballbar length RMS the fit leaves", v, "um"))


def read_chain_diagnose(c: Campaign, doc: _Doc) -> None:
    """``diagnose_chain.json`` of ``abbe diagnose`` on a ``[chain]`` machine file: the
    held-out sphere-centre RMS and the gap before / after, every named effect's amplitude."""
    _begin(c, doc, "chain diagnose")
    for key in ("heldout_before_um", "heldout_after_um", "gap_before_um", "gap_after_um"):
        v = doc.num(key, lo=0)
        assert v is not None
        what = "held-out sphere-centre RMS" if key.startswith("heldout") else \
            "held-out RMS above the floor (gap)"
        c.results.append(Result(f"chain diagnose {key[:-3].replace('_', ' ')}",
                                "chain diagnose", what, v, "um"))
    for i, n in enumerate(_list(doc, "named")):
        where = f"named[{i}]"
        eff = _entry_str(doc, n, "effect", where)
        v = _entry_num(doc, n, "amplitude", where)
        assert v is not None
        c.results.append(Result(f"chain diagnose {eff} amplitude", "chain diagnose",
                                "effect amplitude", v, _unit(doc, n.get("unit"), f"{where}.unit"),
                                axis=_rotary_axis(eff.split(" ")[0])))


READERS = {"five-axis": read_five_axis, "five-axis diagnose": read_five_axis_diagnose,
           "chain fit": read_chain_fit, "chain diagnose": read_chain_diagnose,
           "thermal evaluate": read_thermal_evaluate, "thermal fit": read_thermal_fit,
           "thermal diagnose": read_thermal_diagnose, "printer fit": read_printer_fit,
           "predict": read_predict, "export": read_export}
