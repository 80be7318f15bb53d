"""The HTML report of ``abbe fit`` on a ``[chain]`` machine file (head-head, head-table,
dual-rotary table), read verdict-first as the trunnion's (:mod:`.report`): machine, test,
date; a band with the location errors identified, each with U (k = 2); then what the plan
could not see and the one measurement that would see it, in one short table; the budget
and the detail folded. Built from the ``chain_fit.json`` document written beside it, so
the two cannot disagree."""

from __future__ import annotations

import html
from pathlib import Path
from typing import Any

#: What abbe's rank test tries when an error is not seen (chain_fit.EXTRA_MEASUREMENTS):
#: "none of ..." means none of them sees it; an error of the rotation about the axis
#: itself (its zero) is seen only against a reference of known orientation.
NONE_SEES = "a reference of known orientation: a datum feature on the table probed at a known angle"
NONE_SEES_NOTE = ("abbe's rank test finds that none of a second sphere height, a longer "
                  "stylus, a sphere at a known place or a sphere further out sees it; the "
                  "orientation reference is not part of that test")

_KINDS = {"head-head": "head-head", "head-table": "head-table",
          "table-table": "dual-rotary table"}


def _e(x: Any) -> str:
    return html.escape(str(x))


def _measurement(seen_by: str) -> str:
    """The one measurement that would see an error: the first of abbe's extensions that
    makes it observable (chain_fit's rank test), or the orientation reference."""
    if not seen_by or seen_by.startswith("none of"):
        return NONE_SEES
    return seen_by


def unseen_table(doc: dict[str, Any]) -> list[dict[str, Any]]:
    """One row per measurement that would see them: the location errors and error motion
    coefficients the plan cannot see, how model_five.bin holds them, the measurement."""
    rows: dict[str, dict[str, Any]] = {}
    held = (doc.get("blob") or {}).get("convention", {}).get("held_in_convention", {})
    for r in list(doc.get("location", [])) + list(doc.get("motions", [])):
        if r.get("value") is not None:
            continue
        m = _measurement(r.get("seen_by") or "")
        row = rows.setdefault(m, {"measurement": m, "names": [], "fixed": [], "held": []})
        row["names"].append(r["name"])
        if r.get("status") == "fixed at 0":
            row["fixed"].append(r["name"])
        else:
            row["held"].append((r["name"], held.get(r["name"], r.get("value_in_convention"))))
    return list(rows.values())


def _held_text(row: dict[str, Any], unit: dict[str, str]) -> str:
    parts = []
    if row["fixed"]:
        parts.append("0 (the convention): " + ", ".join(row["fixed"]))
    if row["held"]:
        parts.append("; ".join(f"{n} = {v:.3f} {unit.get(n, '')} (what the others leave)"
                               if isinstance(v, (int, float)) else n for n, v in row["held"]))
    return "; ".join(parts)


_SETUP_KINDS = {"probe": "sphere probing", "rtest": "R-test", "ballbar": "rotary ballbar"}


def _test_text(doc: dict[str, Any], kinds: dict[str, str] | None) -> str:
    """'sphere probing S1, S2; R-test R1' (the set-ups by kind), ISO 230-7 notation."""
    names = list((doc.get("sigma_um") or {}).keys())
    by: dict[str, list[str]] = {}
    for n in names:
        by.setdefault(_SETUP_KINDS.get((kinds or {}).get(n, ""), "set-up"), []).append(n)
    return "; ".join(f"{k} {', '.join(v)}" for k, v in by.items()) + " (ISO 230-7 notation)"


def _axes_text(doc: dict[str, Any]) -> str:
    head = ", ".join(doc.get("tool_side") or [])
    table = ", ".join(doc.get("workpiece_side") or [])
    return "; ".join(p for p in ((f"{head} in the spindle head" if head else ""),
                                 (f"{table} under the workpiece" if table else "")) if p)


