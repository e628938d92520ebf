"""What a calibration prints and writes: the summary, the launch file, the data set, the files."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from ..core.lie import transform_to_quat_xyzw
from ..core.noise.words import noise_lines
from ..core.result import CalibrationResult
from ..core.verdict import Verdict
from ..data.dataset import Dataset
from ..data.export import frames_yaml, urdf_snippet
from ..data.results import session_output_paths, write_outputs
from .accuracy import Accuracy, accuracy_lines, std_words
from .refinement import PUBLISHED_NOTE

__all__ = ["summary", "publishable", "launch_header", "static_transforms_launch",
           "description_texts", "session_dataset", "write_session_outputs"]


def summary(result: CalibrationResult, problem, excluded: dict, config,
            verdict: Verdict | None = None, accuracy: Accuracy | None = None) -> str:
    """The summary of the ``calibrate`` service and the CLI, one line per item: the verdict
    first (``GOOD: ...``, ``CAUTION: <top reason>``, ``UNUSABLE: <top reason>``) and its other
    reasons, the certificate, then each frame (``parent->child: t=[...] q=[...]``, or ``NOT
    CALIBRATED (why)`` for a frame the verdict finds unusable: never a number), the edges
    excluded and why, notes. ``config`` names the published frames (a :class:`CalibratorConfig`
    or :class:`~rwhec_ros.data.results.FrameNaming`).

    With an ``accuracy`` (:class:`~rwhec_ros.session.accuracy.Accuracy`) each frame line ends
    with its std in the worst direction (``+-1.2 mm, +-0.05 deg``: the verdict's, i.e. the
    larger of predicted and a posteriori), followed by the largest per-axis std, the worst
    held-out edge of the cross-validation and the next motion
    (:func:`~rwhec_ros.session.accuracy.accuracy_lines`)."""
    c = result.certificate
    lines = []
    if verdict is not None:
        lines.append(verdict.headline())
        lines += [f"  {m}" for m in verdict.messages()[1:]]
        if verdict.exclusion is not None:
            lines += verdict.exclusion.summary_lines()
    lines.append(f"CERTIFIED globally optimal (rho_hat={c.suboptimality_bound:.2e})"
                 if result.certified else
                 f"NOT certified: {c.status.value} (rho_hat={c.suboptimality_bound:.2e})")
    refined = accuracy is not None and accuracy.refinement is not None and \
        accuracy.refinement.published
    if refined:  # the certificate covers the pose-level optimum, not the published frames
        lines[-1] += ": the pose-level optimum; the frames below are its corner-level refinement"
    lines.append(f"{problem.n_measurements} pairs on {len(problem.edges)} edges, mode "
                 f"{result.mode}")
    lines += noise_lines(getattr(verdict, "noise", None))
    if problem.unknown_scale:  # the std of the scale published (refined: its own)
        s = None if accuracy is None or accuracy.uncertainty is None else \
            accuracy.uncertainty.scale_std
        kind = "predicted"
        if refined and accuracy.refinement.refinement.scale_std is not None:
            s, kind = float(accuracy.refinement.refinement.scale_std), "the refinement's"
        std = ("" if s is None else " (not determined by the data)" if np.isnan(s) else
               f" +-{s:.5f} (1 sigma, {kind})")
        lines.append(f"scale {result.scale:.5f}{std}")
    frames = config.published_frames()
    estimates = dict(zip(result.y_names, result.Y, strict=True))
    estimates.update(zip(result.x_names, result.X, strict=True))
    names = list(verdict.frames) if verdict is not None else list(estimates)
    for name in names:
        parent, child = frames.get(name, ("?", name))
        fv = None if verdict is None else verdict.frames[name]
        if fv is not None and not fv.usable:
            lines.append(f"{parent}->{child}: NOT CALIBRATED ({'; '.join(fv.why)})")
        elif name in estimates:
            q, t = transform_to_quat_xyzw(estimates[name])
            lines.append(f"{parent}->{child}: t=[{t[0]:.4f} {t[1]:.4f} {t[2]:.4f}] "
                         f"q=[{q[0]:.4f} {q[1]:.4f} {q[2]:.4f} {q[3]:.4f}]"
                         + _frame_std(name, fv, accuracy))
    parents = {name: pc[0] for name, pc in frames.items()}
    for d in result.unobservable:
        if d.fixed_by != "prior" and verdict is not None:
            continue  # a reason of the verdict (not calibrated, give a prior)
        how = ("fixed by the priors" if d.fixed_by == "prior" else
               "set by default (the cameras' mean along it is 0): not calibrated, give a prior "
               "(priors.* or --prior FRAME.AXIS=VALUE)")
        lines.append(f"{d.describe(parents=parents, x_names=result.x_names)}: {how}")
    if excluded:
        lines.append("excluded: " + ", ".join(f"{k}: {v}" for k, v in excluded.items()))
    if verdict is None:
        missing = [n for n in config.y_names + config.x_names if n not in problem.frame_names]
        if missing:
            lines.append(f"not calibrated (no usable edge): {missing}")
    lines += accuracy_lines(accuracy)
    lines += [f"note: {n}" for n in result.notes]
    return "\n".join(lines)


def _frame_std(name: str, fv, accuracy: Accuracy | None) -> str:
    """`` +-1.2 mm, +-0.05 deg`` for a frame line: the verdict's precision of the frame (one
    source: :mod:`rwhec_ros.core.verdict.precision`), else the predicted worst-direction std;
    empty when neither is known."""
    if fv is not None and np.isfinite(fv.std_translation_m) and np.isfinite(fv.std_rotation_deg):
        return " " + std_words(fv.std_translation_m, fv.std_rotation_deg)
    if accuracy is not None and accuracy.uncertainty is not None:
        try:
            return " " + std_words(*accuracy.uncertainty.frame(name).worst_std())
        except KeyError:
            return ""
    return ""


def publishable(transforms: list[tuple[str, str, np.ndarray]], names: list[str],
                verdict: Verdict | None, *, publish_unusable: bool = False
                ) -> tuple[list[tuple[str, str, np.ndarray]], dict[str, str]]:
    """The ``(parent, child, T)`` of ``transforms`` (one per frame in ``names``, same order) that
    may be published, and frame name -> why for those left out: a frame the verdict finds
    unusable is left out unless ``publish_unusable`` (``output.publish_unusable``)."""
    keep, left_out = [], {}
    for name, item in zip(names, transforms, strict=True):
        fv = None if verdict is None else verdict.frames.get(name)
        if fv is not None and not fv.usable and not publish_unusable:
            left_out[name] = "; ".join(fv.why) or fv.level
            continue
        keep.append(item)
    return keep, left_out


def launch_header(result: CalibrationResult, verdict: Verdict | None, left_out: dict[str, str],
                  created: str) -> str:
    """The comment at the top of the static-transform launch file: the verdict and its reasons,
    the certificate, the frames left out and why."""
    c = result.certificate
    lines = [] if verdict is None else (verdict.messages() or [verdict.headline()])
    refined = any(n.startswith(PUBLISHED_NOTE) for n in result.notes)
    lines.append(f"certified: {result.certified}, suboptimality bound "
                 f"{c.suboptimality_bound:.3g}" + (" (the pose-level optimum; these frames are "
                 "its corner-level refinement, a local estimate, not certified)" if refined
                 else "") + f", {created}")
    if left_out:
        lines.append("left out (not usable): " + "; ".join(f"{k}: {v}" for k, v in
                                                            left_out.items()))
    return "\n".join(lines)


def static_transforms_launch(
    transforms: list[tuple[str, str, np.ndarray]], *, header: str = ""
) -> str:
    """Text of a ROS 2 Python launch file that publishes ``transforms`` with
    ``tf2_ros static_transform_publisher`` (one node per ``(parent, child, T_parent_child)``),
    so the calibration is reproduced at bring-up: ``ros2 launch <file>``. ``header`` (e.g.
    :func:`launch_header`) becomes the comment at the top."""
    lines = []
    for line in header.splitlines():
        lines += ["# " + w for w in textwrap.wrap(line, 96, break_on_hyphens=False)] or ["#"]
    lines += [
        '"""Static transforms of an rwhec_ros calibration.',
        "",
        "Generated file: ros2 launch <this file>. One tf2_ros static_transform_publisher per",
        "frame (--frame-id parent, --child-frame-id child: T_parent_child).",
        '"""',
        "",
        "from launch import LaunchDescription",
        "from launch_ros.actions import Node",
        "",
        "",
        "def generate_launch_description():",
        "    return LaunchDescription([",
    ]
    for parent, child, T in transforms:
        q, t = transform_to_quat_xyzw(np.asarray(T, dtype=float))
        name = "rwhec_static_" + "".join(ch if ch.isalnum() else "_" for ch in child)
        args = [
            "--x", repr(float(t[0])), "--y", repr(float(t[1])), "--z", repr(float(t[2])),
            "--qx", repr(float(q[0])), "--qy", repr(float(q[1])), "--qz", repr(float(q[2])),
            "--qw", repr(float(q[3])), "--frame-id", parent, "--child-frame-id", child,
        ]
        lines += [
            "        Node(",
            '            package="tf2_ros",',
            '            executable="static_transform_publisher",',
            f"            name={name!r},",
            f"            arguments={args!r},",
            "        ),",
        ]
    lines += ["    ])", ""]
    return "\n".join(lines)


