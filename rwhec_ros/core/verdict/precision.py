"""How precisely each frame is determined: one source for the verdict, the summary and the YAML.

The source is the per-frame covariance of :mod:`rwhec_ros.core.analysis.uncertainty`
(:func:`~rwhec_ros.core.analysis.uncertainty.frame_uncertainty`): the inverse of the exact Hessian
of the MLE cost on the manifold, predicted from the **stated** noise, per frame the worst-direction
standard deviation of the translation [m] and of the rotation [deg]
(:meth:`~rwhec_ros.core.analysis.uncertainty.FrameUncertainty.worst_std`). The verdict uses the
larger of that prediction and the prediction rescaled by the a-posteriori noise ratio ``s`` of the
fit (:mod:`.fit`): a stated noise that is too small must not make a frame look precise, and one that
is too large keeps its (conservative) prediction.

With the noise estimated from the data (:mod:`rwhec_ros.core.noise`) the prediction is that of the
estimated weights, and the factor is instead the upper confidence factor of the estimate
(:func:`~rwhec_ros.core.noise.estimate.std_upper_factor`, the fewest degrees of freedom among the
noise groups that weight the frame's pairs): the prediction is not conservative by a guess, and
few pairs widen it.

Either way, a frame whose own edges fit significantly worse than the weights (chi-square test over
its edges' residuals, ``VerdictOptions.significance``) takes their noise ratio instead when it is
larger (:func:`frame_noise_ratios`): a camera's std is never smaller than its own misfit shows,
also when the other frames' good fit keeps the overall ratio near 1.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

__all__ = ["FramePrecision", "frame_precisions", "frame_noise_ratios", "scale_rel_std"]


@dataclass(frozen=True)
class FramePrecision:
    """Predicted precision of one frame (worst direction).

    Attributes
    ----------
    name : str
    predicted_translation_m, predicted_rotation_deg : float
        Standard deviations predicted from the noise of the weights (``inf``: not determined;
        ``nan``: unknown).
    factor : float
        ``max(1, s)``, the a-posteriori noise ratio applied; with estimated noise the upper
        confidence factor of the estimate.
    """

    name: str
    predicted_translation_m: float
    predicted_rotation_deg: float
    factor: float = 1.0

    @property
    def std_translation_m(self) -> float:
        """``max(predicted, predicted * s)`` [m]."""
        return self.predicted_translation_m * self.factor

    @property
    def std_rotation_deg(self) -> float:
        """``max(predicted, predicted * s)`` [deg]."""
        return self.predicted_rotation_deg * self.factor

    @property
    def determined(self) -> bool:
        """Both predictions finite (``nan``: unknown, e.g. fixed by a prior)."""
        return bool(np.isfinite(self.predicted_translation_m)
                    and np.isfinite(self.predicted_rotation_deg))


def noise_factor(noise_ratio: float) -> float:
    """``max(1, noise_ratio)`` (1 for a ratio that is not finite)."""
    return max(1.0, float(noise_ratio)) if np.isfinite(noise_ratio) else 1.0


def frame_noise_ratios(fit, significance: float) -> dict[str, float]:
    """Frame -> the noise ratio of its own edges (both terms: ``sqrt(sum 2 p_e / sum dof_e)``),
    for the frames whose edges fit significantly worse than the stated noise (upper-tail
    chi-square p-value below ``significance``); the others are left out. ``fit`` is a
    :class:`~.fit.FitStatistics` (None: empty)."""
    if fit is None:
        return {}
    sums: dict[str, list[float]] = {}
    for e in fit.edges:
        c = (e.noise_ratio_translation ** 2 * e.dof_translation
             + e.noise_ratio_rotation ** 2 * e.dof_rotation)
        d = e.dof_translation + e.dof_rotation
        if not (np.isfinite(c) and d > 0):
            continue
        for n in (e.x, e.y):
            acc = sums.setdefault(n, [0.0, 0.0])
            acc[0] += c
            acc[1] += d
    return {n: float(np.sqrt(c / d)) for n, (c, d) in sums.items()
            if d > 0 and c > d and float(chi2.sf(c, d)) < significance}


def frame_precisions(uncertainty, noise_ratio: float = 1.0,
                     pinned: Iterable[str] = (),
                     frame_ratios: dict[str, float] | None = None,
                     factors: Mapping[str, float] | None = None) -> dict[str, FramePrecision]:
    """Per frame, its predicted precision from an
    :class:`~rwhec_ros.core.analysis.uncertainty.Uncertainty` at the solution, with the factor
    ``max(1, noise_ratio)``; empty when ``uncertainty`` is None. A frame in ``pinned`` (a
    translation direction fixed by the user's priors) whose translation is unobservable in
    ``uncertainty`` (computed without those priors) gets ``nan`` (unknown, not undetermined);
    computed with the solve's priors (``UncertaintyOptions(gauge=...)``) its translation std is
    the one given the priors. ``factors``: per frame a factor that replaces ``max(1,
    noise_ratio)`` (estimated noise: the estimate's upper confidence factor); ``frame_ratios``
    (:func:`frame_noise_ratios`) raise the factor of the frames they name to at least their
    own."""
    if uncertainty is None:
        return {}
    factor = noise_factor(noise_ratio)
    pinned = set(pinned)
    out = {}
    for fu in uncertainty.frames:
        t, r = fu.worst_std()
        if fu.name in pinned and not np.isfinite(t):
            t = float("nan")
        own = noise_factor((frame_ratios or {}).get(fu.name, 1.0))
        base = (factors or {}).get(fu.name, factor)
        out[fu.name] = FramePrecision(fu.name, t, r, max(base, own))
    return out


def scale_rel_std(uncertainty, scale: float) -> float | None:
    """Predicted relative std of the unknown scale (``inf`` when not determined); None for
    known scale or without ``uncertainty``."""
    if uncertainty is None or uncertainty.scale_std is None:
        return None
    s = float(uncertainty.scale_std)
    return float("inf") if np.isnan(s) else s / abs(float(scale))
