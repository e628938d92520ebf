"""Outlier rejection: the paper's per-edge RANSAC (Section 9.1) and a robust GNC-TLS solve.

Residuals of one pair
---------------------
For a pair ``(A_i, B_i)`` of edge ``(j, k)`` and estimates ``X_j, Y_k`` (and ``alpha``) the residual
of ``A_i X_j = Y_k B_i`` (eq. (7)) has a translation part and a rotation part::

    r_t = alpha (R_A t_X + t_A - t_Y) - R_Y t_B        (metres; alpha = 1 for known scale)
    r_R = R_A R_X - R_Y R_B,   angle = |log((R_A R_X)^T R_Y R_B)|

``|r_t|`` equals the translation distance between ``X_j`` and ``A_i^-1 Y_k B_i`` of eq. (70) and the
angle the rotation distance between them, so scoring "A X = Y B" and scoring eq. (70) is the same.
The normalised residual is the summand of eq. (33), ``J_i = |r_t|^2 / sigma_i^2 +
kappa_i |r_R|_F^2`` (:func:`pair_residuals`; ``direct_cost = 1/2 sum J_i``).

RANSAC (:func:`ransac_filter`)
------------------------------
The paper knew ``Y_k`` from Kalibr and hypothesised ``X_j`` from one pair with eq. (70). We do not
know ``Y_k``, so each edge is first treated as its own 1X1Y problem (*stage 1*):

* minimal sample: 3 pairs whose relative A rotations ``R_A1^T R_A2`` and ``R_A1^T R_A3`` span two
  axes (second singular value of their stacked rotation vectors ``>= min_axis_span_deg``);
  ``(X, Y)`` solved in closed form (null vector of the stacked linear rotation equations
  ``(I (x) R_A) vec R_X - (R_B^T (x) I) vec R_Y = 0``, projected onto SO(3), then linear least
  squares for ``R_A t_X - t_Y = R_Y t_B - t_A``);
* a pair is an inlier iff its translation residual is ``<= translation_threshold`` (0.6 m) AND its
  rotation residual ``<= rotation_threshold_deg`` (60 deg), the paper's values;
* the best hypothesis (largest consensus set, ties broken by the truncated quadratic MSAC score) is
  refitted on its consensus set (weighted by ``kappa`` and ``1/sigma^2``) and re-scored until the
  set is stable (at most ``local_refinements`` rounds); the refined model's consensus set is the
  one reported. A minimal sample from noisy pairs can be off by decimetres, which lets an outlier
  with a 1 m error slip under the 0.6 m threshold; the refit removes that bias;
* the number of hypotheses adapts to the inlier ratio ``w``:
  ``ceil(log(1 - confidence) / log(1 - w^3))``, clamped to ``[min_iterations, max_iterations]``;
  when ``C(N, 3) <= max_iterations`` the triples are enumerated (in random order) instead of drawn;
* the edge is kept iff the consensus set holds at least ``min_inlier_fraction`` (one third, paper)
  of its pairs (and at least 3).

Edges that stage 1 cannot hypothesise -- 2 pairs, or A rotations that never span two axes (e.g.
planar motion) -- go to *stage 2*, which is the paper's scheme: once a frame of the edge has been
estimated by an accepted edge (``Y_k`` preferred, as in the paper, else ``X_j``), each pair gives a
hypothesis ``X_j = A_i^-1 Y_k B_i`` (or ``Y_k = A_i X_j B_i^-1``), scored the same way; the edge is
kept iff the consensus set holds at least one third of the pairs AND at least 2 pairs (a single
pair agrees with itself and validates nothing). Stage 2 is repeated while it validates new frames.

* **Single-pair edges** are dropped, as in the paper: they cannot be validated.
* **Two-pair edges** are kept (both pairs) only if, in stage 2, the two pairs agree under eq. (70)
  with a frame known from a validated edge; if they disagree neither can be blamed and the edge is
  dropped; if no validated edge shares a frame they are dropped as unvalidated.
* **Limitation**: when no edge is identifiable on its own (e.g. every edge saw only planar
  motion) stage 1 validates nothing, stage 2 has no
  frame to start from, and every edge is dropped; use ``RobustOptions(use_ransac=False)`` (GNC
  alone) for such data.
* **Unknown scale** (monocular, Problem 3): like the paper we assume the tag size known within 10 %,
  i.e. ``|alpha - 1| <= scale_tolerance``. RANSAC runs with ``alpha = 1`` and the translation
  threshold of pair ``i`` is widened to ``translation_threshold + scale_tolerance |t_B_i|``, about
  the largest translation residual a correct pair can get from the scale error alone
  (``|(1 - 1/alpha) t_B|`` at the true frames). It can let a translation outlier of
  ``~ translation_threshold + scale_tolerance |t_B|`` through; GNC then still has it.

GNC-TLS robust solve (:func:`robust_solve`)
-------------------------------------------
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

Finally the weights are binarised (``w > 0.5``) and the inlier problem is solved once more with
the certifiable solver (``SolveOptions(mode="fast")`` by default): that certified result is
returned. Frames all of whose pairs are rejected disappear from the result (listed in ``notes``).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from itertools import combinations

import numpy as np
from scipy.stats import chi2

from .lie import make_transform, project_to_so3, so3_log, unvec
from .problem import Edge, Problem
from .result import CalibrationResult
from .solve import SolveOptions, solve

__all__ = [
    "RansacOptions",
    "EdgeRansacReport",
    "RansacReport",
    "ransac_filter",
    "PairResiduals",
    "pair_residuals",
    "tls_threshold",
    "gnc_tls_weights",
    "GncOptions",
    "RobustOptions",
    "RobustResult",
    "robust_solve",
]

#: Size of the minimal sample of the 1X1Y model (stage 1).
MINIMAL_SAMPLE = 3


# ------------------------------------------------------------------------------------------------
# Options and reports
# ------------------------------------------------------------------------------------------------
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
        _check_positive("translation_threshold", self.translation_threshold)
        _check_positive("rotation_threshold_deg", self.rotation_threshold_deg)
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
class EdgeRansacReport:
    """RANSAC outcome of one edge.

    Attributes
    ----------
    edge : str
        Edge name ``"(x, y)"``.
    n_pairs : int
    kept : ndarray of int
        Indices (into the edge's pairs) of the inliers; empty when the edge is dropped.
    rejected : list of (int, str)
        Every other pair with the reason, e.g. ``"translation residual 0.83 m > 0.6 m"``.
    dropped : bool
        The whole edge was dropped.
    reason : str
        Why the edge was dropped, or how it was validated.
    model : str
        ``"1X1Y"`` (stage 1), ``"eq. (70) given Y"`` / ``"eq. (70) given X"`` (stage 2) or
        ``"none"``.
    iterations : int
        Hypotheses scored.
    X, Y : ndarray (4, 4) or None
        The refitted hypothesis (``T_<tag carrier>_tag``, ``T_<camera carrier>_cam``).
    translation_residual : ndarray (N,) or None
        Residuals of every pair at that hypothesis [m] (with ``alpha = 1``).
    rotation_residual_deg : ndarray (N,) or None
        [deg].
    """

    edge: str
    n_pairs: int
    kept: np.ndarray
    rejected: list[tuple[int, str]]
    dropped: bool
    reason: str
    model: str = "none"
    iterations: int = 0
    X: np.ndarray | None = None
    Y: np.ndarray | None = None
    translation_residual: np.ndarray | None = None
    rotation_residual_deg: np.ndarray | None = None

    @property
    def inliers(self) -> np.ndarray:
        """Boolean mask (N,) of the kept pairs."""
        mask = np.zeros(self.n_pairs, dtype=bool)
        mask[self.kept] = True
        return mask


@dataclass
class RansacReport:
    """Outcome of :func:`ransac_filter` for every edge of a problem.

    Attributes
    ----------
    edges : dict of str to EdgeRansacReport
        Keyed by edge name, in the problem's edge order.
    options : RansacOptions
    unknown_scale : bool
    """

    edges: dict[str, EdgeRansacReport]
    options: RansacOptions
    unknown_scale: bool = False

    @property
    def inliers(self) -> dict[str, np.ndarray]:
        """Edge name -> boolean mask (N,) of kept pairs."""
        return {name: rep.inliers for name, rep in self.edges.items()}

    @property
    def rejected(self) -> list[tuple[str, int, str]]:
        """Every rejected pair as ``(edge, index, reason)``."""
        return [(name, i, why) for name, rep in self.edges.items() for i, why in rep.rejected]

    @property
    def dropped(self) -> list[tuple[str, str]]:
        """Every dropped edge as ``(edge, reason)``."""
        return [(name, rep.reason) for name, rep in self.edges.items() if rep.dropped]

    @property
    def n_kept(self) -> int:
        return int(sum(rep.kept.size for rep in self.edges.values()))

    @property
    def n_rejected(self) -> int:
        return int(sum(len(rep.rejected) for rep in self.edges.values()))

    def filtered(self, problem: Problem) -> Problem:
        """The problem restricted to the kept pairs (dropped edges and orphaned frames removed).

        Raises ``ValueError`` when ``problem`` does not match the report or nothing is kept.
        """
        return _restrict(problem, self.inliers, what="ransac")

    def summary(self) -> str:
        """One line per edge: kept/total, model, reason."""
        lines = []
        for name, rep in self.edges.items():
            lines.append(
                f"{name}: kept {rep.kept.size}/{rep.n_pairs} ({rep.model}, "
                f"{rep.iterations} hypotheses) - {rep.reason}"
            )
        return "\n".join(lines)


@dataclass
class PairResiduals:
    """Residuals of every pair of one edge at given ``X_j, Y_k, alpha``.

    Attributes
    ----------
    translation : ndarray (N,)
        ``|alpha (R_A t_X + t_A - t_Y) - R_Y t_B|`` [m].
    rotation : ndarray (N,)
        Geodesic angle between ``R_A R_X`` and ``R_Y R_B`` [rad].
    normalised : ndarray (N,)
        ``J_i`` of eq. (33): ``|r_t|^2 / sigma_i^2 + kappa_i |R_A R_X - R_Y R_B|_F^2``.
    """

    translation: np.ndarray
    rotation: np.ndarray
    normalised: np.ndarray


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
            _check_positive("threshold", self.threshold)
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


@dataclass
class RobustResult:
    """Outcome of :func:`robust_solve`.

    Attributes
    ----------
    result : CalibrationResult
        Solution of the inlier problem, certified by the final solve (check ``result.certified``).
    inliers : dict of str to ndarray of bool
        Edge name -> mask (N,) over the ORIGINAL pairs of that edge (all edges of the input).
    rejected : list of (str, int, str)
        ``(edge, index, reason)`` for every rejected pair (RANSAC and GNC), original indices.
    iterations : int
        Weighted solves of the GNC loop.
    ransac : RansacReport or None
    threshold : float
        ``c^2`` used for the truncation.
    converged : bool
        GNC reached a binary fixed point before ``max_iterations``.
    weights : dict of str to ndarray
        Final GNC weights over the original pairs (0 for pairs RANSAC rejected).
    residuals : dict of str to ndarray
        ``J_i`` of every original pair at the final estimate (``nan`` if a frame of the edge was
        not estimated).
    inlier_problem : Problem
        The problem that ``result`` solves.
    """

    result: CalibrationResult
    inliers: dict[str, np.ndarray]
    rejected: list[tuple[str, int, str]]
    iterations: int
    ransac: RansacReport | None
    threshold: float
    converged: bool
    weights: dict[str, np.ndarray]
    residuals: dict[str, np.ndarray]
    inlier_problem: Problem

    @property
    def n_inliers(self) -> int:
        return int(sum(int(m.sum()) for m in self.inliers.values()))

    @property
    def n_rejected(self) -> int:
        return len(self.rejected)


def _check_positive(name: str, value: float) -> None:
    if not (np.isfinite(value) and value > 0.0):
        raise ValueError(f"{name}: expected a finite value > 0, got {value!r}")


# ------------------------------------------------------------------------------------------------
# Residuals and the two closed-form fits
# ------------------------------------------------------------------------------------------------
def _score(
    A: np.ndarray, B: np.ndarray, X: np.ndarray, Y: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Residuals of ``A_i X = Y B_i`` (alpha = 1) of N pairs under H hypotheses.

    ``A, B`` (N, 4, 4), ``X, Y`` (H, 4, 4). Returns translation [m] and rotation [rad] residuals,
    each (H, N). The angle comes from the trace (accurate to ~1e-8 rad, ample for thresholds).
    """
    RA, tA = A[:, :3, :3], A[:, :3, 3]
    RB, tB = B[:, :3, :3], B[:, :3, 3]
    RX, tX = X[:, :3, :3], X[:, :3, 3]
    RY, tY = Y[:, :3, :3], Y[:, :3, 3]
    RARX = np.einsum("nij,hjk->hnik", RA, RX)
    RYRB = np.einsum("hij,njk->hnik", RY, RB)
    cos = 0.5 * (np.einsum("hnij,hnij->hn", RARX, RYRB) - 1.0)
    rot = np.arccos(np.clip(cos, -1.0, 1.0))
    rt = (
        np.einsum("nij,hj->hni", RA, tX)
        + tA[None]
        - tY[:, None]
        - np.einsum("hij,nj->hni", RY, tB)
    )
    return np.linalg.norm(rt, axis=-1), rot


def _fit_1x1y(
    A: np.ndarray, B: np.ndarray, kappa: np.ndarray | None = None, sigma: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form ``(X, Y)`` of the 1X1Y problem for H samples of k pairs each.

    ``A, B`` (H, k, 4, 4); optional weights ``kappa, sigma`` (H, k). Rotations: null vector of
    the stacked ``[(I (x) R_A), -(R_B^T (x) I)] [vec R_X; vec R_Y] = 0`` (rows scaled by
    ``sqrt(kappa)``), scaled to a mean unit cube-root determinant and projected onto SO(3);
    translations: least squares of ``R_A t_X - t_Y = R_Y t_B - t_A`` (rows scaled by
    ``1/sigma``). Returns ``X, Y`` (H, 4, 4).
    """
    H, k = A.shape[:2]
    RA, tA = A[..., :3, :3], A[..., :3, 3]
    RB, tB = B[..., :3, :3], B[..., :3, 3]
    I3 = np.eye(3)
    C = np.empty((H, k, 9, 18))
    C[..., :9] = np.einsum("ab,hnij->hnaibj", I3, RA).reshape(H, k, 9, 9)
    C[..., 9:] = -np.einsum("hnba,ij->hnaibj", RB, I3).reshape(H, k, 9, 9)
    if kappa is not None:
        C *= np.sqrt(kappa)[..., None, None]
    _, _, Vt = np.linalg.svd(C.reshape(H, 9 * k, 18), full_matrices=False)
    blocks = unvec(Vt[:, -1, :].reshape(H, 2, 9))
    eta = np.mean(np.cbrt(np.linalg.det(blocks)), axis=1)
    eta = np.where(np.abs(eta) < 1e-300, 1.0, eta)
    R = project_to_so3(blocks / eta[:, None, None, None])
    RX, RY = R[:, 0], R[:, 1]
    L = np.empty((H, k, 3, 6))
    L[..., :3] = RA
    L[..., 3:] = -I3
    rhs = np.einsum("hij,hnj->hni", RY, tB) - tA
    if sigma is not None:
        L = L / sigma[..., None, None]
        rhs = rhs / sigma[..., None]
    t = np.einsum(
        "hij,hj->hi", np.linalg.pinv(L.reshape(H, 3 * k, 6)), rhs.reshape(H, 3 * k)
    )
    return make_transform(RX, t[:, :3]), make_transform(RY, t[:, 3:])


def _x_from_y(A: np.ndarray, B: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """Eq. (70): ``X = A_i^-1 Y B_i`` for every pair, (N, 4, 4)."""
    RA, tA = A[:, :3, :3], A[:, :3, 3]
    RAt = np.swapaxes(RA, 1, 2)
    Tyb = Y[None] @ B
    R = RAt @ Tyb[:, :3, :3]
    t = np.einsum("nij,nj->ni", RAt, Tyb[:, :3, 3] - tA)
    return make_transform(R, t)


def _y_from_x(A: np.ndarray, B: np.ndarray, X: np.ndarray) -> np.ndarray:
    """``Y = A_i X B_i^-1`` for every pair, (N, 4, 4)."""
    RB, tB = B[:, :3, :3], B[:, :3, 3]
    Tax = A @ X[None]
    R = Tax[:, :3, :3] @ np.swapaxes(RB, 1, 2)
    t = Tax[:, :3, 3] - np.einsum("nij,nj->ni", R, tB)
    return make_transform(R, t)


def _refit_given(edge: Edge, idx: np.ndarray, known: str, T_known: np.ndarray) -> np.ndarray:
    """Weighted chordal mean of the one-pair hypotheses of ``idx`` (the unknown frame)."""
    A, B = edge.A[idx], edge.B[idx]
    hyp = _x_from_y(A, B, T_known) if known == "Y" else _y_from_x(A, B, T_known)
    kap, wt = edge.kappa[idx], 1.0 / edge.sigma[idx] ** 2
    R = project_to_so3(np.einsum("n,nij->ij", kap, hyp[:, :3, :3]))
    # Translation: minimise sum_i wt_i |R_A t_X - (..)|^2 == weighted mean of the per-pair t_X
    # (R_A is orthonormal) for X; for Y the residual is t_Y - (R_A t_X + t_A - R_Y t_B).
    if known == "Y":
        t = np.einsum("n,ni->i", wt, hyp[:, :3, 3]) / wt.sum()
    else:
        tY = A[:, :3, 3] + np.einsum("nij,j->ni", A[:, :3, :3], T_known[:3, 3])
        tY = tY - np.einsum("ij,nj->ni", R, B[:, :3, 3])
        t = np.einsum("n,ni->i", wt, tY) / wt.sum()
    return make_transform(R, t)


def _axis_span(RA: np.ndarray) -> np.ndarray:
    """Second singular value [rad] of the rotation vectors of ``R_A1^T R_A2``, ``R_A1^T R_A3``.

    ``RA`` (H, 3, 3, 3) -> (H,): zero when the relative rotations share an axis (or vanish).
    """
    rel = np.swapaxes(RA[:, :1], -1, -2) @ RA[:, 1:]
    phi = so3_log(rel)  # (H, 2, 3)
    return np.linalg.svd(phi, compute_uv=False)[:, 1]


def pair_residuals(
    problem: Problem, X: np.ndarray, Y: np.ndarray, alpha: float = 1.0
) -> dict[str, PairResiduals]:
    """Residuals of every pair at ``X`` (M, 4, 4), ``Y`` (P, 4, 4) (problem order) and ``alpha``.

    Returns edge name -> :class:`PairResiduals`; ``0.5 * sum(normalised)`` over all edges equals
    :func:`rwhec_ros.core.cost.direct_cost` (eq. (33)).
    """
    X = np.asarray(X, float)
    Y = np.asarray(Y, float)
    if X.shape != (problem.M, 4, 4) or Y.shape != (problem.P, 4, 4):
        raise ValueError(
            f"X, Y: expected shapes ({problem.M}, 4, 4) and ({problem.P}, 4, 4), got {X.shape} "
            f"and {Y.shape}"
        )
    out = {}
    for e, j, k in zip(problem.edges, problem.edge_x, problem.edge_y, strict=True):
        out[e.name] = _edge_residuals(e, X[j], Y[k], alpha)
    return out


def _edge_residuals(e: Edge, X: np.ndarray, Y: np.ndarray, alpha: float) -> PairResiduals:
    RA, tA = e.A[:, :3, :3], e.A[:, :3, 3]
    RB, tB = e.B[:, :3, :3], e.B[:, :3, 3]
    RX, tX = X[:3, :3], X[:3, 3]
    RY, tY = Y[:3, :3], Y[:3, 3]
    rt = alpha * (RA @ tX + tA - tY) - tB @ RY.T
    RARX = RA @ RX
    RYRB = RY @ RB
    rR = RARX - RYRB
    fro2 = (rR**2).sum(axis=(1, 2))
    # |R1 - R2|_F^2 = 4 (1 - cos theta): the half-angle form is accurate near theta = 0.
    rot = 2.0 * np.arcsin(np.clip(0.5 * np.sqrt(fro2 / 2.0), 0.0, 1.0))
    t2 = (rt**2).sum(axis=1)
    return PairResiduals(
        translation=np.sqrt(t2),
        rotation=rot,
        normalised=t2 / e.sigma**2 + e.kappa * fro2,
    )


# ------------------------------------------------------------------------------------------------
# RANSAC
# ------------------------------------------------------------------------------------------------
@dataclass
class _Consensus:
    X: np.ndarray
    Y: np.ndarray
    t_res: np.ndarray
    r_res: np.ndarray
    inliers: np.ndarray
    count: int
    score: float


def _consensus(
    t_res: np.ndarray, r_res: np.ndarray, t_thr: np.ndarray, r_thr: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inlier masks (H, N), counts (H,), MSAC scores (H,) of residuals (H, N)."""
    inl = (t_res <= t_thr) & (r_res <= r_thr)
    score = np.minimum((t_res / t_thr) ** 2, 1.0) + np.minimum((r_res / r_thr) ** 2, 1.0)
    return inl, inl.sum(axis=1), score.sum(axis=1)


def _better(count: int, score: float, best: _Consensus | None) -> bool:
    return best is None or count > best.count or (count == best.count and score < best.score)


def _required_hypotheses(n_inliers: int, n: int, opts: RansacOptions, sample: int) -> int:
    """Adaptive RANSAC count ``log(1 - p) / log(1 - w^s)`` clamped to the option bounds."""
    w = n_inliers / n
    if w >= 1.0:
        need = opts.min_iterations
    elif w <= 0.0:
        need = opts.max_iterations
    else:
        denom = math.log1p(-(w**sample))
        need = opts.max_iterations if denom == 0.0 else math.ceil(
            math.log(1.0 - opts.confidence) / denom
        )
    return int(min(opts.max_iterations, max(opts.min_iterations, need)))


def _triple_batches(
    edge: Edge, opts: RansacOptions, rng: np.random.Generator
) -> Iterator[np.ndarray]:
    """Non-degenerate 3-pair samples (b, 3) in batches; stops when none can be found."""
    n = edge.n
    RA = edge.A[:, :3, :3]
    min_span = np.deg2rad(opts.min_axis_span_deg)
    if math.comb(n, 3) <= opts.max_iterations:
        triples = np.array(list(combinations(range(n), 3)), dtype=int)
        triples = triples[rng.permutation(triples.shape[0])]
        triples = triples[_axis_span(RA[triples]) >= min_span]
        for s in range(0, triples.shape[0], opts.batch_size):
            yield triples[s : s + opts.batch_size]
        return
    max_draws = 20 * opts.max_iterations
    draws = 0
    while draws < max_draws:
        cand = rng.integers(0, n, size=(4 * opts.batch_size, 3))
        draws += cand.shape[0]
        distinct = (cand[:, 0] != cand[:, 1]) & (cand[:, 0] != cand[:, 2]) & (
            cand[:, 1] != cand[:, 2]
        )
        cand = cand[distinct]
        cand = cand[_axis_span(RA[cand]) >= min_span][: opts.batch_size]
        if cand.shape[0]:
            draws = 0  # only a long run of degenerate draws ends the search
            yield cand


def _translation_thresholds(edge: Edge, opts: RansacOptions, unknown_scale: bool) -> np.ndarray:
    thr = np.full(edge.n, opts.translation_threshold)
    if unknown_scale:
        thr = thr + opts.scale_tolerance * np.linalg.norm(edge.B[:, :3, 3], axis=1)
    return thr


def _ransac_1x1y(
    edge: Edge, opts: RansacOptions, rng: np.random.Generator, t_thr: np.ndarray
) -> tuple[_Consensus | None, int]:
    """Stage 1 on one edge; ``(None, 0)`` when no non-degenerate minimal sample exists."""
    r_thr = np.deg2rad(opts.rotation_threshold_deg)
    best: _Consensus | None = None
    done = 0
    need = opts.max_iterations
    for batch in _triple_batches(edge, opts, rng):
        batch = batch[: max(need - done, 0)]
        if batch.shape[0] == 0:
            break
        X, Y = _fit_1x1y(edge.A[batch], edge.B[batch])
        t_res, r_res = _score(edge.A, edge.B, X, Y)
        inl, counts, scores = _consensus(t_res, r_res, t_thr, r_thr)
        done += batch.shape[0]
        h = int(np.lexsort((scores, -counts))[0])
        if _better(int(counts[h]), float(scores[h]), best):
            best = _Consensus(X[h], Y[h], t_res[h], r_res[h], inl[h], int(counts[h]),
                              float(scores[h]))
            need = _required_hypotheses(best.count, edge.n, opts, MINIMAL_SAMPLE)
        if done >= need:
            break
    if best is None:
        return None, 0
    for _ in range(opts.local_refinements):
        idx = np.flatnonzero(best.inliers)
        if idx.size < MINIMAL_SAMPLE:
            break
        X, Y = _fit_1x1y(edge.A[idx][None], edge.B[idx][None], edge.kappa[idx][None],
                         edge.sigma[idx][None])
        t_res, r_res = _score(edge.A, edge.B, X, Y)
        inl, counts, scores = _consensus(t_res, r_res, t_thr, r_thr)
        stable = np.array_equal(inl[0], best.inliers)
        best = _Consensus(X[0], Y[0], t_res[0], r_res[0], inl[0], int(counts[0]),
                          float(scores[0]))
        if stable:
            break
    return best, done


def _ransac_given(
    edge: Edge, opts: RansacOptions, known: str, T_known: np.ndarray, t_thr: np.ndarray
) -> _Consensus:
    """Stage 2 (paper, eq. (70)): one hypothesis per pair for the unknown frame of the edge."""
    r_thr = np.deg2rad(opts.rotation_threshold_deg)
    A, B = edge.A, edge.B
    hyp = _x_from_y(A, B, T_known) if known == "Y" else _y_from_x(A, B, T_known)
    rep = np.repeat(T_known[None], edge.n, axis=0)
    X, Y = (hyp, rep) if known == "Y" else (rep, hyp)
    t_res, r_res = _score(A, B, X, Y)
    inl, counts, scores = _consensus(t_res, r_res, t_thr, r_thr)
    h = int(np.lexsort((scores, -counts))[0])
    best = _Consensus(X[h], Y[h], t_res[h], r_res[h], inl[h], int(counts[h]), float(scores[h]))
    for _ in range(opts.local_refinements):
        idx = np.flatnonzero(best.inliers)
        if idx.size == 0:
            break
        T = _refit_given(edge, idx, known, T_known)
        Xr, Yr = (T[None], T_known[None]) if known == "Y" else (T_known[None], T[None])
        t_res, r_res = _score(A, B, Xr, Yr)
        inl, counts, scores = _consensus(t_res, r_res, t_thr, r_thr)
        stable = np.array_equal(inl[0], best.inliers)
        best = _Consensus(Xr[0], Yr[0], t_res[0], r_res[0], inl[0], int(counts[0]),
                          float(scores[0]))
        if stable or best.count == 0:
            break
    return best


def _pair_reason(t: float, t_thr: float, r: float, opts: RansacOptions) -> str:
    parts = []
    if t > t_thr:
        parts.append(f"translation residual {t:.3g} m > {t_thr:.3g} m")
    if np.rad2deg(r) > opts.rotation_threshold_deg:
        parts.append(
            f"rotation residual {np.rad2deg(r):.3g}° > {opts.rotation_threshold_deg:.3g}°"
        )
    return "; ".join(parts) or "outside the consensus set"


def _accepted_report(
    edge: Edge, best: _Consensus, t_thr: np.ndarray, opts: RansacOptions, model: str,
    iterations: int, how: str,
) -> EdgeRansacReport:
    kept = np.flatnonzero(best.inliers)
    rejected = [
        (int(i), _pair_reason(float(best.t_res[i]), float(t_thr[i]), float(best.r_res[i]), opts))
        for i in np.flatnonzero(~best.inliers)
    ]
    return EdgeRansacReport(
        edge=edge.name, n_pairs=edge.n, kept=kept, rejected=rejected, dropped=False,
        reason=f"{how}: consensus {best.count} of {edge.n} pairs", model=model,
        iterations=iterations, X=best.X, Y=best.Y, translation_residual=best.t_res,
        rotation_residual_deg=np.rad2deg(best.r_res),
    )


def _dropped_report(
    edge: Edge, reason: str, model: str = "none", iterations: int = 0,
    best: _Consensus | None = None,
) -> EdgeRansacReport:
    return EdgeRansacReport(
        edge=edge.name, n_pairs=edge.n, kept=np.zeros(0, dtype=int),
        rejected=[(i, f"edge dropped: {reason}") for i in range(edge.n)], dropped=True,
        reason=reason, model=model, iterations=iterations,
        X=None if best is None else best.X, Y=None if best is None else best.Y,
        translation_residual=None if best is None else best.t_res,
        rotation_residual_deg=None if best is None else np.rad2deg(best.r_res),
    )


def _min_consensus(n: int, opts: RansacOptions, floor: int) -> int:
    return max(floor, math.ceil(opts.min_inlier_fraction * n - 1e-9))


def ransac_filter(
    problem: Problem, options: RansacOptions | None = None, *, rng: np.random.Generator
) -> RansacReport:
    """Per-edge RANSAC on the model of eq. (70) (paper Section 9.1); see the module docstring.

    Parameters
    ----------
    problem : Problem
    options : RansacOptions, optional
    rng : numpy.random.Generator
        The only source of randomness (sample order / draws).

    Returns
    -------
    RansacReport
        Kept pair indices, every rejected pair with its reason and every dropped edge with why;
        :meth:`RansacReport.filtered` gives the cleaned problem.
    """
    opts = options or RansacOptions()
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng: expected a numpy.random.Generator, got {type(rng).__name__}")
    reports: dict[str, EdgeRansacReport] = {}
    # frame name -> (estimate, support) from accepted edges, for stage 2
    known: dict[str, tuple[np.ndarray, int]] = {}
    pending: dict[str, str] = {}  # edge name -> why stage 1 could not hypothesise
    thresholds = {e.name: _translation_thresholds(e, opts, problem.unknown_scale)
                  for e in problem.edges}

    def remember(name: str, T: np.ndarray, support: int) -> None:
        if name not in known or known[name][1] < support:
            known[name] = (T, support)

    for e in problem.edges:
        if e.n == 1:
            reports[e.name] = _dropped_report(
                e, "single pair: cannot be validated (paper Section 9.1)")
            continue
        if e.n == 2:
            pending[e.name] = "2 pairs (the 1X1Y model needs 3)"
            continue
        best, iters = _ransac_1x1y(e, opts, rng, thresholds[e.name])
        if best is None:
            pending[e.name] = (f"degenerate: no 3 pairs whose relative A rotations span two axes "
                               f"by >= {opts.min_axis_span_deg:g}°")
            continue
        need = _min_consensus(e.n, opts, MINIMAL_SAMPLE)
        if best.count < need:
            reports[e.name] = _dropped_report(
                e, f"largest consensus set {best.count} of {e.n} pairs < {need} "
                   f"(min_inlier_fraction {opts.min_inlier_fraction:.3g})", "1X1Y", iters, best)
            continue
        reports[e.name] = _accepted_report(e, best, thresholds[e.name], opts, "1X1Y", iters,
                                           "1X1Y RANSAC")
        remember(e.x, best.X, best.count)
        remember(e.y, best.Y, best.count)

    by_name = {e.name: e for e in problem.edges}
    progress = True
    while pending and progress:
        progress = False
        for name in list(pending):
            e = by_name[name]
            if e.y in known:
                side, T = "Y", known[e.y][0]
            elif e.x in known:
                side, T = "X", known[e.x][0]
            else:
                continue
            why = pending.pop(name)
            progress = True
            best = _ransac_given(e, opts, side, T, thresholds[name])
            model = f"eq. (70) given {side}"
            need = _min_consensus(e.n, opts, 2)
            if best.count < need:
                reason = (f"{why}; {model}: largest consensus set {best.count} of {e.n} pairs "
                          f"< {need}")
                if e.n == 2:
                    reason += " (the two pairs disagree; neither can be blamed)"
                reports[name] = _dropped_report(e, reason, model, e.n, best)
                continue
            reports[name] = _accepted_report(e, best, thresholds[name], opts, model, e.n,
                                             f"{why}; validated by {model}")
            if side == "Y":
                remember(e.x, best.X, best.count)
            else:
                remember(e.y, best.Y, best.count)
    for name, why in pending.items():
        reports[name] = _dropped_report(
            by_name[name], f"{why}, and no validated edge shares a frame (eq. (70) needs one)")
    ordered = {e.name: reports[e.name] for e in problem.edges}
    return RansacReport(edges=ordered, options=opts, unknown_scale=problem.unknown_scale)


def _restrict(
    problem: Problem,
    masks: dict[str, np.ndarray],
    *,
    what: str,
    weights: dict[str, np.ndarray] | None = None,
) -> Problem:
    """Problem on the pairs selected by ``masks`` (optionally re-weighted by ``weights``)."""
    edges = []
    for e in problem.edges:
        if e.name not in masks:
            raise ValueError(f"{what}: no mask for edge {e.name}")
        m = np.asarray(masks[e.name], dtype=bool)
        if m.shape != (e.n,):
            raise ValueError(f"{what}: mask of edge {e.name} has shape {m.shape}, expected "
                             f"({e.n},)")
        if not m.any():
            continue
        sigma, kappa = e.sigma[m], e.kappa[m]
        if weights is not None:
            w = weights[e.name][m]
            sigma, kappa = sigma / np.sqrt(w), kappa * w
        edges.append(Edge.build(e.x, e.y, e.A[m], e.B[m], sigma=sigma, kappa=kappa))
    if not edges:
        raise ValueError(f"{what}: every pair of every edge was rejected")
    return problem.with_edges(edges)


# ------------------------------------------------------------------------------------------------
# GNC-TLS
# ------------------------------------------------------------------------------------------------
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
    _check_positive("c2", c2)
    _check_positive("mu", mu)
    r2 = np.asarray(r2, dtype=float)
    lo = mu / (mu + 1.0) * c2
    hi = (mu + 1.0) / mu * c2
    w = np.zeros_like(r2)
    w[r2 <= lo] = 1.0
    mid = (r2 > lo) & (r2 < hi)
    w[mid] = np.sqrt(c2 / r2[mid]) * np.sqrt(mu * (mu + 1.0)) - mu
    return np.clip(w, 0.0, 1.0)


@dataclass
class _GncOutcome:
    weights: dict[str, np.ndarray]
    frames: dict[str, np.ndarray]
    alpha: float
    iterations: int
    converged: bool
    inner_certified: int


def _initial_for(problem: Problem, frames: dict[str, np.ndarray]):
    X = np.stack([frames[n] for n in problem.x_names])
    Y = np.stack([frames[n] for n in problem.y_names])
    return X, Y


def _update_frames(frames: dict[str, np.ndarray], res: CalibrationResult) -> None:
    for name, T in zip(res.x_names, res.X, strict=True):
        frames[name] = T
    for name, T in zip(res.y_names, res.Y, strict=True):
        frames[name] = T


def _residuals_by_name(
    problem: Problem, frames: dict[str, np.ndarray], alpha: float
) -> dict[str, PairResiduals | None]:
    out: dict[str, PairResiduals | None] = {}
    for e in problem.edges:
        if e.x in frames and e.y in frames:
            out[e.name] = _edge_residuals(e, frames[e.x], frames[e.y], alpha)
        else:
            out[e.name] = None
    return out


def _gnc_tls(problem: Problem, c2: float, opts: GncOptions) -> _GncOutcome:
    """The GNC-TLS loop on ``problem``; see the module docstring."""
    weights = {e.name: np.ones(e.n) for e in problem.edges}
    frames: dict[str, np.ndarray] = {}
    alpha = 1.0
    mu: float | None = None
    certified = 0
    for it in range(1, opts.max_iterations + 1):
        masks = {name: w >= opts.weight_floor for name, w in weights.items()}
        sub = _restrict(problem, masks, what="gnc", weights=weights)
        inner = opts.inner
        if frames:
            inner = dataclasses.replace(inner, initial=_initial_for(sub, frames))
        res = solve(sub, inner)
        certified += int(res.certified)
        _update_frames(frames, res)
        alpha = res.scale if problem.unknown_scale else 1.0
        r2 = {name: r.normalised for name, r in _residuals_by_name(problem, frames, alpha).items()}
        if mu is None:
            r2_max = max(float(v.max()) for v in r2.values())
            if r2_max <= c2:
                return _GncOutcome(weights, frames, alpha, it, True, certified)
            mu = c2 / (2.0 * r2_max - c2)
        new = {name: gnc_tls_weights(r2[name], c2, mu) for name in weights}
        binary = all(np.all((w == 0.0) | (w == 1.0)) for w in new.values())
        same = all(np.array_equal(new[n], weights[n]) for n in weights)
        weights = new
        if binary and same:
            return _GncOutcome(weights, frames, alpha, it, True, certified)
        mu *= opts.mu_factor
    return _GncOutcome(weights, frames, alpha, opts.max_iterations, False, certified)


def robust_solve(
    problem: Problem,
    *,
    options: RobustOptions | None = None,
    rng: np.random.Generator | None = None,
) -> RobustResult:
    """RANSAC (optional), GNC-TLS around the certifiable solver, and a certified final solve.

    Parameters
    ----------
    problem : Problem
    options : RobustOptions, optional
    rng : numpy.random.Generator, optional
        Randomness of the RANSAC stage; ``None`` uses ``np.random.default_rng(0)`` so that the
        result is reproducible.

    Returns
    -------
    RobustResult
        ``result`` is the solution of the binarised inlier problem from
        ``solve(inliers, options.solve)`` with its certificate; ``inliers``/``rejected`` refer to
        the pairs of the input ``problem``.
    """
    options = options or RobustOptions()
    if rng is None:
        rng = np.random.default_rng(0)
    c2 = options.gnc.threshold if options.gnc.threshold is not None else tls_threshold(
        options.gnc.quantile)
    report = ransac_filter(problem, options.ransac, rng=rng) if options.use_ransac else None
    work = report.filtered(problem) if report is not None else problem
    kept_idx = {
        e.name: (report.edges[e.name].kept if report is not None else np.arange(e.n))
        for e in problem.edges
    }
    gnc = _gnc_tls(work, c2, options.gnc)
    masks = {name: w > 0.5 for name, w in gnc.weights.items()}
    inlier_problem = _restrict(work, masks, what="gnc")
    final_opts = options.solve
    if final_opts.initial is None:
        final_opts = dataclasses.replace(
            final_opts, initial=_initial_for(inlier_problem, gnc.frames))
    result = solve(inlier_problem, final_opts)

    frames = dict(gnc.frames)
    _update_frames(frames, result)
    alpha = result.scale if problem.unknown_scale else 1.0
    final_res = _residuals_by_name(problem, frames, alpha)

    inliers: dict[str, np.ndarray] = {}
    weights: dict[str, np.ndarray] = {}
    residuals: dict[str, np.ndarray] = {}
    rejected: list[tuple[str, int, str]] = []
    ransac_reasons = {(n, i): why for n, i, why in report.rejected} if report else {}
    n_gnc = 0
    disagree = 0
    for e in problem.edges:
        mask = np.zeros(e.n, dtype=bool)
        w_full = np.zeros(e.n)
        idx = kept_idx[e.name]
        if e.name in gnc.weights:
            mask[idx] = masks[e.name]
            w_full[idx] = gnc.weights[e.name]
        inliers[e.name] = mask
        weights[e.name] = w_full
        pr = final_res[e.name]
        residuals[e.name] = pr.normalised if pr is not None else np.full(e.n, np.nan)
        in_gnc = np.zeros(e.n, dtype=bool)
        in_gnc[idx] = True
        for i in range(e.n):
            if mask[i]:
                if pr is not None and pr.normalised[i] > c2:
                    disagree += 1
                continue
            if not in_gnc[i]:
                rejected.append((e.name, i, f"RANSAC: {ransac_reasons[(e.name, i)]}"))
                continue
            n_gnc += 1
            if pr is None:
                why = "GNC-TLS: weight 0 for every pair of the edge; a frame is not estimated"
            else:
                why = (f"GNC-TLS: normalised residual {pr.normalised[i]:.3g} "
                       f"{'>' if pr.normalised[i] > c2 else '<='} c^2 = {c2:.3g} (translation "
                       f"{pr.translation[i]:.3g} m, rotation {np.rad2deg(pr.rotation[i]):.3g}°)")
                if pr.normalised[i] <= c2:
                    disagree += 1
            rejected.append((e.name, i, why))

    notes = result.notes
    if report is not None:
        notes.append(f"robust_solve: RANSAC kept {report.n_kept} of {problem.n_measurements} "
                     f"pairs, dropped edges {[n for n, _ in report.dropped]}")
    notes.append(
        f"robust_solve: GNC-TLS rejected {n_gnc} pairs in {gnc.iterations} weighted solves "
        f"(c^2 = {c2:.3g}, {'converged' if gnc.converged else 'NOT converged'}; "
        f"{gnc.inner_certified} inner solves certified)"
    )
    if disagree:
        notes.append(f"robust_solve: {disagree} pairs are classified differently by the final "
                     f"estimate's residual than by the GNC weights (borderline)")
    lost = [n for n in problem.frame_names if n not in inlier_problem.frame_names]
    if lost:
        notes.append(f"robust_solve: frames without any inlier pair, not estimated: {lost}")
    return RobustResult(
        result=result, inliers=inliers, rejected=rejected, iterations=gnc.iterations,
        ransac=report, threshold=c2, converged=gnc.converged, weights=weights,
        residuals=residuals, inlier_problem=inlier_problem,
    )
