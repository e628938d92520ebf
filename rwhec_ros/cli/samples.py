"""``samples``: a folder of stop-and-go views (images + robot pose per view) through the session.

The views are read by :func:`rwhec_ros.data.sample_layouts.read_samples` (our manifest or another
tool's layout) and fed, view by view in the order taken, to a
:class:`~rwhec_ros.session.CalibrationSession` through the node's
:class:`~rwhec_ros.session.handlers.MessageHandlers`: each image file is a
``sensor_msgs/CompressedImage``-like message (its bytes, the format from its extension), decoded
as ``bag`` decodes compressed images, and the view's pose is given at the image stamp as ``bag``
gives a tf lookup. So the pairs, the solve, the verdict, the printed summary and the written
files are those of ``bag`` on a recording of the same views (the tests check it to 1e-9).

The configuration is built from the data (:func:`samples_parameters`: carriers from the mount,
one camera per image column, the data's target) and ``--config FILE`` on top of it: a full node
parameter file (its cameras, carriers and targets replace the data's; frames must agree) or a
partial one (e.g. only ``noise`` and ``solver``, or ``tags.unknown_scale`` for the data's target).
"""

from __future__ import annotations

import argparse
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from .common import (
    BadInput,
    Printer,
    SolveSettings,
    config_from_parameters,
    output_paths,
    prior_overrides,
    solver_overrides,
)
from .solving import calibrate_session

__all__ = ["cmd_samples", "samples_parameters", "resolve_frames", "match_cameras",
           "file_message", "SAMPLES_DEFAULTS"]

_NS_PER_S = 1_000_000_000
#: Settings of a stop-and-go data set where ``--config`` does not give them: every view is
#: deliberate, so the keyframe thresholds only drop repeated views (1 mrad, 1 mm), and each pair's
#: precision comes from its PnP, scaled per camera by the noise the data fit (as
#: ``config/arm_charuco.yaml``; ``noise.sigma``/``noise.kappa`` not stated).
SAMPLES_DEFAULTS: dict[str, Any] = {
    "noise.from_reprojection": True,
    "keyframe.min_rotation_rad": 0.001, "keyframe.min_translation_m": 0.001,
    "solver.min_pairs": 3,
}
_CODECS = {".jpg": "jpeg", ".jpeg": "jpeg", ".png": "png", ".bmp": "bmp", ".tif": "tiff",
           ".tiff": "tiff"}


def file_message(path: Path, stamp_ns: int) -> SimpleNamespace:
    """An image file as a ``sensor_msgs/CompressedImage``-like object (``header.stamp``,
    ``format`` from the extension, ``data`` the file's bytes), for
    :meth:`MessageHandlers.on_compressed_image`."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise BadInput(f"image {str(path)!r}: cannot read it ({exc.strerror or exc})") from None
    stamp = SimpleNamespace(sec=stamp_ns // _NS_PER_S, nanosec=stamp_ns % _NS_PER_S)
    return SimpleNamespace(header=SimpleNamespace(stamp=stamp, frame_id=""),
                           format=_CODECS.get(Path(path).suffix.lower(), ""), data=data)


def _image_size(path: Path) -> tuple[int, int]:
    """``(width, height)`` of an image file (decoded once)."""
    from ..vision.compressed import compressed_to_gray

    msg = file_message(path, 0)
    try:
        gray = compressed_to_gray(msg.data, msg.format)
    except ValueError as exc:
        raise BadInput(f"image {str(path)!r}: {exc}") from None
    return int(gray.shape[1]), int(gray.shape[0])


def _intrinsics(samples, given: list[str] | None) -> dict[str, Any]:
    """Per camera the :class:`~rwhec_ros.data.intrinsics_files.IntrinsicsFile`: ``--intrinsics
    [CAMERA=]FILE`` over the data's own; BadInput naming how to give missing ones."""
    from ..data.intrinsics_files import read_intrinsics_file

    files = dict(samples.intrinsics)
    for text in given or ():
        cam, sep, file = str(text).partition("=")
        if not sep:
            if len(samples.cameras) != 1:
                raise BadInput(f"--intrinsics {text}: {len(samples.cameras)} cameras "
                               f"{list(samples.cameras)}: say which, --intrinsics CAMERA=FILE")
            cam, file = samples.cameras[0], text
        if cam not in samples.cameras:
            raise BadInput(f"--intrinsics {text}: no camera {cam!r}; cameras "
                           f"{list(samples.cameras)}")
        files[cam] = read_intrinsics_file(file)
    missing = [c for c in samples.cameras if files.get(c) is None]
    if missing:
        shipped = ("its layout ships no intrinsics" if samples.layout != "manifest"
                   else "the manifest names no intrinsics file for it")
        raise BadInput(
            f"{samples.source}: no intrinsics for camera {missing[0]} ({shipped}): give them "
            f"with --intrinsics FILE (a ROS camera_calibration YAML with camera_matrix, "
            f"distortion_model, distortion_coefficients, image_width/height, or an OpenCV "
            f"FileStorage YAML/XML with camera_matrix and distortion_coefficients)"
            + ("" if len(samples.cameras) == 1 else ", --intrinsics CAMERA=FILE per camera"))
    return files


