#!/usr/bin/env python3
"""Measure the abbe library and write bench/results.md (run by scripts/bench.sh).

Everything counted here is an instruction count or a byte count, so the
numbers repeat exactly for the same compiler, library and table:

1. x86-64 instructions per call (valgrind --tool=callgrind): the library's
   own cost from --toggle-collect=<function> (total / calls), cross-checked by
   the difference of two whole-program runs of N and N + 1000 calls.
2. Cortex-M4F / Cortex-M3 instructions per call from QEMU's exec trace
   (-singlestep -d exec,nochain: one trace line per executed instruction),
   counted between two calls of bench_mark() minus an empty pair.
3. Flash and static RAM of the library per use, from the link maps of the
   bench_size_* images (input sections that come from libabbe.a).
4. Stack: worst case from GCC's -fcallgraph-info=su call graph (deepest
   chain), and the bytes the call really used on the target (stack painting).
5. Two reference programs for comparison, built the same way: a naive
   double-precision evaluator (bench/naive_ref.c) and a lean float one
   (bench/lean_ref.c: the same model without abbe's guarantees).
6. Points per second from Python (bench/bench_python.py; wall clock).
7. Format 1.1's reversal blocks (issue 14): the calls again on the golden
   tables "backlash" (the paper table with a constant backlash, format 1.0) and
   "reversal" (the same with reversal blocks), and a second set of builds with
   -DABBE_WITH_REVERSAL=OFF (a format 1.0 library, the machine code of the
   library before 1.1): what the blocks cost in instructions, flash and stack,
   and that tables without them cost what they did.
9. clang/LLVM beside GCC (issue 28): the same measurements of the builds with
   cmake/toolchain-cortex-{m4f,m3}-clang.cmake (lld maps; the static stack from
   clang's -fstack-usage frames and the calls in the image's disassembly,
   since clang writes no call graph).

Usage: bench_report.py --repo DIR --host BUILD --m4f BUILD --m3 BUILD [-o FILE]
Only the Python standard library is used.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

# Targets from the issue: reported, not asserted.
TARGETS = {
    "x86_f32": 400,
    "m4f_f32": 700,
    "m3_q": 1500,
    "flash_bytes": 6 * 1024,
    "stack_bytes": 256,
}

# The same measurements of the library before this round of work (commit
# af2baa8, bench/results.md of that commit): the "before" column.
BEFORE = {
    "x86_f32": 1404, "m4f_f32": 1461, "m3_q": 2380,
    "flash_f32": 6176, "flash_q_m4f": 7084, "flash_q_m3": 7140,
    "stack_comp_q_m4f": 544, "stack_comp_q_m3": 560,
}

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


# --------------------------------------------------------------------------- link maps

SECTION_RE = re.compile(r"^ (\.[^\s]+)\s+0x([0-9a-f]+)\s+0x([0-9a-f]+)\s+(.+)$")
CONT_RE = re.compile(r"^\s+0x([0-9a-f]+)\s+0x([0-9a-f]+)\s+(.+)$")


@dataclass
class MapSizes:
    lib_flash: int = 0
    lib_ram: int = 0
    gcc_flash: int = 0
    gcc_members: set[str] = field(default_factory=set)
    lib_members: dict[str, int] = field(default_factory=dict)


# lld's map (-Wl,-Map with clang): "VMA LMA Size Align Out In Symbol" columns,
# one line per input section "file:(section)" or "archive(member):(section)".
LLD_INPUT_RE = re.compile(r"^\s*[0-9a-f]+\s+[0-9a-f]+\s+([0-9a-f]+)\s+\d+\s+(\S+):\((\S+)\)$")


def gnu_map_inputs(path: Path, lines: list[str]):
    """(section, size, origin) of every input section of a GNU ld map."""
    try:
        start = next(i for i, l in enumerate(lines) if l.startswith("Linker script and memory map"))
    except StopIteration:
        raise RuntimeError(f"{path}: not a GNU ld map") from None
    pending = None
    for line in lines[start:]:
        m = SECTION_RE.match(line)
        if m:
            sec, _, size, origin = m.groups()
        elif pending and CONT_RE.match(line):
            _, size, origin = CONT_RE.match(line).groups()
            sec = pending
        else:
            pending = line.strip() if re.match(r"^ \.[^\s]+$", line) else None
            continue
        pending = None
        yield sec, int(size, 16), origin


def lld_map_inputs(lines: list[str]):
    """(section, size, origin) of every input section of an lld map."""
    for line in lines[1:]:
        m = LLD_INPUT_RE.match(line)
        if m:
            yield m.group(3), int(m.group(1), 16), m.group(2)


def parse_map(path: Path) -> MapSizes:
    """Flash (.text*, .rodata*) and RAM (.data*, .bss*) taken from libabbe.a / libgcc.a
    (GNU ld or lld map)."""
    sizes = MapSizes()
    lines = path.read_text().splitlines()
    lld = bool(lines) and lines[0].split()[:3] == ["VMA", "LMA", "Size"]
    for sec, size_b, origin in (lld_map_inputs(lines) if lld else gnu_map_inputs(path, lines)):
        if size_b == 0 or not re.search(r"\.a\(", origin):
            continue
        flash = sec.startswith((".text", ".rodata"))
        ram = sec.startswith((".data", ".bss"))
        member = origin.rsplit("(", 1)[-1].rstrip(")")
        if "libabbe.a(" in origin:
            if flash:
                sizes.lib_flash += size_b
                key = member.replace(".c.obj", ".c").replace(".c.o", ".c")
                sizes.lib_members[key] = sizes.lib_members.get(key, 0) + size_b
            elif ram:
                sizes.lib_ram += size_b
        elif "libgcc.a(" in origin and flash:
            sizes.gcc_flash += size_b
            sizes.gcc_members.add(member)
    return sizes


# --------------------------------------------------------------------------- call graph

NODE_RE = re.compile(r'^node: \{ title: "([^"]+)" label: "([^"]*)"')
EDGE_RE = re.compile(r'^edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"')


def parse_callgraph(ci_files: list[Path]) -> tuple[dict[str, int], dict[str, set[str]]]:
    frames: dict[str, int] = {}
    calls: dict[str, set[str]] = {}
    for f in ci_files:
        for line in f.read_text().splitlines():
            m = NODE_RE.match(line)
            if m:
                sm = re.search(r"\\n(\d+) bytes \(([^)]*)\)", m.group(2))
                if sm:
                    frames[m.group(1)] = int(sm.group(1))
                continue
            m = EDGE_RE.match(line)
            if m:
                calls.setdefault(m.group(1), set()).add(m.group(2))
    return frames, calls


def deepest(fn: str, frames: dict[str, int], calls: dict[str, set[str]],
            seen: tuple[str, ...] = ()) -> tuple[int, list[str]]:
    """Worst-case stack from fn and the chain that reaches it (recursion: error)."""
    if fn in seen:
        raise RuntimeError(f"recursion through {fn}: no static stack bound")
    best, chain = 0, []
    for callee in sorted(calls.get(fn, ())):
        d, c = deepest(callee, frames, calls, seen + (fn,))
        if d > best:
            best, chain = d, c
    return frames.get(fn, 0) + best, [fn] + chain


def su_frames(build: Path) -> dict[str, int]:
    """Frame bytes per library function from the -fstack-usage files (.su)."""
    frames: dict[str, int] = {}
    for su in (build / "lib").rglob("*.su"):
        for line in su.read_text().splitlines():
            parts = line.split("\t")
            if len(parts) >= 3:
                if "dynamic" in parts[2]:
                    raise RuntimeError(f"{su}: dynamic stack in {parts[0]}: no static bound")
                name = parts[0].rsplit(":", 1)[-1]
                frames[name] = max(frames.get(name, 0), int(parts[1]))
    return frames


BRANCH_RE = re.compile(r"^\s+[0-9a-f]+:\s+(?:bl|b(?:eq|ne|cs|cc|hs|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le)?)"
                       r"(?:\.w|\.n)?\s+[0-9a-f]+ <([^>+]+)>")


def image_calls(image: Path, objdump: str) -> dict[str, set[str]]:
    """Calls and tail calls (BL, B to the start of another function) between the
    functions of a linked image, from its disassembly: the call graph where the
    compiler writes none (clang). The library makes no indirect calls."""
    calls: dict[str, set[str]] = {}
    fn = None
    for line in run([objdump, "-d", "--no-show-raw-insn", str(image)]).stdout.splitlines():
        m = re.match(r"^[0-9a-f]+ <([^>]+)>:$", line)
        if m:
            fn = m.group(1)
            continue
        m = BRANCH_RE.match(line)
        if m and fn and m.group(1) != fn:
            calls.setdefault(fn, set()).add(m.group(1))
    return calls


def short(fn: str) -> str:
    """Call-graph title without the absolute path GCC puts on static functions."""
    if ":" in fn:
        path, name = fn.rsplit(":", 1)
        return f"{os.path.basename(path)}:{name}"
    return fn


def wrapper_frames(build: Path) -> dict[str, int]:
    """Frames of the bench_target.c wrappers (.su), to take out of the measured stack."""
    out = {}
    for su in build.glob("bench/CMakeFiles/bench_target.dir/*.su"):
        for line in su.read_text().splitlines():
            parts = line.split("\t")
            if len(parts) >= 2:
                out[parts[0].rsplit(":", 1)[-1]] = int(parts[1])
    return out


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


# --------------------------------------------------------------------------- report

def fmt_counts(v: list[int]) -> str:
    lo, hi = min(v), max(v)
    return f"{lo}" if lo == hi else f"{lo} to {hi} (mean {statistics.mean(v):.0f})"


def verdict(value: float, target: float) -> str:
    return "meets" if value <= target else "MISSES"


TABLES_11 = ("backlash", "reversal")
CALL_LABELS = {"f32": "abbe_error_eval_f32", "f32_base": "abbe_error_eval_f32 (SSE2 kernels)",
               "q": "abbe_error_eval_q", "comp_f32": "abbe_comp_step_f32",
               "comp_q": "abbe_comp_step_q"}


def reversal_section(args, nm: str, by: dict, tgt: dict, stdout_by: dict, flash_by: dict,
                     stack_by: dict) -> dict:
    """Section 8 (format 1.1): instructions on the paper / backlash / reversal tables for
    this library and for the 1.0 library (ABBE_WITH_REVERSAL=OFF builds, if given), flash
    and stack of both. Returns the lines and the numbers the summary uses."""
    lines: list[str] = []
    w = lines.append
    out: dict = {"lines": lines, "flash_10": {}}
    w("## 8. Format 1.1: what the reversal blocks cost (issue 14)")
    w("")
    w("Tables (tests/golden): `paper` as above (no backlash); `backlash` = the paper table")
    w("with a constant backlash on every axis (format 1.0); `reversal` = `backlash` with")
    w("reversal blocks of degree 3, 7 and 0 on X, Y, Z (format 1.1). `1.0 library` = the")
    w("same sources built with `-DABBE_WITH_REVERSAL=OFF` (a format 1.0 reader: the")
    w("library's machine code before format 1.1; it refuses the `reversal` table). The")
    w("blocks' cost is `reversal` - `backlash` with this library. x86-64: callgrind,")
    w("instructions inside the call; Cortex-M: the worst of the measured points, QEMU trace.")
    w("")
    w("| target | call | paper | backlash | reversal | blocks' cost | paper, 1.0 library | "
      "backlash, 1.0 library |")
    w("|---|---|---:|---:|---:|---:|---:|---:|")
    host = {None: {m: by[m].per_call for m, _, _ in TABLE_MODES}}
    for t in TABLES_11:
        host[t] = host_table_bench(args.host, t)
    host10 = {}
    if args.host_10:
        for t in (None, "backlash"):
            host10[t] = host_table_bench(args.host_10, t)

    def cell(v) -> str:
        return "-" if v is None else f"{v:.0f}"
    for mode, _, _ in TABLE_MODES:
        vals = [None if host[t] is None else host[t][mode] for t in (None, *TABLES_11)]
        cost = None if None in vals[1:] else vals[2] - vals[1]
        v10 = [None if not host10.get(t) else host10[t][mode] for t in (None, "backlash")]
        w(f"| x86-64 | {CALL_LABELS[mode]} | " + " | ".join(cell(v) for v in vals) +
          f" | {cell(cost)} | " + " | ".join(cell(v) for v in v10) + " |")
    tgt10: dict[str, dict[str, list[int]]] = {}
    stdout10: dict[str, str] = {}
    for name, build, machine in (("Cortex-M4F", args.m4f_10, "mps2-an386"),
                                 ("Cortex-M3", args.m3_10, "mps2-an385")):
        if build:
            tgt10[name], stdout10[name] = qemu_trace_counts(
                machine, build / "bench" / "bench_target.elf", nm)
    for name in ("Cortex-M4F", "Cortex-M3"):
        for mode in ("f32", "q", "comp_f32", "comp_q"):
            c = tgt[name]
            if mode not in c:
                continue
            vals = [max(c[k]) if k in c else None
                    for k in (mode, f"{mode}@backlash", f"{mode}@reversal")]
            cost = None if None in vals[1:] else vals[2] - vals[1]
            c10 = tgt10.get(name, {})
            v10 = [max(c10[k]) if k in c10 else None for k in (mode, f"{mode}@backlash")]
            w(f"| {name} | {CALL_LABELS[mode]} | " + " | ".join(cell(v) for v in vals) +
              f" | {cell(cost)} | " + " | ".join(cell(v) for v in v10) + " |")
            out[(name, mode)] = (vals, v10)
    w("")
    w("A table without reversal blocks executes no block code: `paper` (no backlash) runs")
    w("the 1.0 paths; the few instructions either way there come from the compiler's")
    w("register allocation in the functions that also hold the blocks' calls. With a")
    w("backlash (`backlash` vs the 1.0 library): `_f32` adds one feature test after the")
    w("extras and passes the axis offsets to them (the blocks are a function of their own,")
    w("called last); `_q` tests each axis' block row count in the extras loop (the block")
    w("replaces B by B + R before the one rounding, so a one-row block is bit for bit a")
    w("change of B). Measured during this work: the `_f32` block code inlined into the")
    w("extras loop instead takes 160 B less flash but costs a table with backlash and no")
    w("blocks +23 (Cortex-M4F) / +48 (x86-64) instructions instead of +11 / +9.")
    w("")

    # flash
    w("Flash of the library (as in section 3), this library and the 1.0 library:")
    w("")
    w("| target | use | this library (B) | 1.0 library (B) | the blocks (B) |")
    w("|---|---|---:|---:|---:|")
    labels = {"load": "abbe_model_load only", "eval_f32": "load + eval_f32",
              "eval_q": "load + eval_q", "comp_f32": "load + compensator (f32)",
              "comp_q": "load + compensator (q)"}
    for name, build in (("Cortex-M4F", args.m4f_10), ("Cortex-M3", args.m3_10)):
        for use in ("load", "eval_f32", "eval_q", "comp_f32", "comp_q"):
            if (name, use) not in flash_by:
                continue
            v10 = None
            if build and (build / "bench" / f"bench_size_{use}.map").exists():
                v10 = parse_map(build / "bench" / f"bench_size_{use}.map").lib_flash
                out["flash_10"][(name, use)] = v10
            now = flash_by[(name, use)]
            w(f"| {name} | {labels[use]} | {now} | {cell(v10)} | "
              f"{'-' if v10 is None else f'{now - v10:+d}'} |")
    w("")

    # stack
    w("Stack (as in section 4): static = deepest call chain; measured = painted, on the")
    w("`reversal` table (minus the wrapper's frame):")
    w("")
    w("| target | entry point | static, this library (B) | static, 1.0 library (B) | "
      "measured, reversal table (B) |")
    w("|---|---|---:|---:|---:|")
    for name, build, build10 in (("Cortex-M4F", args.m4f, args.m4f_10),
                                 ("Cortex-M3", args.m3, args.m3_10)):
        frames10 = calls10 = None
        if build10:
            frames10, calls10 = parse_callgraph(sorted((build10 / "lib").rglob("*.ci")))
        measured = stack_measured(stdout_by[name])
        wrappers = wrapper_frames(build)
        for key, fn, wrapper in (("comp_f32", "abbe_comp_step_f32", "run_comp_f32"),
                                 ("comp_q", "abbe_comp_step_q", "run_comp_q")):
            if (name, key) not in stack_by:
                continue
            s10 = None
            if frames10 is not None and fn in frames10:
                s10 = deepest(fn, frames10, calls10)[0]
            meas = measured.get(f"{key}@reversal")
            meas_s = "-" if meas is None else str(meas - wrappers.get(wrapper, 0))
            w(f"| {name} | {fn} | {stack_by[(name, key)]} | {cell(s10)} | {meas_s} |")
    w("")
    return out


# The measured entry points: PLAN key in bench_target.c, function, its wrapper there.
ENTRY_POINTS = (("load", "abbe_model_load", "run_load"), ("f32", "abbe_error_eval_f32", "run_f32"),
                ("q", "abbe_error_eval_q", "run_q"), ("comp_f32", "abbe_comp_step_f32", "run_comp_f32"),
                ("comp_q", "abbe_comp_step_q", "run_comp_q"))
CLANG_USES = (("load", "abbe_model_load only"), ("eval_f32", "load + eval_f32"),
              ("eval_q", "load + eval_q"), ("comp_f32", "load + compensator (f32)"),
              ("comp_q", "load + compensator (q)"))


def clang_section(args, nm: str, tgt: dict, stdout_by: dict, flash_by: dict, stack_by: dict) -> list[str]:
    """Section 9: the clang/LLVM builds beside the GCC ones (instructions, flash, stack)."""
    md: list[str] = []
    w = md.append
    objdump = "arm-none-eabi-objdump"
    builds = (("Cortex-M4F", args.m4f, args.m4f_clang, "mps2-an386"),
              ("Cortex-M3", args.m3, args.m3_clang, "mps2-an385"))
    w("## 9. clang/LLVM beside GCC (issue 28)")
    w("")
    w("The same sources, flags and measurements built with clang and lld instead of")
    w("arm-none-eabi-gcc (cmake/toolchain-cortex-{m4f,m3}-clang.cmake: -O2, the same per-file -Os,")
    w("-munaligned-access as GCC assumes on ARMv7-M, newlib's headers and libgcc.a of the GNU")
    w("packages). " + first_line(["clang", "--version"]) + ". The targets of the summary are")
    w("GCC's; this section reports what clang reaches. The golden vectors pass with both")
    w("compilers (scripts/test.sh: the GCC Cortex-M steps and the clang step). clang's flags")
    w("(compile_commands.json, as in section 7; the -Os files as with GCC):")
    w("")
    for name, _, build, _ in builds:
        w(f"- {name} (Release), lib/src/*.c: `{compile_flags(build, 'lib/src/terms_q.c')}`")
    w("")
    w("| target | call | GCC instructions | clang instructions | clang / GCC |")
    w("|---|---|---:|---:|---:|")
    clang_counts: dict[str, dict[str, list[int]]] = {}
    clang_stdout: dict[str, str] = {}
    for name, _, build, machine in builds:
        counts, stdout = qemu_trace_counts(machine, build / "bench" / "bench_target.elf", nm)
        clang_counts[name], clang_stdout[name] = counts, stdout
        for key, fn, _ in ENTRY_POINTS:
            if key in counts and key in tgt[name]:
                g, c = max(tgt[name][key]), max(counts[key])
                w(f"| {name} | {fn} | {fmt_counts(tgt[name][key])} | {fmt_counts(counts[key])} | {c / g:.2f} |")
    w("")
    m4f_f32 = max(clang_counts["Cortex-M4F"]["f32"])
    m3_q = max(clang_counts["Cortex-M3"]["q"])
    w(f"clang reaches {m4f_f32} instructions for the M4F's abbe_error_eval_f32 (GCC's target "
      f"<= {TARGETS['m4f_f32']}: {verdict(m4f_f32, TARGETS['m4f_f32'])} with clang) and {m3_q} for the "
      f"M3's abbe_error_eval_q (<= {TARGETS['m3_q']}: {verdict(m3_q, TARGETS['m3_q'])} with clang).")
    w("")
    extra = ""
    if args.m4f_clang_nounroll:
        extra = " clang -fno-unroll-loops (B) |"
    w("| target | use | GCC library flash (B) | clang library flash (B) |" + extra)
    w("|---|---|---:|---:|" + ("---:|" if extra else ""))
    clang_flash: dict[tuple[str, str], int] = {}
    for name, gcc_build, build, _ in builds:
        for use, label in CLANG_USES:
            mp = build / "bench" / f"bench_size_{use}.map"
            if not mp.exists():
                continue
            c = parse_map(mp).lib_flash
            clang_flash[(name, use)] = c
            g = flash_by.get((name, use))
            if g is None:
                g = parse_map(gcc_build / "bench" / f"bench_size_{use}.map").lib_flash
            row = f"| {name} | {label} | {g} | {c} |"
            if extra:
                nu = args.m4f_clang_nounroll / "bench" / f"bench_size_{use}.map"
                row += f" {parse_map(nu).lib_flash if name == 'Cortex-M4F' and nu.exists() else '-'} |"
            w(row)
    w("")
    w("Library flash by source file, compensator images (clang):")
    w("")
    for name, _, build, _ in builds:
        for use in ("comp_f32", "comp_q"):
            mp = build / "bench" / f"bench_size_{use}.map"
            if mp.exists():
                members = parse_map(mp).lib_members
                w(f"- {name}, {use}: " + ", ".join(f"{k} {v}" for k, v in
                                                  sorted(members.items(), key=lambda kv: -kv[1])))
    w("")
    w("Stack: `static` for clang = deepest chain of clang's -fstack-usage frames along the")
    w("calls in the image's disassembly (BL and tail-call B; helper routines count 0, as")
    w("for GCC); `measured` as in section 4 (stack painting, wrapper frame taken out).")
    w("")
    w("| target | entry point | GCC static (B) | clang static (B) | GCC measured (B) | clang measured (B) | clang's deepest chain |")
    w("|---|---|---:|---:|---:|---:|---|")
    for name, gcc_build, build, _ in builds:
        frames = su_frames(build)
        calls = image_calls(build / "bench" / "bench_target.elf", objdump)
        meas_g = stack_measured(stdout_by[name])
        meas_c = stack_measured(clang_stdout[name])
        wrap_g, wrap_c = wrapper_frames(gcc_build), wrapper_frames(build)
        for key, fn, wrapper in ENTRY_POINTS:
            if fn not in frames:
                continue
            depth, chain = deepest(fn, frames, calls)
            g_static = stack_by.get((name, key), "-")
            g_meas = meas_g[key] - wrap_g.get(wrapper, 0) if key in meas_g else "-"
            c_meas = meas_c[key] - wrap_c.get(wrapper, 0) if key in meas_c else "-"
            chain_s = " > ".join(f"{c} ({frames.get(c, 0)})" for c in chain)
            w(f"| {name} | {fn} | {g_static} | {depth} | {g_meas} | {c_meas} | {chain_s} |")
    w("")
    w("Where the instructions go (clang; GCC's are in section 5b), one call:")
    w("")
    fc_by = {}
    for (name, _, build, machine), call in zip(builds, ("f32", "q")):
        fc = qemu_function_counts(machine, build / "bench" / "bench_target.elf", nm, call)
        fc_by[name] = fc
        parts = ", ".join(f"{k} {v}" for k, v in fc.items()
                          if k not in ("bench_mark", "measure_calls", "run_f32", "run_q"))
        w(f"- {name}, abbe_error_eval_{call}: {parts}")
    gfc = qemu_function_counts("mps2-an386", args.m4f / "bench" / "bench_target.elf", nm, "f32")
    gfq = qemu_function_counts("mps2-an385", args.m3 / "bench" / "bench_target.elf", nm, "q")
    cf, cq = fc_by["Cortex-M4F"], fc_by["Cortex-M3"]
    w("")
    w("Why clang differs (each reason seen in the disassembly and the counts above):")
    w("")
    w(f"- abbe_axis_fold_f32 ({gfc.get('abbe_axis_fold_f32', 0)} GCC, {cf.get('abbe_axis_fold_f32', 0)} clang "
      "per call): GCC shrink-wraps it and tail-calls fold6_f32 on the six-term path; clang saves")
    w("  d8-d14 and parks the seven float arguments in callee-saved registers on every path, then")
    w("  moves them back for a normal call. The asm kernels themselves are the same: fold6_f32")
    w(f"  {gfc.get('fold6_f32', 0)} GCC, {cf.get('fold6_f32', 0)} clang. Measured while writing this")
    w("  section: the sparse path out of line (both paths tail calls) takes clang to 657-665")
    w("  instructions, but costs GCC 6 instructions (703, over its target; returned by value:")
    w("  GCC reserves a frame it never uses) or 52 B of flash (returned through a pointer); the")
    w("  library keeps the form GCC's targets were met with.")
    w(f"- terms6_q ({gfq.get('terms6_q', 0)} GCC, {cq.get('terms6_q', 0)} clang on the M3): six int64 "
      "accumulators are 12 of the 13 allocatable")
    w("  registers; both compilers spill some to the stack around each row's six SMLALs, clang")
    w("  more of them. assemble_q and the fixed-point sin/cos likewise (register allocation and")
    w("  scheduling, no different algorithm).")
    w("- Flash: clang -O2 unrolls loops (GCC -O2 does not): the loader's validation loops,")
    w("  crc32 (8 bits per byte) and the Chebyshev and harmonic recurrences."
      + (" The last column is the M4F clang build with -fno-unroll-loops, whose abbe_error_eval_f32 "
         "takes " + fmt_counts(qemu_trace_counts("mps2-an386", args.m4f_clang_nounroll / "bench"
                                                  / "bench_target.elf", nm)[0]["f32"])
         + " instructions instead." if args.m4f_clang_nounroll else ""))
    w("- Alignment: clang assumes strict alignment on bare metal unless told otherwise, and then")
    w("  reads each little-endian table word byte by byte (4 LDRB, 3 ORR); the toolchain files")
    w("  pass -munaligned-access, GCC's default for ARMv7-M (measured while adding them: the M4F's")
    w("  abbe_error_eval_q took 2522 instructions without it).")
    w("- Fused multiply-add: LLVM's Cortex-M4 model marks VFMA as slow and keeps C's multiply-adds")
    w("  as VMUL + VADD whatever -ffp-contract says; the M4F clang toolchain file turns that off")
    w("  (-Xclang -target-feature -Xclang -slowfpvfmx), since the library asks for the fused form")
    w("  (measured while adding it: abbe_error_eval_f32 742 -> 732 instructions).")
    w("")
    return md


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repo", type=Path, required=True)
    ap.add_argument("--host", type=Path, required=True)
    ap.add_argument("--m4f", type=Path, required=True)
    ap.add_argument("--m3", type=Path, required=True)
    ap.add_argument("--m4f-os", type=Path, help="Cortex-M4F build at -Os (optional)")
    ap.add_argument("--m3-os", type=Path, help="Cortex-M3 build at -Os (optional)")
    ap.add_argument("--host-1.0", dest="host_10", type=Path,
                    help="host build with -DABBE_WITH_REVERSAL=OFF (optional)")
    ap.add_argument("--m4f-1.0", dest="m4f_10", type=Path,
                    help="Cortex-M4F build with -DABBE_WITH_REVERSAL=OFF (optional)")
    ap.add_argument("--m3-1.0", dest="m3_10", type=Path,
                    help="Cortex-M3 build with -DABBE_WITH_REVERSAL=OFF (optional)")
    ap.add_argument("--m4f-clang", type=Path, help="Cortex-M4F build with clang (optional)")
    ap.add_argument("--m3-clang", type=Path, help="Cortex-M3 build with clang (optional)")
    ap.add_argument("--m4f-clang-nounroll", type=Path,
                    help="Cortex-M4F clang build with -fno-unroll-loops (optional)")
    ap.add_argument("-o", "--out", type=Path)
    args = ap.parse_args()
    nm = "arm-none-eabi-nm"

    md: list[str] = []
    w = md.append
    w("# abbe benchmark results")
    w("")
    w("Written by `scripts/bench.sh` (scripts/bench_report.py); do not edit by hand.")
    w("Instruction and byte counts, not times: they repeat exactly for the same")
    w("compiler, library and table. Table: the `paper` golden table")
    w("(tests/golden: 3 axes x 6 terms, Chebyshev trend degree 1 + 3 harmonics,")
    w("squareness, tool offset); section 8 adds the tables with a backlash and with")
    w("reversal blocks (format 1.1). Library built with CMAKE_BUILD_TYPE=Release")
    w("(host -O3, Cortex-M -O2, see cmake/arm-none-eabi-common.cmake).")
    w("")
    w("Tools: " + "; ".join([
        first_line(["gcc", "--version"]),
        first_line(["arm-none-eabi-gcc", "--version"]),
        first_line(["qemu-system-arm", "--version"]),
        first_line(["valgrind", "--version"]),
    ]))
    w("")

    # 1. host
    host, check = host_bench(args.host)
    by = {r.mode: r for r in host}
    w("## 1. x86-64 instructions per call (callgrind)")
    w("")
    w("`inside` = instructions executed inside the function per call")
    w(f"(--toggle-collect, {CALLGRIND_N} calls over the table's golden points);")
    w(f"`loop` = whole-program difference of {CALLGRIND_N + CALLGRIND_EXTRA} and "
      f"{CALLGRIND_N} calls / {CALLGRIND_EXTRA},")
    w("i.e. including the benchmark loop and the call itself "
      f"(an empty call costs {by['empty'].per_iter:.0f} per iteration).")
    w("")
    w("| call | inside | loop |")
    w("|---|---:|---:|")
    names = {"f32": "abbe_error_eval_f32 (kernels this CPU runs, see below)",
             "f32_base": "abbe_error_eval_f32, x86-64 baseline (SSE2) kernels",
             "lean": "lean reference (float, no guarantees; bench/lean_ref.c)",
             "q": "abbe_error_eval_q",
             "comp_f32": "abbe_comp_step_f32 (compensator cycle)",
             "comp_q": "abbe_comp_step_q (compensator cycle)",
             "naive": "naive reference (double, libm sin/cos)", "empty": "empty call"}
    for r in host:
        w(f"| {names[r.mode]} | {r.per_call:.1f} | {r.per_iter:.1f} |")
    w("")
    w(f"Target x86 f32 <= {TARGETS['x86_f32']}: {by['f32'].per_call:.0f} "
      f"({verdict(by['f32'].per_call, TARGETS['x86_f32'])}) with the kernels this CPU runs; "
      f"the SSE2 kernels every x86-64 runs: {by['f32_base'].per_call:.0f} "
      f"({verdict(by['f32_base'].per_call, TARGETS['x86_f32'])}).")
    w("")
    w(f"Ratios: naive / f32 = {by['naive'].per_call / by['f32'].per_call:.1f}x "
      f"(SSE2: {by['naive'].per_call / by['f32_base'].per_call:.1f}x), "
      f"naive / q = {by['naive'].per_call / by['q'].per_call:.1f}x; "
      f"lean / f32 = {by['lean'].per_call / by['f32'].per_call:.2f}x "
      f"(SSE2: {by['lean'].per_call / by['f32_base'].per_call:.2f}x), "
      f"lean / q = {by['lean'].per_call / by['q'].per_call:.2f}x "
      "(above 1: abbe executes fewer instructions than the lean evaluator).")
    w("")
    w("Naive reference check (`bench_host check`):")
    w("")
    w("```")
    w(check)
    w("```")
    w("")

    # 2. target
    w("## 2. Cortex-M instructions per call (QEMU exec trace)")
    w("")
    w("One trace line per executed instruction (`-singlestep -d exec,nochain`),")
    w("counted from the first to the second `bench_mark()` minus an empty pair;")
    w("the count includes the argument set-up and the call. 8 points per variant")
    w("(golden points of the table: in and out of travel, both directions).")
    w("These are instructions, not cycles (no wait states, pipeline or FPU latency).")
    w("")
    w("| target | call | instructions |")
    w("|---|---|---:|")
    tgt: dict[str, dict[str, list[int]]] = {}
    stdout_by: dict[str, str] = {}
    naive_t: dict[str, list[int]] = {}
    lean_t: dict[str, list[int]] = {}
    for name, build, machine in (("Cortex-M4F", args.m4f, "mps2-an386"),
                                 ("Cortex-M3", args.m3, "mps2-an385")):
        counts, stdout = qemu_trace_counts(machine, build / "bench" / "bench_target.elf", nm)
        tgt[name] = counts
        stdout_by[name] = stdout
        ncounts, _ = qemu_trace_counts(machine, build / "bench" / "bench_naive_target.elf", nm)
        naive_t[name] = ncounts["naive"]
        lean_img = build / "bench" / "bench_lean_target.elf"
        if lean_img.exists():
            lcounts, _ = qemu_trace_counts(machine, lean_img, nm)
            lean_t[name] = lcounts["lean"]
        for call, v in counts.items():
            if "@" in call:
                continue  # other tables: section 8
            label = {"f32": "abbe_error_eval_f32", "load": "abbe_model_load"}.get(call, names.get(call, call))
            w(f"| {name} | {label} | {fmt_counts(v)} |")
        w(f"| {name} | naive reference (double, newlib libm) | {fmt_counts(naive_t[name])} |")
        if name in lean_t:
            w(f"| {name} | lean reference (float, no guarantees) | {fmt_counts(lean_t[name])} |")
    w("")
    m4f_f32 = max(tgt["Cortex-M4F"]["f32"])
    m3_q = max(tgt["Cortex-M3"]["q"])
    w(f"Target M4F f32 <= {TARGETS['m4f_f32']}: {m4f_f32} ({verdict(m4f_f32, TARGETS['m4f_f32'])}); "
      f"M3 q <= {TARGETS['m3_q']}: {m3_q} ({verdict(m3_q, TARGETS['m3_q'])}). "
      f"Naive / library: M4F {statistics.mean(naive_t['Cortex-M4F']) / statistics.mean(tgt['Cortex-M4F']['f32']):.0f}x (f32), "
      f"M3 {statistics.mean(naive_t['Cortex-M3']) / statistics.mean(tgt['Cortex-M3']['q']):.0f}x (q)."
      + (f" Lean / library: M4F {statistics.mean(lean_t['Cortex-M4F']) / statistics.mean(tgt['Cortex-M4F']['f32']):.2f}x (f32)."
         if "Cortex-M4F" in lean_t else ""))
    w("")

    # 3. flash and RAM
    w("## 3. Flash and static RAM of the library")
    w("")
    w("From the link maps of minimal images (bench/bench_size.c, --gc-sections):")
    w("`.text` + `.rodata` input sections taken from libabbe.a, and separately the")
    w("libgcc routines they pull in. Static RAM = `.data` + `.bss` from libabbe.a.")
    w("")
    w("| target | use | library flash (B) | libgcc flash (B) | libgcc routines | library RAM (B) |")
    w("|---|---|---:|---:|---|---:|")
    flash_worst = 0
    flash_eval_worst = 0
    flash_by: dict[tuple[str, str], int] = {}
    ram_worst = 0
    member_rows = []
    for name, build in (("Cortex-M4F", args.m4f), ("Cortex-M3", args.m3)):
        for use in ("load", "eval_f32", "eval_q", "comp_f32", "comp_q"):
            mp = build / "bench" / f"bench_size_{use}.map"
            if not mp.exists():
                continue
            s = parse_map(mp)
            flash_by[(name, use)] = s.lib_flash
            if use != "load":
                flash_worst = max(flash_worst, s.lib_flash)
            if use.startswith("eval"):
                flash_eval_worst = max(flash_eval_worst, s.lib_flash)
            ram_worst = max(ram_worst, s.lib_ram)
            gcc = ", ".join(sorted(m[:-2] if m.endswith(".o") else m
                                   for m in s.gcc_members)) or "none"
            label = {"load": "abbe_model_load only", "eval_f32": "load + eval_f32",
                     "eval_q": "load + eval_q", "comp_f32": "load + compensator (f32)",
                     "comp_q": "load + compensator (q)"}[use]
            w(f"| {name} | {label} | {s.lib_flash} | {s.gcc_flash} | {gcc} | {s.lib_ram} |")
            if use in ("comp_f32", "comp_q"):
                member_rows.append((name, use, s.lib_members))
    w("")
    w(f"Target flash per variant <= {TARGETS['flash_bytes']} B: load + eval worst "
      f"{flash_eval_worst} B ({verdict(flash_eval_worst, TARGETS['flash_bytes'])}), with the "
      f"compensator worst {flash_worst} B ({verdict(flash_worst, TARGETS['flash_bytes'])}). "
      f"Static RAM of the library: {ram_worst} B (must be 0: {'yes' if ram_worst == 0 else 'NO'}).")
    w("")
    w("Library flash by source file, compensator images:")
    w("")
    for name, use, members in member_rows:
        parts = ", ".join(f"{k} {v}" for k, v in sorted(members.items(), key=lambda kv: -kv[1]))
        w(f"- {name}, {use}: {parts}")
    w("")

    # 4. stack
    w("## 4. Stack")
    w("")
    w("`static` = deepest chain in GCC's call graph (-fstack-usage,")
    w("-fcallgraph-info=su) of the library objects; compiler helper routines")
    w("(libgcc, memset/memcpy) are not in that graph and count as 0 there.")
    w("`measured` = bytes really written below SP during the call on the target")
    w("(stack painted, QEMU run), minus the frame of the benchmark wrapper.")
    w("")
    w("| target | entry point | static (B) | measured (B) | deepest chain (frame bytes) |")
    w("|---|---|---:|---:|---|")
    stack_worst = 0
    stack_by: dict[tuple[str, str], int] = {}
    for name, build in (("Cortex-M4F", args.m4f), ("Cortex-M3", args.m3)):
        cis = sorted((build / "lib").rglob("*.ci"))
        frames, calls = parse_callgraph(cis)
        measured = stack_measured(stdout_by[name])
        wrappers = wrapper_frames(build)
        for key, fn, wrapper in ENTRY_POINTS:
            if fn not in frames:
                continue
            depth, chain = deepest(fn, frames, calls)
            stack_by[(name, key)] = depth
            if key != "load":
                stack_worst = max(stack_worst, depth)
            meas = measured.get(key)
            meas_s = "-" if meas is None else str(meas - wrappers.get(wrapper, 0))
            chain_s = " > ".join(f"{short(c)} ({frames.get(c, 0)})" for c in chain)
            w(f"| {name} | {fn} | {depth} | {meas_s} | {chain_s} |")
    w("")
    comp_q_stack = max(stack_by.get(("Cortex-M4F", "comp_q"), 0), stack_by.get(("Cortex-M3", "comp_q"), 0))
    w(f"Target stack of abbe_comp_step_q <= {TARGETS['stack_bytes']} B: worst static {comp_q_stack} B "
      f"({verdict(comp_q_stack, TARGETS['stack_bytes'])}). Worst of all entry points above: {stack_worst} B.")
    w("")

    # 5. -Os
    if args.m4f_os and args.m3_os:
        w("## 5. The same library built for size (-Os, CMAKE_BUILD_TYPE=MinSizeRel)")
        w("")
        w("| target | call | instructions | library flash, load + call (B) | static stack (B) |")
        w("|---|---|---:|---:|---:|")
        for name, build, machine in (("Cortex-M4F", args.m4f_os, "mps2-an386"),
                                     ("Cortex-M3", args.m3_os, "mps2-an385")):
            counts, _ = qemu_trace_counts(machine, build / "bench" / "bench_target.elf", nm)
            frames, calls = parse_callgraph(sorted((build / "lib").rglob("*.ci")))
            for key, fn, use in (("f32", "abbe_error_eval_f32", "eval_f32"),
                                 ("q", "abbe_error_eval_q", "eval_q"),
                                 ("comp_f32", "abbe_comp_step_f32", "comp_f32"),
                                 ("comp_q", "abbe_comp_step_q", "comp_q")):
                if key not in counts:
                    continue
                flash = parse_map(build / "bench" / f"bench_size_{use}.map").lib_flash
                label = "abbe_error_eval_f32" if key == "f32" else names[key]
                w(f"| {name} | {label} | {fmt_counts(counts[key])} | {flash} | "
                  f"{deepest(fn, frames, calls)[0]} |")
        w("")

    # 5b. where the instructions and bytes go
    w("## 5b. Where the instructions and bytes go")
    w("")
    w("Instructions per function during one call (Cortex-M: the first measured point, from the")
    w("QEMU trace; x86-64: callgrind self cost per call). The kernels are the per-axis dot")
    w("products with their basis (Chebyshev recurrence, one sin/cos per block, the rotations to")
    w("the higher harmonics); the core is the argument reduction, the clamps and flags, the")
    w("NaN checks and Eq. 3. The paper table has 8 basis rows x 6 terms per axis: 144")
    w("coefficients, each one load and one multiply-add (two instructions without FMA).")
    w("")
    for tname, build, machine, call in (("Cortex-M4F", args.m4f, "mps2-an386", "f32"),
                                       ("Cortex-M3", args.m3, "mps2-an385", "q")):
        fc = qemu_function_counts(machine, build / "bench" / "bench_target.elf", nm, call)
        parts = ", ".join(f"{k} {v}" for k, v in fc.items() if k not in ("bench_mark", "run_f32", "run_q"))
        w(f"- {tname}, abbe_error_eval_{call}: {parts}")
    host_exe = args.host / "bench" / "bench_host"
    for label, mode in (("x86-64-v3 kernels", "f32"), ("SSE2 kernels", "f32_base")):
        fc = callgrind_function_counts(host_exe, mode)
        parts = ", ".join(f"{k} {v:.0f}" for k, v in sorted(fc.items(), key=lambda kv: -kv[1]))
        w(f"- x86-64, abbe_error_eval_f32 ({label}): {parts}")
    w("")
    w("On x86-64 the core is one function (the kernels inlined: the ABI clobbers every vector")
    w("register at a call). Flash of the images is listed by source file in section 3.")
    w("How the last two targets were met (each step measured, the rest of the guarantees kept):")
    w("")
    w("- q flash (format 1.1 library): the fixed-point sin/cos is one out-of-line function")
    w("  shared by the six-term and the sparse kernel (before: inlined in each), returning")
    w("  its pair as one uint64 (r0:r1) and built -Os, so its frame is 20 B and")
    w("  abbe_comp_step_q stays within 256 B; the sparse kernel is its own -Os file. The")
    w("  six-term kernel also got faster (fewer registers live around the inline sin/cos).")
    w("- x86-64 f32: the three axes' phases are one vector computation on x86-64-v3 (64-bit")
    w("  lanes, the model keeps the per-axis frequencies in lanes); block 1's sin/cos reads its")
    w("  constants through a second opaque pointer (GCC had loaded them once for both blocks")
    w("  and spilled them); a linear trend costs one test (the recurrence for degree >= 2")
    w("  behind it); the harmonic jump table has no range check; GCC flags as in section 7.")
    w("  The SSE2 kernels (every x86-64; what a CPU without AVX2 and FMA runs) benefit from")
    w("  all but the vector phases and stay above 400: the x86-64-v3 path executes 51 fused")
    w("  multiply-adds per call on this table (36 of them the 144 coefficients, four lanes")
    w("  each; the others sin/cos, rotations, conversions and Eq. 3), which SSE2 executes as")
    w("  51 multiplies and 51 adds, and it has neither variable shifts, 32-bit multiplies")
    w("  nor blends for the argument reduction (scalar there): 379 + 51 > 400 before any")
    w("  of those. The target is met by the kernels that Intel CPUs since Haswell (2013) and")
    w("  AMD ones since Excavator (2015) run; abbe_model_load() picks them by CPUID.")
    w("")

    # 6. Python
    py = python_throughput(args.repo, args.host)
    w("## 6. Points per second from Python (ctypes)")
    w("")
    w("bench/bench_python.py on the `paper` table, 20 000 random points in the travel, best of")
    w("several runs: wall-clock times, which vary with the machine and its load (unlike the")
    w("counts above). `point by point` is the loop host_tools/abbe/clib.py ran before the")
    w("batch entry points (one ctypes call per point); `batch` is CModel.error_f32 / error_q")
    w("now (abbe_error_eval_batch_f32 / _q, one call).")
    w("")
    if py is None:
        w("(not measured: build/lib/libabbe.so or .venv missing)")
    elif "error" in py:
        w(f"(failed: {py['error']})")
    else:
        w("| variant | point by point (points/s) | batch (points/s) | speed-up |")
        w("|---|---:|---:|---:|")
        for k in ("f32", "q"):
            pb, b = py[f"{k}_point_by_point"], py[f"{k}_batch"]
            w(f"| {k} | {pb:,.0f} | {b:,.0f} | {b / pb:.0f}x |")
    w("")

    # 7. flags
    w("## 7. Compiler flags per target")
    w("")
    w("From each build's compile_commands.json (library sources; include paths, definitions")
    w("and the warning set `-Wall -Wextra -Wpedantic -Wconversion ... -Werror` left out;")
    w("`-fstack-usage -fcallgraph-info=su` are the benchmark builds' stack analysis only):")
    w("")
    w("| target | sources | flags |")
    w("|---|---|---|")
    w(f"| x86-64 (host, Release) | lib/src/*.c | `{compile_flags(args.host, 'lib/src/eval_q.c')}` |")
    w(f"| x86-64-v3 kernels | lib/src/eval_f32_avx2.c | `{compile_flags(args.host, 'lib/src/eval_f32_avx2.c')}` |")
    w(f"| x86-64 SSE2 kernels | lib/src/eval_f32_sse2.c | `{compile_flags(args.host, 'lib/src/eval_f32_sse2.c')}` |")
    w(f"| Cortex-M4F (Release) | lib/src/*.c | `{compile_flags(args.m4f, 'lib/src/eval_f32.c')}` |")
    w(f"| Cortex-M3 (Release) | lib/src/*.c | `{compile_flags(args.m3, 'lib/src/terms_q.c')}` |")
    w(f"| Cortex-M4F (Release) | lib/src/comp.c | `{compile_flags(args.m4f, 'lib/src/comp.c')}` |")
    w(f"| Cortex-M3 (Release) | lib/src/comp.c | `{compile_flags(args.m3, 'lib/src/comp.c')}` |")
    w(f"| Cortex-M4F (Release) | lib/src/eval_q.c | `{compile_flags(args.m4f, 'lib/src/eval_q.c')}` |")
    w(f"| Cortex-M3 (Release) | lib/src/eval_q.c | `{compile_flags(args.m3, 'lib/src/eval_q.c')}` |")
    w(f"| Cortex-M3 (Release) | lib/src/sincos_q.c, terms_sparse_q.c | `{compile_flags(args.m3, 'lib/src/sincos_q.c')}` |")
    w("")
    w("comp.c (the compensator's state machine: ramps, limits, staleness; no arithmetic of")
    w("the model) and eval_q.c (the fixed-point Eq. 3 assembly: straight-line multiply-adds)")
    w("are built for size on the Cortex-M (the last -O wins): on comp.c -Os takes 132 B")
    w("(Cortex-M4F) / 116 B (Cortex-M3) off the load + compensator images for +16 / +17")
    w("instructions per compensator cycle, on eval_q.c 98 / 138 B for -9 / 0 instructions")
    w("per call; the rows of sections 2 and 8 include both. The fixed-point sin/cos")
    w("(sincos_q.c, out of line, shared by the six-term and the sparse kernel) and the sparse")
    w("kernel (terms_sparse_q.c) are -Os too: at -O2 GCC loads sin/cos's nine constants")
    w("into registers up front and its frame is 56 B instead of 20, which would put")
    w("abbe_comp_step_q over its 256 B of stack.")
    w("")
    w("x86-64 (GCC only): the f32 core files are built with `-fno-tree-pre -fno-ivopts`. The")
    w("core is one function with every vector register in use; partial redundancy elimination")
    w("and the induction-variable rewrite each add register copies, spills and jumps there")
    w("(measured on this table: x86-64-v3 408 -> 379 instructions inside the kernel, SSE2")
    w("573 -> 539).")
    w("")
    w("x86-64: the f32 core exists twice, SSE2 (every x86-64) and x86-64-v3 (AVX2, FMA);")
    w("abbe_model_load() picks by CPUID (`__builtin_cpu_supports`). Cortex-M4F: the row kernel")
    w("uses one `vldm` per row, the harmonics and sin/cos are inline assembly blocks (plain C")
    w("fallback, the same operations in the same order); the CMake option")
    w("`-DABBE_PORTABLE_C=ON` builds the plain C kernels everywhere.")
    w("")

    # 8. format 1.1: the reversal blocks
    rev = reversal_section(args, nm, by, tgt, stdout_by, flash_by, stack_by)
    md += rev["lines"]

    # 9. clang/LLVM
    if args.m4f_clang and args.m3_clang:
        md += clang_section(args, nm, tgt, stdout_by, flash_by, stack_by)

    # summary, inserted after the header
    summary: list[str] = []
    sw = summary.append
    f32_flash = max(flash_by.get(("Cortex-M4F", "comp_f32"), 0), 0)
    q_flash_m4f = flash_by.get(("Cortex-M4F", "comp_q"), 0)
    q_flash_m3 = flash_by.get(("Cortex-M3", "comp_q"), 0)
    rows = [
        ("x86-64 abbe_error_eval_f32 (x86-64-v3 kernels)", by["f32"].per_call, BEFORE["x86_f32"], TARGETS["x86_f32"], "instructions"),
        ("x86-64 abbe_error_eval_f32 (SSE2 kernels)", by["f32_base"].per_call, BEFORE["x86_f32"], TARGETS["x86_f32"], "instructions"),
        ("Cortex-M4F abbe_error_eval_f32", max(tgt["Cortex-M4F"]["f32"]), BEFORE["m4f_f32"], TARGETS["m4f_f32"], "instructions"),
        ("Cortex-M3 abbe_error_eval_q", max(tgt["Cortex-M3"]["q"]), BEFORE["m3_q"], TARGETS["m3_q"], "instructions"),
        ("flash, load + compensator, f32 (M4F)", f32_flash, BEFORE["flash_f32"], TARGETS["flash_bytes"], "B"),
        ("flash, load + compensator, q (M4F)", q_flash_m4f, BEFORE["flash_q_m4f"], TARGETS["flash_bytes"], "B"),
        ("flash, load + compensator, q (M3)", q_flash_m3, BEFORE["flash_q_m3"], TARGETS["flash_bytes"], "B"),
        ("stack, abbe_comp_step_q (M4F)", stack_by.get(("Cortex-M4F", "comp_q"), 0), BEFORE["stack_comp_q_m4f"], TARGETS["stack_bytes"], "B"),
        ("stack, abbe_comp_step_q (M3)", stack_by.get(("Cortex-M3", "comp_q"), 0), BEFORE["stack_comp_q_m3"], TARGETS["stack_bytes"], "B"),
    ]
    f10 = rev["flash_10"]
    for label, key, before in (("f32 (M4F)", ("Cortex-M4F", "comp_f32"), BEFORE["flash_f32"]),
                               ("q (M4F)", ("Cortex-M4F", "comp_q"), BEFORE["flash_q_m4f"]),
                               ("q (M3)", ("Cortex-M3", "comp_q"), BEFORE["flash_q_m3"])):
        if key in f10:
            rows.append((f"flash, load + compensator, {label}, 1.0 library (ABBE_WITH_REVERSAL=OFF)",
                         f10[key], before, TARGETS["flash_bytes"], "B"))
    sw("## Summary: the targets (issue 16)")
    sw("")
    sw("`before` = the same measurement of commit af2baa8. Instruction counts are the worst")
    sw("over the measured points (they no longer vary: the run time depends on the table only).")
    sw("`now` is the library that reads format 1.1 (reversal blocks, issue 14; the default);")
    sw("the `1.0 library` rows are the same sources built with -DABBE_WITH_REVERSAL=OFF,")
    sw("a format 1.0 reader with the machine code of the library before 1.1. Section 8 has")
    sw("the blocks' cost per call, flash and stack.")
    sw("")
    sw("| measurement | now | before | target | |")
    sw("|---|---:|---:|---:|---|")
    for label, now, before, target, unit in rows:
        sw(f"| {label} | {now:.0f} | {before} | <= {target} {unit} | {verdict(now, target)} |")
    sw("")
    if args.m4f_clang and args.m3_clang:
        sw("The targets are GCC's; section 9 has the clang/LLVM builds beside them (issue 28).")
        sw("")
    md[md.index("## 1. x86-64 instructions per call (callgrind)"):md.index("## 1. x86-64 instructions per call (callgrind)")] = summary

    # five-axis tables (format 1.2): scripts/bench_five.py's section
    from bench_five import section as five_section
    md += [""] + five_section(args.m4f, args.m3)
    text = "\n".join(md) + "\n"
    if args.out:
        args.out.write_text(text)
        print(f"bench_report: wrote {args.out}")
    else:
        sys.stdout.write(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
