"""The simulated sensor stream as ROS messages, and recorded into a rosbag2 file (no ROS needed).

The messages are those the simulator node ``rwhec_demo_sim`` publishes, built as ``rosbags``
messages from the field dicts of :mod:`rwhec_ros.messages`.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ..data.rosbag import (
    CAMERA_INFO,
    COMPRESSED_IMAGE,
    IMAGE,
    POSE_STAMPED,
    TF_MESSAGE,
    jazzy_typestore,
    message_from_fields,
    write_bag,
)
from ..messages import (
    gray_to_compressed_image_fields,
    gray_to_image_fields,
    intrinsics_to_camera_info_fields,
    transform_to_pose_stamped_fields,
    transform_to_transform_stamped_fields,
)
from .rig import DEMO_POSE_TOPIC, DEMO_RIG_FRAME, DEMO_WORLD_FRAME, demo_camera_topics
from .stream import SimulatedSample, simulated_stream

__all__ = ["simulation_messages", "write_simulated_bag"]


def simulation_messages(
    rig,
    samples: Iterable[SimulatedSample],
    *,
    pose_source: str = "topic",
    pose_topic: str | None = None,
    image_transport: str = "raw",
    jpeg_quality: int = 95,
    typestore=None,
) -> Iterator[tuple[str, str, int, Any]]:
    """The messages ``rwhec_demo_sim`` would publish for ``samples`` (:func:`simulated_stream`),
    as ``(topic, msgtype, log_time_ns, msg)`` for :func:`write_bag`; log time = header stamp.

    Poses ``T_world_rig``: ``pose_source="topic"`` a ``PoseStamped`` on ``pose_topic`` (default
    :data:`~rwhec_ros.simulation.rig.DEMO_POSE_TOPIC`, ``header.frame_id = world``), ``"tf"``
    ``world -> rig`` on ``/tf``, ``"both"`` both. Images: a camera info and a ``mono8`` image on
    the camera's demo topics, ``header.frame_id = <camera>_optical``; with
    ``image_transport="compressed"`` a ``CompressedImage`` (JPEG of ``jpeg_quality``, the
    ``image_transport`` plugin's format string) on ``<image topic>/compressed`` instead.
    """
    if pose_source not in ("topic", "tf", "both"):
        raise ValueError(f"pose_source: expected 'topic', 'tf' or 'both', got {pose_source!r}")
    if image_transport not in ("raw", "compressed"):
        raise ValueError(
            f"image_transport: expected 'raw' or 'compressed', got {image_transport!r}")
    store = typestore if typestore is not None else jazzy_typestore()
    topic = pose_topic or DEMO_POSE_TOPIC
    for stamp, cam, data in samples:
        if cam is None:
            if pose_source in ("topic", "both"):
                fields = transform_to_pose_stamped_fields(data, DEMO_WORLD_FRAME, stamp)
                yield topic, POSE_STAMPED, stamp, message_from_fields(
                    POSE_STAMPED, fields, typestore=store)
            if pose_source in ("tf", "both"):
                fields = transform_to_transform_stamped_fields(
                    data, DEMO_WORLD_FRAME, DEMO_RIG_FRAME, stamp)
                yield "/tf", TF_MESSAGE, stamp, message_from_fields(
                    TF_MESSAGE, {"transforms": [fields]}, typestore=store)
            continue
        image_topic, info_topic = demo_camera_topics(cam)
        frame = f"{cam}_optical"
        info = intrinsics_to_camera_info_fields(rig.intrinsics[cam], stamp, frame)
        yield info_topic, CAMERA_INFO, stamp, message_from_fields(
            CAMERA_INFO, info, typestore=store)
        if image_transport == "compressed":
            fields = gray_to_compressed_image_fields(data, stamp, frame, quality=jpeg_quality)
            yield image_topic + "/compressed", COMPRESSED_IMAGE, stamp, message_from_fields(
                COMPRESSED_IMAGE, fields, typestore=store)
        else:
            yield image_topic, IMAGE, stamp, message_from_fields(
                IMAGE, gray_to_image_fields(data, stamp, frame), typestore=store)


def write_simulated_bag(
    path: str | Path,
    rig,
    rng: np.random.Generator,
    *,
    seconds: float,
    pose_source: str = "topic",
    pose_topic: str | None = None,
    image_transport: str = "raw",
    storage: str = "sqlite3",
    **stream_options,
) -> Path:
    """Render a :class:`~rwhec_ros.simulation.rig.SimulatedRig` into a rosbag2 recording:
    :func:`simulated_stream` (``seconds``, ``stream_options``) through
    :func:`simulation_messages` (``pose_source``, ``pose_topic``, ``image_transport``) into
    :func:`write_bag`."""
    store = jazzy_typestore()
    samples = simulated_stream(rig, rng, seconds=seconds, **stream_options)
    messages = simulation_messages(rig, samples, pose_source=pose_source,
                                   pose_topic=pose_topic, image_transport=image_transport,
                                   typestore=store)
    return write_bag(path, messages, storage=storage, typestore=store)
