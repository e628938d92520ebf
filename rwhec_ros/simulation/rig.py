"""A ROS-free simulation of a small mobile camera rig among AprilTags (demo, tests, CLI demo).

The scene follows the paper's real-world setting (Section 9) in miniature: ``P`` cameras on a rig
that moves (yaw turns plus roll/pitch oscillations and a small translation, so that rotations
about several axes make every edge identifiable, cf. Section 6) among ``M`` tags fixed on the
walls of a room, with a motion-capture pose stream ``T_world_rig``. In the paper's loop
``A_i X_j = Y_k B_i``::

    A   = T_rig_world   (inverse of the pose stream)     X_j = T_world_tag_j
    Y_k = T_rig_cam_k                                    B   = T_cam_k_tag_j

Everything is deterministic given the model and a ``numpy.random.Generator``; the simulator node
(``rwhec_ros.ros.sim_node``) and the CLI demo share this module. Topic names of the demo are fixed
here and match ``config/demo.yaml``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from ..core.lie import invert_transform, make_transform, so3_exp
from ..vision.boards import AprilGridSpec, CharucoSpec
from ..vision.grids import ChessboardSpec, CircleGridSpec
from ..vision.intrinsics import CameraIntrinsics
from ..vision.render import RenderedBoard, RenderedTag, look_at, render_tags

#: Any board layout the simulation renders.
Board = AprilGridSpec | CharucoSpec | ChessboardSpec | CircleGridSpec

__all__ = [
    "DEMO_POSE_TOPIC",
    "DEMO_WORLD_FRAME",
    "DEMO_RIG_FRAME",
    "demo_camera_topics",
    "Trajectory",
    "SimulatedRig",
    "demo_rig",
    "demo_board",
    "demo_board_rig",
    "DEMO_BOARD_KINDS",
    "DEMO_GRID_KINDS",
]

#: PoseStamped topic of the demo (``header.frame_id`` = world, pose of the rig).
DEMO_POSE_TOPIC = "/demo/rig/pose"
DEMO_WORLD_FRAME = "world"
DEMO_RIG_FRAME = "rig"


def demo_camera_topics(camera: str) -> tuple[str, str]:
    """``(image_topic, camera_info_topic)`` of a demo camera."""
    return f"/demo/{camera}/image_raw", f"/demo/{camera}/camera_info"


@dataclass(frozen=True)
class Trajectory:
    """Smooth rig motion ``T_world_rig(t)`` exciting rotations about all three axes.

    Yaw turns at ``yaw_rate`` [rad/s]; roll and pitch oscillate with amplitude
    ``tilt_amplitude`` [rad] at incommensurate periods; the position oscillates by
    ``translation_amplitude`` [m] around ``centre`` [m].
    """

    yaw_rate: float = 2.0 * np.pi / 24.0
    tilt_amplitude: float = 0.25
    translation_amplitude: float = 0.15
    centre: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def pose(self, t: float) -> np.ndarray:
        """``T_world_rig`` (4, 4) at time ``t`` [s]."""
        t = float(t)
        yaw = self.yaw_rate * t
        roll = self.tilt_amplitude * np.sin(2.0 * np.pi * t / 7.0)
        pitch = self.tilt_amplitude * np.sin(2.0 * np.pi * t / 5.0 + 1.0)
        R = (
            so3_exp(np.array([0.0, 0.0, yaw]))
            @ so3_exp(np.array([0.0, pitch, 0.0]))
            @ so3_exp(np.array([roll, 0.0, 0.0]))
        )
        a = self.translation_amplitude
        p = np.asarray(self.centre, dtype=float) + a * np.array(
            [
                np.sin(2.0 * np.pi * t / 11.0),
                np.cos(2.0 * np.pi * t / 13.0) - 1.0,
                0.6 * np.sin(2.0 * np.pi * t / 6.0),
            ]
        )
        return make_transform(R, p)


@dataclass(frozen=True)
class SimulatedRig:
    """Ground truth and sensors of the simulation.

    Attributes
    ----------
    cameras : tuple of str
        Camera names (Y variables), also the keys of ``intrinsics`` and ``T_rig_cam``.
    intrinsics : dict of str to CameraIntrinsics
    T_rig_cam : dict of str to ndarray (4, 4)
        True ``Y_k``.
    T_world_tag : dict of int to ndarray (4, 4)
        True ``X_j`` by tag id (target position ``j``).
    tag_size : float
        Edge length of every tag's black square [m].
    family : str
        AprilTag family.
    trajectory : Trajectory
    boards : dict of int to a board layout
        Positions ``j`` that hold a board instead of tag ``j`` (board frame at
        ``T_world_tag[j]``); drawn by :meth:`render`, named ``board_<j>``.
    """

    cameras: tuple[str, ...]
    intrinsics: dict[str, CameraIntrinsics]
    T_rig_cam: dict[str, np.ndarray]
    T_world_tag: dict[int, np.ndarray]
    tag_size: float = 0.25
    family: str = "tag36h11"
    trajectory: Trajectory = field(default_factory=Trajectory)
    boards: Mapping[int, Board] = field(default_factory=dict)

    def __post_init__(self) -> None:
        unknown = sorted(set(self.boards) - set(self.T_world_tag))
        if unknown:
            raise ValueError(f"boards: positions {unknown} are not in the rig "
                             f"({sorted(self.T_world_tag)})")

    @property
    def tag_ids(self) -> tuple[int, ...]:
        return tuple(sorted(self.T_world_tag))

    @property
    def single_tag_ids(self) -> tuple[int, ...]:
        """Positions holding a single tag (not a board)."""
        return tuple(j for j in self.tag_ids if j not in self.boards)

    def target_names(self) -> dict[str, int]:
        """X-variable name -> position ``j``: ``tag_<j>`` for tags, ``board_<j>`` for boards,
        in the order of the configuration of :func:`rwhec_ros.cli.replay.demo_parameters`."""
        out = {f"tag_{j}": j for j in self.single_tag_ids}
        out.update({f"board_{j}": j for j in sorted(self.boards)})
        return out

    def true_frames(self) -> list[tuple[str, str, np.ndarray]]:
        """``(parent, child, T_parent_child)`` of the true extrinsics, as the simulator node
        publishes them on ``/tf_static`` to compare with the calibrator's ``*_calibrated``
        frames: ``<cam>_optical_true`` on ``rig`` (``Y_k``), ``<target>_true`` on ``world``
        (``X_j``; targets named as :meth:`target_names`: ``tag_<j>`` or ``board_<j>``)."""
        out = [(DEMO_RIG_FRAME, f"{cam}_optical_true", T) for cam, T in self.T_rig_cam.items()]
        out += [(DEMO_WORLD_FRAME, f"{name}_true", self.T_world_tag[j])
                for name, j in self.target_names().items()]
        return out

    def T_world_rig(self, t: float) -> np.ndarray:
        """True rig pose at time ``t`` [s]."""
        return self.trajectory.pose(t)

    def pose_measurement(
        self, t: float, rng: np.random.Generator | None = None, noise_m: float = 0.0,
        noise_rad: float = 0.0,
    ) -> np.ndarray:
        """Measured ``T_world_rig``: the truth, optionally perturbed (Gaussian position noise
        ``noise_m`` [m] per axis, rotation vector noise ``noise_rad`` [rad] per axis)."""
        T = self.T_world_rig(t)
        if noise_m > 0 or noise_rad > 0:
            if rng is None:
                raise ValueError("rng: required when noise_m or noise_rad > 0")
            dR = so3_exp(noise_rad * rng.standard_normal(3))
            T = make_transform(T[:3, :3] @ dR, T[:3, 3] + noise_m * rng.standard_normal(3))
        return T

    def T_cam_tag(self, camera: str, tag_id: int, T_world_rig: np.ndarray) -> np.ndarray:
        """True ``B = T_cam_tag = Y_k^-1 A X_j`` with ``A = T_rig_world``."""
        T_world_cam = T_world_rig @ self.T_rig_cam[camera]
        return invert_transform(T_world_cam) @ self.T_world_tag[tag_id]

    def visible_tags(
        self, camera: str, T_world_rig: np.ndarray, *, margin_px: float = 4.0
    ) -> list[RenderedTag]:
        """Tags in front of ``camera``, facing it, with all four corners inside the image."""
        K = self.intrinsics[camera]
        h = 0.5 * self.tag_size
        corners = np.array([[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]])
        out = []
        for tag_id in self.tag_ids:
            T = self.T_cam_tag(camera, tag_id, T_world_rig)
            pts = corners @ T[:3, :3].T + T[:3, 3]
            if np.any(pts[:, 2] <= 0.05) or float(T[:3, 2] @ T[:3, 3]) >= 0:
                continue
            uv = K.project_points(pts)
            inside = (
                (uv[:, 0] >= margin_px)
                & (uv[:, 0] <= K.width - 1 - margin_px)
                & (uv[:, 1] >= margin_px)
                & (uv[:, 1] <= K.height - 1 - margin_px)
            )
            if np.all(inside):
                out.append(RenderedTag(tag_id, T, self.tag_size))
        return out

    def render(
        self,
        camera: str,
        T_world_rig: np.ndarray,
        rng: np.random.Generator | None = None,
        *,
        noise_std: float = 2.0,
        blur_sigma: float = 0.6,
        supersample: int = 3,
        boards: Mapping[int, Board] | None = None,
        shift_pattern: bool = False,
    ) -> np.ndarray:
        """(H, W) uint8 image of ``camera`` at rig pose ``T_world_rig`` (true pose).

        Tags partly outside the image are left out entirely (a simple stand-in for a detector
        that rejects cut tags). Noise needs ``rng``; ``noise_std=0`` gives a noise-free image.

        ``boards`` (tag id -> layout; default: the rig's :attr:`boards`) puts a board in place
        of those tags, its frame (:mod:`rwhec_ros.vision.boards`: centre of the pattern) at the
        tag's pose, so ``X_j = T_world_tag[j]`` and ``B = T_cam_tag(camera, j, T_world_rig)``
        stay the truth with the same trajectory and images. A board is drawn when its centre is
        in front of the camera and its face toward it, also when only partly in view (a board
        gives a pose from the corners seen). ``shift_pattern``: see
        :func:`~rwhec_ros.vision.render.render_tags` (the demo's images use it).
        """
        boards = dict(self.boards if boards is None else boards)
        unknown = sorted(set(boards) - set(self.tag_ids))
        if unknown:
            raise ValueError(f"boards: tag ids {unknown} are not in the rig ({self.tag_ids})")
        items: list[RenderedTag | RenderedBoard] = [
            t for t in self.visible_tags(camera, T_world_rig) if t.tag_id not in boards]
        for tag_id, board in boards.items():
            T = self.T_cam_tag(camera, tag_id, T_world_rig)
            if T[2, 3] > 0.05 and float(T[:3, 2] @ T[:3, 3]) < 0:
                items.append(RenderedBoard(board, T))
        return render_tags(
            self.intrinsics[camera],
            items,
            self.family,
            blur_sigma=blur_sigma,
            noise_std=noise_std if rng is not None else 0.0,
            rng=rng,
            supersample=supersample,
            shift_pattern=shift_pattern,
        )


def demo_rig(
    n_cameras: int = 3,
    n_tags: int = 6,
    *,
    room_radius: float = 1.0,
    tag_size: float = 0.25,
    width: int = 640,
    height: int = 480,
    focal_px: float = 500.0,
    trajectory: Trajectory | None = None,
    boards: Mapping[int, Board] | None = None,
) -> SimulatedRig:
    """The demo scene: ``n_cameras`` cameras looking outward from a small rig (evenly spread in
    yaw, each with a different pitch and roll), ``n_tags`` tags on a ring of radius
    ``room_radius`` around the start position facing inward at alternating heights. Camera
    names ``cam<k>``, tag ids ``0..n_tags-1``; ``boards`` (position -> layout, e.g.
    :func:`demo_board`) replaces those tags by boards. Deterministic (no randomness)."""
    if n_cameras < 1:
        raise ValueError(f"n_cameras: must be >= 1, got {n_cameras}")
    if n_tags < 1:
        raise ValueError(f"n_tags: must be >= 1, got {n_tags}")
    if not room_radius > 0.5:
        raise ValueError(f"room_radius: must be > 0.5 m, got {room_radius}")
    cams = tuple(f"cam{k}" for k in range(n_cameras))
    intr = CameraIntrinsics.pinhole(width, height, focal_px, focal_px * 1.002)
    intrinsics = {c: intr for c in cams}
    T_rig_cam = {}
    for k, c in enumerate(cams):
        yaw = 2.0 * np.pi * k / n_cameras + 0.2
        outward = np.array([np.cos(yaw), np.sin(yaw), 0.0])
        pos = 0.08 * outward + np.array([0.0, 0.0, 0.03 * ((k % 3) - 1)])
        pitch = 0.12 * ((k % 3) - 1)  # look slightly up / level / down
        target = pos + outward + np.array([0.0, 0.0, np.tan(pitch)])
        T = look_at(pos, target, up=(0.0, 0.0, 1.0))
        roll = so3_exp(np.array([0.0, 0.0, 0.1 * (k + 1)]))  # about the optical axis
        T_rig_cam[c] = make_transform(T[:3, :3] @ roll, T[:3, 3])
    T_world_tag = {}
    for j in range(n_tags):
        theta = 2.0 * np.pi * j / n_tags
        inward = -np.array([np.cos(theta), np.sin(theta), 0.0])
        pos = -room_radius * inward + np.array([0.0, 0.0, 0.2 * (1 if j % 2 else -1)])
        z = inward
        y = np.array([0.0, 0.0, 1.0])
        x = np.cross(y, z)
        R = np.c_[x, y, z] @ so3_exp(np.array([0.08 * (j % 3 - 1), 0.06 * (j % 2), 0.3 * j]))
        T_world_tag[j] = make_transform(R, pos)
    return SimulatedRig(
        cameras=cams,
        intrinsics=intrinsics,
        T_rig_cam=T_rig_cam,
        T_world_tag=T_world_tag,
        tag_size=float(tag_size),
        trajectory=trajectory if trajectory is not None else Trajectory(),
        boards=dict(boards or {}),
    )


#: The boards of ``demo.launch.py boards:=grids`` (``config/demo_grids.yaml``).
DEMO_GRID_KINDS = ("chessboard", "circles", "asymmetric_circles")
#: Board kinds of :func:`demo_board`.
DEMO_BOARD_KINDS = ("aprilgrid", "charuco", "chessboard", "circles", "asymmetric_circles")


def demo_board(kind: str, position: int = 0) -> Board:
    """A board about the size of a demo tag (25 cm) for position ``position`` of the demo:
    ``"aprilgrid"`` 3 x 3 tags of 7 cm (Kalibr layout, ids ``100 + 9 position ...``, clear of
    the single tags 0..n_tags-1), ``"charuco"`` 5 x 4 squares of 5 cm with 3.8 cm DICT_4X4_250
    markers (ids ``10 position ...``), ``"chessboard"`` 8 x 5 inner corners (9 x 6 squares) of
    3 cm, ``"circles"`` 6 x 5 circles of 2 cm every 4 cm with a larger origin circle,
    ``"asymmetric_circles"`` OpenCV's layout, 4 x 7 circles of 1.5 cm, square size 3 cm."""
    if kind == "aprilgrid":
        return AprilGridSpec(3, 3, tag_size=0.07, tag_spacing=0.3, first_id=100 + 9 * position)
    if kind == "charuco":
        return CharucoSpec(5, 4, square_size=0.05, marker_size=0.038, dictionary="DICT_4X4_250",
                           first_id=10 * position)
    if kind == "chessboard":
        return ChessboardSpec(8, 5, square_size=0.03)
    if kind == "circles":
        return CircleGridSpec(6, 5, 0.04, origin_circle=True, diameter=0.02)
    if kind == "asymmetric_circles":
        return CircleGridSpec(4, 7, 0.03, asymmetric=True, diameter=0.015)
    raise ValueError(f"kind: must be one of {list(DEMO_BOARD_KINDS)}, got {kind!r}")


def demo_board_rig(boards: Sequence[str] = (), n_cameras: int = 3, n_tags: int = 6, *,
                   what: str = "boards") -> SimulatedRig:
    """The demo rig with board ``boards[j]`` (a kind of :data:`DEMO_BOARD_KINDS`, laid out by
    :func:`demo_board`) in place of tag ``j``: what the CLI demo (``--board``) and the simulator
    node (parameter ``boards``) render, and what ``config/demo_boards.yaml`` describes for
    ``["aprilgrid", "charuco"]`` and ``config/demo_grids.yaml`` for
    :data:`DEMO_GRID_KINDS`. ``what`` names the option in the ``ValueError`` of a bad kind
    or of more boards than tag positions."""
    kinds = list(boards)
    if len(kinds) > n_tags:
        raise ValueError(f"{what}: {len(kinds)} boards for {n_tags} tag positions")
    for i, kind in enumerate(kinds):
        if kind not in DEMO_BOARD_KINDS:
            raise ValueError(f"{what}[{i}]: must be one of {list(DEMO_BOARD_KINDS)}, got "
                             f"{kind!r}")
    return demo_rig(n_cameras, n_tags,
                    boards={j: demo_board(kind, j) for j, kind in enumerate(kinds)})
