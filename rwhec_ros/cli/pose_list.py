"""``poses``: a pose list (robot poses + target-in-camera poses), solved like ``csv``.

The layout and the convention (OpenCV's ``gripper2base``/``target2cam`` mapped to ``A``, ``B``,
``X``, ``Y``) are those of :mod:`rwhec_ros.data.pose_list`. The mount comes from
``--eye-in-hand``/``--eye-to-hand``, else the file's ``mount`` (YAML), else a configuration whose
carriers say it (the camera carrier moving: eye-in-hand). Frame names: the file's ``frames``,
else the configuration's carriers, else ``base`` and ``gripper``.
"""

from __future__ import annotations

import argparse
from typing import Any

from .common import BadInput, Printer, SolveSettings, check_positive, output_paths, read_config
from .files import _problem, check_carriers, verdict_settings
from .run import Run

__all__ = ["cmd_poses", "POSES_SIGMA", "POSES_KAPPA"]

#: Noise of a user's PnP when neither ``--sigma`` nor a configuration says (5 mm, about 3 deg:
#: the precision of a board seen at arm's length; ``config/arm_charuco.yaml``'s values).
POSES_SIGMA = 0.005
POSES_KAPPA = 400.0


def _mount(args: argparse.Namespace, pose_list, config) -> str:
    if args.eye_in_hand:
        return "eye_in_hand"
    if args.eye_to_hand:
        return "eye_to_hand"
    if pose_list.mount is not None:
        return pose_list.mount
    if config is not None and config.camera_carrier.moving != config.tag_carrier.moving:
        return "eye_in_hand" if config.camera_carrier.moving else "eye_to_hand"
    raise BadInput(f"{pose_list.source}: the file does not say how the cameras are mounted: "
                   "give --eye-in-hand (cameras on the gripper, targets fixed) or --eye-to-hand "
                   "(cameras fixed, targets on the gripper)")


def cmd_poses(args: argparse.Namespace, say: Printer) -> int:
    config = read_config(args)
    params: dict[str, Any] = {} if config is None else config.to_parameters()
    settings = SolveSettings.resolve(args, params)
    sigma = args.sigma if args.sigma is not None else (
        config.noise.sigma if config else POSES_SIGMA)
    kappa = args.kappa if args.kappa is not None else (
        config.noise.kappa if config else POSES_KAPPA)
    check_positive("--sigma", sigma)
    check_positive("--kappa", kappa)
    unknown_scale = bool(args.unknown_scale or (config and config.tags.unknown_scale))
    # refuse early, before any work
    paths = output_paths(args, report=args.report, root=settings.output_root)
    run = Run("poses", say, paths, settings.output_root, force=args.force,
              resume_options=settings.resume_options(args.report))
    try:
        run.enter("reading")
        return _solve_pose_list(args, say, config, settings, sigma, kappa, unknown_scale, run)
    except KeyboardInterrupt as exc:
        raise run.interrupted(exc) from None


def _solve_pose_list(args, say, config, settings, sigma, kappa, unknown_scale, run) -> int:
    from ..data.dataset import Dataset
    from ..data.pose_list import pose_list_problem, read_pose_list, robot_frames
    from ..data.results import FrameNaming
    from .common import solve_and_write

    pose_list = read_pose_list(args.file)
    mount = _mount(args, pose_list, config)
    if config is not None:
        moving = config.camera_carrier if mount == "eye_in_hand" else config.tag_carrier
        fixed = config.tag_carrier if mount == "eye_in_hand" else config.camera_carrier
        gripper, base = moving.frame, fixed.frame
    else:
        gripper = base = None
    camera_carrier, tag_carrier = robot_frames(pose_list, mount, base=base, gripper=gripper)
    check_carriers(camera_carrier, tag_carrier)
    everything = pose_list_problem(pose_list, mount, sigma=sigma, kappa=kappa,
                                   unknown_scale=unknown_scale)
    naming = FrameNaming.from_carriers(
        everything.x_names, everything.y_names, camera_carrier=camera_carrier,
        tag_carrier=tag_carrier, suffix=config.output.frame_suffix if config else "_calibrated")
    source = {"type": "pose_list", "path": str(args.file), "mount": mount}
    carriers = {n: p for n, (p, _) in naming.frames.items()}
    dataset = Dataset.from_problem(everything, metadata={"source": source}, carriers=carriers)
    run.keep(dataset)
    problem, excluded = _problem(dataset, settings.min_pairs, run)
    say.progress(f"poses: {len(pose_list.pairs)} pairs, {mount.replace('_', '-')}: A = "
                 + ("inv(gripper2base)" if mount == "eye_in_hand" else "gripper2base")
                 + f", cameras on {camera_carrier}, targets on {tag_carrier}")
    used = {
        "camera_carrier.frame": camera_carrier,
        "camera_carrier.moving": mount == "eye_in_hand",
        "tag_carrier.frame": tag_carrier,
        "tag_carrier.moving": mount == "eye_to_hand",
        "tags.unknown_scale": unknown_scale,
        "noise.sigma": float(sigma),
        "noise.kappa": float(kappa),
        **settings.parameters(),
    }
    return solve_and_write(say, problem, dataset, naming, run, settings, excluded=excluded,
                           config=used, source=source, report=args.report,
                           **verdict_settings(config))
