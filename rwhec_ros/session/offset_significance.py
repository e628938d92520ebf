"""Whether a camera's estimated time offset is real: the likelihood ratio of two certified solves.

The offsets' Newton steps (:mod:`rwhec_ros.session.time_offsets`) give each offset ``delta_k``
with a standard deviation from the curvature of the profile cost at the estimate; the Wald test
``|delta_k| > 3 std`` takes that cost as quadratic from the estimate down to zero. On short data a
camera seen in a few pairs has a profile cost that is flatter away from its minimum than its
curvature there says (the demo's early data, ``benchmarks/demo_early.md``: seed 2's cam1, 7 pairs
at 10 s, took Newton steps of 3.0, 2.9, 2.0, 0.8 ms toward 8.8 +- 2.8 ms, each well short of the
rest of the way; no offset is planted), and the Wald test then names an offset that the data do
not support.

The likelihood ratio asks the data directly. With the pairs re-interpolated at the estimated
offsets of every camera except ``k``, whose pairs stay at its configured stamps (``delta_k = 0``),
and the same weights, the certified solve's cost ``f_0`` against the estimate's ``f_hat``:

.. math::

    z_k = \\sqrt{\\max(0, 2 (f_0 - f_{hat}) / s_0^2)} \\cdot \\frac{std_{model,k}}{std_k},

``s0^2`` the residuals' variance factor of the offsets' step (``2 f / dof``), and the last factor
the ratio of the model-based std to the reported (cluster-robust) one: for a quadratic profile
cost ``z_k`` is exactly ``|delta_k| / std_k`` (the offsets of the other cameras held at their
estimates: their coupling through the shared targets is small). ``z_k`` below
:data:`~rwhec_ros.session.time_offset_report.SIGNIFICANT_SIGMAS` makes the offset not
significant: not applied, not named by the verdict. The test only runs for offsets the Wald test
finds significant (a planted 5 ms at 0.2 m/s is 37 std: ``z`` is as large), one solve each.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..core.model.cost import direct_cost
from ..core.problem import Edge, Problem

__all__ = ["likelihood_ratio_sigmas"]


def likelihood_ratio_sigmas(
    problem: Problem,
    reinterpolate: Callable[[np.ndarray], tuple[Problem, list[np.ndarray]]],
    dns: np.ndarray,
    masks: list[np.ndarray],
    weighted: Problem,
    result,
    step,
    cameras: list[int],
    solve_fixed: Callable[[Problem, tuple], object],
) -> dict[int, float]:
    """``z_k`` (module docstring) of each camera index in ``cameras``.

    Parameters
    ----------
    problem : Problem
        The pairs at their configured stamps (every ``delta = 0``).
    reinterpolate : callable(dns) -> (Problem, masks)
        ``problem`` re-interpolated at stamps shifted by ``dns`` (P,) [ns] per camera, with the
        per-edge masks of the pairs the stream reaches.
    dns : ndarray, shape (P,), int64
        The offsets [ns] of the last solve (``result``).
    masks : list of ndarray
        Its per-edge masks.
    weighted : Problem
        The pairs of the last solve with the weights it was solved with.
    result : CalibrationResult
        The last solve.
    step : OffsetStep
        The offsets' step at ``result`` (variance factor, model-based and reported covariance).
    cameras : list of int
        The cameras to test.
    solve_fixed : callable(problem, initial) -> CalibrationResult
        A solve that keeps the problem's weights (no noise estimate of its own).

    Returns
    -------
    dict of int to float
        Camera index -> ``z_k``; a camera is left out when the test cannot be made (a pair
        reached at one of the two stamps and not the other, edges that differ, a failed solve).
    """
    out: dict[int, float] = {}
    s0 = float(step.variance_factor)
    if not cameras or not s0 > 0:
        return out
    f_hat = direct_cost(weighted, result.X, result.Y, result.scale)
    if not np.isfinite(f_hat):
        return out
    for k in cameras:
        d0 = np.array(dns, dtype=np.int64)
        d0[k] = 0
        p0, masks0 = reinterpolate(d0)
        if ([e.name for e in p0.edges] != [e.name for e in weighted.edges]
                or any(not np.array_equal(a, b) for a, b in zip(masks0, masks, strict=True))):
            continue
        p0 = p0.with_edges([Edge._of(e.x, e.y, e.A, e.B, w.sigma, w.kappa)
                            for e, w in zip(p0.edges, weighted.edges, strict=True)])
        try:
            r0 = solve_fixed(p0, (result.X, result.Y))
        except Exception:  # noqa: BLE001 - no test: the Wald test stands alone
            continue
        if (list(r0.x_names), list(r0.y_names)) != (list(p0.x_names), list(p0.y_names)):
            continue
        f0 = direct_cost(p0, r0.X, r0.Y, r0.scale)
        ratio = np.sqrt(step.covariance_model[k, k] / step.covariance[k, k])
        out[k] = float(np.sqrt(max(0.0, 2.0 * (f0 - f_hat) / s0)) * ratio)
    return out
