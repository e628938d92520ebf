"""Which pairs share one noise level: the noise groups of the variance-component estimate.

Three groupings (:data:`GROUPINGS`):

* ``"camera"`` (the default): one group per camera (Y frame), all its targets together. The
  noise of a camera-target pose comes mostly from the camera: its resolution, lens and focus, its
  detector and how far it is from the targets it sees; real rigs mix cameras of different quality,
  which one global sigma/kappa cannot weight right. Per camera each group has the pairs of all
  its edges, so its redundancy is large (a camera with 60 views of 3 tags: about 150 degrees of
  freedom per component) and the estimate converges in a few solves. And a single misfitting
  target (a moved, flipped or wrongly sized tag) stays visible: its edge is compared with the
  other edges of the same camera and of the rig (the verdict's edge check), instead of being
  given a noise of its own that would hide it.
* ``"camera_target"``: one group per edge (camera, target). Right when one camera sees targets of
  very different kinds (a large board near by and small tags far away); each group has fewer
  pairs (groups below the minimum redundancy are pooled), and a target with a fault of its own
  gets a large noise instead of standing out: the verdict then names the group, not the edge.
* ``"global"``: one group for all pairs (the paper's single sigma and kappa, estimated).

Each group has two variance components, translation (sigma) and rotation (kappa): their ratio
decides how translations and rotations are weighted against each other, which a guessed
sigma/kappa pair gets wrong as easily as their size.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..problem import Problem

__all__ = ["GROUPINGS", "NoiseGroups", "noise_groups"]

#: The groupings of :func:`noise_groups` (module docstring).
GROUPINGS = ("camera", "camera_target", "global")


@dataclass(frozen=True)
class NoiseGroups:
    """The noise groups of a problem's edges.

    Attributes
    ----------
    grouping : str
        One of :data:`GROUPINGS`.
    names : tuple of str
        Group names: the camera (``"camera"``), the edge ``"(x, y)"`` (``"camera_target"``) or
        ``"all"`` (``"global"``).
    edge_group : ndarray of int, shape (E,)
        The group of each edge of the problem, in edge order.
    """

    grouping: str
    names: tuple[str, ...]
    edge_group: np.ndarray

    @property
    def size(self) -> int:
        return len(self.names)

    def pair_group(self, problem: Problem) -> np.ndarray:
        """The group of every pair (N,), pairs stacked edge by edge."""
        return np.repeat(self.edge_group, [e.n for e in problem.edges])

    def edges_of(self, problem: Problem, g: int) -> list[str]:
        """Names ``"(x, y)"`` of the edges of group ``g``."""
        return [e.name for e, k in zip(problem.edges, self.edge_group, strict=True) if k == g]


def noise_groups(problem: Problem, grouping: str = "camera") -> NoiseGroups:
    """The noise groups of ``problem`` under ``grouping`` (module docstring); ``ValueError`` for
    an unknown grouping."""
    if grouping not in GROUPINGS:
        raise ValueError(f"noise groups: expected one of {GROUPINGS}, got {grouping!r}")
    if grouping == "global":
        return NoiseGroups(grouping, ("all",), np.zeros(len(problem.edges), dtype=int))
    if grouping == "camera_target":
        return NoiseGroups(grouping, tuple(e.name for e in problem.edges),
                           np.arange(len(problem.edges)))
    cameras = [n for n in problem.y_names if n in {e.y for e in problem.edges}]
    index = {n: i for i, n in enumerate(cameras)}
    return NoiseGroups(grouping, tuple(cameras),
                       np.array([index[e.y] for e in problem.edges], dtype=int))
