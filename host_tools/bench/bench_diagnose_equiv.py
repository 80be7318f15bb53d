#!/usr/bin/env python3
"""Same answers, how fast: ``abbe diagnose`` before / after a speed change (issue 36).

    python bench_diagnose_equiv.py record --work DIR --out RUN.jsonl [--gen2 SEED NAME ...]
           [--team SEED NAME ...] [--ess]
    python bench_diagnose_equiv.py diff BEFORE.jsonl AFTER.jsonl

``record`` builds each named case once into ``DIR`` (the second independent generator's
files and ``abbe fit`` model; the team's independent suite's files, pickled) and diagnoses
it with whatever ``abbe`` this interpreter imports, appending one JSON line per case: the
diagnosis JSON (``DiagnoseResult.to_json``), the unrounded final values, covariance and
s^2 of the fit, and the wall time in seconds. ``--ess`` adds the real ESS X record
(tests/real_data.py). Run it with the code before a change and after, on the same
``--work`` directory: ``diff`` then lists every field that differs (numbers beyond a
relative 1e-9), the largest relative difference of the numbers, and the times.
"""

from __future__ import annotations

import argparse
import json
import math
import pickle
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
sys.path.insert(0, str(Path(__file__).resolve().parent))


def _raw(res: Any) -> dict[str, Any]:
    """The unrounded numbers of the final fit (values, covariance, s^2)."""
    fs = res.fit_state
    if fs is None:
        return {}
    return {"selected": [s.cand.spec.key for s in fs.selected],
            "values": [np.asarray(v, dtype=float).tolist() for v in fs.values],
            "cov": np.asarray(fs.cov, dtype=float).tolist(), "s2": float(fs.s2),
            "effects": [[e.key, float(e.value), [float(x) for x in e.ci95]] for e in res.effects]}


def _case_gen2(seed: int, name: str, work: Path) -> tuple[str, Any]:
    from cases.independent2.suite import suite
    import bench_independent2_ab as ab
    from abbe.diagnose.run import diagnose_machine
    c = next(c for c in suite(seed) if c.name == name)

    def go() -> Any:
        b = ab.built(c, work / f"gen2_{seed}" / name)   # built once, read back after
        return diagnose_machine(b.machine, b.model)
    return f"gen2:{seed}:{name}", go


def _case_build_gen2(name: str, work: Path) -> None:
    """Build a second-generator case's files (not timed)."""
    from cases.independent2.suite import suite
    import bench_independent2_ab as ab
    _, seed, n = name.split(":", 2)
    c = next(c for c in suite(int(seed)) if c.name == n)
    ab.built(c, work / f"gen2_{seed}" / n)


def _case_team(seed: int, name: str, work: Path) -> tuple[str, Any]:
    from cases.independent import suite as ind
    d = work / f"team_{seed}" / name
    pk = d / "built.pickle"
    if pk.exists():
        b = pickle.loads(pk.read_bytes())
    else:
        c = next(c for c in ind.suite(seed) if c.name == name)
        d.mkdir(parents=True, exist_ok=True)
        b = ind.build(c, d)
        pk.write_bytes(pickle.dumps(b))
    return f"team:{seed}:{name}", lambda: ind.run(b)


def _case_ess() -> tuple[str, Any]:
    from real_data import ESS_DAT
    from abbe.diagnose.run import diagnose_positioning
    return "ess:X", lambda: diagnose_positioning(ESS_DAT, "X")


def record(a: argparse.Namespace) -> int:
    work = Path(a.work)
    todo = []
    if a.gen2:
        seed = int(a.gen2[0])
        todo += [_case_gen2(seed, n, work) for n in a.gen2[1:]]
    if a.team:
        seed = int(a.team[0])
        todo += [_case_team(seed, n, work) for n in a.team[1:]]
    if a.ess:
        todo.append(_case_ess())
    for name, fn in todo:
        if name.startswith("gen2:"):
            _case_build_gen2(name, work)
        t = time.perf_counter()
        res = fn()
        dt = time.perf_counter() - t
        line = {"case": name, "seconds": round(dt, 2), "json": res.to_json(), "raw": _raw(res)}
        with open(a.out, "a", encoding="utf-8") as f:
            f.write(json.dumps(line, default=float) + "\n")
        print(f"{name:50s} {dt:7.1f} s  named {[e.key for e in res.effects]}", flush=True)
    return 0


def _walk(a: Any, b: Any, path: str, out: list[str], worst: list[float]) -> None:
    if isinstance(a, dict) and isinstance(b, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                out.append(f"{path}.{k}: only in {'after' if k in b else 'before'}")
                continue
            _walk(a[k], b[k], f"{path}.{k}", out, worst)
    elif isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            out.append(f"{path}: length {len(a)} -> {len(b)}")
            return
        for i, (x, y) in enumerate(zip(a, b)):
            _walk(x, y, f"{path}[{i}]", out, worst)
    elif isinstance(a, (int, float)) and isinstance(b, (int, float)) and \
            not isinstance(a, bool) and not isinstance(b, bool):
        if a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b)):
            return
        rel = abs(a - b) / max(abs(a), abs(b), 1e-300)
        worst[0] = max(worst[0], rel)
        if rel > 1e-9:
            out.append(f"{path}: {a!r} -> {b!r} (rel {rel:.2e})")
    elif a != b:
        out.append(f"{path}: {str(a)[:120]!r} -> {str(b)[:120]!r}")


def diff(a: argparse.Namespace) -> int:
    rb = {r["case"]: r for r in map(json.loads, Path(a.before).read_text().splitlines()) if r}
    ra = {r["case"]: r for r in map(json.loads, Path(a.after).read_text().splitlines()) if r}
    n_diff, tb, ta = 0, 0.0, 0.0
    for c in [c for c in rb if c in ra]:
        out: list[str] = []
        worst = [0.0]
        _walk(rb[c]["json"], ra[c]["json"], "json", out, worst)
        _walk(rb[c]["raw"], ra[c]["raw"], "raw", out, worst)
        tb += rb[c]["seconds"]
        ta += ra[c]["seconds"]
        n_diff += bool(out)
        print(f"{c:50s} {rb[c]['seconds']:7.1f} s -> {ra[c]['seconds']:7.1f} s "
              f"(x{rb[c]['seconds'] / max(ra[c]['seconds'], 1e-9):4.1f})  "
              f"{'SAME' if not out else 'DIFFERS'}  max rel diff {worst[0]:.1e}")
        for o in out[:20]:
            print("    " + o)
    print(f"total {tb:.1f} s -> {ta:.1f} s (x{tb / max(ta, 1e-9):.2f}); {n_diff} case(s) differ")
    return 1 if n_diff else 0


def main() -> int:
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("record")
    r.add_argument("--work", required=True)
    r.add_argument("--out", required=True)
    r.add_argument("--gen2", nargs="+", metavar="SEED_THEN_NAMES")
    r.add_argument("--team", nargs="+", metavar="SEED_THEN_NAMES")
    r.add_argument("--ess", action="store_true")
    d = sub.add_parser("diff")
    d.add_argument("before")
    d.add_argument("after")
    a = ap.parse_args()
    return record(a) if a.cmd == "record" else diff(a)


if __name__ == "__main__":
    raise SystemExit(main())
