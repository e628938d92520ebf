"""What a calibration prints and writes: the summary, the launch file, the data set, the files."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.lie import transform_to_quat_xyzw
from ..core.result import CalibrationResult
from ..data.dataset import Dataset
from ..data.results import session_output_paths, write_outputs

__all__ = ["summary", "static_transforms_launch", "session_dataset", "write_session_outputs"]


def summary(result: CalibrationResult, problem, excluded: dict, config) -> str:
    """The short summary of the ``calibrate`` service and the CLI: certified?, rho_hat, each
    frame's result, edges excluded and why. ``config`` names the published frames (a
    :class:`CalibratorConfig` or :class:`~rwhec_ros.data.results.FrameNaming`)."""
    c = result.certificate
    head = (
        f"CERTIFIED globally optimal (rho_hat={c.suboptimality_bound:.2e})"
        if result.certified
        else f"NOT certified: {c.status.value} (rho_hat={c.suboptimality_bound:.2e})"
    )
    parts = [
        head,
        f"{problem.n_measurements} pairs on {len(problem.edges)} edges, mode {result.mode}",
    ]
    if problem.unknown_scale:
        parts.append(f"scale {result.scale:.5f}")
    frames = config.published_frames()
    for name, T in list(zip(result.y_names, result.Y, strict=True)) + list(
        zip(result.x_names, result.X, strict=True)
    ):
        q, t = transform_to_quat_xyzw(T)
        parent, child = frames.get(name, ("?", name))
        parts.append(
            f"{parent}->{child}: t=[{t[0]:.4f} {t[1]:.4f} {t[2]:.4f}] "
            f"q=[{q[0]:.4f} {q[1]:.4f} {q[2]:.4f} {q[3]:.4f}]"
        )
    parents = {name: pc[0] for name, pc in frames.items()}
    for d in result.unobservable:
        how = ("fixed by the priors" if d.fixed_by == "prior" else
               "set by default (the cameras' mean along it is 0): not calibrated, give a prior "
               "(priors.* or --prior FRAME.AXIS=VALUE)")
        parts.append(f"{d.describe(parents=parents, x_names=result.x_names)}: {how}")
    if excluded:
        parts.append("excluded: " + ", ".join(f"{k}: {v}" for k, v in excluded.items()))
    missing = [n for n in config.y_names + config.x_names if n not in problem.frame_names]
    if missing:
        parts.append(f"not calibrated (no usable edge): {missing}")
    if result.notes:
        parts.append("notes: " + " | ".join(result.notes))
    return "; ".join(parts)


def static_transforms_launch(
    transforms: list[tuple[str, str, np.ndarray]], *, header: str = ""
) -> str:
    """Text of a ROS 2 Python launch file that publishes ``transforms`` with
    ``tf2_ros static_transform_publisher`` (one node per ``(parent, child, T_parent_child)``),
    so the calibration is reproduced at bring-up: ``ros2 launch <file>``."""
    lines = [
        f'"""Static transforms of an rwhec_ros calibration. {header}',
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


def session_dataset(acc, config) -> Dataset | None:
    """A data set of the kept pairs of ``acc`` (a :class:`~rwhec_ros.sync.PairAccumulator`)
    named by ``config`` (a :class:`~rwhec_ros.config.CalibratorConfig`), or None if it cannot be
    built (call with the session's lock held)."""
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
        )
    except ValueError:
        return None


def write_session_outputs(out: Path, transforms: list[tuple[str, str, np.ndarray]],
                          result: CalibrationResult, text: str, dataset, *, created: str,
                          force: bool = False) -> dict[str, str]:
    """Write the result YAML ``text``, the launch file of ``transforms`` (its header says when it
    was ``created``) and ``dataset`` into the directory ``out``; returns the written paths.
    Existing files are refused (``FileExistsError``) unless ``force``."""
    launch = static_transforms_launch(transforms, header=(
        f"certified: {result.certified}, suboptimality bound "
        f"{result.certificate.suboptimality_bound:.3g}, created {created}"
    ))
    return write_outputs(session_output_paths(out), result_yaml=text, launch_text=launch,
                         dataset=dataset, force=force)
