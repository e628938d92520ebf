"""Outlier rejection: the paper's per-edge RANSAC (Section 9.1) and a robust GNC-TLS solve.

Modules, in the order a robust solve runs them:

* :mod:`.pairs`: residuals of every pair at an estimate (eq. (33), eq. (70)) and restricting a
  problem to selected pairs;
* :mod:`.options`: :class:`RansacOptions`, :class:`GncOptions`, :class:`RobustOptions`;
* :mod:`.models`: closed-form hypotheses (the 1X1Y fit of a minimal sample, eq. (70));
* :mod:`.consensus`: the two RANSAC stages on one edge (sampling, scoring, local refinement);
* :mod:`.ransac`: :func:`ransac_filter` over a whole problem and its reports;
* :mod:`.gnc`: the GNC-TLS weights and loop;
* :mod:`.robust`: :func:`robust_solve` (RANSAC, GNC-TLS, certified final solve).
"""

from .gnc import gnc_tls_weights, tls_threshold
from .options import GncOptions, RansacOptions, RobustOptions
from .pairs import PairResiduals, pair_residuals
from .ransac import EdgeRansacReport, RansacReport, ransac_filter
from .robust import RobustResult, robust_solve

__all__ = [
    "RansacOptions",
    "EdgeRansacReport",
    "RansacReport",
    "ransac_filter",
    "PairResiduals",
    "pair_residuals",
    "tls_threshold",
    "gnc_tls_weights",
    "GncOptions",
    "RobustOptions",
    "RobustResult",
    "robust_solve",
]
