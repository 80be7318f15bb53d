"""Independent readers of three JSON outputs, written from docs/formats.md alone (its
sections on `chain_fit.json`, `predict.json` and `iso230_3.json`, and the pages they
point to: docs/uncertainty.md, docs/thermal.md), not from the writers.

Each ``read_*`` parses the file strictly (no NaN / Infinity, no repeated key), checks every
documented field (type, unit, range) and every invariant the documents state (the
version tag, k = 2, U = 2 u >= 0, the first-order U the root sum of squares of its lines,
the 10 % rule that picks the stated U, range = max - min, the envelope the largest
channel, the SHA-256 and CRC-32 of the files named) and returns the parsed document.
A violation raises ``FormatError`` naming the place. Nothing is imported from abbe.
"""

from __future__ import annotations

import hashlib
import json
import math
import zlib
from pathlib import Path
from typing import Any

# The Monte Carlo's 10 % rule is applied by the writer to unrounded figures; a row this
# close to the boundary may go either way and is not judged.
_RULE_MARGIN = 1e-6


class FormatError(AssertionError):
    pass


def _fail(where: str, msg: str) -> None:
    raise FormatError(f"{where}: {msg}")


def load_strict(path: Path) -> Any:
    """json.loads refusing NaN / Infinity and a key given twice in one object."""
    def constant(name: str) -> None:
        _fail(str(path), f"{name} is not a JSON number (docs/formats.md: strict JSON)")

    def pairs(items: list[tuple[str, Any]]) -> dict[str, Any]:
        keys = [k for k, _ in items]
        if len(set(keys)) != len(keys):
            _fail(str(path), f"a key given twice in {keys}")
        return dict(items)

    return json.loads(Path(path).read_text(encoding="utf-8"), parse_constant=constant,
                      object_pairs_hook=pairs)


def _num(v: Any, where: str, lo: float = -math.inf, hi: float = math.inf,
         null: bool = False) -> float | None:
    if v is None and null:
        return None
    if isinstance(v, bool) or not isinstance(v, int | float):
        _fail(where, f"expected a number, got {v!r}")
    if not math.isfinite(v) or not lo <= v <= hi:
        _fail(where, f"expected a finite number in [{lo}, {hi}], got {v!r}")
    return float(v)


def _int(v: Any, where: str, lo: int = 0, hi: int = 2**31) -> int:
    if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
        _fail(where, f"expected an integer in [{lo}, {hi}], got {v!r}")
    return v


def _str(v: Any, where: str, empty: bool = False) -> str:
    if not isinstance(v, str) or (not empty and not v.strip()):
        _fail(where, f"expected {'a' if empty else 'a non-empty'} string, got {v!r}")
    return v


def _obj(v: Any, where: str, keys: set[str] | None = None,
         optional: set[str] = frozenset()) -> dict[str, Any]:
    if not isinstance(v, dict):
        _fail(where, f"expected an object, got {type(v).__name__}")
    if keys is not None:
        missing = keys - set(v)
        extra = set(v) - keys - optional
        if missing or extra:
            _fail(where, f"keys: missing {sorted(missing)}, undocumented {sorted(extra)}")
    return v


def _list(v: Any, where: str) -> list[Any]:
    if not isinstance(v, list):
        _fail(where, f"expected an array, got {type(v).__name__}")
    return v


def _k2(v: Any, where: str) -> None:
    if _num(v, where) != 2:
        _fail(where, f"k must be 2, got {v!r}")


def _close(a: float, b: float, where: str, rel: float = 1e-9, abs_: float = 1e-9) -> None:
    if not math.isclose(a, b, rel_tol=rel, abs_tol=abs_):
        _fail(where, f"{a!r} != {b!r}")


