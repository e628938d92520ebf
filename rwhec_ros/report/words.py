"""Words and colours the report's figure and page share: the verdict banner's colours and the
certificate in words (one module below both :mod:`.figure` and :mod:`.page`, so that neither
imports the other)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from ..core.result import rounding_decides

__all__ = ["BANNER_COLORS", "certificate_words"]

#: Banner colours (text, background) of each verdict level.
BANNER_COLORS = {
    "good": ("#1b5e20", "#e8f5e9"),
    "caution": ("#7a4f00", "#fff3cd"),
    "unusable": ("#b71c1c", "#fdecea"),
    "unknown": ("#424242", "#eeeeee"),
}

_STATUS_WORDS = {
    "certified_optimal": "certified globally optimal",
    "not_tight": "not certified: the certificate does not close (may be a local optimum)",
    "not_identifiable": "not certified: the data do not determine every frame",
    "ill_conditioned": "not certified: no bound can be proven (ill-conditioned)",
    "solver_inaccurate": "not certified: the conic solver did not reach its tolerances",
    "solver_failed": "not certified: the solver failed",
    "local_only": "not certified: local solution only (mode local)",
}


def certificate_words(doc: Mapping[str, Any]) -> str:
    """The certificate in words, e.g. ``certified globally optimal (suboptimality bound
    rho_hat = 5.4e-09)``."""
    status = str(doc.get("status", ""))
    words = _STATUS_WORDS.get(status, status.replace("_", " ") or "no certificate")
    c = doc.get("certificate") or {}
    try:
        if rounding_decides(status, doc.get("suboptimality_bound"), c["tolerance"],
                            c["primal_cost"], c["dual_bound"], c["null_space_dim"],
                            c.get("margins") or {}):
            words = ("not certified: the bound's rounding exceeds the tolerance (coordinates "
                     "large for the residuals: express the poses about a nearby origin)")
    except (KeyError, TypeError, ValueError):  # an older or partial result: the status words
        pass
    rho = doc.get("suboptimality_bound", float("nan"))
    rho = float("nan") if rho is None else float(rho)
    if np.isfinite(rho):
        words += f" (suboptimality bound rho_hat = {rho:.2g})"
    return words
