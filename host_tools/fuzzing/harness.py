"""Run one command on one input and check every promise (docs/formats.md, "Promises").

:func:`run_case` runs ``abbe`` in-process with stdout/stderr captured and a time
budget, and returns an :class:`Outcome` listing every broken promise:

* exit status 0, 2 (bad input or usage), 3 (no C library) or, for the Modbus
  client, 1 (no server) -- never 70 (internal error), never a traceback;
* on exit 2: one line on stderr, ``abbe CMD: error: ...`` or argparse's usage error;
* on any failure: every output path exactly as before (absent, or the same bytes),
  and no staging leftovers (``.abbe-tmp-``, ``.abbe-old-``) beside them;
* on success: the outputs exist, no leftovers, every JSON written or printed is
  strict (no NaN / Infinity);
* the run ends within its time budget (seconds).
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import signal
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

ALLOWED = {0, 2, 3}


class FuzzTimeout(BaseException):
    """The time budget ran out (a BaseException: the CLI guard must not catch it)."""


@dataclass
class Outcome:
    argv: list[str]
    rc: int | None
    stdout: str
    stderr: str
    problems: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.problems


def snapshot(path: Path) -> object:
    """A comparable picture of a path: absent, a file's hash, or a folder's tree."""
    if not os.path.lexists(path):
        return None
    if path.is_symlink():
        return ("link", os.readlink(path))
    if path.is_file():
        return ("file", hashlib.sha256(path.read_bytes()).hexdigest())
    if path.is_dir():
        return ("dir", tuple(sorted((str(p.relative_to(path)), snapshot(p) if p.is_file() else "d")
                                    for p in path.rglob("*"))))
    return ("other",)


def _leftovers(paths: Sequence[Path]) -> list[str]:
    out = []
    for p in paths:
        parent = Path(os.path.abspath(p)).parent
        if parent.is_dir():
            out += [str(q) for q in parent.iterdir() if ".abbe-tmp-" in q.name or
                    ".abbe-old-" in q.name]
    return out


def _strict_json(text: str) -> str | None:
    def bad(name: str) -> None:
        raise ValueError(f"non-strict JSON constant {name}")
    try:
        json.loads(text, parse_constant=bad)
    except ValueError as exc:
        return str(exc)
    return None


def run_case(argv: list[str], outputs: Sequence[Path] = (), *, budget_s: float = 60.0,
             allowed: set[int] = ALLOWED, json_stdout: bool = False) -> Outcome:
    """Run ``abbe argv`` and check the promises (module docstring)."""
    from abbe.cli.entry import main

    before = {p: snapshot(p) for p in outputs}
    out, err = io.StringIO(), io.StringIO()

    def on_alarm(signum, frame):  # noqa: ANN001
        raise FuzzTimeout()

    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, budget_s)
    rc: int | None = None
    problems: list[str] = []
    try:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            try:
                rc = main(list(argv))
            except SystemExit as exc:  # argparse: usage errors
                rc = exc.code if isinstance(exc.code, int) else 2
    except FuzzTimeout:
        problems.append(f"ran over its time budget of {budget_s:g} s")
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)
    so, se = out.getvalue(), err.getvalue()
    if rc is not None and rc not in allowed:
        problems.append(f"exit status {rc}")
    if "Traceback" in se or "Traceback" in so:
        problems.append("a traceback was shown")
    if rc == 2:
        lines = [ln for ln in se.splitlines() if ln.strip()]
        usage = any(ln.startswith("usage:") for ln in lines)
        if not usage and (len(lines) != 1 or not lines[0].startswith("abbe ")):
            problems.append(f"exit 2 without a one-line 'abbe CMD: error:' message: {se!r:.300}")
    if rc != 0:
        for p in outputs:
            if snapshot(p) != before[p]:
                problems.append(f"output {p} changed although the command failed")
    left = _leftovers(outputs)
    if left:
        problems.append(f"staging leftovers: {left[:3]}")
    if rc == 0:
        for p in outputs:
            files = [p] if p.is_file() else (sorted(p.rglob("*.json")) if p.is_dir() else [])
            for f in files:
                if f.suffix == ".json" or f == p and p.suffix == ".json":
                    why = _strict_json(f.read_text(encoding="utf-8"))
                    if why:
                        problems.append(f"{f}: {why}")
        if json_stdout:
            why = _strict_json(so)
            if why:
                problems.append(f"stdout: {why}")
    return Outcome(list(argv), rc, so, se, problems)
