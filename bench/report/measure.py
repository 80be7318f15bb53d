"""How everything in the report is counted: callgrind runs (x86-64), QEMU exec traces
(Cortex-M), the compile flags of a build and the Python throughput run. Nothing here
writes markdown; the section modules do (see report/__init__.py).
"""

from __future__ import annotations

import re
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

CALLGRIND_N = 2000
CALLGRIND_EXTRA = 1000

def run(cmd: list[str], **kw) -> subprocess.CompletedProcess:
    """Run a command, raising with its output on failure."""
    res = subprocess.run(cmd, capture_output=True, text=True, **kw)
    if res.returncode != 0:
        raise RuntimeError(f"{' '.join(map(str, cmd))} failed ({res.returncode}):\n"
                           f"{res.stdout}\n{res.stderr}")
    return res


def first_line(cmd: list[str]) -> str:
    try:
        return subprocess.run(cmd, capture_output=True, text=True).stdout.splitlines()[0].strip()
    except (OSError, IndexError):
        return "not found"


# --------------------------------------------------------------------------- host

def callgrind_total(exe: Path, args: list[str], toggle: str | None) -> int:
    """Total Ir of one callgrind run (only inside `toggle` if given)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "callgrind.out"
        cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}"]
        if toggle:
            cmd.append(f"--toggle-collect={toggle}")
        run(cmd + [str(exe)] + args)
        text = out.read_text()
    m = re.search(r"^(?:summary|totals):\s+(\d+)", text, re.M)
    if not m:
        raise RuntimeError("no totals in callgrind output")
    return int(m.group(1))


@dataclass
class HostResult:
    mode: str
    function: str
    per_call: float          # toggle-collect: instructions inside the function per call
    per_iter: float          # difference method: whole loop iteration


TABLE_MODES = [("f32", "abbe_error_eval_f32", 0), ("f32_base", "abbe_error_eval_f32", 0),
               ("q", "abbe_error_eval_q", 0), ("comp_f32", "abbe_comp_step_f32", 4),
               ("comp_q", "abbe_comp_step_q", 4)]


def host_table_bench(build: Path, table: str | None) -> dict[str, float] | None:
    """Instructions inside each call per call on a golden table (None: BENCH_TABLE);
    None if this build's library refuses the table (bench_host exit 3)."""
    exe = build / "bench" / "bench_host"
    extra = [] if table is None else [table]
    probe = subprocess.run([str(exe), "f32", "1", *extra], capture_output=True, text=True)
    if probe.returncode == 3:
        return None
    if probe.returncode != 0:
        raise RuntimeError(f"bench_host on {table}: {probe.stderr}")
    return {mode: callgrind_total(exe, [mode, str(CALLGRIND_N), *extra], fn) / (CALLGRIND_N + calls)
            for mode, fn, calls in TABLE_MODES}


def host_bench(build: Path) -> tuple[list[HostResult], str]:
    exe = build / "bench" / "bench_host"
    check = run([str(exe), "check"]).stdout.strip()
    modes = [
        ("f32", "abbe_error_eval_f32", 0),
        ("f32_base", "abbe_error_eval_f32", 0),
        ("q", "abbe_error_eval_q", 0),
        ("comp_f32", "abbe_comp_step_f32", 4),
        ("comp_q", "abbe_comp_step_q", 4),
        ("naive", "naive_eval", 0),
        ("lean", "lean_eval", 0),
        ("empty", "bench_empty", 0),
    ]
    results = []
    for mode, fn, extra_calls in modes:
        inside = callgrind_total(exe, [mode, str(CALLGRIND_N)], fn)
        a = callgrind_total(exe, [mode, str(CALLGRIND_N)], None)
        b = callgrind_total(exe, [mode, str(CALLGRIND_N + CALLGRIND_EXTRA)], None)
        results.append(HostResult(mode, fn, inside / (CALLGRIND_N + extra_calls),
                                  (b - a) / CALLGRIND_EXTRA))
    return results, check


# --------------------------------------------------------------------------- target

def nm_address(nm: str, image: Path, symbol: str) -> int:
    for line in run([nm, str(image)]).stdout.splitlines():
        parts = line.split()
        if len(parts) == 3 and parts[2] == symbol:
            return int(parts[0], 16) & ~1
    raise RuntimeError(f"{symbol} not in {image}")


TRACE_RE = re.compile(r"^Trace \d+: \S+ \[[0-9a-f]+/([0-9a-f]+)/")


