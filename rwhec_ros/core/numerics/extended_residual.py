"""A proven entrywise bound on the residual of a linear solve, evaluated in extended precision.

The Schur reduction of :func:`~rwhec_ros.core.model.reduction.reduce_cost` (eqs. (47)-(48)) recovers
the translations with ``G = -Q_ee^{-1} Q_ey`` from a Cholesky solve, and the certificate needs a
bound on the residual ``F = Q_ee G + Q_ey`` of that ``G``: the reduced matrix differs from the exact
one for this ``G`` by ``G^T F`` (:class:`~rwhec_ros.core.model.reduction.ReducedCost`). The a-priori
bound, the backward error of the solve ``|F| <= gamma_{3m+1} |R^T| |R| |G|`` (Higham, *Accuracy and
Stability of Numerical Algorithms*, Thm. 10.4), is a worst case: the actual residual is usually
hundreds of times smaller. Where the cost matrix has entries far larger than the optimal cost
(precise measurements, many pairs), that worst case alone can exceed the certificate's
tolerance and a certifiable estimate goes uncertified.

:func:`residual_bound` computes ``F`` instead, in numpy's ``longdouble`` where that is IEEE
extended (64-bit significand, x86) or quadruple precision (113 bits), else in double, with the
standard bound of a computed matrix product and sum (Higham eq. (3.13)): with ``u'`` the unit
roundoff of the precision used and ``m`` the inner dimension,

    |fl(F) - F| <= gamma'_{m+1} (|Q_ee| |G| + |Q_ey|),

so ``|F| <= |fl(F)| + gamma'_{m+1} (|Q_ee| |G| + |Q_ey|)`` entrywise. The right-hand side is
itself evaluated in that precision (sums of ``m + 1`` non-negative terms, then a product and a
sum), inflated by ``1 + 2 gamma'_{m+3}`` (which covers those roundings to second order), and
rounded up to double. The inputs are
converted to ``longdouble`` exactly (every double is representable).
"""

from __future__ import annotations

import numpy as np

__all__ = ["extended_dtype", "residual_bound"]


def extended_dtype() -> tuple[type, float]:
    """``(dtype, unit roundoff)`` of the most precise IEEE float numpy has here: ``longdouble``
    when its significand has 64 (x86 extended) or 113 (quadruple) bits, else ``float64``
    (e.g. where ``longdouble`` is double, or the non-IEEE double-double of POWER)."""
    info = np.finfo(np.longdouble)
    if int(info.nmant) in (63, 112):
        return np.longdouble, float(info.eps) / 2.0
    return np.float64, float(np.finfo(np.float64).eps) / 2.0


def _gamma(k: int, u: float) -> float:
    ku = k * u
    return float("inf") if ku >= 1.0 else ku / (1.0 - ku)


def residual_bound(Qee: np.ndarray, G: np.ndarray, Qey: np.ndarray) -> np.ndarray:
    """Entrywise upper bound on ``|Q_ee G + Q_ey|`` (module docstring), in double.

    Parameters
    ----------
    Qee : ndarray, shape (m, m)
        The eliminated block (as used by the solve).
    G : ndarray, shape (m, k)
        The recovery actually used (any matrix: the bound holds for it).
    Qey : ndarray or sparse matrix, shape (m, k)
        The coupling block.

    Returns
    -------
    ndarray, shape (m, k)
        ``B >= |Q_ee G + Q_ey|`` entrywise, exactly (every rounding accounted for);
        ``inf`` entries where the inputs are not finite.
    """
    dtype, u = extended_dtype()
    Qey = Qey.toarray() if hasattr(Qey, "toarray") else np.asarray(Qey, dtype=float)
    A = np.asarray(Qee, dtype=float).astype(dtype)
    X = np.asarray(G, dtype=float).astype(dtype)
    C = Qey.astype(dtype)
    m = A.shape[1]
    # einsum: ~3x faster than matmul for longdouble (no BLAS either way); a dot product of m
    # terms in any order, so the bound below holds
    F = np.einsum("ij,jk->ik", A, X) + C
    magnitude = np.einsum("ij,jk->ik", np.abs(A), np.abs(X)) + np.abs(C)
    # the inflation factor in the working precision: in double, 1 + 2 gamma'_{m+3} would round
    # to exactly 1 for an extended u' (found by the retry's soundness study)
    inflate = dtype(1) + dtype(2.0 * _gamma(m + 3, u))
    bound = (np.abs(F) + dtype(_gamma(m + 1, u)) * magnitude) * inflate
    out = bound.astype(np.float64)
    # rounding to double is to nearest: step every entry up by one ulp to stay above
    out = np.nextafter(out, np.inf)
    out[~np.isfinite(out)] = np.inf
    return out
