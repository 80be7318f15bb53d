"""The long fuzz run of every command: ``python -m fuzzing.run [--minutes M] [--seed S]``.

Run from host_tools/. Seeded (the same seed tries the same inputs), round-robin over
the commands of :mod:`fuzzing.commands` until the time is up, each input checked by
:func:`fuzzing.harness.run_case` (for the targets whose file holds only data numbers,
one input in ten has a number replaced by a hostile one and must be refused, exit 2); the process runs under an address-space limit
(``--memory-gib``, default 6) so a reader that loses its bound fails here instead of
swapping. Inputs that break a promise are saved under ``--out``/findings with their
argument line; the summary gives, per command, the inputs tried and the exit statuses.
Exit status 1 if anything was found.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import resource
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m fuzzing.run", description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0, help="total time (default 10)")
    ap.add_argument("--seed", type=int, default=1, help="random seed (default 1)")
    ap.add_argument("--memory-gib", type=float, default=6.0, help="address-space limit (GiB)")
    ap.add_argument("--only", nargs="+", metavar="NAME", help="command names (default: all)")
    ap.add_argument("--out", type=Path, default=None, help="work folder (default: a temp folder)")
    args = ap.parse_args(argv)

    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    limit = int(args.memory_gib * (1 << 30))
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    root = args.out or Path(tempfile.mkdtemp(prefix="abbe-fuzz-"))
    os.environ["ABBE_CRASH_DIR"] = str(root / "crash")

    from abbe.cli.entry import main as abbe
    from fuzzing.commands import (
        OPTION_VALUES,
        option_slots,
        targets,
        with_option_value,
        without_comments,
    )
    from fuzzing.harness import run_case
    from fuzzing.mutate import mutate, replace_number
    from fuzzing.seeds import make_workspace

    ws = make_workspace(root / "ws")
    model = root / "fit0"
    import contextlib
    import io
    with contextlib.redirect_stdout(io.StringIO()):
        assert abbe(["fit", str(ws.machine), "-o", str(model), "--no-clib-check", "--no-report",
                     "-q"]) == 0
    ts = [t for t in targets(ws, root / "out", model / "model.bin")
          if not args.only or t.name in args.only]
    from abbe.model import clib
    no_clib = [t.name for t in ts if t.needs_clib] if not clib.available() else []
    if no_clib:  # they would exit 3 every time: say so, instead of counting them as tried
        print(f"fuzzing.run: warning: the C library is not available (or stale): "
              f"{', '.join(no_clib)} only exit 3", file=sys.stderr)
    rng = random.Random(args.seed)
    pick = lambda n: rng.randrange(max(n, 1))  # noqa: E731
    tried: Counter = Counter()
    codes: dict[str, Counter] = {t.name: Counter() for t in ts}
    found = 0
    (root / "findings").mkdir(parents=True, exist_ok=True)
    end = time.monotonic() + 60.0 * args.minutes
    seeds = {t.name: t.mutated.read_bytes() for t in ts}
    with contextlib.redirect_stdout(io.StringIO()):
        run_case(ts[0].argv, ts[0].outputs)  # warm-up (imports)
    while time.monotonic() < end:
        for t in ts:
            if time.monotonic() >= end:
                break
            seed = seeds[t.name]
            argv = list(t.argv)
            must_refuse = False
            r = rng.random()
            if t.hostile_numbers and r < 0.1:  # a hostile number where a number was
                blob, ops = replace_number(without_comments(seed), pick), ["replace_number"]
                must_refuse = True
            elif r < (0.25 if t.hostile_numbers else 0.15):  # an option value, not the file
                blob, ops = seed, ["option"]
                slots = option_slots(argv)
                if slots:
                    argv = with_option_value(argv, rng.choice(slots), rng.choice(OPTION_VALUES))
            else:
                blob, ops = mutate(seed, pick, rng.randint(1, 4))
            t.mutated.write_bytes(blob)
            try:
                o = run_case(argv, t.outputs, allowed=t.allowed, json_stdout=t.json_stdout,
                             budget_s=t.budget_s)
            except MemoryError:
                from fuzzing.harness import Outcome
                o = Outcome(argv, None, "", "", ["MemoryError: over the memory limit"])
            finally:
                t.mutated.write_bytes(seed)
            if must_refuse and o.rc != 2 and not o.problems:
                o.problems.append(f"exit {o.rc} on a file holding a hostile number (expected 2)")
            tried[t.name] += 1
            codes[t.name][o.rc] += 1
            if not o.ok:
                found += 1
                stem = root / "findings" / f"{t.name.replace(' ', '_')}-{tried[t.name]}"
                stem.with_suffix(".input").write_bytes(blob)
                stem.with_suffix(".json").write_text(json.dumps(
                    {"argv": argv, "mutated": str(t.mutated), "ops": ops, "problems": o.problems,
                     "stderr": o.stderr[-2000:]}, indent=1))
                print(f"FOUND {t.name}: {o.problems} ({stem})", file=sys.stderr)
    print(f"fuzzing.run: seed {args.seed}, {args.minutes:g} min, work folder {root}")
    print(f"{'command':<20} {'inputs':>7} {'exit 0':>7} {'exit 2':>7} {'other':>7}")
    for t in ts:
        c = codes[t.name]
        other = sum(v for k, v in c.items() if k not in (0, 2))
        print(f"{t.name:<20} {tried[t.name]:>7} {c[0]:>7} {c[2]:>7} {other:>7}")
    print(f"{'total':<20} {sum(tried.values()):>7}; promises broken: {found}")
    if no_clib:
        print(f"not exercised (no C library): {', '.join(no_clib)}")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())
