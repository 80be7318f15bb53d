"""A machine file's ballbar test read from its file: abbe's ballbar CSV (or a declared
export) or a Renishaw ``.b5r`` file (:mod:`abbe.formats.renishaw_b5r`), whose plane,
radius and feed must agree with the machine file."""

from __future__ import annotations

from typing import Any

from abbe.errors import AbbeInputError
from abbe.formats.ballbar_csv import BallbarTrace, read_ballbar_csv
from abbe.formats.renishaw_b5r import check_against, read_b5r


def is_b5r(path: Any) -> bool:
    return str(path).lower().endswith(".b5r")


def read_ballbar_file(bt: Any, machine_file: str | None = None) -> BallbarTrace:
    """The trace of ballbar test ``bt`` (a machine file's ``BallbarTest``)."""
    if is_b5r(bt.file):
        if bt.columns is not None:
            raise AbbeInputError("a columns declaration describes a CSV export, not a .b5r "
                                 "file", file=machine_file, field=f"ballbar.{bt.name}.columns")
        test = read_b5r(bt.file)
        check_against(test, bt, machine_file or "the machine file")
        return test.trace
    return read_ballbar_csv(bt.file, columns=bt.columns)
