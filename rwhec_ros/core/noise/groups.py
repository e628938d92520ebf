"""Which pairs share one noise level: the noise groups of the variance-component estimate.

Three groupings (:data:`GROUPINGS`):

* ``"camera"`` (the default): one group per camera (Y frame) and kind of target. The
  noise of a camera-target pose comes mostly from the camera: its resolution, lens and focus, its
  detector and how far it is from the targets it sees; real rigs mix cameras of different quality,
  which one global sigma/kappa cannot weight right. Per camera each group has the pairs of all
  its edges, so its redundancy is large (a camera with 60 views of 3 tags: about 150 degrees of
  freedom per component) and the estimate converges in a few solves. And a single misfitting
  target (a moved, flipped or wrongly sized tag) stays visible: its edge is compared with the
  other edges of the same camera and of the rig (the verdict's edge check), instead of being
  given a noise of its own that would hide it. A camera that sees targets of several kinds (given
  as ``kinds``: single tags, and each board type) has **one group per kind**: the noise of a pose
  is its detector's as much as its camera's. On the demo rig (640 x 480, targets of 20-25 cm at
  about 1 m) the rotation of a single tag, from four edge-refined corners, is 0.01-0.15 deg off
  per axis, of an 8 x 5 chessboard (saddle points) 0.06-0.27 deg, of a 5 x 4 ChArUco board
  (interpolated corners) 0.1-0.44 deg; in one group per camera such a board's every edge fit
  3-10x the noise of the median edge, and the verdict left a good board out as a misfit. Each
  kind is compared with its own kind only (the edge screening below, the groups far above the
  others: :meth:`~.estimate.NoiseEstimate.far_above`).
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

from collections.abc import Mapping
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
        Group names: the camera (``"camera"``; ``"cam0 (chessboard)"`` for a camera whose
        targets are of several kinds), the edge ``"(x, y)"`` (``"camera_target"``) or ``"all"``
        (``"global"``).
    edge_group : ndarray of int, shape (E,)
        The group of each edge of the problem, in edge order.
    cameras : tuple of str
        Per group, its camera (``""`` for the global group).
    kinds : tuple of str
        Per group, the kind of its targets (``""``: not known, or several in the global group).
    """

    grouping: str
    names: tuple[str, ...]
    edge_group: np.ndarray
    cameras: tuple[str, ...] = ()
    kinds: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        # per group: its camera ("" for the global group) and the kind of its targets ("" when
        # not known or mixed); given empty, all groups are of one unknown kind
        if not self.cameras:
            object.__setattr__(self, "cameras", ("",) * len(self.names))
        if not self.kinds:
            object.__setattr__(self, "kinds", ("",) * len(self.names))

    @property
    def size(self) -> int:
        return len(self.names)

    def edge_kinds(self) -> np.ndarray:
        """The kind of each edge's group (E,) (object array of str)."""
        return np.array(self.kinds, dtype=object)[self.edge_group] if self.size else \
            np.zeros(0, dtype=object)

    def pair_group(self, problem: Problem) -> np.ndarray:
        """The group of every pair (N,), pairs stacked edge by edge."""
        return np.repeat(self.edge_group, [e.n for e in problem.edges])

    def edges_of(self, problem: Problem, g: int) -> list[str]:
        """Names ``"(x, y)"`` of the edges of group ``g``."""
        return [e.name for e, k in zip(problem.edges, self.edge_group, strict=True) if k == g]


def noise_groups(problem: Problem, grouping: str = "camera",
                 kinds: Mapping[str, str] | None = None) -> NoiseGroups:
    """The noise groups of ``problem`` under ``grouping`` (module docstring); ``kinds``: target
    (X) name -> its kind (``"tag"``, ``"chessboard"``, ...; targets not in it are of an unknown
    kind ``""``), which splits a camera's group by kind. ``ValueError`` for an unknown
    grouping."""
    if grouping not in GROUPINGS:
        raise ValueError(f"noise groups: expected one of {GROUPINGS}, got {grouping!r}")
    kind_of = dict(kinds or {})
    edge_kind = [str(kind_of.get(e.x, "")) for e in problem.edges]
    if grouping == "global":
        one = set(edge_kind)
        return NoiseGroups(grouping, ("all",), np.zeros(len(problem.edges), dtype=int), ("",),
                           (one.pop() if len(one) == 1 else "",))
    if grouping == "camera_target":
        return NoiseGroups(grouping, tuple(e.name for e in problem.edges),
                           np.arange(len(problem.edges)), tuple(e.y for e in problem.edges),
                           tuple(edge_kind))
    order = {n: i for i, n in enumerate(problem.y_names)}
    seen: dict[str, list[str]] = {}
    for e, k in zip(problem.edges, edge_kind, strict=True):
        if k not in seen.setdefault(e.y, []):
            seen[e.y].append(k)
    keys = [(cam, k) for cam in sorted(seen, key=order.__getitem__) for k in sorted(seen[cam])]
    index = {key: i for i, key in enumerate(keys)}
    names = tuple(cam if len(seen[cam]) == 1 else f"{cam} ({k or 'other'})" for cam, k in keys)
    return NoiseGroups(grouping, names,
                       np.array([index[(e.y, k)] for e, k in zip(problem.edges, edge_kind,
                                                                 strict=True)], dtype=int),
                       tuple(cam for cam, _ in keys), tuple(k for _, k in keys))
