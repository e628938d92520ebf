"""Which estimate is published: the certified pose-level optimum or its corner-level refinement.

The refinement (:mod:`.estimate`) is published when

1. its noise estimates converged;
2. it lowers the corner residual: the robust corner cost of the kept fit, with the pose errors
   re-fitted at each estimate and the same noise, is lower at the refined frames than at the
   certified ones (:attr:`~.estimate.Refinement.cost_start`, :attr:`~.estimate.Refinement.cost`);
3. it stays consistent with the certified estimate within the uncertainties: for every frame the
   difference ``d = [t_ref - t_cert, log(R_ref R_cert^T)]`` has a Mahalanobis distance
   ``d^T (C_ref + C_cert)^-1 d`` at most the chi-square quantile ``consistency_quantile`` with
   6 degrees of freedom (1 for the scale), where ``C_ref`` is the refinement's covariance and
   ``C_cert`` the certified estimate's (a-posteriori, when given). Both estimates come from the
   same data, so their difference varies less than ``C_ref + C_cert`` says: a frame beyond it
   means the two models disagree about the data, and the certified estimate is kept;
4. it predicts the corners of unseen pose samples no worse than the certified estimate's model:
   where the cross-validation scored the pose-level fit too (``"certified"`` in
   :attr:`~.estimate.Refinement.held_out_rms_px`), the kept fit's held-out RMS is at most
   ``1 + held_out_margin`` times that one's. A refinement that fits its own corners better and
   new ones clearly worse has fitted the noise of few pose samples, not the calibration; within
   the margin the two predict alike. The margin is 0 by default: on the rendered rigs the
   refinement predicts unseen corners better in 39 of 40 runs (one wide-angle run tied, 0.282
   against 0.281 px), while on a real 12-view ChArUco set (kvasios/franka-handeye) a refinement
   1.7 % worse on unseen corners moved the camera 15.5 mm from the certified estimate and from
   every OpenCV method (all within 3-4 mm of the certified one);
5. it is, over its frames, at least as precise as the certified estimate: the geometric mean
   over the frames of the ratio of the refined std to the certified one in the worst direction
   (translation and rotation, each frame; :meth:`~.estimate.Refinement.frame_covariance`, scaled
   by its folds' spread, against the certified covariance a posteriori) is at most 1. On the
   rendered rigs of ``benchmarks/refinement.md`` it is 0.77-0.91 (a frame's rotation up to 1.32:
   the verdict widens such a frame's precision to the refined std, ``rwhec_ros.session.
   refinement.published_uncertainty``); on the four real sets of ``../shared`` the refined
   estimates' own covariances were 1.5x (ChArUco), 5.1x (6-view chessboard), 9.1x and 15.7x
   (circle grid, refitted and nominal intrinsics) the certified ones: fits that move from fold to
   fold with a few pose samples, whose widened precision made the circle grid's verdict
   unusable (+-172 mm) where the certified estimate's was a caution.

Otherwise the certified estimate is published, and :attr:`Decision.reason` says why.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2

from ..analysis.worst_direction import block_variances
from .estimate import Refinement
from .model import frame_difference

__all__ = ["DecisionOptions", "Decision", "decide", "frame_difference"]


@dataclass(frozen=True)
class DecisionOptions:
    """``consistency_quantile``: the chi-square quantile of condition 3; ``held_out_margin``:
    the fraction of condition 4 (module docstring)."""

    consistency_quantile: float = 0.999
    held_out_margin: float = 0.0

    def __post_init__(self) -> None:
        q = self.consistency_quantile
        if not (np.isfinite(q) and 0 < q < 1):
            raise ValueError(f"consistency_quantile: must be in (0, 1), got {q!r}")
        m = self.held_out_margin
        if not (np.isfinite(m) and 0 <= m < 1):
            raise ValueError(f"held_out_margin: must be in [0, 1), got {m!r}")


@dataclass
class Decision:
    """What is published and why.

    Attributes
    ----------
    published : str
        ``"refined"`` or ``"certified"``.
    reason : str
        One sentence.
    distances : dict of str to float
        Per frame (and ``"scale"``) the Mahalanobis distance of condition 3 (module docstring).
    limit : float
        Its bound for a frame (6 degrees of freedom).
    """

    published: str
    reason: str
    distances: dict[str, float] = field(default_factory=dict)
    limit: float = float("nan")

    @property
    def refined(self) -> bool:
        return self.published == "refined"


def _mahalanobis(d: np.ndarray, C: np.ndarray) -> float:
    if not np.all(np.isfinite(C)):
        return float("inf")
    try:
        return float(d @ np.linalg.solve(C, d))
    except np.linalg.LinAlgError:
        return float("inf")


def _precision_ratio(refinement: Refinement, certified: Mapping | None) -> float:
    """Condition 5 of the module docstring: the geometric mean over the frames (translation and
    rotation) of refined std / certified std in the worst direction; 1 when not comparable (no
    certified covariances, or none finite)."""
    if certified is None:
        return 1.0
    logs = []
    for name in refinement.names:
        if name not in certified:
            continue
        r = np.sqrt(np.maximum(block_variances(refinement.frame_covariance(name)), 0.0)
                    / np.maximum(block_variances(certified[name]), 0.0))
        logs += [float(np.log(v)) for v in r if np.isfinite(v) and v > 0]
    return float(np.exp(np.mean(logs))) if logs else 1.0


def decide(refinement: Refinement, result, certified_covariances: Mapping | None = None,
           certified_scale_std: float | None = None, options: DecisionOptions | None = None
           ) -> Decision:
    """The published estimate (module docstring).

    Parameters
    ----------
    refinement : Refinement
    result : CalibrationResult
        The certified estimate the refinement started from.
    certified_covariances : mapping of str to ndarray (6, 6), optional
        Per frame the certified estimate's covariance (a posteriori); None: only the
        refinement's.
    certified_scale_std : float, optional
    options : DecisionOptions, optional
    """
    opts = options or DecisionOptions()
    q = opts.consistency_quantile
    limit = float(chi2.ppf(q, 6))
    if not refinement.converged:
        return Decision("certified", f"the refinement's {refinement.message}", limit=limit)
    if not refinement.cost < refinement.cost_start:
        return Decision("certified", f"the refinement does not lower the corner residual "
                        f"(robust cost {refinement.cost_start:.6g} -> {refinement.cost:.6g})",
                        limit=limit)
    held = refinement.held_out_rms_px
    if "certified" in held and refinement.model in held \
            and not held[refinement.model] <= (1.0 + opts.held_out_margin) * held["certified"]:
        return Decision("certified", f"the certified estimate predicts the corners of unseen "
                        f"pose samples better than the refinement (held-out RMS "
                        f"{held['certified']:.3g} px against {held[refinement.model]:.3g} px, "
                        f"cross-validation over the pose samples): the refinement fits its own "
                        f"corners, not the calibration; record more poses to refine",
                        limit=limit)
    moves = {name: frame_difference(refinement.transform(name), result.transform(name))
             for name in refinement.names}
    dist = {}
    for name in refinement.names:
        C = np.array(refinement.frame_covariance(name), float)
        if certified_covariances is not None and name in certified_covariances:
            C = C + np.asarray(certified_covariances[name], float)
        dist[name] = _mahalanobis(moves[name], C)
    bad = {n: v for n, v in dist.items() if not v <= limit}
    if refinement.scale_std is not None:
        var = refinement.scale_std ** 2 + (certified_scale_std or 0.0) ** 2
        ds = (refinement.scale - float(result.scale)) ** 2 / var if var > 0 else float("inf")
        dist["scale"] = float(ds)
        if not ds <= float(chi2.ppf(q, 1)):
            bad["scale"] = ds
    if bad:
        worst = max(bad, key=bad.get)
        return Decision("certified", f"the refinement moves {worst} beyond the uncertainties "
                        f"of both estimates (Mahalanobis distance squared {bad[worst]:.3g} > "
                        f"{limit if worst != 'scale' else chi2.ppf(q, 1):.3g}, the "
                        f"{100 * q:g} % chi-square quantile): the corner-level and the "
                        "pose-level model disagree about these data", dist, limit)
    ratio = _precision_ratio(refinement, certified_covariances)
    if ratio > 1.0:
        return Decision("certified", f"the refinement is less precise than the certified "
                        f"estimate: its std is {ratio:.3g} times the certified one's (geometric "
                        f"mean over the frames, worst directions); the corner-level fit moves "
                        f"with the pose samples it is given", dist, limit)
    worst = max(dist, key=dist.get)
    far = max(moves, key=lambda n: float(np.linalg.norm(moves[n][:3])))
    turned = max(moves, key=lambda n: float(np.linalg.norm(moves[n][3:])))
    return Decision("refined", f"the refinement lowers the corner residual (robust cost "
                    f"{refinement.cost_start:.6g} -> {refinement.cost:.6g}) and every frame "
                    f"stays within the uncertainties of the certified estimate (largest "
                    f"Mahalanobis distance squared {dist[worst]:.3g} on {worst}, bound "
                    f"{limit:.3g}); it moves {far} by "
                    f"{1e3 * float(np.linalg.norm(moves[far][:3])):.3g} mm and "
                    f"{'' if turned == far else turned + ' by '}"
                    f"{np.degrees(float(np.linalg.norm(moves[turned][3:]))):.2g} deg from the "
                    f"certified estimate", dist, limit)
