"""Certification of a candidate solution by a dual point: a bound that holds in floating point.

Weak duality (paper eq. (51), (71)): for multipliers ``lambda`` of the constraints of eq. (50)
and ``lambda_s`` of ``s^2 = 1``, every feasible ``x = [t; y]`` (``y = [vec R; s]``, rotations in
SO(3), ``s^2 = 1``) satisfies ``x^T Q x = lambda_s + x^T Z_full(lambda) x`` with
``Z_full = Q - K(lambda)``, where ``K(lambda) = lambda_s E_ss + sum_c lambda_c A_c`` touches only
the ``y`` block. With the recovery ``t = G y`` of the Schur reduction
(:func:`~rwhec_ros.core.model.reduction.reduce_cost`) and ``t = u + G y``, for ANY ``G``::

    x^T Z_full x = u^T Q_ee u + 2 u^T F y + y^T (S_G - K) y,    F = Q_ee G + Q_ey,

so, minimising over the free ``u`` (``Q_ee`` positive definite) and using ``|y|^2 = 3 n + 1``,
``|y_i| <= 1``::

    p* >= d = lambda_s + (3 n + 1) min(0, lambda_min(Z_fl)) - e_round - (3 n + 1) ||F||^2 / l_e

with ``Z_fl`` the certificate matrix as computed (the reduced ``Q'`` minus ``K``), ``e_round`` a
bound on ``y^T (S_G - K - Z_fl) y`` from the entrywise rounding bounds of the reduction, of the
scaling and of forming ``K`` (the sum of the bound matrix, or ``3 n + 1`` times its largest row
sum), ``||F||`` bounded by the backward error of the Cholesky solve and ``l_e`` a proven lower
bound on ``lambda_min(Q_ee)``. ``lambda_min(Z_fl)`` is bounded from below by a shifted Cholesky
factorisation with a backward-error margin (:mod:`rwhec_ros.core.numerics.verified`). The relative
suboptimality bound of the returned estimate with cost ``p`` (evaluated directly from the
residuals of eq. (33), never from the reduced cost) is ``rho_hat = (p - d) / max(d, floor)``
(eq. (73)).

Scope of the proof: the cost matrix ``Q`` as computed from the data in double precision (its
entries carry a relative rounding error of ~``N u``, which moves the cost by ~``N u L^2 /
sigma^2`` relative -- about 1e-7 for 300 pairs per edge at sigma = 1 mm and 2 m translations --
and cannot be amplified, because a translation block with weak directions is handled by
:mod:`rwhec_ros.core.model.gauge` before any certificate is computed).

The status is CERTIFIED_OPTIMAL only when ``rho_hat <= rho_tol`` AND the computed ``Z`` has a
one-dimensional (numerical) null space (the relaxation is tight with a unique rank-one solution).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..model.reduction import ReducedCost
from ..numerics.verified import UNIT_ROUNDOFF, gamma, smallest_eigenvalues, verified_min_eigenvalue
from ..result import Certificate, Status
from .relaxation import ConstraintSet

__all__ = ["CertificateOptions", "DualBound", "ExactReduction", "certificate_matrix",
           "rigorous_dual_bound", "certify_from_Z", "certificate_from_bound", "certify"]


@dataclass
class CertificateOptions:
    """Tolerances of the certificate (all in the units of the SCALED problem, where the data
    matrix is divided by an upper bound on the optimal cost so that the optimum is O(1)).

    Attributes
    ----------
    rho_tol : float
        Largest relative suboptimality bound ``rho_hat`` accepted as certified (1e-6: a
        millionth of the cost, three orders above the ~1e-9 solver accuracy).
    null_tol : float
        Eigenvalues of the scaled ``Z`` at or below this count towards its null space (1e-6).
    n_eigenvalues : int
        How many of the smallest eigenvalues to report (6).
    """

    rho_tol: float = 1e-6
    null_tol: float = 1e-6
    n_eigenvalues: int = 6

    def __post_init__(self) -> None:
        for name in ("rho_tol", "null_tol"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name}: must be finite and > 0, got {v!r}")
        if int(self.n_eigenvalues) < 2:
            raise ValueError(f"n_eigenvalues: must be >= 2, got {self.n_eigenvalues!r}")


@dataclass(frozen=True)
class DualBound:
    """The pieces of the rigorous dual bound (scaled units, see the module docstring).

    Attributes
    ----------
    value : float
        ``d`` in scaled units (``-inf`` when it could not be established).
    lambda_s : float
    lambda_min_lower : float
        Proven lower bound on ``lambda_min(Z_fl)``.
    eigenvalue_term, rounding_term, schur_term : float
        What each part subtracts from ``lambda_s``: ``(3 n + 1) max(0, -lambda_min_lower)``,
        ``e_round`` and ``(3 n + 1) ||F||^2 / l_e``.
    reason : str
        Why the bound is ``-inf`` (empty otherwise).
    """

    value: float
    lambda_s: float
    lambda_min_lower: float
    eigenvalue_term: float
    rounding_term: float
    schur_term: float
    reason: str = ""


@dataclass(frozen=True)
class ExactReduction:
    """Reduction bounds of a problem given directly on the reduced variables (no translations to
    eliminate, no rounding in a reduction): what :func:`certify_from_Z` needs from a
    :class:`~rwhec_ros.core.model.reduction.ReducedCost`, for matrices given as they are (tests,
    crafted
    certificates)."""

    size: int
    verified: bool = True
    block_lower: float = 1.0
    residual_norm: float = 0.0

    @property
    def err_rows(self) -> np.ndarray:
        return np.zeros(self.size)


def certificate_matrix(Qs: np.ndarray, constraints: ConstraintSet, lam: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """``Z = Q' - K(lambda)`` (symmetrised, eq. (51)) and the row sums of an entrywise bound on
    its rounding error (forming ``K = C lambda``, the subtraction, the symmetrisation).

    The bound, row ``i``: ``gamma_{t+1} sum_j (|C| |lambda|)_ij + gamma_3 sum_j (|Q'_ij| +
    |K_ij|)`` with ``t`` the largest number of constraints touching one entry (a dot product of
    ``t`` terms is accurate to ``gamma_t`` times the sum of its absolute terms; one more rounding
    for the product with ``lambda``; three for the subtraction, the sum and the halving of the
    symmetrisation)."""
    d = constraints.d
    K = constraints.apply(lam)
    K_abs = np.asarray(constraints.abs_C @ np.abs(lam)).reshape(d, d, order="F")
    terms = constraints.max_terms
    Z = np.asarray(Qs, float) - K
    Z = 0.5 * (Z + Z.T)
    err_rows = (gamma(terms + 1) * K_abs.sum(axis=1)
                + gamma(3) * (np.abs(Qs).sum(axis=1) + np.abs(K).sum(axis=1)))
    return Z, err_rows


def rigorous_dual_bound(
    Z: np.ndarray,
    z_err_rows: np.ndarray,
    lambda_s: float,
    reduced: ReducedCost | ExactReduction,
    scale: float,
    n_rotations: int,
    lambda_min_estimate: float,
) -> DualBound:
    """``d`` of the module docstring in scaled units, from the certificate matrix ``Z``
    (scaled), the row sums of its rounding bound, ``lambda_s``, the reduction (unscaled bounds)
    and the data scale."""
    ny = 3 * n_rotations + 1
    if not reduced.verified or reduced.err_rows is None:
        return DualBound(float("-inf"), lambda_s, float("nan"), float("nan"), float("nan"),
                         float("nan"), "the translation block could not be factorised")
    if not (np.isfinite(lambda_s) and np.all(np.isfinite(Z))):
        return DualBound(float("-inf"), lambda_s, float("nan"), float("nan"), float("nan"),
                         float("nan"), "non-finite multipliers")
    vb = verified_min_eigenvalue(Z, lambda_min_estimate)
    if not vb.verified:
        return DualBound(float("-inf"), lambda_s, float("-inf"), float("inf"), float("nan"),
                         float("nan"), "no shifted factorisation of Z succeeded")
    # reduction bounds are unscaled: divide (one more relative rounding, u |Q'| per entry)
    rows = (reduced.err_rows / scale) * (1.0 + gamma(2)) + UNIT_ROUNDOFF * np.abs(Z).sum(axis=1)
    rows = (rows + z_err_rows) * (1.0 + gamma(3))
    rounding = float(min(rows.sum(), ny * rows.max(initial=0.0)) * (1.0 + gamma(rows.size)))
    schur = float(ny * reduced.residual_norm**2 / (reduced.block_lower * scale))
    eig_term = float(ny * max(0.0, -vb.lower))
    value = float(lambda_s - eig_term - rounding - schur)
    return DualBound(value, float(lambda_s), float(vb.lower), eig_term, rounding, schur)


def certify_from_Z(
    Z: np.ndarray,
    lambda_s: float,
    primal_cost: float,
    scale: float,
    n_rotations: int,
    *,
    reduced: ReducedCost | ExactReduction | None = None,
    z_err_rows: np.ndarray | None = None,
    solver_ok: bool = True,
    solver_status: str = "",
    homogeneous: bool = False,
    cost_floor: float = 0.0,
    options: CertificateOptions | None = None,
) -> Certificate:
    """The certificate of a (scaled) certificate matrix ``Z`` and ``lambda_s``.

    Parameters
    ----------
    Z : ndarray, shape (9 n + 1, 9 n + 1)
        ``Z(lambda)`` on ``[vec R; s]`` of the scaled problem (symmetric).
    lambda_s : float
        Multiplier of ``s^2 = 1`` (scaled units).
    primal_cost : float
        ``p``: cost of the returned estimate (unscaled), evaluated directly (eq. (33)).
    scale : float
        Factor by which the data matrix was divided.
    n_rotations : int
        ``n = M + P``.
    reduced : ReducedCost or ExactReduction
        Error bounds of the Schur reduction (unscaled); ``ExactReduction`` when ``Z`` is exact.
    z_err_rows : ndarray, optional
        Row sums of an entrywise bound on the rounding in forming ``Z`` (zeros if omitted).
    solver_ok : bool
        Whether the numerical solver that produced ``lambda`` reported success.
    homogeneous : bool
        The objective does not involve ``s`` (unknown scale, Problem 6: ``alpha`` is eliminated
        and the last row/column of ``Q'`` is zero). Then ``(r, s)`` and ``(r, -s)`` have the same
        cost, and when ``Z`` does not couple ``s`` to the rotations (the orthogonality-only
        multipliers of the fast certificate) ``e_s`` is a trivial null vector of ``Z``; it carries
        no information about the rotations, so uniqueness is judged on the rotation block.
    cost_floor : float
        A cost regarded as zero at the scale of the data (noise-free problems have optimum 0, where
        eq. (73) is undefined): ``rho_hat = (p - d) / max(d, cost_floor)``.
    """
    opts = options or CertificateOptions()
    Z = np.asarray(Z, dtype=float)
    p = float(primal_cost)
    if reduced is None:
        reduced = ExactReduction(Z.shape[0])
    if z_err_rows is None:
        z_err_rows = np.zeros(Z.shape[0])
    if not (np.isfinite(lambda_s) and np.isfinite(p) and np.all(np.isfinite(Z))):
        return Certificate(Status.SOLVER_FAILED, p, float("nan"), float("nan"), float("nan"),
                           np.zeros(0), -1, opts.rho_tol,
                           f"solver status '{solver_status}': no finite dual point")
    w = smallest_eigenvalues(Z, opts.n_eigenvalues)
    null_dim = int(np.sum(w <= opts.null_tol))
    trivial_s = False
    if homogeneous and np.linalg.norm(Z[:-1, -1]) <= opts.null_tol and \
            abs(Z[-1, -1]) <= opts.null_tol:
        w_r = smallest_eigenvalues(Z[:-1, :-1], opts.n_eigenvalues)
        null_dim = int(np.sum(w_r <= opts.null_tol))
        trivial_s = True
    bound = rigorous_dual_bound(Z, z_err_rows, float(lambda_s), reduced, scale, n_rotations,
                                float(w[0]))
    return certificate_from_bound(bound, w, null_dim, trivial_s, p, scale, solver_ok=solver_ok,
                                  solver_status=solver_status, cost_floor=cost_floor, options=opts)


def certificate_from_bound(
    bound: DualBound,
    w: np.ndarray,
    null_dim: int,
    trivial_s: bool,
    primal_cost: float,
    scale: float,
    *,
    solver_ok: bool = True,
    solver_status: str = "",
    cost_floor: float = 0.0,
    options: CertificateOptions | None = None,
) -> Certificate:
    """The status decision of a certificate from its rigorous dual bound (scaled units), the
    smallest eigenvalues ``w`` of the certificate matrix (an estimate; ascending), the dimension
    of its numerical null space and whether the trivial ``e_s`` null vector of a homogeneous
    problem was set aside (see :func:`certify_from_Z`). Shared by the dense certificate and the
    sparse one of :mod:`rwhec_ros.core.certify.sparse`."""
    opts = options or CertificateOptions()
    p = float(primal_cost)
    d = float(bound.value * scale)
    denom = max(d, cost_floor)
    rho = (p - d) / denom if np.isfinite(d) and denom > 0 else float("nan")
    eigs = np.asarray(w, dtype=float).copy()
    margins = {"eigenvalue": bound.eigenvalue_term * scale, "rounding": bound.rounding_term * scale,
               "schur": bound.schur_term * scale}
    if not solver_ok:
        status = Status.SOLVER_INACCURATE
        msg = (f"solver status '{solver_status}': the dual point is not reliable "
               f"(rho_hat={rho:.3g}, lambda_min={eigs[0]:.3g})")
    elif not np.isfinite(d):
        status = Status.ILL_CONDITIONED
        msg = f"not certified: no rigorous dual bound ({bound.reason})"
    elif rho <= opts.rho_tol and null_dim == 1:
        status = Status.CERTIFIED_OPTIMAL
        msg = (f"certified globally optimal: rho_hat={rho:.3g} <= {opts.rho_tol:g}, Z has a "
               f"one-dimensional null space (eigenvalues {eigs[0]:.2g}, {eigs[1]:.2g}, ...)")
        if trivial_s:
            msg += " on the rotation block (the sign of s is free for unknown scale)"
    else:
        status = Status.NOT_TIGHT
        why = []
        if not rho <= opts.rho_tol:
            why.append(f"rho_hat={rho:.3g} > {opts.rho_tol:g}")
        if null_dim != 1:
            why.append(f"Z has {null_dim} eigenvalues <= {opts.null_tol:g} "
                       f"(smallest {np.array2string(eigs, precision=3)})")
        msg = "not certified: " + "; ".join(why)
    cert = Certificate(
        status=status,
        primal_cost=p,
        dual_bound=d,
        suboptimality_bound=float(rho),
        lambda_min=float(eigs[0]),
        eigenvalues=eigs,
        null_space_dim=null_dim,
        tolerance=opts.rho_tol,
        message=msg,
        lambda_min_lower=float(bound.lambda_min_lower),
        margins=margins,
        cost_floor=float(cost_floor),
    )
    if cert.rounding_decides:
        rounding = margins["rounding"] + margins["schur"]
        cert.message += (f"; the bound's rounding terms alone ({rounding:.2g}) exceed the gap "
                         f"rho_hat <= {opts.rho_tol:g} allows ({opts.rho_tol * denom:.2g}): the "
                         "coordinates are large for the size of the residuals (e.g. a world "
                         "frame far from the data); poses expressed about a nearby origin may "
                         "be certified")
    return cert


def certify(
    reduced: ReducedCost,
    scale: float,
    Qs: np.ndarray,
    constraints: ConstraintSet,
    lam: np.ndarray,
    primal_cost: float,
    *,
    solver_ok: bool = True,
    solver_status: str = "",
    homogeneous: bool = False,
    cost_floor: float = 0.0,
    options: CertificateOptions | None = None,
) -> Certificate:
    """Build a :class:`Certificate` for a dual point ``lam`` and an estimate of cost
    ``primal_cost``: :func:`certificate_matrix` then :func:`certify_from_Z`.

    Parameters
    ----------
    reduced : ReducedCost
        The reduction the solve used (unscaled), with its error bounds.
    scale : float
        Factor by which the data matrix was divided.
    Qs : ndarray, shape (9 n + 1, 9 n + 1)
        The scaled reduced cost ``reduced.Qr / scale`` as used by the solvers.
    constraints : ConstraintSet
        The constraints of eq. (50) on ``[vec R; s]`` (:func:`~rwhec_ros.core.certify.relaxation.
        so3_constraint_matrices`).
    lam : ndarray, shape (constraints.m,)
        Multipliers in scaled units, ``lam[-1] = lambda_s``.
    primal_cost : float
        ``p``: cost of the returned estimate (unscaled), evaluated directly (eq. (33)).
    solver_ok, solver_status, homogeneous, cost_floor, options
        As for :func:`certify_from_Z`.
    """
    opts = options or CertificateOptions()
    lam = np.asarray(lam, dtype=float)
    if not np.all(np.isfinite(lam)):
        return Certificate(Status.SOLVER_FAILED, float(primal_cost), float("nan"), float("nan"),
                           float("nan"), np.zeros(0), -1, opts.rho_tol,
                           f"solver status '{solver_status}': no finite dual point")
    Z, z_err = certificate_matrix(Qs, constraints, lam)
    return certify_from_Z(Z, float(lam[-1]), primal_cost, scale, constraints.n_rotations,
                          reduced=reduced, z_err_rows=z_err, solver_ok=solver_ok,
                          solver_status=solver_status, homogeneous=homogeneous,
                          cost_floor=cost_floor, options=opts)
