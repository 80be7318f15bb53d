"""One BLAS thread while ``abbe diagnose`` runs: its matrices are small, its threads are not.

The diagnosis multiplies and factorises matrices of a few thousand rows by a few tens of
columns, thousands of times. OpenBLAS splits each such product over every core and
busy-waits between the pieces: on an idle machine that gains nothing, on a shared one
(another job on the cores) each product waits for a descheduled thread, and a diagnosis
took 3-13 minutes where one thread takes well under one (docs/effects.md, "Speed";
``bench/bench_diagnose_equiv.py`` times a diagnosis and compares its answers).
:func:`one_blas_thread` sets the OpenBLAS libraries loaded in the process (numpy's and
scipy's) to one thread for the duration of a call and restores their count after; where
none is found (another BLAS, another OS) it does nothing.

The answer does not depend on it beyond the last digits: a threaded dot product sums its
halves in another order (relative 1e-16 per sum).
"""

from __future__ import annotations

import ctypes
import functools
import threading
from collections.abc import Callable
from typing import Any, TypeVar

F = TypeVar("F", bound=Callable[..., Any])

#: getter / setter names the OpenBLAS builds export (plain, numpy's and scipy's wheels)
_NAMES = (("openblas_get_num_threads", "openblas_set_num_threads"),
          ("openblas_get_num_threads64_", "openblas_set_num_threads64_"),
          ("scipy_openblas_get_num_threads64_", "scipy_openblas_set_num_threads64_"),
          ("scipy_openblas_get_num_threads", "scipy_openblas_set_num_threads"))

_lock = threading.Lock()
_depth = 0
_saved: list[tuple[Any, int]] = []


def _openblas() -> list[tuple[Any, Any]]:
    """(get, set) of every OpenBLAS library mapped into this process (Linux: /proc)."""
    try:
        with open("/proc/self/maps", encoding="utf-8", errors="replace") as fh:
            paths = sorted({ln.split()[-1] for ln in fh if "openblas" in ln.lower()
                            and ".so" in ln and ln.split()[-1].startswith("/")})
    except OSError:
        return []
    out = []
    for p in paths:
        try:
            lib = ctypes.CDLL(p)
        except OSError:
            continue
        for g, s in _NAMES:
            get, set_ = getattr(lib, g, None), getattr(lib, s, None)
            if get is not None and set_ is not None:
                get.restype = ctypes.c_int
                set_.argtypes = [ctypes.c_int]
                out.append((get, set_))
                break
    return out


def _enter() -> None:
    global _depth
    with _lock:
        _depth += 1
        if _depth > 1:
            return
        for get, set_ in _openblas():
            n = int(get())
            if n > 1:
                _saved.append((set_, n))
                set_(1)


def _leave() -> None:
    global _depth
    with _lock:
        _depth -= 1
        if _depth > 0:
            return
        while _saved:
            set_, n = _saved.pop()
            set_(n)


def one_blas_thread(fn: F) -> F:
    """Decorator: ``fn`` runs with one OpenBLAS thread (nested calls share the setting)."""
    @functools.wraps(fn)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        _enter()
        try:
            return fn(*args, **kwargs)
        finally:
            _leave()
    return wrapper  # type: ignore[return-value]
