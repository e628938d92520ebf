"""The real third-party sets of ``../shared/data/real/`` as the benchmarks use them.

Read by the package's one reader of each layout, :func:`rwhec_ros.data.sample_layouts.read_samples`
(what ``rwhec-calibrate samples`` reads), configured by
:func:`rwhec_ros.cli.samples.samples_parameters` (the carriers from the mount, the data's target),
with the configuration's noise defaults instead of ``samples``' stop-and-go ones (the benchmark
tables state them). What ``samples`` cannot do from the folder alone is done here:

* camera_calibration_toolkit ships no intrinsics (``samples`` asks for ``--intrinsics FILE``):
  they are refitted by ``cv2.calibrateCamera`` on the chessboard corners of the same views
  (``cv2.findChessboardCornersSB``), as the toolkit itself does;
* its folder does not say how the camera is mounted: the set is eye-in-hand (its README).
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rwhec_ros.cli.samples import SAMPLES_DEFAULTS, samples_parameters  # noqa: E402
from rwhec_ros.config import CalibratorConfig  # noqa: E402
from rwhec_ros.data.sample_layouts import BOARD_NAME, read_samples  # noqa: E402
from rwhec_ros.vision.grids import ChessboardSpec  # noqa: E402
from rwhec_ros.vision.intrinsics import CameraIntrinsics  # noqa: E402
from rwhec_ros.vision.targets import TargetSpec  # noqa: E402

#: The single camera and target of a tool's layout (the names ``samples`` gives them).
CAMERA = "cam0"
TARGET = BOARD_NAME
#: The mount of a set whose folder does not say it (from the sets' READMEs).
MOUNTS = {"cct_chessboard_eye_in_hand": "eye_in_hand"}


@dataclass(frozen=True)
class RealView:
    """One view: its image file and the robot pose ``T_base_tool`` (4, 4)."""

    image: Path
    T_base_tool: np.ndarray

    def gray(self) -> np.ndarray:
        """The image as (H, W) uint8 (``ValueError`` when it cannot be read)."""
        img = cv2.imread(str(self.image), cv2.IMREAD_GRAYSCALE)
        if img is None:
            raise ValueError(f"{self.image}: not a readable image")
        return img


@dataclass(frozen=True)
class RealSet:
    """A real set: views, intrinsics (and where they come from), the target, the parameters."""

    name: str
    layout: str
    views: tuple[RealView, ...]
    intrinsics: CameraIntrinsics
    intrinsics_source: str
    target: TargetSpec
    flat: dict[str, Any]

    def parameters(self) -> dict[str, Any]:
        """Flat calibrator parameters (a copy): carriers, pose source, camera, target."""
        return dict(self.flat)


def _refit_chessboard(grays: list[np.ndarray], spec: ChessboardSpec,
                      where: Path) -> tuple[CameraIntrinsics, str]:
    """``cv2.calibrateCamera`` (plumb_bob) on the chessboard corners of ``grays``, in OpenCV's
    own order and board frame (the intrinsics do not depend on the frame)."""
    cols, rows = spec.pattern_size
    grid = np.zeros((rows * cols, 3), np.float32)
    grid[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * spec.square_size
    obj, img = [], []
    for g in grays:
        ok, corners = cv2.findChessboardCornersSB(g, spec.pattern_size)
        if ok:
            obj.append(grid)
            img.append(np.asarray(corners, dtype=np.float32).reshape(-1, 1, 2))
    if len(obj) < 3:
        raise ValueError(f"{where}: the chessboard is found in {len(obj)} images, at least 3 "
                         f"are needed to refit the intrinsics")
    h, w = grays[0].shape
    rms, K, D, _, _ = cv2.calibrateCamera(obj, img, (w, h), None, None)
    intr = CameraIntrinsics(w, h, K, np.asarray(D, dtype=float).reshape(-1)[:5], "plumb_bob")
    return intr, (f"refitted by cv2.calibrateCamera from the chessboard in {len(obj)} of the "
                  f"{len(grays)} views (RMS {rms:.3f} px)")


def load_set(folder: str | Path) -> RealSet:
    """A real set read as ``rwhec-calibrate samples`` reads it (module docstring)."""
    folder = Path(folder)
    samples = read_samples(folder)
    flat, invert, _ = samples_parameters(samples, {}, MOUNTS.get(folder.name))
    assert not invert and samples.cameras == (CAMERA,), (invert, samples.cameras)
    for key in SAMPLES_DEFAULTS:  # the configuration's defaults, as the tables say
        flat.pop(key)
    (target,) = CalibratorConfig.from_parameters(flat).target_specs()
    views = tuple(RealView(v.images[CAMERA], np.asarray(v.T_parent_child, dtype=float))
                  for v in samples.views)
    first = views[0].gray()
    file = samples.intrinsics[CAMERA]
    if file is not None:
        intrinsics = file.intrinsics(first.shape[1], first.shape[0])
        source = f"{Path(file.path).name.replace(' (intrinsics)', '')}'s intrinsics" + (
            " (no distortion)" if not np.any(intrinsics.D) else "")
    elif isinstance(target.board, ChessboardSpec):
        intrinsics, source = _refit_chessboard([v.gray() for v in views], target.board, folder)
    else:
        raise ValueError(f"{folder}: no intrinsics and no chessboard to refit them from")
    return RealSet(folder.name, samples.layout, views, intrinsics, source, target, flat)


def feed_session(session, real: RealSet, *,
                 on_image: Callable[[int, Any], None] | None = None) -> None:
    """Give every view of ``real`` to ``session`` (configured with :meth:`RealSet.parameters`):
    the camera's intrinsics, then each image with its pose at a stamp one second after the
    previous (``add_image`` with the pose, as from tf)."""
    session.set_camera_info(CAMERA, real.intrinsics)
    for i, view in enumerate(real.views):
        outcome = session.add_image(CAMERA, (i + 1) * 1_000_000_000, view.gray(),
                                    T_parent_child=view.T_base_tool)
        if on_image is not None:
            on_image(i, outcome)
