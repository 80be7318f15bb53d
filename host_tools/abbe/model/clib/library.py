"""Finding, loading and typing the shared library, and turning its status codes into
errors.

The shared object is looked up in ``$ABBE_LIB`` first, then in the installed
package (a wheel carries it), then in the checkout's ``build/lib/`` (built by
CMake); see :mod:`abbe.paths`. Loaded once per process (``_LIB``); every class of
:mod:`abbe.model.clib` calls :func:`load_library`. Also the row conversions the
evaluation calls share (float32 / int32 rows of three).
"""

from __future__ import annotations

import ctypes as C
from pathlib import Path
from typing import Any

import numpy as np

from abbe import paths
from abbe.model.clib.structs import (Comp, CompConfig, CompInputF32, CompInputQ, CompOutput,
                                     CompStats, ErrorF32, ErrorQ, InputF32, InputQ, Model)
from abbe.model.table import TableError

STATUS_NAMES: dict[int, str] = {
    0: "ABBE_OK", -1: "ABBE_E_ARG", -2: "ABBE_E_TRUNCATED", -3: "ABBE_E_MAGIC",
    -4: "ABBE_E_VERSION_MAJOR", -5: "ABBE_E_VERSION_MINOR", -6: "ABBE_E_SIZE",
    -7: "ABBE_E_CRC", -8: "ABBE_E_FLAGS", -9: "ABBE_E_COUNT", -10: "ABBE_E_OFFSET",
    -11: "ABBE_E_NONFINITE", -12: "ABBE_E_PERIOD", -13: "ABBE_E_TRAVEL",
    -14: "ABBE_E_RANGE", -15: "ABBE_E_INPUT", -16: "ABBE_E_NO_MODEL", -17: "ABBE_E_MISMATCH",
    -18: "ABBE_E_ALIGN", -19: "ABBE_E_KIND",
}

FLAG_OUT_OF_TRAVEL = 0x0001
FLAG_SATURATED = 0x0002
FLAG_INPUT_INVALID = 0x0200


class LibraryNotFound(RuntimeError):
    """The shared library is not built or not where expected.

    ``what`` is the finding alone (no advice), for a caller that gives its own advice
    (``abbe fit``: the build command or ``--no-clib-check``) and must say it once."""

    def __init__(self, what: str, advice: str = "") -> None:
        super().__init__(what + (f": {advice}" if advice else ""))
        self.what = what


_LIB: C.CDLL | None = None


def library_path() -> Path:
    """Where the shared library is expected (:func:`abbe.paths.library_path`)."""
    return paths.library_path()