def qemu_trace_counts(machine: str, image: Path, nm: str) -> tuple[dict[str, list[int]], str]:
    """Instructions per measured call, by PLAN name, from QEMU's exec trace."""
    mark = nm_address(nm, image, "bench_mark")
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "exec.log"
        res = run(["qemu-system-arm", "-M", machine, "-nographic",
                   "-semihosting-config", "enable=on,target=native", "-kernel", str(image),
                   "-singlestep", "-d", "exec,nochain", "-D", str(log)],
                  stdin=subprocess.DEVNULL, timeout=600)
        hits = []
        n = 0
        with log.open() as f:
            for line in f:
                m = TRACE_RE.match(line)
                if not m:
                    continue
                if int(m.group(1), 16) == mark:
                    hits.append(n)
                n += 1
    stdout = res.stdout + res.stderr  # QEMU writes semihosting output to stderr
    plan = [(m.group(1), int(m.group(2))) for m in re.finditer(r"^PLAN (\S+) (\d+)$", stdout, re.M)]
    intervals = [hits[i + 1] - hits[i] for i in range(0, len(hits) - 1, 2)]
    expected = sum(k for _, k in plan)
    if len(hits) != 2 * expected:
        raise RuntimeError(f"{image}: {len(hits)} marks in the trace, plan wants {2 * expected}")
    counts: dict[str, list[int]] = {}
    pos = 0
    for name, k in plan:
        counts.setdefault(name, []).extend(intervals[pos:pos + k])
        pos += k
    calib = counts.pop("calibration")[0]
    for k in [k for k in counts if k == "stack" or k.startswith("stack@")]:
        counts.pop(k)
    return {name: [c - calib for c in v] for name, v in counts.items()}, stdout


def qemu_function_counts(machine: str, image: Path, nm: str, plan_name: str) -> dict[str, int]:
    """Instructions per function during the first measured call of plan_name."""
    import bisect
    syms = []
    for line in run([nm, "-S", str(image)]).stdout.splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[2] in "tTwW":
            syms.append((int(parts[0], 16) & ~1, int(parts[1], 16), parts[3]))
    syms.sort()
    starts = [x[0] for x in syms]
    mark = next(x[0] for x in syms if x[2] == "bench_mark")
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "exec.log"
        res = run(["qemu-system-arm", "-M", machine, "-nographic",
                   "-semihosting-config", "enable=on,target=native", "-kernel", str(image),
                   "-singlestep", "-d", "exec,nochain", "-D", str(log)],
                  stdin=subprocess.DEVNULL, timeout=600)
        plan = [(m.group(1), int(m.group(2)))
                for m in re.finditer(r"^PLAN (\S+) (\d+)$", res.stdout + res.stderr, re.M)]
        first = 0
        for name, k in plan:
            if name == plan_name:
                break
            first += k
        pcs = []
        with log.open() as f:
            for line in f:
                m = TRACE_RE.match(line)
                if m:
                    pcs.append(int(m.group(1), 16))
    hits = [i for i, pc in enumerate(pcs) if pc == mark]
    seg = pcs[hits[2 * first] + 1:hits[2 * first + 1]]
    out: dict[str, int] = {}
    for pc in seg:
        i = bisect.bisect_right(starts, pc) - 1
        fn = syms[i][2] if i >= 0 and pc < syms[i][0] + syms[i][1] else "?"
        out[fn] = out.get(fn, 0) + 1
    return dict(sorted(out.items(), key=lambda kv: -kv[1]))


def callgrind_function_counts(exe: Path, mode: str) -> dict[str, float]:
    """Instructions per function (self cost) per call of one bench_host mode."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "callgrind.out"
        run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
             "--toggle-collect=abbe_error_eval_f32", str(exe), mode, str(CALLGRIND_N)])
        ann = run(["callgrind_annotate", str(out)]).stdout
    res: dict[str, float] = {}
    for line in ann.splitlines():
        m = re.match(r"^\s*([\d,]+)\s+\([^)]*\)\s+\S*:(\S+)", line)
        if m and any(key in m.group(2) for key in ("abbe", "eval_f32", "terms")):
            res[m.group(2)] = int(m.group(1).replace(",", "")) / CALLGRIND_N
    return res


def stack_measured(stdout: str) -> dict[str, int]:
    return {m.group(1): int(m.group(2)) for m in re.finditer(r"^STACK (\S+) (\d+)$", stdout, re.M)}


# --------------------------------------------------------------------------- flags

def compile_flags(build: Path, source: str) -> str:
    """The flags one library source was compiled with (compile_commands.json),
    without include paths, definitions and the warning set."""
    import json
    import shlex
    try:
        cmds = json.loads((build / "compile_commands.json").read_text())
    except (OSError, ValueError):
        return "(compile_commands.json missing)"
    for c in cmds:
        if c["file"].endswith(source) and "/abbe.dir/" in c.get("output", c.get("command", "")):
            words = shlex.split(c["command"])[1:]
            keep = [w for w in words if not w.startswith(("-I", "-D", "-W", "-o", "-c"))
                    and not w.endswith((".c", ".o", ".obj")) and w not in ("-o", "-c")]
            return " ".join(keep)
    return "(not found)"


# --------------------------------------------------------------------------- python

def python_throughput(repo: Path, host: Path) -> dict | None:
    """bench/bench_python.py --json against the host build's libabbe.so."""
    import json
    lib = host / "lib" / "libabbe.so"
    py = repo / ".venv" / "bin" / "python"
    if not lib.exists() or not py.exists():
        return None
    res = subprocess.run([str(py), str(repo / "bench" / "bench_python.py"), "--lib", str(lib), "--json"],
                         capture_output=True, text=True)
    if res.returncode != 0:
        return {"error": (res.stdout + res.stderr).strip()[-300:]}
    return json.loads(res.stdout.strip().splitlines()[-1])