def _mount_flag(args: argparse.Namespace) -> str | None:
    if getattr(args, "eye_in_hand", False):
        return "eye_in_hand"
    if getattr(args, "eye_to_hand", False):
        return "eye_to_hand"
    return None


def resolve_frames(samples, file_flat: dict[str, Any], mount_flag: str | None
                   ) -> tuple[dict[str, Any], bool]:
    """The carrier and pose-source parameters, and whether each view's pose must be inverted to
    be ``T_<pose_source.parent>_<pose_source.child>``.

    With carriers in ``file_flat`` (a node parameter file) they are used: the data's pose frames
    must be its pose source's (either order); data without frame names (a tool's layout) take
    them, the fixed carrier being the robot base. Otherwise the mount decides: ``--eye-in-hand``
    / ``--eye-to-hand``, else the data's ``mount`` or ``camera_carrier``.
    """
    parent, child = samples.pose_parent, samples.pose_child
    if "camera_carrier.frame" in file_flat and "tag_carrier.frame" in file_flat:
        cam = str(file_flat["camera_carrier.frame"])
        tag = str(file_flat["tag_carrier.frame"])
        ps_parent = str(file_flat.get("pose_source.parent", ""))
        if samples.frames_named:
            if {parent, child} != {cam, tag}:
                raise BadInput(f"{samples.source}: the poses are {parent} -> {child} but the "
                               f"configuration's carriers are {cam} and {tag}")
            base = parent
        else:
            fixed = [f for f, key in ((cam, "camera_carrier"), (tag, "tag_carrier"))
                     if not file_flat.get(f"{key}.moving", True)]
            if len(fixed) != 1:
                raise BadInput(f"{samples.source}: the {samples.layout} layout does not name "
                               "its frames and the configuration does not say which carrier is "
                               "the fixed robot base (exactly one of camera_carrier.moving / "
                               "tag_carrier.moving false)")
            base = fixed[0]
        tool = tag if base == cam else cam
        mount = "eye_to_hand" if cam == base else "eye_in_hand"
        if mount_flag is not None and mount_flag != mount:
            raise BadInput(f"--{mount_flag.replace('_', '-')}: the configuration's carriers "
                           f"say {mount.replace('_', '-')} (cameras on {cam})")
        out = {"camera_carrier.frame": cam, "tag_carrier.frame": tag,
               "camera_carrier.moving": cam == tool, "tag_carrier.moving": tag == tool,
               "pose_source.parent": ps_parent or base,
               "pose_source.child": str(file_flat.get("pose_source.child", "")) or tool}
        return out, out["pose_source.parent"] != base
    mount = mount_flag or samples.mount
    if mount is None and samples.camera_carrier is not None:
        mount = "eye_in_hand" if samples.camera_carrier == child else "eye_to_hand"
    if mount is None:
        raise BadInput(f"{samples.source}: the data do not say how the cameras are mounted: give "
                       f"--eye-in-hand (cameras on {child}, the target fixed in {parent}) or "
                       f"--eye-to-hand (cameras fixed in {parent}, the target on {child})")
    cam, tag = (child, parent) if mount == "eye_in_hand" else (parent, child)
    return {"camera_carrier.frame": cam, "camera_carrier.moving": cam == child,
            "tag_carrier.frame": tag, "tag_carrier.moving": tag == child,
            "pose_source.parent": parent, "pose_source.child": child}, False


