"""The expectation of one hostile-input case (issue 15), shared by the regression corpora
(cli/test_hostile_corpus.py, cli/test_hostile_interchange.py)."""

from __future__ import annotations

import re
from pathlib import Path

from fuzzing.harness import Outcome, run_case


def expect(argv, outputs=(), rc=2, *, where=None, field=None, text=None,
           json_stdout=False) -> Outcome:
    """Run the command in-process through the fuzzing harness (which checks the promises:
    exit 0/2, one-line message, no traceback, nothing written on failure, no staging
    leftovers, strict JSON), then the case's own expectation: exit status ``rc``, the
    FILE:LINE ``where`` and ``field`` named, ``text`` (a regex) in the message, and no
    Python repr (np.float64 ...) or traceback in it."""
    o = run_case([str(a) for a in argv], [Path(p) for p in outputs], json_stdout=json_stdout)
    assert o.ok, (o.problems, o.stderr)
    assert o.rc == rc, (o.rc, o.stderr)
    if where is not None:
        assert str(where) in o.stderr, o.stderr
    if field is not None:
        assert f"field '{field}'" in o.stderr, o.stderr
    if text is not None:
        assert re.search(text, o.stderr), o.stderr
    for repr_ in ("np.float64", "np.int64", "Traceback"):
        assert repr_ not in o.stderr, o.stderr
    return o