def session_dataset(acc, config, intrinsics=None, *, pose_stream=None) -> Dataset | None:
    """A data set of the kept pairs of ``acc`` (a :class:`~rwhec_ros.sync.PairAccumulator`)
    named by ``config`` (a :class:`~rwhec_ros.config.CalibratorConfig`), with the pairs' tag
    corners, the cameras' ``intrinsics`` (camera -> CameraIntrinsics) and the configured tag
    sizes (for the reprojection error per camera), the configured time offsets and the
    recorded ``pose_stream`` (:class:`~rwhec_ros.sync.pose_track.PoseTrackData`, for time
    offsets), or None if it cannot be built (call with the session's lock held)."""
    c = config
    carriers = {n: c.camera_carrier.frame for n in c.y_names}
    carriers.update({n: c.tag_carrier.frame for n in c.x_names})
    try:
        return Dataset.from_accumulator(
            acc,
            x_names=c.x_names,
            y_names=c.y_names,
            unknown_scale=c.tags.unknown_scale,
            metadata={"config": c.to_parameters()},
            carriers=carriers,
            intrinsics=dict(intrinsics or {}),
            tag_sizes_m={c.tags.frame_name(t): s for t, s in c.tags.sizes.items()},
            time_offsets_s={n: s for n, s in c.sync.time_offsets if s},
            pose_stream=pose_stream,
        )
    except ValueError:
        return None


