"""The thresholds of the verdict (:class:`VerdictOptions`), each a named, documented parameter.

The defaults were tuned on simulated data with the stated noise (the paper's Section 8 scenarios
at its four noise levels and the demo rig; ``benchmarks/verdict.py``): ``good`` in >= 99 % of
those runs, and not ``good`` when a tag size, a focal length, the time sync or a tag is wrong.
The node and the CLI read them from the ``verdict.*`` parameters (same names).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["VerdictOptions", "LEVELS", "level_rank", "worst_level"]

#: The verdict levels, from best to worst.
LEVELS = ("good", "caution", "unusable")


def level_rank(level: str) -> int:
    """0 for ``good``, 1 for ``caution``, 2 for ``unusable`` (``ValueError`` otherwise)."""
    try:
        return LEVELS.index(level)
    except ValueError:
        raise ValueError(f"level: expected one of {LEVELS}, got {level!r}") from None


def worst_level(levels) -> str:
    """The worst of ``levels`` (``good`` for none)."""
    return LEVELS[max((level_rank(v) for v in levels), default=0)]


@dataclass(frozen=True)
class VerdictOptions:
    """When a result is ``good``, ``caution`` or ``unusable`` (see :func:`~.assess.assess`).

    Noise ratios are in standard-deviation units: the noise the residuals imply divided by the
    stated noise (``sqrt`` of the a-posteriori variance factor), e.g. 2.0 when the data fit a
    ``sigma`` twice the configured one.

    Attributes
    ----------
    significance : float
        A chi-square test counts as significant below this p-value (1e-3); the per-edge tests use
        it divided by the number of edges (Bonferroni), so that 70 good edges give no false alarm.
    fit_caution_ratio : float
        Estimated / stated noise (translation or rotation) above which the fit is a caution
        (1.5), when the chi-square test is significant too.
    fit_unusable_ratio : float
        ... above which the result is unusable (3.0).
    edge_ratio : float
        An edge whose noise ratio is this many times that of the median edge (5.0), significantly
        so, is named as an outlier (its frames: caution; a frame with no other edge: unusable)
        ...
    edge_min_noise_ratio : float
        ... if its noise ratio also reaches this (0.5: half the stated noise), so that
        differences far below the stated noise (near and far tags, oblique views) are not named;
    edge_noisy_ratio : float
        an edge this many times the median edge (2.0), significantly so, whose noise ratio also
        exceeds ``fit_caution_ratio``, is named too.
    min_edges : int
        Edges needed to compare an edge with the median edge (3).
    scale_check : bool
        With known scale, also solve with an unknown scale and check that it is 1 (True): wrong
        tag sizes, focal lengths or pose-stream units show as a scale.
    scale_sigmas : float
        The scale counts as different from 1 beyond this many standard deviations (4.0) ...
    scale_caution : float
        ... and beyond this relative difference (0.02: 2 %) -> caution,
    scale_unusable : float
        ... beyond this one (0.05: 5 %) -> unusable.
    caution_std_translation_m, caution_std_rotation_deg : float
        A frame whose predicted standard deviation (worst direction; the larger of the stated-noise
        prediction and that rescaled by the a-posteriori noise ratio) exceeds these is a caution
        (0.06 m, 4.0 deg: the worst frame of the Section 8 scenarios at the noisiest level,
        kappa 12 and sigma 5 cm, reaches 0.050 m and 3.1 deg in 300 runs).
    unusable_std_translation_m, unusable_std_rotation_deg : float
        ... unusable (0.1 m, 6.0 deg).
    caution_scale_rel_std, unusable_scale_rel_std : float
        Unknown scale: predicted relative standard deviation of the scale above which the result
        is a caution (0.02) or unusable (0.1).
    focal_check : bool
        When the data keep the tag corners and the intrinsics, check per camera the focal length
        that the corners fit, each image through its own pose (True; see :mod:`.focal_check`).
    focal_sigmas : float
        A camera's fitted focal length counts as different from the configured one beyond this
        many standard deviations (4.0) ...
    focal_caution : float
        ... and beyond this relative difference (0.02: 2 %) -> caution for that camera (good
        rendered runs: within 0.23 %; a focal length 5 % off: 4.5-5.5 %).
    reprojection_ratio : float
        A camera whose detected corners reproject through the calibration with an RMS error
        this many times the median of the other cameras' (5.0) ...
    reprojection_min_px : float
        ... and above this (2.0 px) is named, a caution (:mod:`.reprojection_check`; good
        rendered runs: 0.3-0.5 px on every camera).
    exclude_misfits : bool
        Exclude a target or an edge that does not fit and solve again without it
        (:mod:`.exclusion`, True); what is published is that solve. Off: the misfit is only
        named.
    exclusion_max_rounds : int
        At most this many targets or edges are excluded, one per re-solve (3).
    exclusion_max_share : float
        ... leaving out at most this share of the pairs (0.34): beyond that the misfit is not
        one target's.
    exclusion_rejected_share : float
        With outlier rejection: a target (or an edge) more than this share of whose pairs the
        rejection left out (0.5) does not fit, and is excluded like one that fits badly.
    noise_confidence : float
        With the noise estimated from the data (:mod:`rwhec_ros.core.noise`), the precision
        check uses each frame's std times the one-sided upper confidence factor of the estimated
        noise at this level (0.95): ``sqrt(dof / chi2_0.05(dof))`` for the fewest degrees of
        freedom among the groups that weight its pairs (1.04 at 1000, 1.36 at 20): few pairs,
        a wider bound.
    noise_group_ratio : float
        A noise group (camera) whose estimated noise is this many times the median of the others
        (5.0), significantly so, is named (caution): a camera much noisier than the rest of the
        rig usually has a fault.
    lag_check : bool
        Check whether the residuals follow the motion between neighbouring pairs (poses out of
        step with the images, :mod:`.lag_check`; True).
    lag_sigmas : float
        ... a caution when the lag is beyond this many standard deviations (4.0) ...
    lag_shift_std : float
        ... and taking it out moves a frame by at least this many of its std (1.0).
    pair_check : bool
        Name single pairs far off their camera's other pairs (Bonferroni at ``significance``)
        that move a frame by at least ``pair_shift_std`` of its std (1.0) (:mod:`.pair_check`;
        True).
    pair_shift_std : float
        See ``pair_check``.
    """

    significance: float = 1e-3
    fit_caution_ratio: float = 1.5
    fit_unusable_ratio: float = 3.0
    edge_ratio: float = 5.0
    edge_min_noise_ratio: float = 0.5
    edge_noisy_ratio: float = 2.0
    min_edges: int = 3
    scale_check: bool = True
    scale_sigmas: float = 4.0
    scale_caution: float = 0.02
    scale_unusable: float = 0.05
    caution_std_translation_m: float = 0.06
    caution_std_rotation_deg: float = 4.0
    unusable_std_translation_m: float = 0.1
    unusable_std_rotation_deg: float = 6.0
    caution_scale_rel_std: float = 0.02
    unusable_scale_rel_std: float = 0.1
    focal_check: bool = True
    focal_sigmas: float = 4.0
    focal_caution: float = 0.02
    reprojection_ratio: float = 5.0
    reprojection_min_px: float = 2.0
    exclude_misfits: bool = True
    exclusion_max_rounds: int = 3
    exclusion_max_share: float = 0.34
    exclusion_rejected_share: float = 0.5
    noise_confidence: float = 0.95
    noise_group_ratio: float = 5.0
    lag_check: bool = True
    lag_sigmas: float = 4.0
    lag_shift_std: float = 1.0
    pair_check: bool = True
    pair_shift_std: float = 1.0

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if isinstance(value, bool):
                continue
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"VerdictOptions.{name}: must be finite and > 0, got {value!r}")
        if not self.noise_confidence < 1:
            raise ValueError(f"VerdictOptions.noise_confidence: must be < 1, got "
                             f"{self.noise_confidence!r}")
        if self.noise_group_ratio < 1:
            raise ValueError(f"VerdictOptions.noise_group_ratio: must be >= 1, got "
                             f"{self.noise_group_ratio!r}")
        if not self.significance < 1:
            raise ValueError(f"VerdictOptions.significance: must be < 1, got {self.significance!r}")
        if not self.min_edges >= 2 or int(self.min_edges) != self.min_edges:
            raise ValueError(f"VerdictOptions.min_edges: must be an integer >= 2, got "
                             f"{self.min_edges!r}")
        if int(self.exclusion_max_rounds) != self.exclusion_max_rounds:
            raise ValueError(f"VerdictOptions.exclusion_max_rounds: must be an integer >= 1, "
                             f"got {self.exclusion_max_rounds!r}")
        for name in ("exclusion_max_share", "exclusion_rejected_share"):
            if not getattr(self, name) < 1:
                raise ValueError(f"VerdictOptions.{name}: must be < 1 (a share of the pairs), "
                                 f"got {getattr(self, name)!r}")
        for low, high in (("fit_caution_ratio", "fit_unusable_ratio"),
                          ("scale_caution", "scale_unusable"),
                          ("caution_std_translation_m", "unusable_std_translation_m"),
                          ("caution_std_rotation_deg", "unusable_std_rotation_deg"),
                          ("caution_scale_rel_std", "unusable_scale_rel_std")):
            if getattr(self, low) > getattr(self, high):
                raise ValueError(f"VerdictOptions.{low}: {getattr(self, low)!r} is above "
                                 f"{high} {getattr(self, high)!r}")
        if self.fit_caution_ratio < 1:
            raise ValueError(f"VerdictOptions.fit_caution_ratio: must be >= 1 (the stated noise "
                             f"itself), got {self.fit_caution_ratio!r}")
        for name in ("edge_ratio", "edge_noisy_ratio", "reprojection_ratio"):
            if getattr(self, name) < 1:
                raise ValueError(f"VerdictOptions.{name}: must be >= 1, got "
                                 f"{getattr(self, name)!r}")
