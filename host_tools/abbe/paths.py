"""Where the package finds its C library, the library headers and the example machines.

An installed wheel carries them inside the package: ``abbe/_lib/libabbe.so``,
``abbe/_lib/include/abbe/*.h`` and ``abbe/examples/`` (installed there by the
repository's CMake project, component "python"). A development install runs from
a source checkout and uses the checkout instead: ``build/lib/libabbe.so`` (built
by CMake), ``lib/include/`` and ``examples/``. ``$ABBE_LIB`` overrides the library.
"""

from __future__ import annotations

import os
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
BUNDLED_LIB_DIR = PACKAGE_DIR / "_lib"
LIBRARY_NAME = "libabbe.so"


def checkout_root() -> Path | None:
    """The repository root when the package runs from a source checkout, else None."""
    root = PACKAGE_DIR.parents[1]  # <repo>/host_tools/abbe -> <repo>
    if ((root / "lib" / "include" / "abbe" / "abbe.h").is_file()
            and (root / "host_tools" / "pyproject.toml").is_file()):
        return root
    return None


def library_path() -> Path:
    """The shared library to load: $ABBE_LIB, else the wheel's, else the checkout's build.

    The path returned may not exist (then it is the one a message should name).
    """
    env = os.environ.get("ABBE_LIB")
    if env:
        return Path(env)
    bundled = BUNDLED_LIB_DIR / LIBRARY_NAME
    if bundled.is_file():
        return bundled
    root = checkout_root()
    if root is not None:
        return root / "build" / "lib" / LIBRARY_NAME
    return bundled


def include_dir() -> Path | None:
    """The directory holding ``abbe/abbe.h`` (for compiling generated C), or None."""
    for d in (BUNDLED_LIB_DIR / "include",
              *([checkout_root() / "lib" / "include"] if checkout_root() else [])):
        if (d / "abbe" / "abbe.h").is_file():
            return d
    return None


def examples_dir() -> Path:
    """The bundled example machines (``vmc500``, ``paper_table``)."""
    bundled = PACKAGE_DIR / "examples"
    if bundled.is_dir():
        return bundled
    root = checkout_root()
    if root is not None and (root / "examples").is_dir():
        return root / "examples"
    return bundled
