"""Graded identifiability verdicts and the thresholds that grade them (paper Section 6)."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from enum import Enum

import numpy as np

__all__ = ["IdentifiabilityStatus", "IdentifiabilityThresholds", "worst_status", "best_status"]


class IdentifiabilityStatus(str, Enum):
    """Graded verdict for an edge, a component or the whole problem."""

    #: Every criterion above its comfortable threshold.
    IDENTIFIABLE = "identifiable"
    #: Identifiable (above every hard threshold) but some criterion below a comfortable one.
    WEAK = "weak"
    #: A hard criterion fails: not identifiable (from this edge / at all).
    INSUFFICIENT = "insufficient"


_ORDER = {
    IdentifiabilityStatus.IDENTIFIABLE: 0,
    IdentifiabilityStatus.WEAK: 1,
    IdentifiabilityStatus.INSUFFICIENT: 2,
}


def worst_status(statuses) -> IdentifiabilityStatus:
    statuses = list(statuses)
    if not statuses:
        return IdentifiabilityStatus.IDENTIFIABLE
    return max(statuses, key=_ORDER.__getitem__)


def best_status(statuses) -> IdentifiabilityStatus:
    statuses = list(statuses)
    if not statuses:
        return IdentifiabilityStatus.INSUFFICIENT
    return min(statuses, key=_ORDER.__getitem__)


@dataclass(frozen=True)
class IdentifiabilityThresholds:
    """Thresholds of the graded verdicts (hard: below -> insufficient; comfortable: -> weak).

    Attributes
    ----------
    min_pairs : int
        Hard. Corollaries 2 and 4 need three pairs ``i1, i2, i3``.
    min_rotation_deg : float
        Hard. ``rotation_spread_deg`` below this: "no rotation (pure translations)". 1 deg is
        far above the rounding of exact data and at the level of real pose-stream noise.
    min_second_axis_deg : float
        Hard. ``second_axis_spread_deg`` below this: "rotations only about one axis".
    good_second_axis_deg : float
        Comfortable. ``second_axis_spread_deg`` below this: weak.
    max_rotation_std_deg : float
        Comfortable. Predicted ``rotation_std_deg`` above this: weak (noise-aware).
    min_translation_excitation_m : float
        ``translation_excitation_m`` below this: for unknown scale insufficient (scale not
        identifiable), for known scale weak (eq. (63) fails).
    max_scale_rel_std : float
        Comfortable (unknown scale). Predicted ``scale_rel_std`` above this: weak.
    kernel_rtol : float
        Hard. ``rotation_sv_ratio`` below this: the rotation system of eq. (60) has a kernel of
        dimension > 1 (Corollary 2 fails).
    null_tol : float
        Numeric check: eigenvalues of the Jacobi-normalised Hessian (unit diagonal) below this
        span null directions (not identifiable). Exact degeneracies give ~1e-14, the flat
        directions of exact symmetries at a polished minimiser ~1e-12.
    full_rotation_std_deg, full_translation_std_m, full_scale_rel_std : float
        Numeric check, comfortable: predicted per-frame standard deviations above these: weak.
    """

    min_pairs: int = 3
    min_rotation_deg: float = 1.0
    min_second_axis_deg: float = 1.0
    good_second_axis_deg: float = 5.0
    max_rotation_std_deg: float = 5.0
    min_translation_excitation_m: float = 1e-3
    max_scale_rel_std: float = 0.01
    kernel_rtol: float = 1e-6
    null_tol: float = 1e-8
    full_rotation_std_deg: float = 1.0
    full_translation_std_m: float = 0.02
    full_scale_rel_std: float = 0.01

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if not np.isfinite(value) or value < 0:
                raise ValueError(f"IdentifiabilityThresholds.{name} must be finite and >= 0, "
                                 f"got {value!r}")

