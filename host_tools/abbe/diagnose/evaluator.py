"""How ``abbe diagnose`` evaluates a table: the C library, or the float64 reference.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

from abbe.errors import AbbeInputError
from abbe.formats.blob import write_blob
from abbe.model.table import AXES, OWN_SIGN, Table


class Evaluator:
    """Evaluates tables: ``backend`` "c" (C library, f32 path), "reference" (float64
    reference of the quantized table) or "auto" (C if the library loads).

    Loaded models are cached by blob bytes (small LRU). ``calls`` counts model
    evaluations (for the benchmark).
    """

    def __init__(self, backend: str = "auto", cache: int = 64) -> None:
        if backend not in ("auto", "c", "reference"):
            raise ValueError(f"backend {backend!r}: expected auto, c or reference")
        if backend in ("auto", "c"):
            from abbe.model import clib
            ok = clib.available()
            if not ok and backend == "c":
                raise AbbeInputError(
                    f"the C library is not built ({clib.library_path()} missing): build it "
                    "with cmake (target abbe_shared) or set ABBE_LIB", field="backend")
            backend = "c" if ok else "reference"
        self.backend = backend
        self._cache: OrderedDict[bytes, Any] = OrderedDict()
        self._size = cache
        self.calls = 0
        self._pin: tuple[Table, Any] | None = None

    @contextmanager
    def pinned(self, table: Table) -> Iterator[None]:
        """Within the block ``table`` is read only: its loaded model is found once, not by
        encoding the table again at every evaluation (a prediction of every check
        evaluates the same table many times; encoding it was most of a diagnosis' time)."""
        prev = self._pin
        self._pin = (table, self.model(table))
        try:
            yield
        finally:
            self._pin = prev

    def model(self, table: Table) -> Any:
        """The loaded model of ``table`` (CModel or quantized Table)."""
        if self._pin is not None and table is self._pin[0]:
            return self._pin[1]
        blob = write_blob(table)
        m = self._cache.get(blob)
        if m is not None:
            self._cache.move_to_end(blob)
            return m
        if self.backend == "c":
            from abbe.model.clib import CModel
            m = CModel(blob)
        else:
            from abbe.formats.blob import read_blob
            m = read_blob(blob)
        self._cache[blob] = m
        if len(self._cache) > self._size:
            self._cache.popitem(last=False)
        return m

    def error(self, table: Table, pos_mm: np.ndarray, dir_state: np.ndarray | None = None,
              temp_c: np.ndarray | None = None) -> np.ndarray:
        """Spatial error (N, 3) um at positions (N, 3) mm."""
        m = self.model(table)
        pos = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
        self.calls += 1
        if self.backend == "c":
            err, _ = m.error_f32(pos, dir_state, temp_c)
            return np.asarray(err, dtype=np.float64)
        from abbe.model.reference import spatial_error
        return spatial_error(m, pos, dir_state, temp_c)

    def term(self, table: Table, axis: str, term: str, pos_mm: np.ndarray) -> np.ndarray:
        """Fitted term value (um / urad) at axis positions (N,) mm (no backlash/thermal)."""
        m = self.model(table)
        p = np.asarray(pos_mm, dtype=np.float64).reshape(-1)
        self.calls += 1
        if self.backend == "c":
            return m.term_f32(axis, term, p)
        from abbe.model.reference import term_values
        return term_values(m, axis, term, p)

    def own_extra(self, table: Table, axis: str, pos_mm: np.ndarray, dir_state: np.ndarray,
                  temp_c: np.ndarray | None) -> np.ndarray:
        """Backlash / reversal + thermal addition to the own positioning term of ``axis`` (um),
        through the library: the difference of the spatial error with and without the
        direction state / temperature, on the axis' own component."""
        ax = table.axes[axis]
        has_b = ax.has_reversal()  # backlash_um or a reversal block (format 1.1)
        has_t = temp_c is not None and bool(ax.thermal_expansion_ppm_per_k
                                            or ax.thermal_offset_um_per_k)
        pos = np.asarray(pos_mm, dtype=np.float64).reshape(-1, 3)
        if not (has_b or has_t):
            return np.zeros(pos.shape[0])
        j = AXES.index(axis)
        with_ = self.error(table, pos, dir_state if has_b else None, temp_c if has_t else None)
        without = self.error(table, pos, None, None)
        return OWN_SIGN[axis] * (with_[:, j] - without[:, j])