def match_cameras(samples, file_flat: dict[str, Any]):
    """``samples`` with its single camera renamed to the configuration's single camera when
    their names differ (a tool's layout calls it ``cam0``); unchanged otherwise."""
    from dataclasses import replace

    names = list(file_flat.get("cameras.names") or ())
    if len(names) != 1 or len(samples.cameras) != 1 or samples.cameras[0] == names[0]:
        return samples
    old, new = samples.cameras[0], str(names[0])
    views = tuple(replace(v, images={new: v.images[old]}) for v in samples.views)
    return replace(samples, cameras=(new,), views=views,
                   intrinsics={new: samples.intrinsics.get(old)})


def _has(flat: dict[str, Any], *prefixes: str) -> bool:
    return any(k.startswith(prefixes) for k in flat)


def _defines_targets(flat: dict[str, Any]) -> bool:
    """Whether a parameter file names targets of its own (``targets.*``, ``tags.ids``, tag sizes);
    settings of the data's targets alone (``tags.unknown_scale``, ``tags.family``, ...) keep the
    data's targets."""
    return _has(flat, "targets.", "tags.ids", "tags.default_size", "tags.sizes.")


def samples_parameters(samples, file_flat: dict[str, Any] | None = None,
                       mount_flag: str | None = None) -> tuple[dict[str, Any], bool, list[str]]:
    """Flat calibrator parameters for ``samples``: :data:`SAMPLES_DEFAULTS`, the frames
    (:func:`resolve_frames`), one camera per camera of the data (topics ``/samples/<camera>/...``,
    used by nothing but an equivalent bag), the data's target, then ``file_flat`` on top.

    Returns ``(flat, invert_poses, warnings)``.
    """
    file_flat = dict(file_flat or {})
    warnings: list[str] = []
    frames, invert = resolve_frames(samples, file_flat, mount_flag)
    flat: dict[str, Any] = dict(SAMPLES_DEFAULTS)
    flat.update(frames)
    flat.update({"pose_source.type": "topic", "pose_source.topic": "/samples/pose"})
    if not _has(file_flat, "cameras."):
        flat["cameras.names"] = list(samples.cameras)
        for cam in samples.cameras:
            flat[f"cameras.{cam}.image_topic"] = f"/samples/{cam}/image"
            flat[f"cameras.{cam}.camera_info_topic"] = f"/samples/{cam}/camera_info"
    elif set(samples.cameras) - set(file_flat.get("cameras.names", ())):
        missing = sorted(set(samples.cameras) - set(file_flat.get("cameras.names", ())))
        raise BadInput(f"{samples.source}: cameras {missing} of the data are not in the "
                       f"configuration's cameras.names {list(file_flat.get('cameras.names', []))}")
    if _defines_targets(file_flat):
        if samples.target_parameters:
            warnings.append(f"the configuration's targets are used; the data's "
                            f"({samples.target_words or 'targets'}) are ignored")
    elif samples.target_parameters:
        flat.update(samples.target_parameters)
    else:
        from ..config.specs import TARGET_TYPES

        said = (f"the data describe their target as: {samples.target_words}; this installation "
                f"has no target type for it (types: {', '.join(TARGET_TYPES)}): "
                if samples.target_words else "")
        raise BadInput(f"{samples.source}: no target: {said}give the targets in the manifest "
                       "(targets:, tags: as in the configuration) or with --config FILE")
    flat.update(file_flat)
    return flat, invert, warnings


