"""Seeded mutations of a five-axis campaign's files: ``abbe fit`` and ``abbe diagnose`` either
succeed or refuse with exit 2 and a located message, never crash (exit 70)."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from abbe.cli.entry import main
from abbe.model.five_axis import TrunnionGeometry
from abbe.sim.five_axis import VirtualFiveAxis, probing_positions, random_errors, write_campaign

TOKENS = ["NaN", "inf", "-1e400", "", "1e9", "x", "0x10", "1,5", "\u00a0", "[]", "{", "\"", "-0"]


def _mutate(text: str, rng: np.random.Generator) -> str:
    lines = text.splitlines()
    op = int(rng.integers(0, 5))
    i = int(rng.integers(0, len(lines)))
    if op == 0:  # a cell or a value replaced by a hostile token
        sep = "," if "," in lines[i] else "="
        parts = lines[i].split(sep)
        parts[int(rng.integers(0, len(parts)))] = str(rng.choice(TOKENS))
        lines[i] = sep.join(parts)
    elif op == 1:
        del lines[i]
    elif op == 2:
        lines.insert(i, lines[int(rng.integers(0, len(lines)))])
    elif op == 3:
        lines = lines[: max(i, 1)]
    else:
        lines[i] = lines[i][: int(rng.integers(0, len(lines[i]) + 1))]
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def campaign(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("c5")
    g = TrunnionGeometry("xyzbc-trt", (0.0, 0.0, -300.0), (15.0, 0.0, -80.0), 120.0,
                         {"B": (-110.0, 110.0), "C": (-360.0, 360.0)})
    vm = VirtualFiveAxis(g, random_errors(g, np.random.default_rng(0)), probe_noise_um=0.3)
    c = np.arange(0.0, 360.0, 30.0)
    write_campaign(vm, d, positions=probing_positions(g, 3, 6), sphere_mm=(50.0, 0.0, 30.0),
                   rtest_path=np.column_stack([np.zeros(c.size), c]),
                   indexer_targets=np.arange(0.0, 360.0, 45.0))
    return d


@pytest.mark.parametrize("seed", range(16))
def test_mutated_files_never_crash(campaign: Path, tmp_path: Path, seed: int, capsys) -> None:
    rng = np.random.default_rng(seed)
    work = tmp_path / "w"
    shutil.copytree(campaign, work)
    target = ["machine.toml", "probe.csv", "rtest.csv", "indexer_C.csv"][seed % 4]
    p = work / target
    p.write_text(_mutate(p.read_text(), rng), encoding="utf-8")
    cmd = ["fit", str(work / "machine.toml"), "-o", str(tmp_path / "out"), "--no-report", "-q"]
    if seed % 6 == 5:
        cmd = ["diagnose", str(work / "machine.toml"), "-o", str(tmp_path / "out")]
    rc = main(cmd)
    err = capsys.readouterr().err
    assert rc in (0, 2), err
    if rc == 2:
        assert "error" in err and ("line" in err or ":" in err)


def test_the_mutations_do_reach_the_readers(campaign: Path, tmp_path: Path, capsys) -> None:
    """Most mutated probing files are refused (the fuzz test above is not vacuous)."""
    refused = 0
    for seed in range(8):
        work = tmp_path / f"w{seed}"
        shutil.copytree(campaign, work)
        p = work / "probe.csv"
        rng = np.random.default_rng(100 + seed)
        text = p.read_text()
        lines = text.splitlines()
        lines[1 + seed] = lines[1 + seed].replace(",", "," + str(rng.choice(TOKENS[:3])), 1)
        p.write_text("\n".join(lines) + "\n")
        refused += main(["fit", str(work / "machine.toml"), "-o", str(tmp_path / "o"),
                         "--no-report", "-q"]) == 2
    assert refused == 8
    assert "probe.csv:" in capsys.readouterr().err
