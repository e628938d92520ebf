"""Part 4 of ``benchmarks/verdict.py``: one bad target of a rig must not move the cameras.

The rendered pipeline (render -> detect -> synchronise -> solve -> exclusion -> verdict, as
``rwhec-calibrate bag`` and ``demo`` run it through the session) on the demo rig (3 cameras,
6 tags, motion capture), with ONE target broken: tag_2's size configured 25 % and 10 % too small
(printed 0.25 m, configured 0.1875 m / 0.225 m), tag_2 moved by 5 cm halfway through, tag_2's
pose flipped on about a third of its views (rendered in the other pose of its planar ambiguity:
its normal mirrored about the line of sight); each with and without ``--robust``
(``solver.reject_outliers``), known and unknown scale (``tags.unknown_scale``), next to the good
stream. The same rendered streams serve every row that only changes what the session is told.

Columns: the verdict levels; ``exit 0``: runs the CLI would exit 0 (usable verdict); ``tag_2 named
and not published``: runs whose reasons name tag_2 (or an edge of it) and that leave it out;
``tag_2 published (off > 3 std)``: runs that publish it, and of those the runs where it is off by
more than 3 of its std from its true pose (a moved tag: from the nearer of its two poses; a tag
whose bad views the outlier rejection or the exclusion of one edge removed is right again);
``cameras published``: usable cameras over all runs; ``off > 3 std``: published
(usable) cameras whose error against the truth exceeds 3 of their own standard deviations
(the verdict's worst-direction std, translation or rotation); ``worst err/std``: the largest
error over std of a published camera; ``excluded``: runs where the exclusion left something out,
and the largest camera shift it measured (median over those runs).
"""

from __future__ import annotations

import dataclasses
import sys
import tempfile
import time

import numpy as np

from rwhec_ros.core.lie import make_transform, rotation_distance, so3_exp

#: The broken target, and the stated noise of the rendered runs (verdict.py's RENDER_*).
BAD_TAG = 2
BAD = f"tag_{BAD_TAG}"
MOVE_M = 0.05
FLIP_SHARE = 0.33


def flipped_pose(T_cam_tag: np.ndarray) -> np.ndarray:
    """The other pose of a square's planar ambiguity: the tag's normal mirrored about the line
    of sight through its centre (same centre)."""
    R, t = T_cam_tag[:3, :3], T_cam_tag[:3, 3]
    v = t / np.linalg.norm(t)
    n = R[:, 2]
    m = 2.0 * float(n @ v) * v - n  # n mirrored about the line of sight
    axis = np.cross(n, m)
    s = np.linalg.norm(axis)
    if s < 1e-9:
        return T_cam_tag.copy()
    angle = np.arctan2(s, float(n @ m))
    return make_transform(so3_exp(axis / s * angle) @ R, t)


def moved_pose(T_world_tag: np.ndarray) -> np.ndarray:
    """The tag moved by MOVE_M along its own x axis."""
    T = T_world_tag
    return make_transform(T[:3, :3], T[:3, 3] + MOVE_M * T[:3, 0])


def bad_stream(rig, rng: np.random.Generator, seconds: float, change: str | None):
    """The rendered stream of ``rig`` (``simulated_stream``), with tag_2 moved by MOVE_M halfway
    (``"moved"``) or flipped on about FLIP_SHARE of the images that show it (``"flipped"``)."""
    from rwhec_ros.simulation import simulated_stream
    from rwhec_ros.vision.render import RenderedTag, render_tags

    if change is None:
        return list(simulated_stream(rig, rng, seconds=seconds))
    moved = dataclasses.replace(rig, T_world_tag={**rig.T_world_tag,
                                                  BAD_TAG: moved_pose(rig.T_world_tag[BAD_TAG])})
    out = []
    for s in simulated_stream(rig, rng, seconds=seconds):
        if s.camera is None:
            out.append(s)
            continue
        t = (s.stamp_ns - 1_000_000_000) / 1e9
        Tw = rig.T_world_rig(t)
        if change == "moved" and t > seconds / 2:
            s = s._replace(data=moved.render(s.camera, Tw, rng, supersample=2))
        elif change == "flipped":
            tags = rig.visible_tags(s.camera, Tw)
            if any(g.tag_id == BAD_TAG for g in tags) and rng.random() < FLIP_SHARE:
                tags = [RenderedTag(g.tag_id, flipped_pose(g.T_cam_tag), g.size)
                        if g.tag_id == BAD_TAG else g for g in tags]
                s = s._replace(data=render_tags(rig.intrinsics[s.camera], tags, rig.family,
                                                blur_sigma=0.6, noise_std=2.0, rng=rng,
                                                supersample=2))
        out.append(s)
    return out


def calibrate(rig, samples, extra: dict, noise: tuple[float, float]):
    """A session with the demo configuration, the stated ``noise`` and ``extra`` parameters,
    fed ``samples``; its ``calibrate()`` outcome."""
    from rwhec_ros.cli import demo_parameters
    from rwhec_ros.config import CalibratorConfig
    from rwhec_ros.session import CalibrationSession

    with tempfile.TemporaryDirectory() as tmp:
        flat = demo_parameters(rig, output_directory=tmp)
        flat["noise.sigma"], flat["noise.kappa"] = float(noise[0]), float(noise[1])
        flat.update(extra)
        session = CalibrationSession(CalibratorConfig.from_parameters(flat))
        for cam in rig.cameras:
            session.set_camera_info(cam, rig.intrinsics[cam])
        for stamp, cam, data in samples:
            if cam is None:
                session.add_pose(stamp, data, source="world")
            else:
                session.add_image(cam, stamp, data)
        return session.calibrate(tmp)


