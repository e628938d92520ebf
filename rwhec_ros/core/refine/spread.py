"""The cross-validation folds' spread against the corner-level covariance: a check of the model.

The covariance of the refined estimate comes from the corner-level model
(:meth:`.fit.CornerFit.covariance`): the corner noise per camera and the pose stream's noise,
estimated from the residuals. It holds when the model does (renders: error over predicted std
0.99-1.15, ``benchmarks/refinement.md``). On real data the model misses what it does not know
(intrinsics calibrated from a few views, a board's print, the structure of a robot's pose
errors), and its covariance can be far too small: on a real 8-view eye-to-hand set with a single
ArUco marker the refined camera had a std of 0.4-0.7 mm per axis while leaving one view out moved
it by up to 6 mm.

The cross-validation of :mod:`.estimate` already fits the kept model once per fold of pose
samples. Those fits are a **delete-a-group jackknife** (Efron and Stein): over ``K`` folds the
spread ``C = (K - 1) / K sum_k (d_k - mean d)(d_k - mean d)^T`` of the fold estimates ``d_k``
(tangent of each frame about the refined estimate: translation added, rotation on the left, the
covariance's convention) estimates the estimate's covariance without the model's noise
assumptions. Its ratio to the model's, ``f = sum_frames tr(Sigma^-1 C) / (6 n_frames)``, is about
1 when the model holds. When ``f`` exceeds the 99 % quantile of ``chi2(nu) / nu`` with
``nu = 6 (K - 1)`` (the degrees of freedom of one frame's jackknife: frames move together, so the
frames are not counted as independent evidence), the whole covariance is multiplied by ``f`` and
the result says so; otherwise it is left as the model gives it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy import stats

from .model import State, frame_difference

__all__ = ["FoldSpread", "fold_spread", "SIGNIFICANCE"]

#: Upper tail of the test that the folds spread more than the covariance says.
SIGNIFICANCE = 0.01


@dataclass(frozen=True)
class FoldSpread:
    """The folds' spread against the model's covariance (module docstring).

    Attributes
    ----------
    factor : float
        ``f``: the jackknife covariance over the model's, averaged over the frames' 6 axes.
    folds : int
        ``K``.
    threshold : float
        ``chi2_0.99(nu) / nu``: ``factor`` beyond it scales the covariance.
    """

    factor: float
    folds: int
    threshold: float

    @property
    def significant(self) -> bool:
        return bool(self.factor > self.threshold)

    def to_dict(self) -> dict:
        return {"factor": float(self.factor), "folds": self.folds,
                "threshold": float(self.threshold), "applied": self.significant}


def fold_spread(folds: Sequence[State], estimate: State, covariance: np.ndarray
                ) -> FoldSpread | None:
    """The spread of the fold fits ``folds`` about ``estimate`` against ``covariance``
    ((n_frames, 6, 6), X frames then Y frames); None with fewer than 4 folds or a singular
    frame covariance."""
    K = len(folds)
    if K < 4:
        return None
    frames = np.concatenate([estimate.X, estimate.Y])
    d = np.stack([frame_difference(np.concatenate([s.X, s.Y]), frames)
                  for s in folds])  # (K, n, 6)
    centred = d - d.mean(axis=0)
    total = 0.0
    for f in range(frames.shape[0]):
        C = (K - 1) / K * centred[:, f, :].T @ centred[:, f, :]
        try:
            total += float(np.trace(np.linalg.solve(covariance[f], C)))
        except np.linalg.LinAlgError:
            return None
    factor = total / (6 * frames.shape[0])
    nu = 6 * (K - 1)
    threshold = float(stats.chi2.ppf(1.0 - SIGNIFICANCE, nu) / nu)
    return FoldSpread(float(factor), K, threshold)
