"""The worst direction of a frame's covariance: the largest eigenvalue of its translation block
and of its rotation block (``[dt (m), phi (rad)]``, the convention of
:mod:`rwhec_ros.core.analysis.uncertainty`). The verdict's precision, the refinement's decision
and the precision of the frames published all read a frame's std this way."""

from __future__ import annotations

import numpy as np

__all__ = ["block_variances"]


def block_variances(C: np.ndarray, missing: float = np.nan) -> np.ndarray:
    """The largest eigenvalues of the translation and rotation blocks of a (6, 6) covariance
    ``[dt (m), phi (rad)]``: the variances in the worst directions, shape (2,); ``missing``
    for a block that is not finite."""
    C = np.asarray(C, dtype=float)
    out = np.full(2, float(missing))
    for k, sl in enumerate((slice(0, 3), slice(3, 6))):
        block = C[sl, sl]
        if np.isfinite(block).all():
            out[k] = float(np.linalg.eigvalsh(0.5 * (block + block.T))[-1])
    return out
