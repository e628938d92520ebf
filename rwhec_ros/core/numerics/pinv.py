"""Solves with a positive semi-definite information matrix whose null directions are a gauge.

The information of the pose-level problem (:mod:`rwhec_ros.core.analysis.information`) is
singular along directions the data do not fix (a translation along the only rotation axis, a
frame nothing constrains); its pseudo-inverse on the rest is what the covariance and the
Gauss-Newton steps of the analyses need (:mod:`~rwhec_ros.core.analysis.time_offset`,
:mod:`~rwhec_ros.core.analysis.motion_lag`, :mod:`rwhec_ros.core.verdict.pair_check`).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

__all__ = ["pinv_solve", "NULL_TOL"]

#: Relative eigenvalue floor of the Jacobi-normalised ``H`` below which a direction is a null
#: (gauge) direction and left out of ``H^+`` (exact symmetries give ~1e-12).
NULL_TOL = 1e-9


def pinv_solve(H: np.ndarray, B: np.ndarray) -> np.ndarray:
    """``H^+ B`` for a symmetric positive semi-definite ``H`` (n, n), its null (gauge)
    directions left out (Jacobi-normalised eigenvalues below ``NULL_TOL`` of the largest)."""
    d = np.sqrt(np.clip(np.diag(H), 0.0, None))
    d = np.where(d > 0, d, 1.0)
    Hn = H / np.outer(d, d)
    Bn = B / d.reshape((-1,) + (1,) * (B.ndim - 1))
    try:  # the usual case, every direction determined: a Cholesky factor, well conditioned
        L = np.linalg.cholesky(Hn)
        if np.diag(L).min() ** 2 > NULL_TOL ** 0.5:
            x = scipy.linalg.cho_solve((L, True), Bn)
            return x / d.reshape((-1,) + (1,) * (B.ndim - 1))
    except np.linalg.LinAlgError:
        pass
    w, V = np.linalg.eigh(0.5 * (Hn + Hn.T))
    keep = w > NULL_TOL * max(float(w.max(initial=0.0)), 1e-300)
    Vk = V[:, keep]
    out = Vk @ ((Vk.T @ Bn) / w[keep].reshape((-1,) + (1,) * (B.ndim - 1)))
    return out / d.reshape((-1,) + (1,) * (B.ndim - 1))
