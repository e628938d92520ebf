"""End-to-end board section of the perception benchmark (imported by ``benchmarks/perception.py``;
``python benchmarks/perception_end_to_end.py`` prints this section alone, ``--layout TEXT`` only
the layouts whose label contains TEXT, e.g. ``--layout Kalibr``, ``--seeds 0 1 2 3`` other seeds
of the noise).

The demo rig (3 cameras 640x480, f = 500 px, the demo trajectory for 24 s) among 6 targets on a
ring of radius 2 m, calibrated through the real :class:`~rwhec_ros.session.CalibrationSession`
(keyframes, motion gate, detector gates, per-pair noise ``noise.from_reprojection``, ``fast``
solve): single tags vs boards at the same six poses, the same trajectory and the same number of
images (2 Hz: 48 per camera). Each layout's images are rendered once and fed to two sessions:
one with the demo's noisy motion-capture poses (0.5 mm and 0.5 mrad per axis), one with the
exact poses, which separates the error the pose stream brings from the one the detections bring.
The last columns are the errors of the kept pairs' ``B`` against the truth
``Y_k^-1 A X_j`` (exact-pose session: ``A`` is the truth up to interpolation). Seeds are fixed.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rwhec_ros.cli.replay import demo_parameters  # noqa: E402
from rwhec_ros.config import CalibratorConfig  # noqa: E402
from rwhec_ros.core.lie import invert_transform, rotation_distance  # noqa: E402
from rwhec_ros.session import CalibrationSession  # noqa: E402
from rwhec_ros.simulation import demo_rig  # noqa: E402
from rwhec_ros.vision.boards import AprilGridSpec, CharucoSpec  # noqa: E402

NS = 1_000_000_000
KALIBR_LABEL = "Kalibr's AprilGrid 6x6, 88 mm tags (66 cm pattern, ~0.8 m printed: larger)"
POSE_NOISE = 5e-4  # m and rad per axis: the demo's motion capture

#: label -> (plate size [m] of a single tag, or None; board of position j, or None)
LAYOUTS = {
    "single tags (25 cm, the demo's)": (0.25, None),
    "single tags (40 cm)": (0.40, None),
    "AprilGrid 3x3 (43 cm)": (None, lambda j: AprilGridSpec(3, 3, tag_size=0.12,
                                                            tag_spacing=0.3,
                                                            first_id=100 + 9 * j)),
    "ChArUco 5x4 (40x32 cm)": (None, lambda j: CharucoSpec(5, 4, square_size=0.08,
                                                           marker_size=0.06,
                                                           dictionary="DICT_4X4_250",
                                                           first_id=10 * j)),
    # the board Kalibr users print (its standard aprilgrid: 6x6 tags of 88 mm, tagSpacing 0.3,
    # on A0): a LARGER board than the targets above, 66 cm of pattern
    KALIBR_LABEL: (None, lambda j: AprilGridSpec(6, 6, tag_size=0.088, tag_spacing=0.3,
                                                 first_id=100 + 36 * j)),
}


def _deg(R1: np.ndarray, R2: np.ndarray) -> float:
    return float(np.degrees(rotation_distance(R1, R2)))


def _run(label: str, room_radius: float, image_rate_hz: float, duration_s: float,
         out: Path, seed: int = 0) -> list[dict]:
    """Both sessions of one layout: a dict per pose-noise setting."""
    plate, make = LAYOUTS[label]
    rig = demo_rig(n_cameras=3, n_tags=6, room_radius=room_radius,
                   tag_size=plate if plate is not None else 0.25,
                   boards=None if make is None else {j: make(j) for j in range(6)})
    sessions = {}
    for noisy in (True, False):
        flat = demo_parameters(rig, output_directory=str(out / f"{noisy}"))
        flat["noise.from_reprojection"] = True
        config = CalibratorConfig.from_parameters(flat)
        session = CalibrationSession(config)
        for cam in rig.cameras:
            session.set_camera_info(cam, rig.intrinsics[cam])
        sessions[noisy] = (session, config.pose_source.parent)
    image_rng, pose_rng = np.random.default_rng(2 * seed), np.random.default_rng(2 * seed + 1)
    pose_period, image_period = NS // 100, int(round(NS / image_rate_hz))
    end = int(round(duration_s * NS))
    images = [(s, 1) for s in range(pose_period // 2, end, image_period)]
    for s, kind in sorted([(s, 0) for s in range(0, end + 1, pose_period)] + images):
        t = s / NS
        if kind == 0:
            exact = rig.T_world_rig(t)
            measured = rig.pose_measurement(t, pose_rng, POSE_NOISE, POSE_NOISE)
            for noisy, (session, parent) in sessions.items():
                session.add_pose(NS + s, measured if noisy else exact, source=parent)
            continue
        for cam in rig.cameras:
            gray = rig.render(cam, rig.T_world_rig(t), image_rng, supersample=2)
            for session, _ in sessions.values():
                session.add_image(cam, NS + s, gray)
    rows = []
    positions = rig.target_names()
    for noisy, (session, _) in sessions.items():
        outcome = session.calibrate()
        row = {"noisy": noisy, "pairs": session.counters().get("pairs_kept", 0)}
        if outcome.result is not None:
            res = outcome.result
            r_err = [_deg(Y[:3, :3], rig.T_rig_cam[n][:3, :3])
                     for n, Y in zip(res.y_names, res.Y, strict=True)]
            t_err = [1e3 * float(np.linalg.norm(Y[:3, 3] - rig.T_rig_cam[n][:3, 3]))
                     for n, Y in zip(res.y_names, res.Y, strict=True)]
            row.update(certified=res.certified, r=r_err, t=t_err,
                       missing=sorted(set(rig.cameras) - set(res.y_names)))
        if not noisy and outcome.files.get("dataset"):
            from rwhec_ros.data.dataset import Dataset

            b_t, b_r = [], []
            for e in Dataset.load(outcome.files["dataset"]).edges:
                X = rig.T_world_tag[positions[e.x]]
                Y_inv = invert_transform(rig.T_rig_cam[e.y])
                for A, B in zip(e.A, e.B, strict=True):
                    B_true = Y_inv @ A @ X
                    b_t.append(1e3 * float(np.linalg.norm(B[:3, 3] - B_true[:3, 3])))
                    b_r.append(_deg(B[:3, :3], B_true[:3, :3]))
            row.update(b_t=np.array(b_t), b_r=np.array(b_r))
        rows.append(row)
    for session, _ in sessions.values():
        session.close()
    return rows


def end_to_end_table(room_radius: float = 2.0, image_rate_hz: float = 2.0,
                     duration_s: float = 24.0, seeds: tuple[int, ...] = (0, 1, 2),
                     layouts: tuple[str, ...] | None = None) -> list[str]:
    """The Markdown tables of the module docstring: every column for the first seed, then the
    worst camera translation error of each seed (image noise and pose noise drawn anew);
    ``layouts``: labels of :data:`LAYOUTS` (default all)."""
    worst: dict[tuple[str, bool], list[str]] = {}
    lines = ["| targets | motion-capture noise | pairs kept | certified | worst camera error: "
             "R (deg) / t (mm) | mean camera error: R (deg) / t (mm) | B error of the kept "
             "pairs, median / 95 %: t (mm), R (deg) |", "|---|---|---|---|---|---|---|"]
    b_stats = {}
    with tempfile.TemporaryDirectory() as tmp:
        for label in (LAYOUTS if layouts is None else layouts):
            for seed in seeds[1:]:
                for row in _run(label, room_radius, image_rate_hz, duration_s,
                                Path(tmp) / f"{label}{seed}", seed):
                    worst.setdefault((label, row["noisy"]), []).append(
                        f"{max(row['t']):.2f}" if "t" in row else "-")
            for row in _run(label, room_radius, image_rate_hz, duration_s, Path(tmp) / label,
                            seeds[0]):
                worst.setdefault((label, row["noisy"]), []).insert(
                    0, f"{max(row['t']):.2f}" if "t" in row else "-")
                if "b_t" in row:
                    b_stats[label] = row
                noise = "0.5 mm, 0.5 mrad" if row["noisy"] else "none (exact poses)"
                if "r" not in row:
                    lines.append(f"| {label} | {noise} | {row['pairs']} | no result | | | |")
                    continue
                miss = f" (not calibrated: {row['missing']})" if row["missing"] else ""
                b = ""
                if label in b_stats and not row["noisy"]:
                    bt, br = b_stats[label]["b_t"], b_stats[label]["b_r"]
                    b = (f"{np.median(bt):.2f} / {np.percentile(bt, 95):.2f} mm, "
                         f"{np.median(br):.3f} / {np.percentile(br, 95):.3f} deg")
                lines.append(
                    f"| {label} | {noise} | {row['pairs']} | {row['certified']} "
                    f"| {max(row['r']):.3f} / {max(row['t']):.2f}{miss} "
                    f"| {np.mean(row['r']):.3f} / {np.mean(row['t']):.2f} | {b} |")
    lines += ["", f"Worst camera translation error (mm) per seed {list(seeds)} (first: the "
              "table above):", "", "| targets | motion-capture noise | worst camera t (mm) "
              "per seed |", "|---|---|---|"]
    for (label, noisy), values in worst.items():
        noise = "0.5 mm, 0.5 mrad" if noisy else "none"
        lines.append(f"| {label} | {noise} | {', '.join(values)} |")
    return lines


#: Printed under the tables by ``benchmarks/perception.py``: the set-up and the reading of the
#: run committed in ``benchmarks/perception.md`` (numbers quoted from it).
EXPLANATION = (
    "The demo rig (3 cameras 640x480, f = 500 px, the demo trajectory for 24 s, images at 2 Hz: "
    "48 per camera) among 6 targets on a 2 m ring, calibrated through the real "
    "`CalibrationSession` (keyframes, motion gate, detector gates, `noise.from_reprojection`, "
    "`fast`): the same six poses hold single tags or boards (each board with its own ids). Each "
    "layout's images are rendered once and fed to two sessions, one with the demo's noisy "
    "motion-capture poses, one with the exact poses; the B errors are those of the kept pairs "
    "of the exact-pose session against `Y_k^-1 A X_j`.\n\n"
    "Reading (issue 12's target: a board reduces the worst end-to-end camera error by >= 2x at "
    "2 m; not met). Against the demo's 25 cm tags the 43 cm AprilGrid gives 1.4-2.4x lower "
    "worst camera errors over the three seeds (1.9x on the worst of each); against a single "
    "40 cm tag of the same size it gives no gain with exact poses (0.48-0.63 mm vs 0.34-0.42 "
    "mm) and a steadier result with noisy ones (0.77-0.96 mm vs 0.75-1.66 mm). What dominates: "
    "(1) the target's extent in the image, not its number of corners: the 40 cm tag's four "
    "corners come from edge-line fits along 100-px edges and give B rotations as precise as "
    "the grid's 36 corners (median 0.079 vs 0.077 deg); the grid gains over the 25 cm tag "
    "because it is larger. (2) The pose stream: at the demo's 0.5 mm / 0.5 mrad per axis, "
    "exact poses halve the error of the large targets (0.36 vs 0.75, 0.61 vs 0.96 mm), so "
    "about 0.7 mm (in quadrature) of the worst camera error comes from A whatever the target; "
    "the grid's "
    "advantage with noisy poses is its number of pairs (148 vs 89 kept: it still gives a pose "
    "when partly in view, a single tag must be entirely in the image), which averages that "
    "noise. (3) ChArUco at this scale (8 cm squares at 2 m: 20 px, 6 cm markers: 15 px) is "
    "worse than single tags: OpenCV's interpolated ChArUco corners give B errors of 1.7 mm / "
    "0.9 deg median (cf. the board table: ChArUco degrades fastest with distance). A 2x gain at "
    "2 m would need a board that is larger in the image than the single tags it replaces, or a "
    "more precise pose stream.\n\n"
    "Kalibr's standard AprilGrid (the last rows; a LARGER board than the others: 6x6 tags of 88"
    " mm, tagSpacing 0.3, 66 cm of pattern, ~0.8 m printed on A0; same six poses, trajectory, "
    "image budget and seeds; run on its own with `--layout Kalibr`, next to a re-run of the 25 "
    "cm rows with `--layout '25 cm'` that reproduced them to the digit): worst camera error "
    "0.46, 0.73, 0.32 mm with the noisy poses and 0.16, 0.26, 0.18 mm with exact ones, against "
    "1.71, 1.14, 1.82 and 1.10, 0.91, 1.44 mm for the demo's 25 cm tags: 3.7x, 1.6x and 5.7x "
    "lower per seed with the noisy poses (2.5x on the worst of each), 3.5-8.0x with exact ones."
    " So the 2x at 2 m is reached, in two seeds of three with the demo's pose noise, by a board"
    " much larger in the image than the tags it replaces (66 vs 25 cm; 173 pairs kept vs 104; B"
    " rotation median 0.048 deg vs 0.222), as the reading above says it would need; the boards "
    "of the demo's size above still miss it. Against the 40 cm single tag it is 1.6-2.9x lower "
    "with noisy poses and 1.3-2.3x with exact ones."
)


def main(argv: list[str] | None = None) -> None:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--layout", action="append", default=[], metavar="TEXT",
                        help="only the layouts whose label contains TEXT (repeatable)")
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], metavar="N",
                        help="seeds of the image and pose noise (default 0 1 2; the first one "
                             "gets every column)")
    args = parser.parse_args(argv)
    layouts = None
    if args.layout:
        layouts = tuple(k for k in LAYOUTS if any(t in k for t in args.layout))
        if not layouts:
            parser.error(f"--layout: no layout label contains {args.layout}: {list(LAYOUTS)}")
    print("## End to end through the session: demo rig with single tags vs boards "
          "(targets 2 m away)\n")
    print("\n".join(end_to_end_table(seeds=tuple(args.seeds), layouts=layouts)))
    if layouts is None:
        print("\n" + EXPLANATION)


if __name__ == "__main__":
    main()
