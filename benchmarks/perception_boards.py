"""Board section of the perception benchmark (imported by ``benchmarks/perception.py``).

Tables: pose accuracy of single tags vs a Kalibr AprilGrid vs a ChArUco board at 0.5-3 m; the
pose-flip rate on small far tags without and with the flip check (and with a predicted pose);
the ratio threshold sweep behind ``DetectorConfig.flip_min_ratio``; Kalibr corner squares and the
extra threshold passes of ``TargetDetector``. Seeds are fixed: the tables are reproducible.
"""

from __future__ import annotations

import numpy as np

from rwhec_ros.core.lie import invert_transform, rotation_distance, so3_exp
from rwhec_ros.vision.boards import AprilGridSpec, CharucoSpec
from rwhec_ros.vision.detection import DetectorConfig, TagDetector, tag_object_points
from rwhec_ros.vision.intrinsics import CameraIntrinsics
from rwhec_ros.vision.planar_pose import solve_planar_pose
from rwhec_ros.vision.render import RenderedBoard, RenderedTag, look_at, render_tags
from rwhec_ros.vision.target_detector import TargetDetector
from rwhec_ros.vision.targets import TargetSpec

NOISE_STD = 2.0
BLUR_SIGMA = 0.6
CAM_HD = CameraIntrinsics.pinhole(1280, 1024, 1000.0)
#: Kalibr-style grid (2-bit borders, corner squares) and ChArUco board of about 0.4 m.
GRID = AprilGridSpec(6, 6, tag_size=0.055, tag_spacing=0.3)
CHARUCO = CharucoSpec(8, 6, square_size=0.05, marker_size=0.037, dictionary="DICT_5X5_100")


def _view(rng: np.random.Generator, distance: float, max_obliquity_deg: float,
          aim_std: float) -> np.ndarray:
    """T_cam_target: camera at ``distance`` within ``max_obliquity_deg`` of the normal."""
    th = np.deg2rad(rng.uniform(0.0, max_obliquity_deg))
    ph = rng.uniform(0.0, 2 * np.pi)
    pos = distance * np.array([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)])
    aim = np.r_[rng.normal(0.0, aim_std, 2), 0.0]
    return invert_transform(look_at(pos, aim, up=[0.0, 1.0, 0.0]))


def _deg(R1: np.ndarray, R2: np.ndarray) -> float:
    return float(np.degrees(rotation_distance(R1, R2)))


def _fmt(values: list[float], digits: int) -> str:
    if not values:
        return "-"
    return f"{np.mean(values):.{digits}f} / {np.max(values):.{digits}f}"


# --------------------------------------------------------------------------- accuracy
def board_accuracy_table(distances=(0.5, 1.0, 1.5, 2.0, 3.0), n_views: int = 8,
                         supersample: int = 3) -> list[str]:
    """Single tags (16 cm; 40 cm, the boards' plate size) vs the grid vs the ChArUco board."""
    candidates = {
        "tag 16 cm": TargetSpec("t", tag_id=0, tag_size=0.16),
        "tag 40 cm": TargetSpec("t", tag_id=0, tag_size=0.40),
        "AprilGrid 6x6 (41 cm)": TargetSpec("t", board=GRID),
        "ChArUco 8x6 (40x30 cm)": TargetSpec("t", board=CHARUCO),
    }
    rows = [
        "| target | distance (m) | detected | corners used | t mean / max (mm) "
        "| R mean / max (deg) |",
        "|---|---|---|---|---|---|",
    ]
    for label, spec in candidates.items():
        det = TargetDetector([spec], DetectorConfig())
        for d in distances:
            rng = np.random.default_rng(int(1000 * d))
            t_err, r_err, corners, n_det = [], [], [], 0
            for _ in range(n_views):
                T = _view(rng, d, 45.0, 0.03 * d)
                item = (RenderedTag(0, T, spec.tag_size) if spec.board is None
                        else RenderedBoard(spec.board, T))
                img = render_tags(CAM_HD, [item], noise_std=NOISE_STD, blur_sigma=BLUR_SIGMA,
                                  rng=rng, supersample=supersample)
                obs = det.detect(img, CAM_HD).observations
                if not obs:
                    continue
                n_det += 1
                o = obs[0]
                t_err.append(1000 * float(np.linalg.norm(o.T_cam_target[:3, 3] - T[:3, 3])))
                r_err.append(_deg(o.T_cam_target[:3, :3], T[:3, :3]))
                corners.append(o.n_corners)
            rows.append(
                f"| {label} | {d:.1f} | {n_det}/{n_views} "
                f"| {np.mean(corners) if corners else 0:.0f} | {_fmt(t_err, 2)} "
                f"| {_fmt(r_err, 3)} |"
            )
    return rows


# --------------------------------------------------------------------------- flips
CAM_FLIP = CameraIntrinsics.pinhole(480, 400, 1000.0)
FLIP_SIZE = 0.08


