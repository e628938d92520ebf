"""Numbers and names in words for the reasons of a verdict."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

__all__ = ["mm", "deg", "times", "names"]

def mm(value_m: float) -> str:
    """``36 mm``, ``4.2 mm``, ``0.31 mm`` (``inf``: ``unbounded``)."""
    v = 1e3 * float(value_m)
    if not np.isfinite(v):
        return "unbounded"
    return f"{v:.0f} mm" if v >= 100 else f"{v:.1f} mm" if v >= 1 else f"{v:.2f} mm"


def deg(value_deg: float) -> str:
    v = float(value_deg)
    if not np.isfinite(v):
        return "unbounded"
    return f"{v:.0f} deg" if v >= 100 else f"{v:.1f} deg" if v >= 1 else f"{v:.2f} deg"


def times(ratio: float) -> str:
    """``17x``, ``2.8x``."""
    return f"{ratio:.0f}x" if ratio >= 10 else f"{ratio:.1f}x"


def names(items: Iterable[str]) -> str:
    """``a``, ``a and b``, ``a, b and c``."""
    items = list(items)
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]
