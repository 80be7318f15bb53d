"""Reports rendered by headless Chromium, read as a person reads them: where the verdict
band (docs/cli.md, "Reports read verdict-first") lands on the first screen.

``ABBE_SCREENSHOTS=DIR`` keeps a copy of every screenshot as DIR/NAME.png (the issue's
note shows them)."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

WINDOW = (1200, 1600)

needs_chromium = pytest.mark.skipif(shutil.which("chromium") is None,
                                    reason="chromium not installed: the report is not rendered")


def screenshot(html: Path, png: Path, name: str) -> np.ndarray:
    """The first screen (1200 x 1600 px) of ``html`` as an RGB array."""
    from PIL import Image
    subprocess.run(["chromium", "--headless", "--no-sandbox", "--disable-gpu",
                    f"--screenshot={png}", f"--window-size={WINDOW[0]},{WINDOW[1]}",
                    html.as_uri()], check=True, capture_output=True, timeout=180)
    keep = os.environ.get("ABBE_SCREENSHOTS")
    if keep:
        Path(keep).mkdir(parents=True, exist_ok=True)
        shutil.copyfile(png, Path(keep) / f"{name}.png")
    return np.asarray(Image.open(png).convert("RGB")).astype(int)


def band_rows(img: np.ndarray) -> tuple[str | None, np.ndarray]:
    """The verdict band: (its verdict, the pixel rows it fills at more than half the
    page's width); (None, empty) when no band colour fills a row."""
    from abbe.analysis.certificate import BAND_RGB
    best: tuple[str | None, np.ndarray] = (None, np.array([], dtype=int))
    for verdict, rgb in BAND_RGB.items():
        hit = np.all(np.abs(img - np.array(rgb)) <= 3, axis=2)
        rows = np.flatnonzero(hit.sum(axis=1) > 0.5 * img.shape[1])
        if rows.size > best[1].size:
            best = (verdict, rows)
    return best


def assert_verdict_first(img: np.ndarray) -> str:
    """The band is there (more than 10 px of rows filled by its colour) and starts in the
    top quarter of the first screen. Returns its verdict."""
    verdict, rows = band_rows(img)
    assert verdict is not None and rows.size > 10, "no full-width verdict band"
    assert rows.min() < img.shape[0] / 4, f"the band starts at {rows.min()} px of {img.shape[0]}"
    return verdict


def assert_band_before(html: str, *later: str) -> None:
    """In the page's source the band comes before each of ``later`` (plots, folds)."""
    at = html.index("id='verdict'")
    for s in later:
        assert s in html and html.index(s) > at, s


def pdf_pages(html: Path, pdf: Path) -> int:
    """Pages of ``html`` printed to PDF by headless Chromium (the browser's print)."""
    import re
    subprocess.run(["chromium", "--headless", "--no-sandbox", "--disable-gpu",
                    f"--print-to-pdf={pdf}", html.as_uri()], check=True, capture_output=True,
                   timeout=180)
    return len(re.findall(rb"/Type\s*/Page[^s]", pdf.read_bytes()))