def load_library() -> C.CDLL:
    """Load (once) and type the C library; LibraryNotFound if it is missing."""
    global _LIB
    if _LIB is not None:
        return _LIB
    path = library_path()
    if not path.is_file():
        raise LibraryNotFound(
            f"abbe C library not found at {path}",
            "build it with 'cmake -S . -B build && cmake --build build' or set ABBE_LIB")
    try:
        lib = C.CDLL(str(path))
    except OSError as exc:
        raise LibraryNotFound(f"cannot load {path}: {exc}") from exc
    P = C.POINTER
    sigs: dict[str, tuple[Any, list[Any]]] = {
        "abbe_strerror": (C.c_char_p, [C.c_int]),
        "abbe_model_load": (C.c_int, [P(Model), C.c_void_p, C.c_size_t]),
        "abbe_model_crc": (C.c_uint32, [P(Model)]),
        "abbe_model_features": (C.c_uint32, [P(Model)]),
        "abbe_model_size": (C.c_uint32, [P(Model)]),
        "abbe_crc32": (C.c_uint32, [C.c_uint32, C.c_void_p, C.c_size_t]),
        "abbe_error_eval_f32": (C.c_int, [P(Model), P(InputF32), P(ErrorF32)]),
        "abbe_error_eval_q": (C.c_int, [P(Model), P(InputQ), P(ErrorQ)]),
        "abbe_error_eval_batch_f32": (C.c_int, [P(Model), C.c_size_t, P(InputF32), P(ErrorF32)]),
        "abbe_error_eval_batch_q": (C.c_int, [P(Model), C.c_size_t, P(InputQ), P(ErrorQ)]),
        "abbe_term_eval_f32": (C.c_int, [P(Model), C.c_uint, C.c_uint, C.c_float,
                                         P(C.c_float)]),
        "abbe_term_eval_q": (C.c_int, [P(Model), C.c_uint, C.c_uint, C.c_int32,
                                       P(C.c_int32)]),
        "abbe_reversal_eval_f32": (C.c_int, [P(Model), C.c_uint, C.c_float, P(C.c_float)]),
        "abbe_reversal_eval_q": (C.c_int, [P(Model), C.c_uint, C.c_int32, P(C.c_int32)]),
        "abbe_comp_init": (C.c_int, [P(Comp), P(CompConfig), P(Model)]),
        "abbe_comp_enable": (C.c_int, [P(Comp)]),
        "abbe_comp_disable": (C.c_int, [P(Comp)]),
        "abbe_comp_reset": (C.c_int, [P(Comp)]),
        "abbe_comp_swap_model": (C.c_int, [P(Comp), P(Model)]),
        "abbe_comp_load_model": (C.c_int, [P(Comp), P(Model), C.c_void_p, C.c_size_t]),
        "abbe_comp_model": (C.c_void_p, [P(Comp)]),
        "abbe_comp_step_f32": (C.c_int, [P(Comp), P(CompInputF32), P(CompOutput)]),
        "abbe_comp_step_q": (C.c_int, [P(Comp), P(CompInputQ), P(CompOutput)]),
        "abbe_comp_stats": (CompStats, [P(Comp)]),
        "abbe_model_sizeof": (C.c_size_t, []),
        "abbe_comp_sizeof": (C.c_size_t, []),
    }
    for name, (res, args) in sigs.items():
        try:
            fn = getattr(lib, name)
        except AttributeError as exc:
            raise LibraryNotFound(f"{path} does not export {name}: rebuild it from this checkout") from exc
        fn.restype = res
        fn.argtypes = args
    # The binding allocates abbe_model_t / abbe_comp_t itself: a layout that
    # differs from the library's would corrupt memory silently, so refuse it.
    for mirror, fn in ((Model, lib.abbe_model_sizeof), (Comp, lib.abbe_comp_sizeof)):
        if C.sizeof(mirror) != fn():
            raise LibraryNotFound(
                f"{path}: sizeof({mirror.__name__}) is {fn()} in the library but {C.sizeof(mirror)} "
                "in abbe/model/clib/structs.py: the binding and the library are from different versions")
    _LIB = lib
    return lib


def available() -> bool:
    """True if the shared library can be loaded."""
    try:
        load_library()
        return True
    except LibraryNotFound:
        return False


def status_name(status: int) -> str:
    """C status code -> its name (``ABBE_E_CRC``)."""
    return STATUS_NAMES.get(int(status), f"status {int(status)}")


def _check(status: int, what: str, source: str | None = None) -> None:
    if status != 0:
        lib = load_library()
        text = lib.abbe_strerror(status)
        msg = f"{what}: {text.decode() if text else 'unknown status'}"
        raise TableError(msg, status=status_name(status), file=source)


def _f32_rows(a: Any, n: int | None = None, default: float = 0.0) -> np.ndarray:
    if a is None:
        return np.full((n or 0, 3), default, dtype=np.float32)
    return np.asarray(a, dtype=np.float32).reshape(-1, 3)


def _i32_rows(a: Any, n: int | None = None, default: int = 0) -> np.ndarray:
    if a is None:
        return np.full((n or 0, 3), default, dtype=np.int64)
    arr = np.asarray(a)
    if arr.dtype.kind == "f":
        if not np.all(arr == np.rint(arr)):
            raise ValueError("integer input expected")
    arr = arr.astype(np.int64).reshape(-1, 3)
    if np.any(arr < -(1 << 31)) or np.any(arr >= (1 << 31)):
        raise ValueError("value outside int32")
    return arr