class Row:
    """The tallies of one row."""

    def __init__(self, broken: bool) -> None:
        self.broken = broken
        self.levels = {"good": 0, "caution": 0, "unusable": 0, "failed": 0}
        self.exit0 = self.bad_out = self.published = self.off = 0
        self.bad_published = self.bad_off = 0
        self.worst = 0.0
        self.excluded_runs = 0
        self.shifts: list[float] = []
        self.seconds: list[float] = []

    def add(self, rig, outcome, seconds: float, truths: list) -> None:
        self.seconds.append(seconds)
        v = outcome.verdict
        if not outcome.success or v is None:
            self.levels["failed"] += 1
            return
        self.levels[v.level] += 1
        self.exit0 += v.usable
        named = any(BAD in r.frames or any(BAD in e for e in r.edges) for r in v.reasons)
        bad = v.frames.get(BAD)
        published = bad is not None and bad.usable and BAD in outcome.result.x_names
        self.bad_out += named and not published
        if published:  # against its true pose (a moved tag: either of its two)
            X = outcome.result.transform(BAD)
            ratio = min(max(float(np.linalg.norm(X[:3, 3] - T[:3, 3])) / bad.std_translation_m,
                            float(np.degrees(rotation_distance(X[:3, :3], T[:3, :3])))
                            / bad.std_rotation_deg) for T in truths)
            self.bad_published += 1
            self.bad_off += ratio > 3.0
        for cam in rig.cameras:
            f = v.frames.get(cam)
            if f is None or not f.usable or cam not in outcome.result.y_names:
                continue
            self.published += 1
            Y, T = outcome.result.transform(cam), rig.T_rig_cam[cam]
            et = float(np.linalg.norm(Y[:3, 3] - T[:3, 3]))
            er = float(np.degrees(rotation_distance(Y[:3, :3], T[:3, :3])))
            ratio = max(et / f.std_translation_m, er / f.std_rotation_deg)
            self.worst = max(self.worst, ratio)
            self.off += ratio > 3.0
        ex = v.exclusion
        if ex is not None and ex.excluded:
            self.excluded_runs += 1
            cams = [s.translation_m for s in ex.shifts if s.role == "Y"]
            if cams:
                self.shifts.append(max(cams))

    def line(self, label: str, runs: int, cameras: int) -> str:
        lv = self.levels
        shift = (f"{self.excluded_runs}, {1e3 * float(np.median(self.shifts)):.1f} mm"
                 if self.shifts else f"{self.excluded_runs}")
        return (f"| {label} | {runs} | {lv['good']} | {lv['caution']} | {lv['unusable']} | "
                f"{lv['failed']} | {self.exit0} | {self.bad_out} | {self.bad_published} "
                f"({self.bad_off}) | {self.published}/{cameras} | "
                f"{self.off} | {self.worst:.1f} | {shift} | {np.median(self.seconds):.1f} |")


HEADER = ("| case | runs | good | caution | unusable | failed | exit 0 | tag_2 named and not "
          "published | tag_2 published (off > 3 std) | cameras published | off > 3 std | "
          "worst err/std | excluded (runs, median largest camera shift) | median s/run |\n"
          "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")

#: (label, stream, session parameters)
FAULTS = [
    ("good", "normal", {}),
    (f"{BAD} size configured 25 % too small", "normal",
     {"tags.sizes.ids": [BAD_TAG], "tags.sizes.values": [0.1875]}),
    (f"{BAD} size configured 10 % too small", "normal",
     {"tags.sizes.ids": [BAD_TAG], "tags.sizes.values": [0.225]}),
    (f"{BAD} moved 5 cm halfway", "moved", {}),
    (f"{BAD} flipped on ~1/3 of its views", "flipped", {}),
]
VARIANTS = [("", {}), ("--robust", {"solver.reject_outliers": True}),
            ("unknown scale", {"tags.unknown_scale": True}),
            ("--robust, unknown scale", {"solver.reject_outliers": True,
                                         "tags.unknown_scale": True})]


def bad_target(runs: int, seed: int, rig_factory, noise: tuple[float, float]) -> list[str]:
    """The rows of part 4 (module docstring); ``rig_factory()`` gives the demo rig."""
    lines = ["## 4. One bad target: excluded, re-solved, the cameras right (rendered pipeline)",
             "", f"One stream per run (12 s, 5 Hz, 3 cameras, 6 tags, motion capture), {BAD} "
             "broken; every row through `CalibrationSession.calibrate` (the path of `bag`, "
             "`demo` and the node). Targets: 0 runs with a published camera off by more than "
             f"3 of its std; {BAD} named and not published; exit 0 (cameras usable).", "",
             HEADER]
    rows = {(f, v): Row(f != "good") for f, *_ in FAULTS for v, _ in VARIANTS}
    rig = rig_factory()
    T = rig.T_world_tag[BAD_TAG]
    truths = {"normal": [T], "flipped": [T], "moved": [T, moved_pose(T)]}
    for r in range(runs):
        streams = {}
        for i, kind in enumerate(("normal", "moved", "flipped")):
            rng = np.random.default_rng([seed, 400, r, i])
            streams[kind] = bad_stream(rig, rng, 12.0, None if kind == "normal" else kind)
        for label, kind, extra in FAULTS:
            for vlabel, vextra in VARIANTS:
                t0 = time.perf_counter()
                outcome = calibrate(rig, streams[kind], {**extra, **vextra}, noise)
                rows[(label, vlabel)].add(rig, outcome, time.perf_counter() - t0,
                                          truths[kind])
        print(f"bad-target run {r + 1}/{runs} done", file=sys.stderr)
    for label, *_ in FAULTS:
        for vlabel, _ in VARIANTS:
            name = f"{label}, {vlabel}" if vlabel else label
            lines.append(rows[(label, vlabel)].line(name, runs, runs * len(rig.cameras)))
    return lines
