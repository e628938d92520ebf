"""The evidence behind the perception defaults, on the real sets and on renders (a part of
``benchmarks/real_data.py``, which prints it after the per-set tables)."""

from __future__ import annotations

import sys
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rwhec_ros.core.lie import invert_transform, rotation_distance  # noqa: E402
from rwhec_ros.vision.board_detection import charuco_detector  # noqa: E402
from rwhec_ros.vision.detection import tag_object_points  # noqa: E402
from rwhec_ros.vision.detector_config import DetectorConfig  # noqa: E402
from rwhec_ros.vision.edges import refine_corners_edges  # noqa: E402
from rwhec_ros.vision.families import get_dictionary  # noqa: E402
from rwhec_ros.vision.grid_detection import GridFinder, centre_bias  # noqa: E402
from rwhec_ros.vision.grids import ChessboardSpec, CircleGridSpec  # noqa: E402
from rwhec_ros.vision.intrinsics import CameraIntrinsics  # noqa: E402
from rwhec_ros.vision.planar_pose import solve_planar_pose  # noqa: E402
from rwhec_ros.vision.render import RenderedBoard, look_at, render_tags  # noqa: E402
from rwhec_ros.vision.target_detector import TargetDetector  # noqa: E402
from rwhec_ros.vision.targets import TargetSpec  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from real_sets import load_set as read_samples  # noqa: E402

SETS = ("ic_charuco", "ic_circle_10x10", "cct_chessboard_eye_in_hand")
VGA = CameraIntrinsics.pinhole(640, 480, 500.0)


def _rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(e)))) if len(e) else float("nan")


# ----------------------------------------------------------------------------------- the gate
def gate_table(data: Path) -> None:
    print("### Reprojection gate: fixed 1 px vs scaled to the camera's corner noise\n")
    print("| set | views with the target posed | kept, fixed gate (1 px) | kept, scaled gate "
          "(floor 1 px, 4x the median corner noise) | pose RMS median / max (px) |")
    print("|---|---|---|---|---|")
    for name in SETS:
        if not (data / name).is_dir():
            continue
        samples = read_samples(data / name)
        det = TargetDetector([samples.target])
        fixed = scaled = posed = 0
        history: list[float] = []
        rms = []
        for v in samples.views:
            g = v.gray()
            a = det.detect(g, samples.intrinsics)
            b = det.detect(g, samples.intrinsics, noise_history=history)
            history.extend(b.corner_noise_px.values())
            posed += bool(b.corner_noise_px)
            fixed += bool(a.observations)
            scaled += bool(b.observations)
            rms += [o.reprojection_rms_px for o in b.observations]
        print(f"| {name} | {posed} | {fixed} | {scaled} | {np.median(rms):.2f} / "
              f"{np.max(rms):.2f} |")
    print("\nThe fixed 1 px gate was tuned on renders (0.01-0.05 px); real views posed through "
          "nominal or refitted intrinsics reproject at 0.1-1.1 px. The scaled gate rejects a "
          "pose whose corner noise exceeds 4 times the median of the camera's poses (itself "
          "included), never one below the 1 px floor, so renders are judged as before.\n")