def _stated(u_first: float, u_mc: float | None, stated: float, u_from: str,
            where: str) -> None:
    """docs/uncertainty.md: the first-order U is stated unless the Monte Carlo's is more
    than 10 % off it, then the Monte Carlo's; U_from says which."""
    if u_mc is None:
        _close(stated, u_first, where + ".U (no Monte Carlo: the first order)")
        return
    off = abs(u_mc / u_first - 1.0) if u_first > 0 else math.inf
    if abs(off - 0.10) < _RULE_MARGIN:
        return
    want, word = (u_first, "first order") if off <= 0.10 else (u_mc, "Monte Carlo")
    _close(stated, want, where + f".U (MC {off:+.1%} off: {word})")
    if not u_from.lower().startswith(word.lower()):
        _fail(where + ".U_from", f"says {u_from!r}, the rule gives {word!r}")


def _rss(lines: dict[str, Any], where: str) -> float:
    return math.sqrt(sum(_num(v, f"{where}.{k}", 0.0) ** 2 for k, v in lines.items()))


# --------------------------------------------------------------------- chain_fit.json

CHAIN_ROW = {"name", "value", "u", "U", "u95", "unit", "status", "confounded_with", "seen_by",
             "value_in_convention"}
CHAIN_MC = {"U_first_order", "U_mc", "U_from"}
CHAIN_TOP = {"format", "machine", "provenance", "location", "harmonics", "motions", "blob",
             "uncertainty", "chain", "kind", "workpiece_side", "tool_side", "rank", "unknowns",
             "condition", "rms_weighted", "sigma_um", "setup_um"}
BALLBAR_ROW = {"turning_axis", "setup", "length_mm", "readings", "measured_pv_um",
               "left_pv_um", "left_rms_um"}


def _chain_row(r: Any, where: str, units: set[str], mc: bool) -> dict[str, Any]:
    r = _obj(r, where, CHAIN_ROW, CHAIN_MC)
    name = _str(r["name"], where + ".name")
    if r["unit"] not in units:
        _fail(where + ".unit", f"expected one of {sorted(units)}, got {r['unit']!r}")
    if r["status"] not in ("identified", "fixed at 0", "convention"):
        _fail(where + ".status", f"not a documented status: {r['status']!r}")
    _num(r["value_in_convention"], where + ".value_in_convention")
    _list(r["confounded_with"], where + ".confounded_with")
    for i, c in enumerate(r["confounded_with"]):
        _str(c, f"{where}.confounded_with[{i}]")
    _str(r["seen_by"], where + ".seen_by", empty=True)
    figures = ("u", "U", "u95") + (("U_first_order", "U_mc") if mc else ())
    if r["value"] is None:  # unseen: no U, the convention's value, and what would see it
        for k in figures:
            if r.get(k) is not None:
                _fail(f"{where}.{k}", f"{name} is unseen (value null) but has {r[k]!r}")
        if r["status"] == "identified":
            _fail(where + ".status", f"{name}: 'identified' with a null value")
        _str(r["seen_by"], where + ".seen_by")
        return r
    if r["status"] != "identified":
        _fail(where + ".status", f"{name} has a value but status {r['status']!r}")
    _num(r["value"], where + ".value")
    _close(r["value_in_convention"], r["value"], where + ".value_in_convention")
    u = _num(r["u"], where + ".u", 0.0)
    _close(_num(r["U"], where + ".U", 0.0), 2.0 * u, where + ".U (k = 2)")
    _close(_num(r["u95"], where + ".u95", 0.0), 1.96 * u, where + ".u95 (1.96 u)")
    if mc:
        if set(r) != CHAIN_ROW | CHAIN_MC:
            _fail(where, f"--mc: expected {sorted(CHAIN_MC)} too")
        _stated(_num(r["U_first_order"], where + ".U_first_order", 0.0),
                _num(r["U_mc"], where + ".U_mc", 0.0), r["U"],
                _str(r["U_from"], where + ".U_from"), where)
    return r


