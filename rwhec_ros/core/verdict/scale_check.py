"""The scale check of a known-scale problem: is ``alpha = 1`` what the data say?

With known scale the camera-tag translations (``B``) and the pose stream (``A``) must agree in
units. A wrong tag size ``s`` (PnP distances scale with ``s_configured / s_true``), a wrong focal
length (with ``f_configured / f_true``) or a pose stream in other units shows as a common factor
``alpha`` of the ``B`` translations, which the unknown-scale problem (paper Problem 3, eq. (22))
estimates. So the same data are solved with an unknown scale (mode ``fast``) and ``alpha`` is
compared with 1.

Its standard deviation comes from the information of ``alpha`` after the translations are
eliminated at the optimal rotations: with the state layout of :mod:`rwhec_ros.core.model.cost` the
cost is quadratic in ``e = [alpha t; alpha]`` with Hessian ``2 Q_ee``, so ``var(alpha) =
[(2 Q_ee)^-1]_{alpha alpha}`` (the Schur complement of the translation block, eq. (47)); directions
the data do not determine are left out (pseudo-inverse), and a scale inside such a direction is
``not determined``. The standard deviation is then rescaled by ``s_t`` (floored at
``MIN_NOISE_RATIO``), the translation noise ratio of the unknown-scale fit (:mod:`.fit`): the
a-posteriori standard deviation. A stated noise that is too small does not make the check
overconfident (``s_t > 1`` widens it), and one that is too large -- a cautious user, e.g.
``config/demo.yaml``'s 5 mm where rendered detections scatter by ~0.5 mm -- does not hide a scale
error the data clearly show (on the rendered demo rig stated at 5 mm the scale's std is 0.8 % with
``max(1, s_t)``, so a tag size 3 % off stays below ``verdict.scale_sigmas``; the a-posteriori std
is 0.07 %). A false
alarm on good data also needs the relative deviation beyond ``verdict.scale_caution`` (2 %), so the
sharper test does not flag the detector's small depth bias. A wrong focal length is only partly a
scale: it scales the depth of each tag but not its lateral position, so on the demo rig a focal
length 5 % off gives ``alpha`` ~1.01 and shows mainly in the fit (``benchmarks/verdict.md``).
Rotations are held at their optimum (their uncertainty adds little).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.cost import StateLayout, build_cost_matrix
from ..model.recentre import recentred_problem, recentring_for
from ..problem import Problem
from ..result import CalibrationResult, Status
from .fit import goodness_of_fit

__all__ = ["ScaleCheck", "check_scale", "scale_std", "MIN_NOISE_RATIO"]

#: Floor of the noise ratio that rescales the scale's standard deviation (module docstring): the
#: stated noise is taken to overstate the actual one at most tenfold.
MIN_NOISE_RATIO = 0.1


@dataclass
class ScaleCheck:
    """The unknown-scale estimate of a known-scale problem.

    Attributes
    ----------
    alpha : float
        ``B`` translations are ``alpha`` times what the pose stream implies (1: consistent).
    std : float
        Its standard deviation (``inf`` when the data do not determine it).
    noise_ratio_translation : float
        Translation noise ratio of the unknown-scale fit (how well the data fit once the scale
        is free; cf. the known-scale fit).
    status : str
        Status of the unknown-scale solve (``certified_optimal``, ...).
    message : str
        Why the check could not be made, if so.
    """

    alpha: float
    std: float
    noise_ratio_translation: float = float("nan")
    status: str = ""
    message: str = ""

    @property
    def available(self) -> bool:
        return bool(np.isfinite(self.alpha) and self.alpha > 0 and np.isfinite(self.std))

    @property
    def deviation(self) -> float:
        """``alpha - 1``."""
        return float(self.alpha - 1.0)

    @property
    def sigmas(self) -> float:
        """``|alpha - 1| / std``."""
        return abs(self.deviation) / self.std if self.std > 0 else float("inf")

    def to_dict(self) -> dict:
        return {"alpha": float(self.alpha), "std": float(self.std),
                "noise_ratio_translation": float(self.noise_ratio_translation),
                "status": self.status, "message": self.message}


def scale_std(problem: Problem, result: CalibrationResult) -> float:
    """Standard deviation of ``alpha`` of an unknown-scale ``result`` from the stated noise, at
    its rotations (module docstring); ``inf`` when the data do not determine the scale."""
    if not problem.unknown_scale:
        raise ValueError("problem: scale_std needs an unknown-scale problem")
    layout = StateLayout(problem.M, problem.P)
    idx = np.arange(layout.n_t + 1)  # alpha t, then alpha (eq. (44))
    Q = build_cost_matrix(problem).tocsr()
    E = Q[idx][:, idx].toarray()
    w, V = np.linalg.eigh(0.5 * (E + E.T))
    floor = max(float(w[-1]), 0.0) * 1e-10
    a = V[-1]  # alpha's row of the eigenvectors
    weak = w <= floor
    if np.any(np.abs(a[weak]) > 1e-6):
        return float("inf")
    var = float(np.sum(a[~weak] ** 2 / (2.0 * w[~weak])))
    return float(np.sqrt(var)) if var > 0 else 0.0


def check_scale(problem: Problem, *, mode: str = "fast") -> ScaleCheck:
    """Solve ``problem`` (known scale) again with an unknown scale and measure ``alpha``."""
    from ..solve import SolveOptions, solve

    if problem.unknown_scale:
        raise ValueError("problem: the scale check is for known-scale problems")
    rc = recentring_for(problem)
    if rc is not None:
        # far from a carrier's origin the information of alpha (from the cost matrix) loses the
        # scale to rounding, as the unknown-scale solve would without its own re-centring:
        # check it about a point near the data, where alpha, its std and the fit are the same
        # (a diagnostic: the tag carrier's shift rounds by ~u |c|, far below the noise)
        problem = recentred_problem(problem, rc)[0]
    free = problem.with_edges(problem.edges, unknown_scale=True)
    res = solve(free, SolveOptions(mode=mode))
    status = res.certificate.status
    if status is Status.SOLVER_FAILED or not (np.isfinite(res.scale) and res.scale > 0):
        return ScaleCheck(float(res.scale), float("inf"), status=status.value,
                          message=f"the unknown-scale solve gave no usable scale "
                                  f"({res.certificate.message})")
    fit = goodness_of_fit(free, res)
    s_t = fit.noise_ratio_translation
    std = scale_std(free, res) * max(MIN_NOISE_RATIO, s_t if np.isfinite(s_t) else 1.0)
    return ScaleCheck(float(res.scale), std, s_t, status.value)