def chain_html(doc: dict[str, Any], text: str, date: str,
               setup_kinds: dict[str, str] | None = None) -> str:
    """The report page of one chain fit (``doc``: its chain_fit.json; ``text``: its
    report.txt; ``date``: the test's date; ``setup_kinds``: set-up name -> probe | rtest |
    ballbar)."""
    from abbe.analysis.certificate import band, page_head
    loc = doc["location"]
    seen = [r for r in loc if r["value"] is not None]
    n_unseen = len(loc) - len(seen)
    status = "pass" if n_unseen == 0 else "inconclusive"
    headline = (f"All {len(loc)} location errors identified, each with U (k = 2)"
                if n_unseen == 0 else
                f"{len(seen)} of {len(loc)} location errors identified, each with U (k = 2); "
                f"{n_unseen} not seen by this plan: the table below names the measurement "
                "that would see them")
    mc = (doc.get("uncertainty") or {}).get("monte_carlo")

    def U_cell(r: dict[str, Any]) -> str:
        tag = " <span class='small'>(Monte Carlo)</span>" if r.get("U_from", "").startswith(
            "Monte Carlo") else ""
        return f"&plusmn; {r['U']:.3f}{tag}"

    lrows = "".join(f"<tr><td class='l'>{_e(r['name'])}</td><td>{r['value']:.3f}</td>"
                    f"<td>{U_cell(r)}</td><td class='l'>{_e(r['unit'])}</td></tr>" for r in seen)
    body = ("<table><tr><th class='l'>location error</th><th>value</th><th>U (k = 2)</th>"
            "<th class='l'>unit</th></tr>" + lrows + "</table>")
    if mc:
        body += (f"<p class='small'>U checked by a Monte Carlo (GUM S1, {mc.get('draws')} draws "
                 f"re-solving the identification): {mc.get('agree', '?')} of "
                 f"{mc.get('of', '?')} within 10 %; beyond, its U is stated.</p>")
    blob = doc.get("blob") or {}
    table = (f"model_five.bin, format {blob.get('format')} (CRC {blob.get('crc32')})"
             if blob.get("file") else f"none: {blob.get('reason', 'not written')}")
    prov = doc.get("provenance") or {}
    head = page_head(f"Kinematic chain identification: {doc.get('machine') or doc['chain']}", [
        ("Machine", f"{doc.get('machine') or 'not named'}: {_KINDS.get(doc['kind'], doc['kind'])}"
                    f" five-axis, kinematics {doc['chain']} ({_axes_text(doc)})"),
        ("Test", _test_text(doc, setup_kinds)),
        ("Date", date),
        ("Table", table),
        ("Machine file", str(prov.get("machine_file", "-")))])
    unit = {r["name"]: r["unit"] for r in list(loc) + list(doc.get("motions", []))}
    unseen = unseen_table(doc)
    urows = "".join(
        f"<tr><td class='l'>{_e(', '.join(r['names']))}</td>"
        f"<td class='l'>{_e(_held_text(r, unit))}</td>"
        f"<td class='l'><b>{_e(r['measurement'])}</b>"
        + (f"<br><span class='small'>{NONE_SEES_NOTE}</span>" if r["measurement"] == NONE_SEES
           else "") + "</td></tr>" for r in unseen)
    unseen_html = ("<h2>What this plan could not see</h2><table><tr><th class='l'>not seen</th>"
                   "<th class='l'>held in model_five.bin as</th><th class='l'>the measurement "
                   "that would see them</th></tr>" + urows + "</table>"
                   "<p class='small'>The table holds the errors the plan cannot see in the "
                   "fit's convention: the machine moves the tool as measured; a workpiece "
                   "datum absorbs what they leave (docs/concepts.md).</p>"
                   if unseen else "<p>The plan sees every error it models.</p>")
    mot = doc.get("motions") or []
    mot_html = ""
    if mot:
        n_seen = sum(r["value"] is not None for r in mot)
        mrows = "".join(f"<tr><td class='l'>{_e(r['name'])}</td><td>{r['value']:.3f}</td>"
                        f"<td>{U_cell(r)}</td><td class='l'>{_e(r['unit'])}</td></tr>"
                        for r in mot if r["value"] is not None)
        mot_html = (f"<details><summary>Error motions: {n_seen} of {len(mot)} Fourier "
                    f"coefficients identified (harmonics up to {doc.get('harmonics')})</summary>"
                    "<table><tr><th class='l'>coefficient</th><th>value</th><th>U (k = 2)</th>"
                    f"<th class='l'>unit</th></tr>{mrows}</table></details>")
    bb = doc.get("rotary_ballbar") or {}
    bb_html = ""
    if bb:
        brows = "".join(f"<tr><td class='l'>{_e(n)}</td><td class='l'>{_e(c['turning_axis'])}</td>"
                        f"<td>{c['measured_pv_um']:.2f}</td><td>{c['left_pv_um']:.2f}</td>"
                        f"<td>{c['left_rms_um']:.2f}</td></tr>" for n, c in bb.items())
        bb_html = ("<h2>Rotary ballbar tests</h2><table><tr><th class='l'>test</th>"
                   "<th class='l'>turning</th><th>measured PV (um)</th><th>left PV (um)</th>"
                   f"<th>left RMS (um)</th></tr>{brows}</table>")
    unc = doc.get("uncertainty") or {}
    bud = unc.get("budget") or {}
    srows = "".join(f"<tr><td class='l'>{_e(n)}</td><td>{v:.3f}</td></tr>"
                    for n, v in (bud.get("block_sigma_um") or {}).items())
    budget_html = (
        "<h2>Budget</h2>"
        f"<p>{_e(unc.get('method', ''))}; U = {unc.get('k', 2):g} u. Weighted residual "
        f"variance s<sup>2</sup> = {bud.get('s2', float('nan')):.3g} (at least 1 is used).</p>"
        "<details><summary>Each set-up's standard deviation (Type A, from its own residuals)"
        "</summary><table><tr><th class='l'>set-up</th><th>sigma (um)</th></tr>"
        f"{srows}</table><p class='small'>{_e(bud.get('block_sigma_from', ''))}</p></details>"
        "<p class='small'>Not included: "
        f"{_e('; '.join(unc.get('not_included') or []) or '-')}.</p>")
    details = (
        "<h2>Details</h2>"
        f"<details><summary>Observability</summary><p>rank {doc['rank']} of {doc['unknowns']} "
        f"unknowns, condition number {doc['condition']:.3g}.</p></details>"
        f"<details><summary>Text report</summary><pre>{_e(text)}</pre></details>")
    return ("\n".join(head) + "\n" + band(status, headline, body) + unseen_html + mot_html
            + bb_html + budget_html + details + "</body></html>\n")


def write_chain_html(doc: dict[str, Any], text: str, out: Path, date: str,
                     setup_kinds: dict[str, str] | None = None) -> Path:
    """Write ``out``/index.html (the folder is created) and return its path."""
    out.mkdir(parents=True, exist_ok=True)
    p = out / "index.html"
    p.write_text(chain_html(doc, text, date, setup_kinds), encoding="utf-8")
    return p
