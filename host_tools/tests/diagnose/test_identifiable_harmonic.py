"""A cyclic harmonic the data cannot identify is no candidate, and a covariance without
one gives no evidence (never an internal error): the ESS file's targets every 10 mm made
a period of 10 mm (and its harmonic, 5 mm) a column of zeros and a constant, which
normalising each column by its own norm let through (LinAlgError in log_evidence)."""

from __future__ import annotations

import numpy as np

from abbe.diagnose.evidence import log_evidence
from abbe.diagnose.problem import is_identifiable, project_out, qr_basis


def test_a_harmonic_sampled_at_its_nodes_is_not_identifiable() -> None:
    x = np.arange(0.0, 500.0, 10.0)                      # targets every 10 mm
    nuis = qr_basis(np.ones((x.size, 1)))                  # a zero offset per run
    phi = 2 * np.pi * x / 10.0                              # period = the spacing
    S = np.column_stack([np.sin(phi) + 1e-15 * np.cos(x), np.cos(phi),
                         np.sin(2 * phi), np.cos(2 * phi)])
    Z = project_out(nuis, S)
    ref = float(np.max(np.linalg.norm(S, axis=0)))
    assert not is_identifiable(Z, ref_norm=ref)
    # a period the targets resolve stays identifiable with the same test
    phi = 2 * np.pi * x / 37.0
    S2 = np.column_stack([np.sin(phi), np.cos(phi), np.sin(2 * phi), np.cos(2 * phi)])
    assert is_identifiable(project_out(nuis, S2),
                           ref_norm=float(np.max(np.linalg.norm(S2, axis=0))))


def test_a_singular_covariance_has_no_evidence_and_no_error() -> None:
    C = np.array([[1.0, 1.0], [1.0, 1.0 + 1e-17]])          # rank 1 (rounding only)
    ev = log_evidence(np.array([0.3, 0.3]), C, 5.0, 0.2, np.array([50.0, 50.0]),
                      typical=np.array([1.0, 1.0]))
    assert ev["log_evidence"] == -np.inf
    ev = log_evidence(np.array([0.3, 0.3]), np.array([[1.0, 0.0], [0.0, 1.0]]), 5.0, 0.2,
                      np.array([50.0, 50.0]))
    assert np.isfinite(ev["log_evidence"])