def read_chain_fit(path: Path, machine_file: Path | None = None) -> dict[str, Any]:
    """chain_fit.json (docs/formats.md "Kinematic chain"); with the machine file, its
    SHA-256 is checked against provenance; the table named by `blob` is checked."""
    path = Path(path)
    d = _obj(load_strict(path), "chain_fit.json")
    optional = {"rotary_ballbar"}
    _obj(d, "chain_fit.json", CHAIN_TOP, optional)
    if d["format"] != "abbe-chain-fit 1.0":
        _fail("format", f"expected 'abbe-chain-fit 1.0', got {d['format']!r}")
    _str(d["machine"], "machine")
    _str(d["chain"], "chain")
    if d["kind"] not in ("head-head", "head-table", "table-table"):
        _fail("kind", f"not a documented kind: {d['kind']!r}")
    wp, tl = _list(d["workpiece_side"], "workpiece_side"), _list(d["tool_side"], "tool_side")
    if sorted(wp + tl) != sorted(set(wp + tl)) or len(wp + tl) != 2 or \
            not set(wp + tl) <= {"A", "B", "C"}:
        _fail("workpiece_side", f"two distinct rotary axes expected, got {wp} / {tl}")
    want_kind = {(2, 0): "table-table", (1, 1): "head-table", (0, 2): "head-head"}
    if want_kind[(len(wp), len(tl))] != d["kind"]:
        _fail("kind", f"{d['kind']!r} with workpiece side {wp}, tool side {tl}")
    unknowns = _int(d["unknowns"], "unknowns", 1)
    _int(d["rank"], "rank", 0, unknowns)
    _num(d["condition"], "condition", 1.0)
    _num(d["rms_weighted"], "rms_weighted", 0.0)
    sig = _obj(d["sigma_um"], "sigma_um")
    for k, v in sig.items():
        _num(v, f"sigma_um.{k}", 0.0)

    prov = _obj(d["provenance"], "provenance")
    sha = _str(prov.get("sha256"), "provenance.sha256")
    if len(sha) != 64 or any(c not in "0123456789abcdef" for c in sha):
        _fail("provenance.sha256", f"not a hex SHA-256: {sha!r}")
    if machine_file is not None:
        real = hashlib.sha256(Path(machine_file).read_bytes()).hexdigest()
        if sha != real:
            _fail("provenance.sha256", f"{sha} is not the machine file's ({real})")

    unc = _obj(d["uncertainty"], "uncertainty")
    _k2(unc.get("k"), "uncertainty.k")
    _str(unc.get("method"), "uncertainty.method")
    budget = _obj(unc.get("budget"), "uncertainty.budget")
    s2 = _num(budget.get("s2"), "uncertainty.budget.s2", 1.0)  # "s^2 at least 1"
    del s2
    for k, v in _obj(budget.get("block_sigma_um"), "uncertainty.budget.block_sigma_um").items():
        _num(v, f"uncertainty.budget.block_sigma_um.{k}", 0.0)
    if not unc.get("not_included"):
        _fail("uncertainty.not_included", "the budget must say what it leaves out")
    mc = "monte_carlo" in unc

    rows: list[dict[str, Any]] = []
    for i, r in enumerate(_list(d["location"], "location")):
        rows.append(_chain_row(r, f"location[{i}]", {"um", "urad"}, mc))
    if not rows:
        _fail("location", "no location error")
    h = _int(d["harmonics"], "harmonics", 0, 8)
    motions = _list(d["motions"], "motions")
    if (h == 0) != (not motions):
        _fail("motions", f"{len(motions)} rows with harmonics = {h}")
    for i, r in enumerate(motions):
        r = _chain_row(r, f"motions[{i}]", {"um", "urad"}, mc)
        parts = r["name"].split()
        if len(parts) != 2 or parts[1][:3] not in ("sin", "cos") or \
                not 1 <= int(parts[1][3:] or 0) <= h:
            _fail(f"motions[{i}].name", f"not 'E..(C) sinN' / 'cosN' with N <= {h}: {r['name']!r}")
        rows.append(r)
    names = [r["name"] for r in rows]
    if len(set(names)) != len(names):
        _fail("location", f"a name given twice: {names}")
    if mc:
        m = _obj(unc["monte_carlo"], "uncertainty.monte_carlo")
        _int(m.get("draws"), "uncertainty.monte_carlo.draws", 1)
        _int(m.get("seed"), "uncertainty.monte_carlo.seed", 0, 2**63)
        seen = [r for r in rows if r["value"] is not None]
        if _int(m.get("of"), "uncertainty.monte_carlo.of") != len(seen):
            _fail("uncertainty.monte_carlo.of", f"{m['of']} but {len(seen)} identified rows")
        first = sum(r["U_from"].lower().startswith("first order") for r in seen)
        if _int(m.get("agree"), "uncertainty.monte_carlo.agree") != first:
            _fail("uncertainty.monte_carlo.agree", f"{m['agree']} but {first} rows first order")

    setup = _obj(d["setup_um"], "setup_um")
    for k, v in setup.items():
        _num(v, f"setup_um.{k}")
    for i, (name, t) in enumerate(_obj(d.get("rotary_ballbar", {}), "rotary_ballbar").items()):
        where = f"rotary_ballbar.{name}"
        t = _obj(t, where, BALLBAR_ROW)
        if t["turning_axis"] not in wp + tl:
            _fail(where + ".turning_axis", f"{t['turning_axis']!r} is not one of {wp + tl}")
        _str(t["setup"], where + ".setup")
        _num(t["length_mm"], where + ".length_mm", 10.0, 1000.0)  # "10 to 1000 mm apart"
        _int(t["readings"], where + ".readings", 3)
        pv = _num(t["measured_pv_um"], where + ".measured_pv_um", 0.0)
        left_pv = _num(t["left_pv_um"], where + ".left_pv_um", 0.0)
        left_rms = _num(t["left_rms_um"], where + ".left_rms_um", 0.0)
        if left_rms > left_pv + 1e-9:
            _fail(where, f"RMS {left_rms} above its peak-to-valley {left_pv}")
        del pv
        if f"{name}.length_zero" not in setup:
            _fail("setup_um", f"no {name}.length_zero (each test has its own length zero)")
        for ball in ("table_ball", "tool_ball"):  # the set-up's unknowns, one per set-up
            for c in "xyz":
                if f"set-up {t['setup']}.{ball}_{c}" not in setup:
                    _fail("setup_um", f"no 'set-up {t['setup']}.{ball}_{c}' for {name}")

    blob = _obj(d["blob"], "blob")
    if blob.get("file") is None:
        _str(blob.get("reason"), "blob.reason")
    else:
        _obj(blob, "blob", {"file", "format", "bytes", "crc32", "convention"})
        if blob["format"] != "1.4":
            _fail("blob.format", f"expected '1.4', got {blob['format']!r}")
        data = (path.parent / _str(blob["file"], "blob.file")).read_bytes()
        if _int(blob["bytes"], "blob.bytes", 1) != len(data):
            _fail("blob.bytes", f"{blob['bytes']} but the file has {len(data)}")
        crc = zlib.crc32(data[:-4])  # docs/table-format.md "CRC": all but the last 4 bytes
        if crc != int.from_bytes(data[-4:], "little") or blob["crc32"] != f"0x{crc:08X}":
            _fail("blob.crc32", f"{blob['crc32']}, the table's CRC is 0x{crc:08X}, its last "
                  f"4 bytes hold 0x{int.from_bytes(data[-4:], 'little'):08X}")
        conv = _obj(blob["convention"], "blob.convention", {"fixed_at_zero", "held_in_convention"})
        fixed = set(_list(conv["fixed_at_zero"], "blob.convention.fixed_at_zero"))
        held = _obj(conv["held_in_convention"], "blob.convention.held_in_convention")
        unseen = {r["name"] for r in rows if r["value"] is None}
        if fixed & set(held) or fixed | set(held) != unseen:
            _fail("blob.convention", f"fixed {sorted(fixed)} + held {sorted(held)} are not "
                  f"the unseen rows {sorted(unseen)}")
        byname = {r["name"]: r for r in rows}
        for n in fixed:
            _close(byname[n]["value_in_convention"], 0.0, f"blob.convention.fixed_at_zero {n}")
        for n, v in held.items():
            _close(byname[n]["value_in_convention"], _num(v, f"held_in_convention.{n}"),
                   f"blob.convention.held_in_convention.{n}")
    return d