def description_texts(transforms: list[tuple[str, str, np.ndarray]], header: str
                      ) -> tuple[str, str]:
    """The robot-description forms of the published ``transforms`` (issue 12, item 4): the
    URDF/xacro snippet (one fixed joint per calibrated frame, ``header`` -- e.g.
    :func:`launch_header` -- as its comment) and the plain frames YAML (``header`` as its
    ``metadata.calibration``); see :mod:`rwhec_ros.data.export`."""
    one_line = " / ".join(line.strip() for line in header.splitlines() if line.strip())
    urdf = urdf_snippet(transforms, comment=one_line)
    frames = frames_yaml(transforms, metadata={"calibration": one_line} if one_line else None)
    return urdf, frames


def write_session_outputs(out: Path, transforms: list[tuple[str, str, np.ndarray]],
                          result: CalibrationResult, text: str, dataset, *, created: str,
                          force: bool = False, verdict: Verdict | None = None,
                          left_out: dict[str, str] | None = None) -> dict[str, str]:
    """Write the result YAML ``text``, the launch file of ``transforms`` (its comment gives the
    ``verdict``, the frames ``left_out`` and when it was ``created``), the same transforms as a
    URDF/xacro snippet and a frames YAML (:func:`description_texts`) and ``dataset`` into the
    directory ``out``; returns the written paths. Existing files are refused
    (``FileExistsError``) unless ``force``."""
    header = launch_header(result, verdict, left_out or {}, f"created {created}")
    launch = static_transforms_launch(transforms, header=header)
    urdf, frames = description_texts(transforms, header)
    return write_outputs(session_output_paths(out), result_yaml=text, launch_text=launch,
                         dataset=dataset, force=force, urdf_text=urdf, frames_text=frames)
