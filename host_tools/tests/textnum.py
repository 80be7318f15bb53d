"""Compare generated text files: every character exactly, except numbers, within a
stated tolerance (docs/formats.md, "Reproducibility").

Floating-point library kernels (numpy's SIMD sin/cos, glibc's FMA paths) are chosen
by the CPU at run time, so the last digit of a printed float64 may differ between
machines with the same pinned environment. A decimal number must agree within
``rel`` (relative) or one unit of its last printed digit, whichever is larger; an
integer within ``int_tol``; hexadecimal literals (blob bytes, hex floats) exactly.
"""

from __future__ import annotations

import re

_NUM = re.compile(r"0[xX][0-9a-fA-F.]+(?:[pP][+-]?\d+)?[uUfF]?|[-+]?(?:\d+\.\d*|\.\d+|\d+)(?:[eE][-+]?\d+)?")


def _unit(tok: str) -> float:
    mant = re.split(r"[eE]", tok)[0]
    exp = int(re.split(r"[eE]", tok)[1]) if re.search(r"[eE]", tok) else 0
    frac = len(mant.split(".")[1]) if "." in mant else 0
    return 10.0 ** (exp - frac)


def differences(a: str, b: str, *, rel: float = 1e-9, int_tol: int = 1) -> list[str]:
    """Where ``a`` and ``b`` differ beyond the tolerance (empty list: equivalent)."""
    ta, tb = _NUM.split(a), _NUM.split(b)
    na, nb = _NUM.findall(a), _NUM.findall(b)
    out: list[str] = []
    if ta != tb or len(na) != len(nb):
        for i, (x, y) in enumerate(zip(ta, tb)):
            if x != y:
                return [f"text differs near number {i}: {x[:60]!r} != {y[:60]!r}"]
        return ["different number of fields"]
    for i, (x, y) in enumerate(zip(na, nb)):
        if x == y:
            continue
        if x.lower().startswith("0x") or y.lower().startswith("0x"):
            out.append(f"number {i}: {x} != {y} (hex literals must match exactly)")
            continue
        fx, fy = float(x), float(y)
        if re.fullmatch(r"[-+]?\d+", x) and re.fullmatch(r"[-+]?\d+", y):
            ok = abs(int(x) - int(y)) <= int_tol
        else:
            ok = abs(fx - fy) <= max(rel * max(abs(fx), abs(fy)), 1.0000001 * max(_unit(x), _unit(y)))
        if not ok:
            out.append(f"number {i}: {x} != {y}")
    return out
