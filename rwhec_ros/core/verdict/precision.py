"""How precisely each frame is determined: one source, so that it can be swapped.

Today the source is the identifiability numeric check at the solution
(:func:`rwhec_ros.core.identifiability.numeric_check`): the inverse of the exact Hessian of the
MLE cost on the manifold, predicted from the **stated** noise, per frame the worst-direction
standard deviation of the translation [m] and of the rotation [deg]. The verdict uses the larger
of that prediction and the prediction rescaled by the a-posteriori noise ratio ``s`` of the fit
(:mod:`.fit`): a stated noise that is too small must not make a frame look precise, and one that is
too large keeps its (conservative) prediction.

When the per-frame covariance of issue 11 lands, :func:`frame_precisions` is the one function to
change (its covariance's worst-direction standard deviations instead of the numeric check's).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

__all__ = ["FramePrecision", "frame_precisions"]


@dataclass(frozen=True)
class FramePrecision:
    """Predicted precision of one frame (worst direction).

    Attributes
    ----------
    name : str
    predicted_translation_m, predicted_rotation_deg : float
        Standard deviations predicted from the stated noise (``inf``: not determined).
    factor : float
        ``max(1, s)``, the a-posteriori noise ratio applied.
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


def frame_precisions(identifiability, noise_ratio: float = 1.0,
                     pinned: Iterable[str] = ()) -> dict[str, FramePrecision]:
    """Per frame, its predicted precision from an identifiability report at the solution
    (:class:`~rwhec_ros.core.identifiability.IdentifiabilityReport` with a numeric check), with
    the factor ``max(1, noise_ratio)``; empty when the report has no numeric check. A frame in
    ``pinned`` (a translation direction fixed by the user's priors, which the numeric check does
    not know) gets ``nan`` for an unbounded translation (unknown, not undetermined)."""
    numeric = getattr(identifiability, "numeric", None)
    if numeric is None:
        return {}
    factor = max(1.0, float(noise_ratio)) if np.isfinite(noise_ratio) else 1.0
    pinned = set(pinned)
    out = {}
    for name in numeric.frame_status:
        t = float(numeric.translation_std_m.get(name, np.inf))
        if name in pinned and not np.isfinite(t):
            t = float("nan")
        out[name] = FramePrecision(name, t, float(numeric.rotation_std_deg.get(name, np.inf)),
                                   factor)
    return out
