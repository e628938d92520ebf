"""Options of the outlier-rejection steps: RANSAC (paper Section 9.1), GNC-TLS, the robust solve."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..solve import SolveOptions

__all__ = ["RansacOptions", "GncOptions", "RobustOptions", "check_positive"]


@dataclass
class RansacOptions:
    """Options of :func:`ransac_filter` (paper Section 9.1 defaults).

    Attributes
    ----------
    translation_threshold : float
        Largest translation residual of an inlier [m] (0.6, paper).
    rotation_threshold_deg : float
        Largest rotation residual of an inlier [deg] (60, paper).
    min_inlier_fraction : float
        Smallest consensus set, as a fraction of the edge's pairs, for the edge to be kept (1/3).
    confidence : float
        Probability of drawing at least one all-inlier sample; sets the adaptive number of
        hypotheses (0.99).
    min_iterations, max_iterations : int
        Bounds on the number of (non-degenerate) hypotheses per edge (20, 500).
    min_axis_span_deg : float
        A 3-pair sample is degenerate unless the relative A rotations span a second axis by at
        least this much (second singular value of their rotation vectors, 5 deg).
    scale_tolerance : float
        Unknown scale only: assumed bound on ``|alpha - 1|`` (0.1, paper: tag size within 10 %);
        widens the translation threshold of pair ``i`` by ``scale_tolerance |t_B_i|``.
    local_refinements : int
        Bound on the refit/re-score rounds of the best hypothesis (5); the rounds stop early
        when the consensus set no longer changes.
    batch_size : int
        Hypotheses evaluated per vectorised batch (32).
    """

    translation_threshold: float = 0.6
    rotation_threshold_deg: float = 60.0
    min_inlier_fraction: float = 1.0 / 3.0
    confidence: float = 0.99
    min_iterations: int = 20
    max_iterations: int = 500
    min_axis_span_deg: float = 5.0
    scale_tolerance: float = 0.1
    local_refinements: int = 5
    batch_size: int = 32

    def __post_init__(self) -> None:
        check_positive("translation_threshold", self.translation_threshold)
        check_positive("rotation_threshold_deg", self.rotation_threshold_deg)
        if not 0.0 < self.rotation_threshold_deg <= 180.0:
            raise ValueError(
                f"rotation_threshold_deg: expected a value in (0, 180], got "
                f"{self.rotation_threshold_deg!r}"
            )
        for name in ("min_inlier_fraction", "confidence"):
            v = getattr(self, name)
            if not (np.isfinite(v) and 0.0 < v < 1.0):
                raise ValueError(f"{name}: expected a value in (0, 1), got {v!r}")
        for name in ("min_iterations", "max_iterations", "batch_size"):
            v = getattr(self, name)
            if int(v) != v or v < 1:
                raise ValueError(f"{name}: expected a positive integer, got {v!r}")
        if self.min_iterations > self.max_iterations:
            raise ValueError(
                f"min_iterations: {self.min_iterations} exceeds max_iterations "
                f"{self.max_iterations}"
            )
        if int(self.local_refinements) != self.local_refinements or self.local_refinements < 0:
            raise ValueError(
                f"local_refinements: expected an integer >= 0, got {self.local_refinements!r}"
            )
        for name in ("min_axis_span_deg", "scale_tolerance"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0.0):
                raise ValueError(f"{name}: expected a finite value >= 0, got {v!r}")



@dataclass
class GncOptions:
    """Options of the GNC-TLS loop of :func:`robust_solve`.

    Attributes
    ----------
    quantile : float
        ``c^2`` is this quantile of ``chi2(6)``, the law of ``J_i`` for an inlier (0.99).
    threshold : float or None
        ``c^2`` given explicitly (overrides ``quantile``); use it when ``sigma, kappa`` are
        weights rather than true noise levels.
    mu_factor : float
        Growth of the GNC parameter per iteration (1.4, Yang et al. 2020).
    max_iterations : int
        Bound on the weighted solves (100).
    weight_floor : float
        Pairs with a smaller weight are left out of the weighted problem (1e-4).
    inner : SolveOptions
        Solver of the weighted problems: ``fast`` without SDP fallback (a warm-started local
        solve with a cheap certificate; certification happens in the final solve).
    """

    quantile: float = 0.99
    threshold: float | None = None
    mu_factor: float = 1.4
    max_iterations: int = 100
    weight_floor: float = 1e-4
    inner: SolveOptions = field(
        default_factory=lambda: SolveOptions(mode="fast", fallback_to_sdp=False)
    )

    def __post_init__(self) -> None:
        if not (np.isfinite(self.quantile) and 0.0 < self.quantile < 1.0):
            raise ValueError(f"quantile: expected a value in (0, 1), got {self.quantile!r}")
        if self.threshold is not None:
            check_positive("threshold", self.threshold)
        if not (np.isfinite(self.mu_factor) and self.mu_factor > 1.0):
            raise ValueError(f"mu_factor: expected a finite value > 1, got {self.mu_factor!r}")
        if int(self.max_iterations) != self.max_iterations or self.max_iterations < 1:
            raise ValueError(
                f"max_iterations: expected a positive integer, got {self.max_iterations!r}"
            )
        if not (np.isfinite(self.weight_floor) and 0.0 < self.weight_floor < 0.5):
            raise ValueError(f"weight_floor: expected a value in (0, 0.5), got "
                             f"{self.weight_floor!r}")


@dataclass
class RobustOptions:
    """Options of :func:`robust_solve`.

    Attributes
    ----------
    use_ransac : bool
        Run :func:`ransac_filter` before GNC (True, as the paper).
    ransac : RansacOptions
    gnc : GncOptions
    solve : SolveOptions
        The final, certifying solve on the inlier set (``mode="fast"``, SDP fallback on).
    """

    use_ransac: bool = True
    ransac: RansacOptions = field(default_factory=RansacOptions)
    gnc: GncOptions = field(default_factory=GncOptions)
    solve: SolveOptions = field(default_factory=lambda: SolveOptions(mode="fast"))



def check_positive(name: str, value: float) -> None:
    if not (np.isfinite(value) and value > 0.0):
        raise ValueError(f"{name}: expected a finite value > 0, got {value!r}")

