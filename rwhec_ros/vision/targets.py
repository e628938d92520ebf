"""Targets (the X frames): a single AprilTag or a board, and what detecting them returns.

A :class:`TargetSpec` names one rigid target with its own frame ``X_j``: either one tag of the
detector's family (``tag_id``, ``tag_size``; frame of :mod:`rwhec_ros.vision.detection`) or a board
(:class:`~rwhec_ros.vision.boards.AprilGridSpec`, :class:`~rwhec_ros.vision.boards.CharucoSpec`:
frame of :mod:`rwhec_ros.vision.boards`; :class:`~rwhec_ros.vision.grids.ChessboardSpec`,
:class:`~rwhec_ros.vision.grids.CircleGridSpec`: frame of :mod:`rwhec_ros.vision.grids`).
:func:`validate_targets` checks a whole set (unique names, no marker id claimed twice within
one dictionary). The configuration layer builds the
specs; :class:`~rwhec_ros.vision.target_detector.TargetDetector` detects them and returns
:class:`TargetObservation` (``B = T_cam_target`` with its quality figures) and
:class:`TargetRejection` records.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from .boards import AprilGridSpec, CharucoSpec, dictionary_key, dictionary_size
from .grids import ChessboardSpec, CircleGridSpec

#: Board layouts a target may hold.
BOARD_TYPES = (AprilGridSpec, CharucoSpec, ChessboardSpec, CircleGridSpec)

__all__ = [
    "BOARD_TYPES",
    "TargetSpec",
    "validate_targets",
    "nested_grids",
    "TargetObservation",
    "TargetRejection",
    "TargetDetectionResult",
]


@dataclass(frozen=True)
class TargetSpec:
    """One target: a single tag or a board (exactly one of the two).

    Attributes
    ----------
    name : str
        Frame name of the target (the X variable), non-empty.
    tag_id : int or None
        Id of a single tag in the detector's family.
    tag_size : float or None
        Its black-square edge [m] (nominal if the scale is unknown).
    board : AprilGridSpec, CharucoSpec, ChessboardSpec, CircleGridSpec or None
        Layout of a board.
    min_corners : int
        Boards only: fewest detected corners for a pose (>= 4; default 8, i.e. two tags of an
        AprilGrid or eight ChArUco corners). A partly occluded marker board gives a pose from
        the corners seen (a chessboard or circle grid only where its labels are resolved,
        :mod:`rwhec_ros.vision.grid_detection`).
    """

    name: str
    tag_id: int | None = None
    tag_size: float | None = None
    board: AprilGridSpec | CharucoSpec | ChessboardSpec | CircleGridSpec | None = None
    min_corners: int = 8

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise ValueError(f"target name must be a non-empty string, got {self.name!r}")
        who = f"target {self.name!r}"
        if self.board is None:
            if self.tag_id is None or self.tag_size is None:
                raise ValueError(f"{who}: give tag_id and tag_size (single tag) or board")
            tid = self.tag_id
            if isinstance(tid, bool) or not isinstance(tid, (int, np.integer)) or tid < 0:
                raise ValueError(f"{who}: tag_id must be a non-negative integer, got {tid!r}")
            object.__setattr__(self, "tag_id", int(tid))
            size = self.tag_size
            if isinstance(size, bool) or not (np.isscalar(size) and np.isfinite(size)
                                              and size > 0):
                raise ValueError(f"{who}: tag_size must be a positive number, got {size!r}")
            object.__setattr__(self, "tag_size", float(size))
        else:
            if self.tag_id is not None or self.tag_size is not None:
                raise ValueError(f"{who}: a board target takes no tag_id / tag_size")
            if not isinstance(self.board, BOARD_TYPES):
                raise ValueError(f"{who}: board must be one of "
                                 f"{[b.__name__ for b in BOARD_TYPES]}, got "
                                 f"{type(self.board).__name__}")
        mc = self.min_corners
        if isinstance(mc, bool) or not isinstance(mc, (int, np.integer)) or mc < 4:
            raise ValueError(f"{who}: min_corners must be an integer >= 4, got {mc!r}")
        if self.board is not None and mc > self.board.n_corners:
            raise ValueError(f"{who}: min_corners {mc} exceeds the {self.board.n_corners} "
                             f"corners of the board")
        object.__setattr__(self, "min_corners", int(mc))

    @property
    def kind(self) -> str:
        """``"tag"``, ``"aprilgrid"``, ``"charuco"``, ``"chessboard"``, ``"circles"`` or
        ``"asymmetric_circles"``."""
        return "tag" if self.board is None else self.board.kind

    @property
    def has_markers(self) -> bool:
        """False for a chessboard or circle grid (found as a whole, no coded markers)."""
        return not isinstance(self.board, (ChessboardSpec, CircleGridSpec))

    @property
    def turn_symmetric(self) -> bool:
        """A board that looks the same turned by 180 degrees (a chessboard with both square
        counts even or both odd): its views' turns come from the pose stream
        (:mod:`rwhec_ros.sync.board_turns`)."""
        return bool(getattr(self.board, "turn_symmetric", False))

    def marker_ids(self) -> tuple[int, ...]:
        """Marker ids of the target (its dictionary: :meth:`dictionary`); empty for a
        chessboard or circle grid."""
        return (self.tag_id,) if self.board is None else self.board.marker_ids

    def dictionary(self, tag_family: str) -> str:
        """Canonical dictionary of the target's markers (``tag_family`` for single tags)."""
        return dictionary_key(tag_family) if self.board is None else self.board.dictionary

    def border_bits(self) -> int:
        """Black border width of the markers in cells."""
        return int(getattr(self.board, "border_bits", 1))


