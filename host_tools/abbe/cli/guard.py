"""The top-level guard: a user never sees a bare traceback.

* a known input problem (:class:`abbe.errors.AbbeInputError`, TableError included)
  -> ``abbe CMD: error: FILE:LINE: field 'F': message`` on stderr, exit 2;
* the C library not built -> exit 3 with the build command;
* Ctrl-C -> exit 130; a closed stdout (``abbe ... | head``) -> exit 141, quietly;
* anything else is a bug -> exit 70 (EX_SOFTWARE) with one line naming the
  exception and a log file holding the traceback, the command line and the
  versions. The log goes to ``$ABBE_CRASH_DIR``, else ``$XDG_CACHE_HOME/abbe``
  (``~/.cache/abbe``), else the system temporary folder.

Nothing the guard writes holds a password: every line it prints and the whole crash
log pass through :func:`redact` (``scheme://user:SECRET@`` and ``password=SECRET``
become ``***``), and the log is created with mode 0600 (its folder 0700 when the
guard makes it): a traceback may quote a file path or a query that is nobody else's
business.
"""

from __future__ import annotations

import os
import platform
import re
import sys
import tempfile
import time
import traceback
from pathlib import Path
from typing import Callable, Sequence

from abbe.errors import AbbeInputError

EXIT_INPUT = 2
EXIT_NO_LIBRARY = 3
EXIT_INTERNAL = 70
EXIT_INTERRUPTED = 130
EXIT_BROKEN_PIPE = 141


_URL_USERINFO = re.compile(r"(?P<head>[A-Za-z][A-Za-z0-9+.\-]*://[^:/@\s]*:)[^@\s]*@")
_PASSWORD_PARAM = re.compile(r"(?i)\b(?P<key>password|passwd|pwd)(?P<eq>\s*=\s*)"
                             r"(?:'[^']*'|\"[^\"]*\"|[^&\s'\"]+)")


def redact(text: str) -> str:
    """``text`` with URL passwords (``scheme://user:SECRET@``) and ``password=SECRET``
    masked as ``***`` (the same rule as abbe.history.database.mask_secrets)."""
    text = _URL_USERINFO.sub(lambda m: m.group("head") + "***@", text)
    return _PASSWORD_PARAM.sub(lambda m: m.group("key") + m.group("eq") + "***", text)


def _crash_dirs() -> list[Path]:
    out = []
    if os.environ.get("ABBE_CRASH_DIR"):
        out.append(Path(os.environ["ABBE_CRASH_DIR"]))
    cache = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    out.append(Path(cache) / "abbe")
    out.append(Path(tempfile.gettempdir()))
    return out


def write_crash_log(prog: str, argv: Sequence[str] | None, exc: BaseException) -> Path | None:
    """Write the traceback and context to a new log file; its path, or None if nowhere."""
    from abbe import __version__
    stamp = time.strftime("%Y%m%d-%H%M%S")
    text = (f"{prog}: internal error\n"
            f"command: {' '.join(['abbe', *(argv if argv is not None else sys.argv[1:])])}\n"
            f"abbe {__version__}, Python {platform.python_version()}, {platform.platform()}\n\n"
            + "".join(traceback.format_exception(type(exc), exc, exc.__traceback__)))
    text = redact(text)
    for d in _crash_dirs():
        try:
            d.mkdir(mode=0o700, parents=True, exist_ok=True)
            p = d / f"abbe-crash-{stamp}-{os.getpid()}.log"
            fd = os.open(p, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                os.fchmod(fd, 0o600)  # whatever the umask
                fh.write(text)
            return p
        except OSError:
            continue
    return None


def run_guarded(prog: str, work: Callable[[], int], argv: Sequence[str] | None = None) -> int:
    """Run ``work`` and turn every exception into its exit status (module docstring)."""
    try:
        return work()
    except AbbeInputError as exc:
        print(f"{prog}: error: {redact(_one_line(str(exc)))}", file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        try:  # stdout is gone: say nothing more there
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        return EXIT_BROKEN_PIPE
    except Exception as exc:  # noqa: BLE001 -- the guard: every other exception is a bug
        from abbe.model.clib import LibraryNotFound
        if isinstance(exc, LibraryNotFound):
            print(f"{prog}: error: {redact(_one_line(str(exc)))}", file=sys.stderr)
            return EXIT_NO_LIBRARY
        log = write_crash_log(prog, argv, exc)
        where = f"traceback in {log}" if log else "no log file could be written"
        print(f"{prog}: internal error (a bug, please report it with the log): "
              f"{type(exc).__name__}: {redact(_one_line(str(exc)))[:300]}; {where}",
              file=sys.stderr)
        return EXIT_INTERNAL


def _one_line(s: str) -> str:
    return " ".join(s.split("\n")).strip()
