#!/usr/bin/env python3
"""Fail if library sources use a poisoned identifier outside comments.

The core (lib/) has no heap, no double, no stdio and no libm. This check
strips comments and string/character literals from every .c/.h file under the
given directories, then looks for the poisoned identifiers as whole words and
for an include of <math.h>. Exit status 1 (and one FILE:LINE line per hit) if
anything is found, 0 otherwise.

Usage: check_poison.py DIR_OR_FILE [...]
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

POISONED = (
    "malloc", "calloc", "realloc", "free", "aligned_alloc",
    "double",
    "printf", "sprintf", "fprintf", "snprintf", "vprintf", "vsprintf", "vsnprintf", "vfprintf",
)
WORD_RE = re.compile(r"\b(" + "|".join(POISONED) + r")\b")
MATH_RE = re.compile(r"^\s*#\s*include\s*[<\"](?:math|tgmath)\.h[>\"]")


def strip_comments_and_literals(text: str) -> str:
    """Blank out comments and string/char literals, keeping newlines (line numbers)."""
    out: list[str] = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        nxt = text[i + 1] if i + 1 < n else ""
        if c == "/" and nxt == "*":
            end = text.find("*/", i + 2)
            end = n if end < 0 else end + 2
            out.append("".join("\n" if ch == "\n" else " " for ch in text[i:end]))
            i = end
        elif c == "/" and nxt == "/":
            end = text.find("\n", i)
            end = n if end < 0 else end
            out.append(" " * (end - i))
            i = end
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c and text[j] != "\n":
                j += 2 if text[j] == "\\" else 1
            j = min(j + 1, n)
            out.append(c + " " * (j - i - 2) + c if j - i >= 2 else text[i:j])
            i = j
        else:
            out.append(c)
            i += 1
    return "".join(out)


def scan(path: Path) -> list[str]:
    """Return 'FILE:LINE: message' for every poisoned use in one file."""
    raw = path.read_text(encoding="utf-8", errors="replace")
    code = strip_comments_and_literals(raw)
    hits: list[str] = []
    for lineno, line in enumerate(code.splitlines(), start=1):
        if MATH_RE.match(line):
            hits.append(f"{path}:{lineno}: #include <math.h> (no libm in the core)")
        for m in WORD_RE.finditer(line):
            hits.append(f"{path}:{lineno}: poisoned identifier '{m.group(1)}'")
    return hits


def main(argv: list[str]) -> int:
    if not argv:
        print(__doc__, file=sys.stderr)
        return 2
    files: list[Path] = []
    for arg in argv:
        p = Path(arg)
        if p.is_dir():
            files.extend(sorted(q for q in p.rglob("*") if q.suffix in (".c", ".h")))
        elif p.is_file():
            files.append(p)
        else:
            print(f"check_poison: no such file or directory: {arg}", file=sys.stderr)
            return 2
    hits = [h for f in files for h in scan(f)]
    for h in hits:
        print(h)
    print(f"check_poison: {len(files)} files scanned, {len(hits)} poisoned uses")
    return 1 if hits else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
