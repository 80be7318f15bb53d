"""Shared fixtures: the fuzzing seed workspace (host_tools/fuzzing/seeds.py), made once."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def seed_ws(tmp_path_factory):
    """A read-only-by-convention seed workspace; copy it (``ws_copy``) before changing files."""
    from fuzzing.seeds import make_workspace
    return make_workspace(tmp_path_factory.mktemp("seed") / "ws")


@pytest.fixture()
def ws(seed_ws, tmp_path):
    """A private copy of the seed workspace for one test."""
    from fuzzing.seeds import Workspace
    root = tmp_path / "ws"
    shutil.copytree(seed_ws.root, root, symlinks=True)
    return Workspace(**{k: (root / Path(v).relative_to(seed_ws.root) if isinstance(v, Path) else v)
                        for k, v in vars(seed_ws).items()})


@pytest.fixture(autouse=True, scope="session")
def _crash_logs_in_tmp(tmp_path_factory):
    """Crash logs of the CLI guard go to a temporary folder, not ~/.cache."""
    import os
    d = tmp_path_factory.mktemp("crash")
    old = os.environ.get("ABBE_CRASH_DIR")
    os.environ["ABBE_CRASH_DIR"] = str(d)
    yield d
    if old is None:
        os.environ.pop("ABBE_CRASH_DIR", None)
    else:
        os.environ["ABBE_CRASH_DIR"] = old


def pytest_configure(config):
    config.addinivalue_line("markers", "real_data(path): reads real data not carried by the project "
                            "(tests/real_data.py): SKIPPED without it, a failure under CI=true")


def pytest_runtest_setup(item):
    from real_data import check_real_data
    check_real_data(item)
