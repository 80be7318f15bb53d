"""The speed-ups of ``abbe diagnose`` give the same numbers (issue 36: a diagnosis took 3-13
minutes on a shared machine): one BLAS thread during a diagnosis (restored after), the
qr_basis cache, the evaluator's pinned model, the Theil-Sen line of the outlier screen and
the cyclic scan's sines computed once at the distinct positions, each against the
computation it replaces, bit for bit."""

from __future__ import annotations

import types

import numpy as np
import pytest
from scipy import stats

from abbe.diagnose import blas, candidates, evaluator
from abbe.diagnose.candidates import Engine
from abbe.diagnose.evaluator import Evaluator
from abbe.diagnose.outliers import _theil_sen
from abbe.diagnose.problem import _qr_basis, qr_basis
from abbe.model.examples import paper_table


def test_one_blas_thread_inside_restored_after_and_nested() -> None:
    libs = blas._openblas()
    if not libs:
        pytest.skip("no OpenBLAS in this process (another BLAS): nothing to set")
    before = [int(get()) for get, _ in libs]

    @blas.one_blas_thread
    def inner() -> list[int]:
        return [int(get()) for get, _ in libs]

    @blas.one_blas_thread
    def outer() -> tuple[list[int], list[int]]:
        a = inner()
        return a, [int(get()) for get, _ in libs]   # still one after the nested call

    a, b = outer()
    assert a == [1] * len(libs) and b == [1] * len(libs)
    assert [int(get()) for get, _ in libs] == before

    @blas.one_blas_thread
    def fails() -> None:
        raise ValueError("x")
    with pytest.raises(ValueError):
        fails()
    assert [int(get()) for get, _ in libs] == before


def test_qr_basis_cache_returns_the_same_basis_read_only() -> None:
    rng = np.random.default_rng(3)
    A = rng.normal(size=(400, 7))
    A[:, 3] = A[:, 1] + A[:, 2]                      # rank 6: one column dropped
    Q = qr_basis(A)
    assert np.array_equal(Q, _qr_basis(np.ascontiguousarray(A), 1e-10))
    assert Q.shape == (400, 6)
    assert qr_basis(A.copy()) is Q                   # same bytes: the cached array
    assert qr_basis(np.asfortranarray(A)) is Q       # the layout does not matter
    with pytest.raises(ValueError):
        Q[0, 0] = 1.0                                # nobody can change a cached basis
    B = A.copy()
    B[0, 0] += 1e-12                                 # other bytes: computed again
    assert qr_basis(B) is not Q


def test_a_pinned_table_is_not_encoded_again(monkeypatch: pytest.MonkeyPatch) -> None:
    ev = Evaluator("reference")
    t = paper_table()
    pos = np.array([[10.0, 20.0, -30.0], [100.0, -50.0, -10.0]])
    ref = ev.error(t, pos)
    calls = []
    real = evaluator.write_blob
    monkeypatch.setattr(evaluator, "write_blob", lambda tab: calls.append(1) or real(tab))
    with ev.pinned(t):
        n = len(calls)
        for _ in range(5):
            assert np.array_equal(ev.error(t, pos), ref)
        assert len(calls) == n                       # no encoding inside the block
        other = paper_table()                        # another table object: looked up
        ev.error(other, pos)
        assert len(calls) == n + 1
    ev.error(t, pos)
    assert len(calls) == n + 2                       # outside the block: as before


def test_theil_sen_is_scipys_bit_for_bit() -> None:
    rng = np.random.default_rng(7)
    for n in (3, 4, 9, 21, 40):
        for k in range(20):
            x = np.linspace(0.0, 800.0, n) if k % 2 else np.sort(rng.uniform(-400, 400, n))
            y = rng.normal(size=n) * 10.0 ** int(rng.integers(-3, 3))
            if k % 5 == 0:
                y = np.round(y, 1)                   # ties among the slopes
            r = stats.theilslopes(y, x)
            s, i = _theil_sen(x, y)
            assert s == r[0] and i == r[1]


def _scan_engine(rng: np.random.Generator) -> tuple[Engine, object]:
    eng = Engine.__new__(Engine)
    n_t, reps = 241, 4                               # a laser line: targets repeated
    pos = np.tile(np.linspace(0.0, 600.0, n_t), reps)
    g = rng.uniform(0.5, 1.5, pos.size)
    g[::17] = 0.0                                    # samples the axis does not reach
    eng._probe = {"X": g}
    eng._cyc_pos = {"X": pos}
    eng._cyc_freqs = {"X": np.arange(1 / 300.0, 1 / 8.0, 1 / 2400.0)}
    table = types.SimpleNamespace(axes={"X": types.SimpleNamespace(travel_mm=(-5.0, 605.0))})
    return eng, table


@blas.one_blas_thread
def test_cyclic_scan_with_the_sines_kept_is_the_scan_without(monkeypatch: pytest.MonkeyPatch
                                                             ) -> None:
    rng = np.random.default_rng(11)
    eng, table = _scan_engine(rng)
    N = eng._cyc_pos["X"].size
    W = rng.uniform(0.5, 2.0, N)
    Qb = np.linalg.qr(rng.normal(size=(N, 5)))[0]
    phi = 2 * np.pi * (eng._cyc_pos["X"] + 5.0) / 23.7
    r = eng._probe["X"] * W * np.sin(phi) * 3.0 + rng.normal(size=N)
    rb = r - Qb @ (Qb.T @ r)
    kept = [eng.cyclic_scan("X", table, W, Qb, rb) for _ in range(2)]   # cached, then hit
    assert len(eng._cyc_trig) == 1
    monkeypatch.setattr(candidates, "_TRIG_CACHE_MAX", 0)               # nothing kept
    fresh = Engine.__new__(Engine)
    fresh.__dict__.update({k: v for k, v in eng.__dict__.items() if k != "_cyc_trig"})
    plain = fresh.cyclic_scan("X", table, W, Qb, rb)
    assert not fresh._cyc_trig
    assert kept[0] == kept[1] == plain
    assert abs(plain[0] - 23.7) < 0.5
