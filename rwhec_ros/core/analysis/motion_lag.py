"""Poses out of step with the images, seen in pose pairs that carry no stamps.

Pose pairs from a script, a CSV file or a pose list have no stamps and no pose stream, so the
time offsets of :mod:`rwhec_ros.core.analysis.time_offset` cannot be estimated: a pose read a
few tens of milliseconds after its image (the robot's pose queried once the image is in) then
fits no worse than noise, and with the noise estimated from the data every check passes (a rig
moving at 0.5 m/s puts every pair 15 mm off at 30 ms).

What the pairs still show: the error of a late pose is the motion over the lag, so the residuals
follow the motion. When the pairs are in the order they were taken (an edge's pairs keep their
recording order in every input path), the motion around pair ``i`` of an edge is, to first
order, half the step between its neighbours, ``xi_i = log(A_{i+1} A_{i-1}^-1) / 2`` (one-sided
at the ends): the stream's twist rate of :mod:`~rwhec_ros.core.analysis.time_offset` in units
of "one pair interval" instead of seconds. With these rates the same profile Newton step gives,
per camera, a lag ``lambda_k`` in pair intervals (``A_i(lambda) = exp(lambda xi_i^) A_i``: a
negative lag means the pose that fits the image is an earlier one, i.e. the poses were taken
after the images) with its cluster-robust std (each pair its own cluster: the rates of
neighbours share poses, not residuals). A pose lag is the stream's, so the same for every
camera: the cameras' lags are pooled (generalised least squares with their covariance) into one
``lambda`` with its std and ``z = lambda / std``.

Why this holds up without the order being known to be right: under "no lag", the residual of
pair ``i`` does not depend on its neighbours' poses (their noise is theirs), so ``lambda`` has
mean zero and the stated std whatever the rates are: pairs in random order, or taken at rest
between moves (stop-and-go: the step to the neighbours is the move, the pair itself was at rest)
give ``z`` of a standard normal. The rates only decide how much a real lag shows. Where the
spacing of the pairs varies, ``lambda`` is an average fraction of it.

How much it matters: the frames' shift when the lag is taken out, ``d theta = -H_tt^+ H_td
lambda`` (the profile's linear response), against each frame coordinate's std. A lag the data
show clearly (``|z|``) but that moves no frame by its std is reported, not a caution
(:mod:`rwhec_ros.core.verdict.lag_check`).

Measured (``benchmarks/verdict.md`` section 2, the demo rig's pairs at 5 Hz with the noise
estimated): poses 30 or 50 ms late give ``|z|`` 5.1-6.0 and move a frame by 1.7-2.3 std; good
data ``|z|`` below 2.4 in 99 of 100 runs. The paper's real data show ``z = -10.9`` (every camera
the same sign: the poses trail the images) moving a frame by about its std.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..lie import invert_transform, se3_log
from ..numerics.pinv import pinv_solve
from ..problem import Problem
from .information import frame_of_coordinate, information_matrix
from .time_offset import offset_step, offset_terms

__all__ = ["MotionLag", "neighbour_rates", "motion_lag"]


@dataclass(frozen=True)
class MotionLag:
    """The lag of the poses behind the images, in pair intervals (module docstring).

    Attributes
    ----------
    lag : float
        Pooled over the cameras, in pair intervals (negative: the poses were taken after the
        images).
    std : float
        Its standard deviation (cluster-robust, pair intervals).
    z : float
        ``lag / std``.
    cameras : dict of str to float
        Each determined camera's own ``lag / std``.
    shift_std : float
        The largest shift of a frame coordinate when the lag is taken out, in that coordinate's
        std (translation or rotation axis).
    frame : str
        The frame of that coordinate.
    """

    lag: float
    std: float
    z: float
    cameras: dict
    shift_std: float
    frame: str

    def to_dict(self) -> dict:
        return {"lag_pair_intervals": float(self.lag), "std_pair_intervals": float(self.std),
                "z": float(self.z), "cameras_z": {k: float(v) for k, v in self.cameras.items()},
                "frame_shift_std": float(self.shift_std), "frame": self.frame}


def neighbour_rates(problem: Problem) -> np.ndarray:
    """Per pair (problem order), the motion of ``A`` per pair interval from its neighbours in its
    edge, shape (N, 6) ``[rho, omega]`` with ``A_{i+1} A_{i-1}^-1 = exp(2 xi^)`` (one-sided at the
    ends; zeros in an edge of fewer than 3 pairs)."""
    out = []
    for e in problem.edges:
        xi = np.zeros((e.n, 6))
        if e.n >= 3:
            lo = np.r_[0, np.arange(e.n - 2), e.n - 2]
            hi = np.r_[1, np.arange(2, e.n), e.n - 1]
            step = e.A[hi] @ invert_transform(e.A[lo])
            xi = se3_log(step) / (hi - lo)[:, None]
        out.append(xi)
    return np.concatenate(out) if out else np.zeros((0, 6))


def motion_lag(problem: Problem, X: np.ndarray, Y: np.ndarray, alpha: float = 1.0,
               H: np.ndarray | None = None) -> MotionLag | None:
    """The pooled lag of the poses behind the images (module docstring); None when no camera's
    lag is determined (every edge below 3 pairs, no motion, or the motion confounded with the
    extrinsics).

    Parameters
    ----------
    problem : Problem
        The pairs that were solved, each edge's pairs in recording order.
    X, Y : ndarray, shape (M, 4, 4) and (P, 4, 4)
        Its solution (metric translations).
    alpha : float
        Its scale (unknown-scale problems).
    H : ndarray, shape (n, n), optional
        :func:`~rwhec_ros.core.analysis.information.information_matrix` ``.H`` at the solution
        (computed when None).
    """
    if H is None:
        H = information_matrix(problem, X, Y, alpha).H
    terms = offset_terms(problem, X, Y, alpha, neighbour_rates(problem))
    step = offset_step(terms, H, np.arange(problem.n_measurements))
    ix = np.flatnonzero(step.determined)
    if ix.size == 0:
        return None
    C = step.covariance[np.ix_(ix, ix)]
    try:
        w = np.linalg.solve(C, np.ones(ix.size))
    except np.linalg.LinAlgError:
        return None
    var = 1.0 / float(w.sum())
    if not (np.isfinite(var) and var > 0):
        return None
    lag = var * float(w @ step.step_s[ix])
    delta = np.zeros(problem.P)
    delta[ix] = lag
    shift = -pinv_solve(H, terms.H_td @ delta)
    cov_diag = np.diag(pinv_solve(H, np.eye(H.shape[0]))) * step.variance_factor
    with np.errstate(divide="ignore", invalid="ignore"):
        z_shift = np.where(cov_diag > 0, np.abs(shift) / np.sqrt(cov_diag), 0.0)
    worst = int(np.argmax(z_shift))
    return MotionLag(lag=lag, std=float(np.sqrt(var)), z=lag / float(np.sqrt(var)),
                     cameras={problem.y_names[k]: float(step.step_s[k] / step.std_s[k])
                              for k in ix},
                     shift_std=float(z_shift[worst]), frame=frame_of_coordinate(problem, worst))

