"""A candidate for the exclusion (:class:`Misfit`) and a solve of the caller's solver
(:class:`Attempt`): the records :mod:`.exclusion` and :mod:`.hidden_misfits` share."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

from ..problem import Problem
from ..result import CalibrationResult

__all__ = ["Misfit", "Attempt", "edge_target"]


def edge_target(edge: str) -> str:
    """The target ``x`` of an edge named ``"(x, y)"``."""
    return edge.strip("()").split(",")[0].strip()


@dataclass(frozen=True)
class Misfit:
    """A target or an edge that does not fit (a candidate for exclusion).

    Attributes
    ----------
    kind : str
        ``"tag"`` (every edge of the target) or ``"edge"``.
    name : str
        The tag's name, or the edge ``"(x, y)"``.
    edges : tuple of str
        The edges ``"(x, y)"`` it stands for (in the data given to the solve).
    pairs : int
        Their pairs.
    finding : str
        What was found, in words (``every edge of tag_2 fits far worse than the others (cam0
        2.7x, ...)``).
    noise_ratio_without : float
        The a-posteriori noise ratio of the rest solved without it (``nan``: not tried).
    causes : str
        Its likely causes, in words (the verdict's reason; a size found wrong says so).
    camera : str
        A candidate for the misfit of this camera (:func:`.hidden_misfits.camera_misfits`):
        excluded only when the re-solve shows that it explains it.
    """

    kind: str
    name: str
    edges: tuple[str, ...]
    pairs: int
    finding: str
    noise_ratio_without: float = float("nan")
    causes: str = "its size is wrong, it moved during the recording, or its pose flips"
    camera: str = ""

    def to_dict(self) -> dict:
        return {"kind": self.kind, "name": self.name, "edges": list(self.edges),
                "pairs": int(self.pairs), "finding": self.finding,
                "noise_ratio_without": float(self.noise_ratio_without)}


@dataclass
class Attempt:
    """One solve of the caller's solver: the ``result``, the ``problem`` it solved (with outlier
    rejection: the inlier problem), the pairs it rejected (edge ``"(x, y)"`` -> count),
    whatever else the caller keeps (``extra``, returned untouched) and whether the problem's
    weights are the noise estimated from the data (``noise_estimated``: an edge is then flagged
    only by its ratio to the median edge, :func:`~.fit.goodness_of_fit`), and the estimate
    (``noise``: :class:`~rwhec_ros.core.noise.NoiseEstimate` or None)."""

    result: CalibrationResult
    problem: Problem
    rejected: Mapping[str, int] = field(default_factory=dict)
    extra: object = None
    noise_estimated: bool = False
    noise: object = None