def cmd_samples(args: argparse.Namespace, say: Printer) -> int:
    import numpy as np

    from ..config import read_parameter_file
    from ..core.lie import invert_transform
    from ..data.sample_layouts import read_samples
    from ..session import CalibrationSession, MessageHandlers
    from ..session.capture import seen_words
    from ..session.paths import plain_output_root
    from .detections import detection_images
    from .run import Run
    from .solving import input_line

    samples = read_samples(args.path, args.layout)
    for note in samples.notes:
        say.progress(f"note: {note}")
    file_flat = ({} if args.config is None
                 else read_parameter_file(args.config, args.node_name))
    samples = match_cameras(samples, file_flat)
    intrinsics = _intrinsics(samples, args.intrinsics)
    flat, invert, warnings = samples_parameters(samples, file_flat, _mount_flag(args))
    flat.update(solver_overrides(args))
    flat.update(prior_overrides(args, flat))
    where = samples.source if args.config is None else f"config file {str(args.config)!r}"
    config = config_from_parameters(flat, where)
    for text in warnings:
        say.warning("samples", text)
    stamps = samples.stamps_ns()
    root = plain_output_root(config.output.directory)
    paths = output_paths(args, report=args.report, root=root)  # refuse early, before any work

    session = CalibrationSession(config)
    handlers = MessageHandlers(session)
    for cam in samples.cameras:
        first = next(v.images[cam] for v in samples.views if cam in v.images)
        width, height = _image_size(first)
        try:
            session.set_camera_info(cam, intrinsics[cam].intrinsics(width, height))
        except ValueError as exc:
            raise BadInput(f"camera {cam}: {exc}") from None
    kf = config.keyframe
    say.progress(f"samples: {len(samples.views)} views of {len(samples.cameras)} camera(s) "
                 f"from the {samples.layout} layout {samples.source}; poses "
                 f"{config.pose_source.parent} -> {config.pose_source.child}, cameras on "
                 f"{config.camera_carrier.frame}")
    settings = SolveSettings.from_parameters(config.to_parameters())
    run = Run("samples", say, paths, root, force=args.force,
              **{"resume_options": settings.resume_options(args.report),
                 **getattr(args, "run_as", {})})  # check: its directory and resume command
    drawn = detection_images(args)
    try:
        run.enter("reading")
        for index, (view, stamp) in enumerate(zip(samples.views, stamps, strict=True)):
            T = invert_transform(view.T_parent_child) if invert else np.array(view.T_parent_child)
            for cam, file in view.images.items():
                outcome = handlers.on_compressed_image(cam, file_message(file, stamp), T)
                if drawn is not None:  # <camera>_<view index>_<image file's stem>.jpg
                    drawn(cam, f"{index:03d}_{Path(file).stem}", outcome)
                say.progress(f"{view.name} {cam}: "
                             f"{seen_words(outcome, (kf.min_rotation_rad, kf.min_translation_m))}")
        session.close()
        counters = session.counters()
        for sentence in session.rejections():
            say.warning("samples", sentence)
        line = (f"samples: {len(samples.views)} views, {len(samples.cameras)} camera(s), "
                f"{samples.layout} {samples.source}")
        finish = getattr(args, "finish", None) or calibrate_session  # check: its own
        code, _ = finish(say, session, run, report=args.report,
                         inputs=[input_line(counters), line]
                         + ([] if drawn is None else [drawn.line()]))
        return code
    except KeyboardInterrupt as exc:
        session.close()
        raise run.interrupted(exc, session.dataset) from None
