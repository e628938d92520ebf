"""An estimate of the state, and the rounding of a vectorised rotation state onto SO(3)^n.

:class:`Estimate` is what every stage hands on -- the initial estimates, the local solvers'
recoveries and the SDP's rounding: rotations, translations, the scale and the cost of eq. (33).
:func:`rotations_from_vector` turns a vector of stacked ``vec(R)`` defined up to scale (the null
vector of a rotation-only cost or of the SDP's ``Z(lambda*)``) into rotations (Algorithm 1 step 6),
for the dense closed form (:mod:`rwhec_ros.core.initial.closed_form`), the sparse one
(:meth:`~rwhec_ros.core.model.sparse_cost.FullForm.closed_form_rotations`) and the SDP.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..lie import make_transform, project_to_so3, unvec

__all__ = ["Estimate", "rotations_from_vector"]


@dataclass
class Estimate:
    """Rotations ``R`` (n, 3, 3) in state order, translations ``t`` (n, 3) (metric), ``alpha``,
    and the objective value ``cost`` of eq. (33) at this estimate."""

    R: np.ndarray
    t: np.ndarray
    alpha: float
    cost: float

    def split(self, M: int) -> tuple[np.ndarray, np.ndarray]:
        """``(X (M,4,4), Y (P,4,4))``."""
        T = make_transform(self.R, self.t)
        return T[:M], T[M:]


def rotations_from_vector(r: np.ndarray, n: int) -> tuple[np.ndarray, float]:
    """Normalise a (null) vector ``r`` (9 n,) of stacked ``vec(R)`` to rotations (n, 3, 3).

    The vector is defined up to scale ``eta`` (Corollary 2): ``eta`` is chosen so that the mean
    cube-root determinant of the blocks is +1 (fixing sign and magnitude, Algorithm 1 step 6),
    then each block is projected onto SO(3). Returns the rotations and the largest Frobenius
    distance a block moved in the projection (0 for an exact rotation vector).
    """
    blocks = unvec(np.asarray(r, float).reshape(n, 9))
    dets = np.linalg.det(blocks)
    eta = np.mean(np.cbrt(dets))
    if abs(eta) < 1e-300:
        eta = 1.0
    blocks = blocks / eta
    R = project_to_so3(blocks)
    moved = float(np.max(np.linalg.norm(R - blocks, axis=(1, 2)))) if n else 0.0
    return R, moved
