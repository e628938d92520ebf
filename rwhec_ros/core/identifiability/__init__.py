"""Identifiability of generalized RWHEC, per edge and for the whole problem (paper Section 6).

Three levels, from cheap and incremental to complete:

1. **Per edge** (Corollaries 2 and 4), from sums of per-pair terms only (:class:`EdgeStatistics`),
   graded ``identifiable`` / ``weak`` / ``insufficient`` with reasons in words.
2. **Propagation** (Theorems 1 and 3): a weakly connected component is identifiable as soon as
   one of its edges is; components without such an edge are reported.
3. **Numeric check** on the assembled MLE cost (:func:`numeric_check`): the Hessian on the
   manifold at a minimiser of ``x^T Q x`` (eq. (42)), whose null space and inverse reveal what the
   per-edge test cannot (e.g. several single-axis edges that together fix a frame, Theorem 1's
   general case) and predict every frame's uncertainty from the stated noise levels.

The modules, one concept each:

* :mod:`.status`: the graded verdict (:class:`IdentifiabilityStatus`) and its thresholds;
* :mod:`.edge`: per-edge sufficient statistics and the per-edge verdict (Corollaries 2 and 4);
* :mod:`.numeric`: the whole-problem check on the manifold Hessian of the MLE cost;
* :mod:`.report`: components, the batch report (grid, text, PNG) and :func:`analyze`;
* :mod:`.tracker`: the incremental :class:`IdentifiabilityTracker` of a live session.
"""

from .edge import EdgeIdentifiability, EdgeStatistics, analyze_edge
from .numeric import NumericCheck, numeric_check
from .report import ComponentIdentifiability, IdentifiabilityReport, analyze
from .status import IdentifiabilityStatus, IdentifiabilityThresholds
from .tracker import IdentifiabilityTracker

__all__ = [
    "IdentifiabilityStatus",
    "IdentifiabilityThresholds",
    "EdgeStatistics",
    "EdgeIdentifiability",
    "NumericCheck",
    "ComponentIdentifiability",
    "IdentifiabilityReport",
    "analyze_edge",
    "numeric_check",
    "analyze",
    "IdentifiabilityTracker",
]
