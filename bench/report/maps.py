"""What the builds left on disk: link-map sizes (GNU ld and lld), GCC's call graph
(-fcallgraph-info=su), the -fstack-usage frames, the calls in an image's disassembly
(clang writes no call graph) and the benchmark wrappers' frames."""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from report.measure import run


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