# ----------------------------------------------------------------------- predict.json

PRED_ROW = {"ballbar", "residual_max_um", "residual_rms_um", "roundness_before_um",
            "ideal_roundness_um", "ideal_improvement_pct", "roundness_before_U_um",
            "residual_max_U_um", "residual_rms_U_um", "uncertainty"}
PRED_FIG = {"value_um", "u_um", "U_um", "budget_u_um", "U_mc_um", "U_stated_um", "U_from"}
BALLBAR_BUDGET = {"scale_pct", "resolution_um", "calibration_U_um", "expansion_ppm_per_k",
                  "expansion_u_ppm_per_k", "bar_temp_u_c", "drift_c"}


def _rounded(top: float, full: float, where: str) -> None:
    """Figures at the top of an entry are the block's, rounded to 4 decimals."""
    if abs(top - full) > 0.5e-4 + 1e-12:
        _fail(where, f"{top!r} is not {full!r} rounded to 4 decimals")


def read_predict(path: Path) -> dict[str, Any]:
    """predict.json 1.1 (docs/formats.md "abbe predict ... --json FILE")."""
    d = _obj(load_strict(path), "predict.json",
             {"format", "machine", "model", "k", "budget", "predictions"})
    if d["format"] != "abbe-predict 1.1":
        _fail("format", f"expected 'abbe-predict 1.1', got {d['format']!r}")
    _str(d["machine"], "machine")
    _str(d["model"], "model")
    _k2(d["k"], "k")
    b = _obj(d["budget"], "budget", {"source", "figures"})
    _str(b["source"], "budget.source")
    figs = _obj(b["figures"], "budget.figures", BALLBAR_BUDGET)
    for k, v in figs.items():
        _num(v, f"budget.figures.{k}", 0.0)
    preds = _list(d["predictions"], "predictions")
    if not preds:
        _fail("predictions", "no entry")
    for i, p in enumerate(preds):
        w = f"predictions[{i}]"
        p = _obj(p, w, PRED_ROW)
        _str(p["ballbar"], w + ".ballbar")
        for k in PRED_ROW - {"ballbar", "uncertainty", "ideal_improvement_pct"}:
            _num(p[k], f"{w}.{k}", 0.0)
        if p["residual_rms_um"] > p["residual_max_um"]:
            _fail(w, "residual RMS above its max")
        before, ideal = p["roundness_before_um"], p["ideal_roundness_um"]
        pct = _num(p["ideal_improvement_pct"], w + ".ideal_improvement_pct", -math.inf, 100.0)
        if before > 0 and abs(pct - 100.0 * (1.0 - ideal / before)) > 0.01:
            _fail(w + ".ideal_improvement_pct", f"{pct} is not 100 (1 - {ideal} / {before})")
        u = _obj(p["uncertainty"], w + ".uncertainty",
                 {"k", "budget", "note", "max_abs", "rms"}, {"monte_carlo"})
        _k2(u["k"], w + ".uncertainty.k")
        _str(u["budget"], w + ".uncertainty.budget")
        draws = 0  # --mc 0: no monte_carlo block, no U_mc_um
        if "monte_carlo" in u:
            mc = _obj(u["monte_carlo"], w + ".uncertainty.monte_carlo", {"draws", "seed"})
            draws = _int(mc["draws"], w + ".uncertainty.monte_carlo.draws", 1)
            _int(mc["seed"], w + ".uncertainty.monte_carlo.seed", 0, 2**63)
        for key, top in (("max_abs", "residual_max"), ("rms", "residual_rms")):
            wf = f"{w}.uncertainty.{key}"
            f = _obj(u[key], wf, PRED_FIG - {"U_mc_um"}, {"U_mc_um"})
            _rounded(p[f"{top}_um"], _num(f["value_um"], wf + ".value_um", 0.0), f"{w}.{top}_um")
            lines = _obj(f["budget_u_um"], wf + ".budget_u_um",
                         {"scale", "thermal drift", "resolution"})
            uu = _num(f["u_um"], wf + ".u_um", 0.0)
            _close(uu, _rss(lines, wf + ".budget_u_um"), wf + ".u_um (root sum of squares)")
            _close(_num(f["U_um"], wf + ".U_um", 0.0), 2.0 * uu, wf + ".U_um (k = 2)")
            if ("U_mc_um" in f) != (draws > 0):
                _fail(wf + ".U_mc_um", f"{'present' if 'U_mc_um' in f else 'absent'} with "
                      f"{draws} Monte Carlo draws")
            u_mc = _num(f["U_mc_um"], wf + ".U_mc_um", 0.0) if draws else None
            stated = _num(f["U_stated_um"], wf + ".U_stated_um", 0.0)
            _stated(f["U_um"], u_mc, stated, _str(f["U_from"], wf + ".U_from"), wf)
            _rounded(p[f"{top}_U_um"], stated, f"{w}.{top}_U_um")
    return d


