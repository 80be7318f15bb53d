"""Before / after on the same cases of the second independent generator (issue 36).

python host_tools/bench/bench_independent2_ab.py --work DIR --out RESULTS.jsonl
       [--seed S] [--per-single N] [--per-pair N] [--clean N] [--per-limit N]
       [--shard I/N]

Each case is built once into ``DIR/<case>`` (files + ``abbe fit`` model + truth.json)
and then diagnosed with whatever ``abbe`` this interpreter imports: run it once with
the code before a change (e.g. ``PYTHONPATH`` at a snapshot of main's host_tools,
the script copied beside it) and once after, on the same ``--work`` directory, so the
two runs see identical files. One JSON line per case is appended to ``--out`` as it
ends (a run stopped early keeps what it did); a case already in ``--out`` is skipped.
``--shard I/N`` runs every N-th case starting at I (two processes on two cores).
Without ``--seed`` a fresh seed is drawn and printed.
"""
from __future__ import annotations

import argparse
import json
import os
import secrets
import tempfile
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from cases.independent2.suite import BuiltCase, build, run, score, suite  # noqa: E402


def built(case, d: Path) -> BuiltCase:
    """The case's files, built now or read back from an earlier run."""
    tj = d / "truth.json"
    if tj.exists() and (d / "model" / "model.bin").exists():
        t = json.loads(tj.read_text())
        if "seen_um" not in t:
            # built before the scorer measured what the checks see: every draw is the same,
            # so the files are rebuilt aside (no fit) for it
            with tempfile.TemporaryDirectory() as tmp:
                t["seen_um"] = build(case, tmp, fit=False).seen_um
            if os.access(tj, os.W_OK):
                tj.write_text(json.dumps(t))
        return BuiltCase(case, d, d / "machine.toml", d / "model" / "model.bin", t["truth"],
                         t["declared_tool_mm"], t["true_tool_mm"], t["seen_um"])
    b = build(case, d)
    tj.write_text(json.dumps({"truth": b.truth, "declared_tool_mm": b.declared_tool_mm,
                              "true_tool_mm": b.true_tool_mm, "seen_um": b.seen_um}))
    return b


def compare(before: Path, after: Path) -> dict:
    """Figures of two runs on the cases both finished (bench_independent2.summarise), and
    the cases whose names differ."""
    from bench_independent2 import summarise
    rb = {r["case"]: r for r in map(json.loads, before.read_text().splitlines()) if r}
    ra = {r["case"]: r for r in map(json.loads, after.read_text().splitlines()) if r}
    both = [c for c in rb if c in ra]
    out = {"cases": len(both), "case_names": both,
           "before": summarise([rb[c] for c in both]), "after": summarise([ra[c] for c in both]),
           "changed": [f"{c}: truth {rb[c]['truth']} before {rb[c]['named']} after {ra[c]['named']}"
                       for c in both if rb[c]["named"] != ra[c]["named"]]}
    return out


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--compare", nargs=2, metavar=("BEFORE.jsonl", "AFTER.jsonl"),
                    help="print the figures of two runs on the cases both finished")
    ap.add_argument("--work")
    ap.add_argument("--out")
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--per-single", type=int, default=1)
    ap.add_argument("--per-pair", type=int, default=1)
    ap.add_argument("--clean", type=int, default=6)
    ap.add_argument("--per-limit", type=int, default=1)
    ap.add_argument("--shard", default="0/1")
    ap.add_argument("--order", default="interleave", choices=("interleave", "suite"),
                    help="interleave: one case of each kind in turn, so a stopped run is "
                         "still a stratified subset")
    a = ap.parse_args()
    if a.compare:
        sys.path.insert(0, str(Path(__file__).resolve().parent))
        print(json.dumps(compare(Path(a.compare[0]), Path(a.compare[1])), indent=1))
        return 0
    if not (a.work and a.out):
        ap.error("--work and --out are needed (or --compare)")
    seed = a.seed if a.seed is not None else secrets.randbelow(2**31)
    print(f"seed {seed}", flush=True)
    cases = suite(seed, per_single=a.per_single, per_pair=a.per_pair, n_clean=a.clean,
                  per_limit=a.per_limit)
    if a.order == "interleave":
        by: dict[str, list] = {}
        for c in cases:
            by.setdefault(c.kind, []).append(c)
        mixed = []
        while any(by.values()):
            for k in ("single", "clean", "pair", "limit"):
                if by.get(k):
                    mixed.append(by[k].pop(0))
        cases = mixed
    i0, n = (int(x) for x in a.shard.split("/"))
    cases = cases[i0::n]
    out = Path(a.out)
    done = set()
    if out.exists():
        done = {json.loads(x)["case"] for x in out.read_text().splitlines() if x.strip()}
    work = Path(a.work)
    for c in cases:
        if c.name in done:
            continue
        t = time.time()
        try:
            b = built(c, work / c.name)
            t_b = time.time()
            res = run(b)
            s = score(b, res)
            d = res.to_json()
            s["effects"] = [{"key": e["key"], "value": e["value"], "unit": e["unit"],
                             "ci95": e["ci95"], "state": e.get("state"),
                             "undecided_between": e.get("undecided_between")}
                            for e in d["effects"]]
            s["state"] = d.get("state")
            s["seconds_diagnose"] = round(time.time() - t_b, 1)
        except Exception as exc:   # a failure of the case is a result too
            s = {"case": c.name, "kind": c.kind, "truth": list(c.effects), "named": [],
                 "exact": False, "undecided": False, "false_names": [],
                 "tool_changed_where_right": False, "values": [],
                 "error": f"{type(exc).__name__}: {exc}"[:500]}
        s["seed"] = seed
        s["seconds"] = round(time.time() - t, 1)
        with out.open("a") as f:
            f.write(json.dumps(s) + "\n")
        print(f"{s['case']:40s} {s['kind']:6s} exact={s['exact']!s:5s} und={s['undecided']!s:5s} "
              f"named={s['named']} {s['seconds']}s {s.get('error', '')}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