# ------------------------------------------------------------------------ chessboard corners
def _view(rng, distance, obliquity_deg):
    th, ph = np.deg2rad(obliquity_deg), rng.uniform(0, 2 * np.pi)
    pos = distance * np.array([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
    return invert_transform(look_at(pos, np.r_[rng.normal(0, 0.05 * distance, 2), 0.0],
                                    up=rng.normal(size=3)))


def chessboard_table(data: Path) -> None:
    spec = ChessboardSpec(9, 6, 0.03)
    print("### Chessboard corners: `sb` (findChessboardCornersSB as found) vs `subpix` "
          "(cornerSubPix after it)\n")
    print("Renders (640x480, f = 500 px, 3 cm squares, blur 0.6 px, noise 2 grey levels, 8 "
          "views per row; corner error against the render's truth):\n")
    print("| distance (m) | square (px) | obliquity (deg) | found | sb corner RMS (px) | "
          "subpix corner RMS (px) |")
    print("|---|---|---|---|---|---|")
    finders = {m: GridFinder(TargetSpec("b", board=spec), DetectorConfig(
        chessboard_refinement=m)) for m in ("sb", "subpix")}
    totals = {m: [] for m in finders}
    for dist in (0.6, 1.2):
        for obl in (0, 30, 50):
            rng = np.random.default_rng(int(10 * dist) + obl)
            errs = {m: [] for m in finders}
            found = 0
            for _ in range(8):
                T = _view(rng, dist, obl)
                img = render_tags(VGA, [RenderedBoard(spec, T)], blur_sigma=0.6, noise_std=2.0,
                                  rng=rng, supersample=3)
                pts = {m: f.find(img, VGA)[0] for m, f in finders.items()}
                if any(p is None for p in pts.values()):
                    continue
                found += 1
                for m, p in pts.items():
                    e = np.linalg.norm(p.image_points - VGA.project_points(p.object_points, T),
                                       axis=1)
                    errs[m].append(e)
                    totals[m].append(e)
            cells = [f"{_rms(np.concatenate(errs[m])):.3f}" if errs[m] else "-"
                     for m in finders]
            print(f"| {dist} | {500 * 0.03 / dist:.0f} | {obl} | {found}/8 | {cells[0]} | "
                  f"{cells[1]} |")
    cct = data / "cct_chessboard_eye_in_hand"
    if cct.is_dir():
        samples = read_samples(cct)
        cols, rows = samples.target.board.pattern_size
        grid = np.zeros((rows * cols, 3), np.float32)
        grid[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * samples.target.board.pitch
        print("\nReal (cct_chessboard_eye_in_hand, 6 views 960x540, strong barrel distortion): "
              "`cv2.calibrateCamera` on each corner set (plumb_bob); a lower RMS means corners "
              "more consistent with one camera model:\n")
        print("| corners | calibrateCamera RMS (px) | fx (px) |")
        print("|---|---|---|")
        grays = [v.gray() for v in samples.views]
        crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 50, 1e-3)
        for label in ("sb", "sb + ACCURACY flag", "subpix (package rule: 0.4 x spacing)",
                      "classic findChessboardCorners + cornerSubPix 11x11"):
            pts = []
            for g in grays:
                if label == "sb + ACCURACY flag":
                    ok, c = cv2.findChessboardCornersSB(
                        g, (cols, rows), flags=cv2.CALIB_CB_ACCURACY | cv2.CALIB_CB_NORMALIZE_IMAGE)
                elif label.startswith("classic"):
                    ok, c = cv2.findChessboardCorners(g, (cols, rows))
                    if ok:
                        c = cv2.cornerSubPix(g, c, (5, 5), (-1, -1), crit)
                else:
                    ok, c = cv2.findChessboardCornersSB(g, (cols, rows))
                    if ok and label.startswith("subpix"):
                        c = GridFinder._subpix(g, np.asarray(c, float).reshape(rows, cols, 2))
                pts.append(np.asarray(c, np.float32).reshape(-1, 1, 2) if ok else None)
            ok_pts = [p for p in pts if p is not None]
            rms, K, *_ = cv2.calibrateCamera([grid] * len(ok_pts), ok_pts, grays[0].shape[::-1],
                                             None, None)
            print(f"| {label} ({len(ok_pts)} views) | {rms:.3f} | {K[0, 0]:.1f} |")
        print("\n`sb` is the default: the most consistent corners on the real set (subpix is "
              "better on renders at an angle, worse on these real JPEG views); the classic "
              "detector's order is not consistent between these views (its RMS is that of "
              "turned boards), one more reason for the sector-based one.\n")
    print(f"Renders, all rows: sb {_rms(np.concatenate(totals['sb'])):.3f} px, subpix "
          f"{_rms(np.concatenate(totals['subpix'])):.3f} px.\n")


# ------------------------------------------------------------------------- marker corners
def marker_table(data: Path) -> None:
    folder = data / "ic_charuco"
    if not folder.is_dir():
        return
    samples = read_samples(folder)
    board, intr = samples.target.board, samples.intrinsics
    chess = board.corner_object_points()
    modes = ("edge", "subpix", "apriltag", "contour", "none")
    err = {m: [] for m in modes}
    pnp = {m: [] for m in modes}
    for v in samples.views:
        g = v.gray()
        cc, ci, _, _ = charuco_detector(board, DetectorConfig()).detectBoard(g)
        if ci is None:
            continue
        pos = {int(i): p for i, p in zip(ci.ravel(), cc.reshape(-1, 2).astype(float),
                                         strict=True)}
        for mode in modes:
            ad = cv2.aruco.ArucoDetector(get_dictionary(board.dictionary),
                                         DetectorConfig(corner_refinement=mode).aruco_parameters())
            corners, ids, _ = ad.detectMarkers(g)
            for mid, q in zip(() if ids is None else ids.ravel(), corners, strict=False):
                if int(mid) not in board.marker_ids:
                    continue
                q = q.reshape(4, 2).astype(float)
                if mode == "edge":
                    out = refine_corners_edges(g, q, intr, 8)
                    if out is not None:
                        q = out[1]
                pose = solve_planar_pose(tag_object_points(board.marker_size), q,
                                         intr.undistort_points(q), intr, square=True,
                                         min_ratio=1.0)
                if pose.T is not None:
                    pnp[mode].append(pose.rms_px)
                mo = board.marker_object_points(int(mid))
                c, h = mo[:, :2].mean(axis=0), 0.5 * board.square_size
                square = np.array([c + [sx * h, sy * h]
                                   for sx, sy in ((-1, 1), (1, 1), (1, -1), (-1, -1))])
                idx = []
                for p in square:
                    d = np.linalg.norm(chess[:, :2] - p, axis=1)
                    idx.append(int(np.argmin(d)) if d.min() < 1e-6 else -1)
                if not all(i in pos for i in idx):
                    continue
                H, _ = cv2.findHomography(square, np.array([pos[i] for i in idx]), 0)
                pred = cv2.perspectiveTransform(mo[:, :2].reshape(-1, 1, 2), H).reshape(-1, 2)
                err[mode].append(np.linalg.norm(q - pred, axis=1))
    print("### Marker corner refinement on real markers (ic_charuco, 16 views 1600x1200, "
          "DICT_6X6_250 markers of ~70-110 px)\n")
    print("Each marker sits in a square whose four corners are ChArUco saddle points "
          "(`CharucoDetector`, cornerSubPix-refined); their homography predicts the marker's "
          "corners (lens distortion is negligible over one square). Errors include the "
          "printed marker's size and placement tolerance (the set's README: the board's scale "
          "is off by about 3 %, i.e. ~1 px at a marker corner), the same for every mode.\n")
    print("| corner refinement | marker corners | error vs the saddle-point prediction: RMS / "
          "median / 90 % (px) | 4-corner PnP RMS per marker: median / max (px) |")
    print("|---|---|---|---|")
    for m in modes:
        e = np.concatenate(err[m]) if err[m] else np.zeros(0)
        print(f"| {m} | {len(e)} | {_rms(e):.2f} / {np.median(e):.2f} / "
              f"{np.percentile(e, 90):.2f} | {np.median(pnp[m]):.3f} / {np.max(pnp[m]):.3f} |")
    print("\n`edge` stays the default for tag corners: the lowest error against the saddle "
          "points and the lowest 4-corner PnP RMS on these real markers, as on renders "
          "(`benchmarks/perception.md`). The real AprilTag set of issue 41 (held out here) "
          "lost tags to the fixed 1 px gate, not to the refinement: the scaled gate keeps "
          "them.\n")


# --------------------------------------------------------------------------- circle bias
def circle_bias_table() -> None:
    print("### Circle-centre projection bias at 45 degrees (renders)\n")
    print("| circles | distance (m) | circle (px) | largest bias (px) | point error, raw blob "
          "centres (px RMS) | corrected (px RMS) | pose error raw: t (mm) / R (deg) | "
          "corrected |")
    print("|---|---|---|---|---|---|---|---|")
    for label, spec, dist in (
            ("4 x 11 asymmetric, 1 cm every 2 cm (OpenCV's)",
             CircleGridSpec(4, 11, 0.02, asymmetric=True, diameter=0.01), 0.5),
            ("6 x 5 with origin, 2 cm every 4 cm", CircleGridSpec(
                6, 5, 0.04, origin_circle=True, diameter=0.02), 0.5),
            ("5 x 4 with origin, 2 cm every 3.5 cm", CircleGridSpec(
                5, 4, 0.035, origin_circle=True, diameter=0.02), 0.35)):
        finder = GridFinder(TargetSpec("b", board=spec), DetectorConfig())
        rng = np.random.default_rng(7)
        raw_e, cor_e, bias_max = [], [], 0.0
        pose_raw, pose_cor = [], []
        for k in range(6):
            ph = 2 * np.pi * k / 6
            pos = dist * np.array([np.sin(np.pi / 4) * np.cos(ph),
                                   np.sin(np.pi / 4) * np.sin(ph), np.cos(np.pi / 4)])
            T = invert_transform(look_at(pos, [0, 0, 0], up=rng.normal(size=3)))
            img = render_tags(VGA, [RenderedBoard(spec, T)], blur_sigma=0.6, noise_std=2.0,
                              rng=rng, supersample=4)
            pts, _, _ = finder.find(img, VGA)
            if pts is None:
                continue
            bias = centre_bias(pts.object_points, finder.circle_radii(pts), T, VGA)
            raw = pts.image_points + bias  # the blob centres before the correction
            truth = VGA.project_points(pts.object_points, T)
            raw_e.append(np.linalg.norm(raw - truth, axis=1))
            cor_e.append(np.linalg.norm(pts.image_points - truth, axis=1))
            bias_max = max(bias_max, float(np.max(np.linalg.norm(bias, axis=1))))
            for img_pts, out in ((raw, pose_raw), (pts.image_points, pose_cor)):
                p = solve_planar_pose(pts.object_points, img_pts, VGA.undistort_points(img_pts),
                                      VGA, min_ratio=1.0)
                out.append((1e3 * np.linalg.norm(p.T[:3, 3] - T[:3, 3]),
                            np.degrees(rotation_distance(p.T[:3, :3], T[:3, :3]))))
        px = 500 * spec.printed_diameter / dist
        if not raw_e:
            print(f"| {label} | {dist} | {px:.0f} | not found | | | | |")
            continue
        pr, pc = np.max(pose_raw, axis=0), np.max(pose_cor, axis=0)
        print(f"| {label} | {dist} | {px:.0f} | {bias_max:.2f} | "
              f"{_rms(np.concatenate(raw_e)):.3f} | {_rms(np.concatenate(cor_e)):.3f} | "
              f"{pr[0]:.2f} / {pr[1]:.3f} | {pc[0]:.2f} / {pc[1]:.3f} |")
    print("\n640x480, f = 500 px, six views 45 degrees off the normal (all around), blur 0.6 "
          "px, noise 2 grey levels, 16 samples/pixel; raw = the blob centres before the "
          "correction; pose errors are the worst of the six views. The bias grows with the "
          "circles' size in the image; the correction (`grid_detection.centre_bias` at a first "
          "pose) removes it, leaving the blob detector's noise.\n")


def print_all(data: Path) -> None:
    print("## Perception defaults: the evidence\n")
    gate_table(data)
    chessboard_table(data)
    marker_table(data)
    circle_bias_table()