def _flip_samples(distances, n_views: int):
    """Per view: (distance, side px, ratio, separation, flip of the best-reprojecting pose,
    ambiguous-check outcome, outcome with a prediction) for 8 cm tags, 0-30 deg off face-on."""
    off = TagDetector(DetectorConfig(default_tag_size=FLIP_SIZE, flip_min_ratio=1.0))
    on = TagDetector(DetectorConfig(default_tag_size=FLIP_SIZE))
    out = []
    for d in distances:
        rng = np.random.default_rng(int(10 * d))
        for _ in range(n_views):
            T = _view(rng, d, 30.0, 0.05)
            img = render_tags(CAM_FLIP, [RenderedTag(0, T, FLIP_SIZE)], noise_std=NOISE_STD,
                              blur_sigma=BLUR_SIGMA, rng=rng)
            res = off.detect(img, CAM_FLIP)
            if not res.observations:
                continue
            o = res.observations[0]
            pose = solve_planar_pose(tag_object_points(FLIP_SIZE), o.corners,
                                     CAM_FLIP.undistort_points(o.corners), CAM_FLIP, square=True)

            def flipped(T_kept, T=T, pose=pose):
                if pose.alternative is None or pose.separation_deg < 2.0:
                    return False
                other = pose.alternative if np.allclose(T_kept, pose.T) else pose.T
                return _deg(T[:3, :3], T_kept[:3, :3]) > _deg(T[:3, :3], other[:3, :3])

            res_on = on.detect(img, CAM_FLIP)
            predicted = T.copy()
            predicted[:3, :3] = T[:3, :3] @ so3_exp(np.deg2rad(rng.normal(0.0, 2.0, 3)))
            res_pred = on.detect(img, CAM_FLIP, predicted={0: predicted})
            out.append({
                "d": d, "side": o.side_px, "err": _deg(T[:3, :3], o.T_cam_tag[:3, :3]),
                "ratio": pose.ratio if pose.separation_deg >= 2.0 else np.inf,
                "flip": flipped(o.T_cam_tag),
                "on": None if not res_on.observations else flipped(res_on.observations[0]
                                                                    .T_cam_tag),
                "pred": None if not res_pred.observations else flipped(
                    res_pred.observations[0].T_cam_tag),
                "pred_err": (_deg(T[:3, :3], res_pred.observations[0].T_cam_tag[:3, :3])
                             if res_pred.observations else np.nan),
            })
    return out


def flip_tables(distances=(1.5, 2.0, 2.5, 3.0, 3.5), n_views: int = 60) -> list[str]:
    samples = _flip_samples(distances, n_views)
    rows = [
        "| distance (m) | side (px) | detected | flips, no check | check (ratio >= 3): kept "
        "/ flips among kept / rejected ambiguous | with a prediction (truth + 2 deg): kept / "
        "flips | R max kept, no check / with prediction (deg) |",
        "|---|---|---|---|---|---|---|",
    ]
    for d in distances:
        s = [x for x in samples if x["d"] == d]
        flips = sum(x["flip"] for x in s)
        kept = [x for x in s if x["on"] is not None]
        pred = [x for x in s if x["pred"] is not None]
        rows.append(
            f"| {d:.1f} | {np.mean([x['side'] for x in s]):.0f} | {len(s)}/{n_views} "
            f"| {flips} ({100 * flips / max(len(s), 1):.0f} %) "
            f"| {len(kept)} / {sum(x['on'] for x in kept)} / {len(s) - len(kept)} "
            f"| {len(pred)} / {sum(x['pred'] for x in pred)} "
            f"| {max(x['err'] for x in s):.1f} / "
            f"{np.nanmax([x['pred_err'] for x in pred]) if pred else float('nan'):.1f} |"
        )
    sweep = [
        "| flip_min_ratio | kept | flips among kept | kept at >= 30 px | kept below 30 px |",
        "|---|---|---|---|---|",
    ]
    for thr in (1.0, 2.0, 3.0, 5.0, 10.0):
        kept = [x for x in samples if x["ratio"] >= thr]
        big = [x for x in samples if x["side"] >= 30]
        small = [x for x in samples if x["side"] < 30]
        sweep.append(
            f"| {thr:g} | {len(kept)}/{len(samples)} | {sum(x['flip'] for x in kept)} "
            f"| {sum(x['ratio'] >= thr for x in big)}/{len(big)} "
            f"| {sum(x['ratio'] >= thr for x in small)}/{len(small)} |"
        )
    return rows + [""] + sweep


# --------------------------------------------------------------------------- Kalibr squares
def corner_square_table(distances=(0.6, 1.2, 1.7, 2.2, 2.8)) -> list[str]:
    """Grid tags found (of 20) with aruco's default threshold only vs the extra passes."""
    cam = CameraIntrinsics.pinhole(1024, 768, 900.0)
    grid = AprilGridSpec(4, 5, tag_size=0.06, tag_spacing=0.3)
    spec = [TargetSpec("g", board=grid, min_corners=4)]
    rows = ["| contrast (black/white) | distance (m) | tag side (px) | tags found, default "
            "threshold only | tags found, passes 7/20/40 |", "|---|---|---|---|---|"]
    for lo, hi in ((30, 225), (70, 170), (90, 140)):
        one = TargetDetector(spec, grid_threshold_constants=(7.0,))
        multi = TargetDetector(spec)
        for d in distances:
            T = invert_transform(look_at([0.25, -0.2, d], [0.0, 0.0, 0.0], up=[0, 1, 0]))
            img = render_tags(cam, [RenderedBoard(grid, T)], noise_std=NOISE_STD,
                              blur_sigma=BLUR_SIGMA, rng=np.random.default_rng(0),
                              black_level=lo, white_level=hi, supersample=3)

            def found(det, img=img):
                return sum(o.n_corners for o in det.detect(img, cam).observations) // 4

            rows.append(f"| {lo}/{hi} | {d:.1f} | {900 * 0.06 / d:.0f} | {found(one)}/20 "
                        f"| {found(multi)}/20 |")
    return rows
