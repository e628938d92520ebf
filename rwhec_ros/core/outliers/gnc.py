"""Graduated non-convexity with a truncated least-squares cost (GNC-TLS) around the solver.

Beyond the paper (its conclusion points at truncated least squares, Yang et al. 2021):
graduated non-convexity (Yang, Antonante, Tzoumas, Carlone 2020, "Graduated Non-Convexity for
Robust Spatial Perception") with the truncated least-squares cost
``sum_i min(J_i, c^2)`` around the certifiable solver. Each iteration solves the weighted MLE
(``w_i`` multiplies ``1/sigma_i^2`` and ``kappa_i``: ``sigma_i / sqrt(w_i)``, ``kappa_i w_i``;
pairs with ``w_i < weight_floor`` are left out) warm-started at the previous estimate, then
updates the weights with the GNC-TLS rule (:func:`gnc_tls_weights`) and ``mu <- mu_factor mu``,
starting from ``mu_0 = c^2 / (2 max J_i - c^2)``. It stops when the weights are binary and
unchanged (a fixed point) or after ``max_iterations``.

Threshold: under the noise model of eq. (20) ``r_t / sigma ~ N(0, I_3)`` so ``|r_t|^2/sigma^2 ~
chi2(3)``; ``r_R = R_Y R_B (R_eps^T - I)`` with ``R_eps ~ Lang(I, kappa)``, so
``kappa |r_R|_F^2 = 4 kappa (1 - cos theta) ~= 2 kappa theta^2``, and for concentrated Langevin
noise the rotation vector is ``N(0, I / (2 kappa))``, hence ``2 kappa theta^2 ~ chi2(3)``. So
``J_i ~ chi2(6)`` for an inlier, and ``c^2`` is its ``quantile`` (0.99: 16.81), i.e. about 1 % of
correct pairs are expected to be truncated. This holds only if ``sigma, kappa`` are the true noise
levels; give ``threshold`` explicitly otherwise.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from ..problem import Problem
from ..result import CalibrationResult
from ..solve import solve
from .options import GncOptions, check_positive
from .pairs import residuals_by_name, restrict_problem

__all__ = ["tls_threshold", "gnc_tls_weights", "GncOutcome", "gnc_tls", "initial_for",
           "update_frames"]


def tls_threshold(quantile: float = 0.99, dof: int = 6) -> float:
    """``c^2``: the ``quantile`` of ``chi2(dof)``, the law of ``J_i`` of an inlier (6 dof)."""
    if not 0.0 < quantile < 1.0:
        raise ValueError(f"quantile: expected a value in (0, 1), got {quantile!r}")
    if int(dof) != dof or dof < 1:
        raise ValueError(f"dof: expected a positive integer, got {dof!r}")
    return float(chi2.ppf(quantile, dof))


def gnc_tls_weights(r2: np.ndarray, c2: float, mu: float) -> np.ndarray:
    r"""GNC-TLS weight update (Yang et al. 2020, TLS surrogate of the Black-Rangarajan duality).

    .. math::

        w_i = \begin{cases} 1 & r_i^2 \le \frac{\mu}{\mu+1} c^2 \\
        \frac{c}{r_i}\sqrt{\mu(\mu+1)} - \mu & \text{otherwise, if }
        r_i^2 \le \frac{\mu+1}{\mu} c^2 \\ 0 & \text{otherwise} \end{cases}

    ``r2`` (N,) squared (normalised) residuals, ``c2`` the squared threshold, ``mu > 0``.
    """
    check_positive("c2", c2)
    check_positive("mu", mu)
    r2 = np.asarray(r2, dtype=float)
    lo = mu / (mu + 1.0) * c2
    hi = (mu + 1.0) / mu * c2
    w = np.zeros_like(r2)
    w[r2 <= lo] = 1.0
    mid = (r2 > lo) & (r2 < hi)
    w[mid] = np.sqrt(c2 / r2[mid]) * np.sqrt(mu * (mu + 1.0)) - mu
    return np.clip(w, 0.0, 1.0)


@dataclass
class GncOutcome:
    """State at the end of :func:`gnc_tls`: weights and frames by name, scale, counts."""

    weights: dict[str, np.ndarray]
    frames: dict[str, np.ndarray]
    alpha: float
    iterations: int
    converged: bool
    inner_certified: int


def initial_for(problem: Problem, frames: dict[str, np.ndarray]):
    X = np.stack([frames[n] for n in problem.x_names])
    Y = np.stack([frames[n] for n in problem.y_names])
    return X, Y


def update_frames(frames: dict[str, np.ndarray], res: CalibrationResult) -> None:
    for name, T in zip(res.x_names, res.X, strict=True):
        frames[name] = T
    for name, T in zip(res.y_names, res.Y, strict=True):
        frames[name] = T



def gnc_tls(problem: Problem, c2: float, opts: GncOptions) -> GncOutcome:
    """The GNC-TLS loop on ``problem``; see the module docstring."""
    weights = {e.name: np.ones(e.n) for e in problem.edges}
    frames: dict[str, np.ndarray] = {}
    alpha = 1.0
    mu: float | None = None
    certified = 0
    for it in range(1, opts.max_iterations + 1):
        masks = {name: w >= opts.weight_floor for name, w in weights.items()}
        sub = restrict_problem(problem, masks, what="gnc", weights=weights)
        inner = opts.inner
        if frames:
            inner = dataclasses.replace(inner, initial=initial_for(sub, frames))
        res = solve(sub, inner)
        certified += int(res.certified)
        update_frames(frames, res)
        alpha = res.scale if problem.unknown_scale else 1.0
        r2 = {name: r.normalised for name, r in residuals_by_name(problem, frames, alpha).items()}
        if mu is None:
            r2_max = max(float(v.max()) for v in r2.values())
            if r2_max <= c2:
                return GncOutcome(weights, frames, alpha, it, True, certified)
            mu = c2 / (2.0 * r2_max - c2)
        new = {name: gnc_tls_weights(r2[name], c2, mu) for name in weights}
        binary = all(np.all((w == 0.0) | (w == 1.0)) for w in new.values())
        same = all(np.array_equal(new[n], weights[n]) for n in weights)
        weights = new
        if binary and same:
            return GncOutcome(weights, frames, alpha, it, True, certified)
        mu *= opts.mu_factor
    return GncOutcome(weights, frames, alpha, opts.max_iterations, False, certified)

