"""Benchmark of ``abbe history``: 1,000 campaigns added, then the report.

Each campaign is a full one: the folders of ``abbe fit`` and ``abbe diagnose`` of
examples/vmc500 and the JSON of ``abbe ballbar`` and ``abbe iso230-2`` (about 70
values, 2 table blobs), its ballbar and ISO 230-2 values varied per campaign so each
is a new campaign (every 7 days). ``history add`` is timed in-process for every
campaign (after imports) and as a command in a fresh interpreter for the last few;
then ``show``, ``report`` and ``export`` of the 1,000 campaigns.

    python host_tools/bench/bench_history.py [-n 1000] [--db URL] [--work DIR]
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "examples" / "vmc500"


def _abbe() -> str:
    return shutil.which("abbe") or str(Path(sys.executable).with_name("abbe"))


def _outputs(work: Path) -> Path:
    """fit/, diagnose/, ballbar.json, iso_x.json of examples/vmc500 (made once)."""
    out = work / "outputs"
    if (out / "done").exists():
        return out
    out.mkdir(parents=True, exist_ok=True)
    m = str(EXAMPLE / "machine.toml")
    run = lambda *a, **kw: subprocess.run([_abbe(), *a], check=True, **kw)  # noqa: E731
    run("fit", m, "-o", str(out / "fit"), "--no-report", "-q", stdout=subprocess.DEVNULL)
    run("diagnose", m, "--model", str(out / "fit" / "model.bin"), "--ballbar", "circle1",
        "-o", str(out / "diagnose"), "--no-plots", stdout=subprocess.DEVNULL)
    with open(out / "ballbar.json", "w") as fh:
        run("ballbar", m, "circle1", "--json", "-", "--no-plot", stdout=fh)
    with open(out / "iso_x.json", "w") as fh:
        run("iso230-2", str(EXAMPLE / "laser" / "x.csv"), "--json", "-", stdout=fh)
    (out / "done").write_text("")
    return out


def _variant(out: Path, dest: Path, i: int) -> list[str]:
    dest.mkdir(parents=True, exist_ok=True)
    bb = json.loads((out / "ballbar.json").read_text())
    bb["bidirectional"]["G_um"] = round(bb["bidirectional"]["G_um"] + 0.002 * i, 4)
    iso = json.loads((out / "iso_x.json").read_text())
    iso["B_um"] = round(iso["B_um"] + 0.001 * i, 4)
    (dest / "ballbar.json").write_text(json.dumps(bb))
    (dest / "iso_x.json").write_text(json.dumps(iso))
    return [str(out / "fit"), str(out / "diagnose"), str(dest / "ballbar.json"),
            str(dest / "iso_x.json")]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("-n", type=int, default=1000, help="campaigns (default 1000)")
    ap.add_argument("--cli", type=int, default=10, help="of them, added as a command (default 10)")
    ap.add_argument("--db", help="database (default: a new SQLite file in --work)")
    ap.add_argument("--work", type=Path, help="work folder (default: a temporary one)")
    args = ap.parse_args()
    from abbe.cli.entry import main as abbe_main

    work = args.work or Path(tempfile.mkdtemp(prefix="abbe-bench-history-"))
    out = _outputs(work)
    db = args.db or str(work / "history.sqlite")
    if not args.db:
        for suffix in ("", "-wal", "-shm"):
            Path(db + suffix).unlink(missing_ok=True)
    t0 = dt.datetime(2000, 1, 3, 9, 0)
    times = []
    for i in range(args.n):
        argv = ["history", "--db", db, "add", *_variant(out, work / "v" / f"{i % 50}", i),
                "--axis", "X", "--date", (t0 + dt.timedelta(days=7 * i)).strftime("%Y-%m-%dT%H:%MZ"),
                "--operator", "bench"]
        if i >= args.n - args.cli:
            s = time.perf_counter()
            subprocess.run([_abbe(), *argv], check=True, stdout=subprocess.DEVNULL)
            times.append(("cli", time.perf_counter() - s))
        else:
            s = time.perf_counter()
            with open(os.devnull, "w") as null:
                old, sys.stdout = sys.stdout, null
                try:
                    rc = abbe_main(argv)
                finally:
                    sys.stdout = old
            assert rc == 0, f"campaign {i}: exit {rc}"
            times.append(("in", time.perf_counter() - s))
    ins = [t for k, t in times if k == "in"]
    cli = [t for k, t in times if k == "cli"]
    print(f"history add, in-process ({len(ins)} campaigns): median {statistics.median(ins) * 1e3:.1f} ms, "
          f"first 100 {statistics.median(ins[:100]) * 1e3:.1f} ms, last 100 "
          f"{statistics.median(ins[-100:]) * 1e3:.1f} ms, max {max(ins) * 1e3:.0f} ms, "
          f"total {sum(ins):.1f} s")
    if cli:
        print(f"history add, command in a fresh interpreter (the last {len(cli)}): median "
              f"{statistics.median(cli) * 1e3:.0f} ms")
    for name, argv in (("show", ["show", "vmc500", "--last", "8"]),
                       ("report", ["report", "vmc500", "-o", str(work / "report")]),
                       ("export csv", ["export", "vmc500", "-o", str(work / "all.csv")]),
                       ("export json", ["export", "vmc500", "-o", str(work / "all.json")])):
        s = time.perf_counter()
        subprocess.run([_abbe(), "history", "--db", db, *argv], check=True,
                       stdout=subprocess.DEVNULL)
        print(f"history {name} of {args.n} campaigns (command): {time.perf_counter() - s:.2f} s")
    if not args.db:
        print(f"database: {os.path.getsize(db) / 1e6:.1f} MB ({db})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