def nested_grids(a: TargetSpec, b: TargetSpec) -> str | None:
    """Why two targets cannot be told apart in an image, or None: two boards without markers of
    one kind (two chessboards, two circle grids of one layout) of which one's pattern fits
    inside the other's, either way round. OpenCV's grid detectors look for a pattern of a given
    size, and can find the smaller pattern on the larger board (a 7 x 5 chessboard was found on a
    9 x 5 one in one image per camera of a rendered scene; the pair was 66 deg and 1 m off, the
    other board's place); nothing on a plain board says which board it is."""
    if a.has_markers or b.has_markers or a.kind != b.kind:
        return None
    (c1, r1), (c2, r2) = a.board.pattern_size, b.board.pattern_size

    def inside(c: int, r: int, cc: int, rr: int) -> bool:
        return (c <= cc and r <= rr) or (c <= rr and r <= cc)

    if not (inside(c1, r1, c2, r2) or inside(c2, r2, c1, r1)):
        return None
    return (f"targets {a.name!r} ({c1} x {r1}) and {b.name!r} ({c2} x {r2}) are {a.kind} "
            "boards without markers, and one's pattern fits inside the other's: the detector "
            "can find the smaller pattern on the larger board, and nothing on a plain board says "
            "which board it is; use patterns that do not fit inside each other (e.g. 9 x 6 and "
            "7 x 8), or a board with markers (charuco, aprilgrid)")


def validate_targets(targets: Sequence[TargetSpec], tag_family: str) -> tuple[TargetSpec, ...]:
    """Check a set of targets: unique names, every single-tag id in ``tag_family``, no marker id
    used by two targets of one dictionary (an id printed twice cannot be told apart), no two
    plain boards that can be taken for each other (:func:`nested_grids`).

    Returns
    -------
    tuple of TargetSpec

    Raises
    ------
    ValueError
        Naming the targets and the id.
    """
    out = tuple(targets)
    family = dictionary_key(tag_family)
    seen_names: set[str] = set()
    owners: dict[tuple[str, int], str] = {}
    for i, t in enumerate(out):
        if not isinstance(t, TargetSpec):
            raise ValueError(f"targets[{i}] must be a TargetSpec, got {type(t).__name__}")
        if t.name in seen_names:
            raise ValueError(f"targets[{i}]: duplicate target name {t.name!r}")
        seen_names.add(t.name)
        dictionary = t.dictionary(family)
        if t.board is None and t.tag_id >= dictionary_size(family):
            raise ValueError(f"target {t.name!r}: tag_id {t.tag_id} is not in {family} "
                             f"({dictionary_size(family)} tags)")
        for marker in t.marker_ids():
            other = owners.get((dictionary, marker))
            if other is not None:
                raise ValueError(
                    f"targets {other!r} and {t.name!r} both use marker id {marker} of "
                    f"{dictionary}: ids must be unique per dictionary"
                )
            owners[(dictionary, marker)] = t.name
    for i, a in enumerate(out):
        for b in out[i + 1:]:
            why = nested_grids(a, b)
            if why is not None:
                raise ValueError(why)
    return out


