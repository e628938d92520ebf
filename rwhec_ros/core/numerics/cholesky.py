"""Cholesky factorisation and solves through LAPACK directly (``dpotrf``, ``dpotrs``).

``scipy.linalg.cholesky``, ``cho_factor`` and ``cho_solve`` (with ``check_finite=False``) end in
exactly these LAPACK calls with exactly these arguments, so the factors and solutions are the
same bit for bit (the same routine on the same input in the same memory layout: f2py copies a
C-ordered input to Fortran order either way). What the wrappers add -- the batching decorator,
the array-API conversions, the dtype look-up of ``get_lapack_funcs`` and the shape checks --
costs 10-20 microseconds per call, a tenth of the live re-solve's 72 x 72 factorisation and
most of each of its one-column solves (the live re-solve makes about ten such calls). The
callers here pass float64 matrices of the right shapes, which the wrappers would only check.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack

__all__ = ["upper_cholesky", "upper_cholesky_solve"]


def upper_cholesky(A: np.ndarray, *, clean: bool = True, overwrite: bool = False
                   ) -> np.ndarray | None:
    """The upper Cholesky factor ``R`` (``R^T R = A``) of the symmetric float64 ``A`` (n, n)
    (upper triangle used), or ``None`` when the factorisation breaks down (``A`` not positive
    definite as computed).

    ``clean=True`` zeroes the strictly lower triangle (``scipy.linalg.cholesky``); ``False``
    leaves ``A``'s entries there (``scipy.linalg.cho_factor``; :func:`upper_cholesky_solve`
    reads the upper triangle only). ``overwrite=True`` lets LAPACK factor ``A`` in place when it
    is Fortran-contiguous (no copy); the factor is returned either way. ``R`` is
    Fortran-ordered, as scipy's.
    """
    R, info = lapack.dpotrf(A, lower=0, clean=int(clean), overwrite_a=int(overwrite))
    return R if info == 0 else None


def upper_cholesky_solve(R: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``A^-1 b`` for the upper Cholesky factor ``R`` of ``A`` (:func:`upper_cholesky`) and
    ``b`` (n,) or (n, k), as ``scipy.linalg.cho_solve((R, False), b, check_finite=False)``
    (``b`` is not overwritten)."""
    x, info = lapack.dpotrs(R, b, lower=0)
    if info != 0:
        raise ValueError(f"b: LAPACK potrs rejected argument {-info} (shape {np.shape(b)})")
    return x