# --------------------------------------------------------------------- iso230_3.json

ISO3_ROW = {"name", "unit", "range", "final", "max", "max_h", "min", "min_h", "u", "U",
            "U_first_order", "U_mc", "U_from", "budget_u"}


def read_iso230_3(path: Path) -> dict[str, Any]:
    """iso230_3.json 1.1 (docs/formats.md, thermal record section; docs/thermal.md)."""
    d = _obj(load_strict(path), "iso230_3.json",
             {"format", "machine", "record", "duration_h", "samples", "channels", "tilts",
              "temperatures", "envelope", "uncertainty"})
    if d["format"] != "abbe-iso230-3 1.1":
        _fail("format", f"expected 'abbe-iso230-3 1.1', got {d['format']!r}")
    _str(d["machine"], "machine")
    _str(d["record"], "record")
    dur = _num(d["duration_h"], "duration_h", 0.0)
    _int(d["samples"], "samples", 2)
    unc = _obj(d["uncertainty"], "uncertainty",
               {"method", "k", "sensors", "not_included", "monte_carlo"})
    _k2(unc["k"], "uncertainty.k")
    _str(unc["method"], "uncertainty.method")
    _str(unc["not_included"], "uncertainty.not_included")
    sensors = _obj(unc["sensors"], "uncertainty.sensors")
    for s, v in sensors.items():
        v = _obj(v, f"uncertainty.sensors.{s}", {"sensitivity", "noise_sd", "unit"})
        _str(v["sensitivity"], f"uncertainty.sensors.{s}.sensitivity")
        _num(v["noise_sd"], f"uncertainty.sensors.{s}.noise_sd", 0.0)
        if v["unit"] not in ("um", "K"):
            _fail(f"uncertainty.sensors.{s}.unit", f"expected um or K, got {v['unit']!r}")
    mc = _obj(unc["monte_carlo"], "uncertainty.monte_carlo", {"draws", "seed", "agree", "of"})
    draws = _int(mc["draws"], "uncertainty.monte_carlo.draws", 0)
    _int(mc["seed"], "uncertainty.monte_carlo.seed", 0, 2**63)
    rows = []
    for group, unit in (("channels", "um"), ("tilts", "urad"), ("temperatures", "K")):
        for i, r in enumerate(_list(d[group], group)):
            w = f"{group}[{i}]"
            r = _obj(r, w, ISO3_ROW)
            name = _str(r["name"], w + ".name")
            if r["unit"] != unit:
                _fail(w + ".unit", f"expected {unit!r}, got {r['unit']!r}")
            if group == "tilts" and not name.startswith("tilt "):
                _fail(w + ".name", f"expected 'tilt a|b (chN-chM)', got {name!r}")
            if group != "tilts" and name not in sensors:
                _fail(w + ".name", f"{name!r} has no line in uncertainty.sensors")
            hi, lo = _num(r["max"], w + ".max"), _num(r["min"], w + ".min")
            if not hi >= 0.0 >= lo:  # drift from the first sample
                _fail(w, f"max {hi} / min {lo}: a drift from its start has max >= 0 >= min")
            _close(_num(r["range"], w + ".range", 0.0), hi - lo, w + ".range (max - min)",
                   abs_=1e-6)
            _num(r["final"], w + ".final", lo - 1e-9, hi + 1e-9)
            _num(r["max_h"], w + ".max_h", 0.0, dur + 1e-9)
            _num(r["min_h"], w + ".min_h", 0.0, dur + 1e-9)
            u = _num(r["u"], w + ".u", 0.0)
            _close(_num(r["U"], w + ".U", 0.0), 2.0 * u, w + ".U (k = 2)", abs_=2e-6)
            lines = _obj(r["budget_u"], w + ".budget_u")
            if "reading noise (Type A)" not in lines:
                _fail(w + ".budget_u", "no 'reading noise (Type A)' line")
            for s in set(lines) - {"reading noise (Type A)"}:
                if s not in sensors:
                    _fail(f"{w}.budget_u.{s}", "not a sensor of uncertainty.sensors")
            # each sensor's own sensitivity; a tilt takes both channels of its pair
            own = name[name.find("(") + 1:name.rfind(")")].split("-") if group == "tilts" \
                else [name]
            if not set(own) <= set(lines):
                _fail(w + ".budget_u", f"no line for {sorted(set(own) - set(lines))}")
            u1 = _num(r["U_first_order"], w + ".U_first_order", 0.0)
            _close(u1, 2.0 * _rss(lines, w + ".budget_u"), w + ".U_first_order (2 x RSS)",
                   rel=1e-5, abs_=2e-6)
            u_mc = _num(r["U_mc"], w + ".U_mc", 0.0, null=True)
            if (u_mc is None) != (draws == 0):
                _fail(w + ".U_mc", f"{u_mc!r} with {draws} draws")
            _stated(u1, u_mc, r["U"], _str(r["U_from"], w + ".U_from"), w)
            rows.append(r)
    if _int(mc["of"], "uncertainty.monte_carlo.of") != len(rows):
        _fail("uncertainty.monte_carlo.of", f"{mc['of']} but {len(rows)} rows")
    if draws:
        first = sum(r["U_from"].lower().startswith("first order") for r in rows)
        if _int(mc["agree"], "uncertainty.monte_carlo.agree") != first:
            _fail("uncertainty.monte_carlo.agree", f"{mc['agree']} but {first} rows first order")
    env = _obj(d["envelope"], "envelope", {"channel", "range_um", "U_um"})
    if not d["channels"]:
        _fail("channels", "no displacement channel")
    big = max(d["channels"], key=lambda r: r["range"])
    if env["channel"] != big["name"]:
        _fail("envelope.channel", f"{env['channel']!r}, but the largest range is {big['name']!r}")
    _close(_num(env["range_um"], "envelope.range_um", 0.0), big["range"], "envelope.range_um")
    _close(_num(env["U_um"], "envelope.U_um", 0.0), big["U"], "envelope.U_um")
    return d
