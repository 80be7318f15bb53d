"""The ``abbe`` command line (see :mod:`abbe.cli.entry`)."""

from abbe.cli.entry import main

__all__ = ["main"]