@dataclass(eq=False)
class TargetObservation:
    """One accepted target: ``B = T_cam_target`` with its quality figures.

    Attributes
    ----------
    name : str
        Target (frame) name.
    kind : str
        :attr:`TargetSpec.kind`.
    T_cam_target : ndarray, shape (4, 4)
        Pose of the target frame in the camera frame.
    reprojection_rms_px : float
        RMS distance of detected and reprojected points (distorted pixels).
    obliquity_deg : float
        Angle between the target normal (``+z``) and the ray from its origin to the camera.
    marker_ids : tuple of int
        Markers that contributed (a tag's id; the grid tags; the ChArUco markers found; none
        for a chessboard or circle grid).
    image_points : ndarray, shape (N, 2)
        Points used for the pose (distorted pixels): tag corners, board corners or circle
        centres (the latter with the projection bias of :func:`~rwhec_ros.vision.
        grid_detection.centre_bias` removed).
    object_points : ndarray, shape (N, 3)
        The same points in the target frame.
    sigma, kappa : float or None
        Translation standard deviation [m] and Langevin rotation concentration (paper eq.
        (20)), None when not estimated.
    pose_status : str
        ``"unique"`` or ``"resolved_by_prediction"``.
    flip_ratio : float
        ``e_alt / e_best`` of the two IPPE poses (inf when only one was in front).
    outlier_corners : int
        Boards: corners left out as outliers (not in ``image_points``).
    """

    name: str
    kind: str
    T_cam_target: np.ndarray
    reprojection_rms_px: float
    obliquity_deg: float
    marker_ids: tuple[int, ...]
    image_points: np.ndarray
    object_points: np.ndarray
    sigma: float | None = None
    kappa: float | None = None
    pose_status: str = "unique"
    flip_ratio: float = float("inf")
    outlier_corners: int = 0

    @property
    def n_corners(self) -> int:
        return int(len(self.image_points))


@dataclass(frozen=True)
class TargetRejection:
    """A detection that did not become an observation.

    ``reason`` is a :class:`~rwhec_ros.vision.detection.RejectReason` value; ``name`` is the
    target ("" for a marker of no target); ``marker_id`` the marker concerned (-1 for a whole
    board or the image).
    """

    name: str
    reason: str
    detail: str = ""
    marker_id: int = -1


@dataclass
class TargetDetectionResult:
    """Output of :meth:`~rwhec_ros.vision.target_detector.TargetDetector.detect`.

    Attributes
    ----------
    observations : list of TargetObservation
    rejections : list of TargetRejection
    skipped : list of str
        Targets found in the image but left unexamined (not in ``detect(..., only=...)``).
    markers : dict of str to list of (int, ndarray (4, 2))
        Every marker found, by target name (``""``: markers of no target), as cv2.aruco
        reported it (distorted pixels): where to draw each target
        (:mod:`rwhec_ros.vision.annotate`), also when it was rejected. A chessboard or circle
        grid found has one entry, id -1, the outline of its grid points.
    corner_noise_px : dict of str to float
        Corner noise (:func:`~rwhec_ros.vision.detector_config.corner_noise_px`) of each
        target whose pose was solved, accepted or not (the caller's noise history).
    """

    observations: list[TargetObservation] = field(default_factory=list)
    rejections: list[TargetRejection] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    markers: dict[str, list[tuple[int, np.ndarray]]] = field(default_factory=dict)
    corner_noise_px: dict[str, float] = field(default_factory=dict)

    def by_name(self) -> dict[str, TargetObservation]:
        """Accepted observations keyed by target name."""
        return {obs.name: obs for obs in self.observations}
