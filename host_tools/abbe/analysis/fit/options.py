"""Options of ``abbe fit``'s model selection and the models it compares.
"""

from __future__ import annotations

from dataclasses import dataclass

MODELS = ("auto", "paper-fourier3", "paper-poly7")

COMPARED = ("chosen", "paper_fourier3", "paper_poly7")


@dataclass
class FitOptions:
    """Fit settings (machine file ``[fit]``, CLI options override)."""

    max_degree: int = 7
    max_harmonics: int = 8
    max_wave_degree: int = 3
    folds: int = 5
    samples_per_wavelength: float = 2.5
    col_tol: float = 0.02
    one_se: bool = True
    model: str = "auto"
