"""The sensor stream of a simulated rig: measured poses and rendered images in stamp order."""

from __future__ import annotations

from collections.abc import Iterator
from typing import NamedTuple

import numpy as np

__all__ = ["SimulatedSample", "simulated_stream", "DEMO_SUPERSAMPLE"]

_NS = 1_000_000_000
#: Samples per pixel along each axis of the demo's images (the CLI demo and the simulator node),
#: with the sample pattern shifted in every pixel (``render_tags(..., shift_pattern=True)``). A
#: fixed lattice resolves edges of some direction in a few coverage levels (2 x 2: 45 degrees,
#: 3 x 3: slope 1/2, 4 x 4: slope 1/3), which put the corners of a demo tag turned that way in the
#: image 0.2-0.7 px off and its pose 1.5-3 degrees off: the false CAUTION of issue 39 on the
#: demo's early data (``benchmarks/demo_early.md``). 3 x 3 shifted samples: 24 vs 16 ms per
#: 640x480 image for 2 x 2 (one core).
DEMO_SUPERSAMPLE = 3


class SimulatedSample(NamedTuple):
    """One sample of :func:`simulated_stream`: a pose (``camera`` None, ``data`` the measured
    ``T_world_rig`` (4, 4)) or an image (``data`` the (H, W) uint8 image of ``camera``)."""

    stamp_ns: int
    camera: str | None
    data: np.ndarray


def simulated_stream(
    rig,
    rng: np.random.Generator,
    *,
    seconds: float,
    image_rate_hz: float = 5.0,
    pose_rate_hz: float = 100.0,
    pose_noise_m: float = 5e-4,
    pose_noise_rad: float = 5e-4,
    image_noise_std: float = 2.0,
    supersample: int = DEMO_SUPERSAMPLE,
    shift_pattern: bool = True,
    start_ns: int = _NS,
) -> Iterator[SimulatedSample]:
    """The sensor stream of a :class:`~rwhec_ros.simulation.rig.SimulatedRig` in stamp order.

    Poses ``T_world_rig`` (measured: Gaussian noise ``pose_noise_m`` [m] and ``pose_noise_rad``
    [rad] per axis) every ``1 / pose_rate_hz`` seconds from simulation time 0 to ``seconds``;
    one image per camera every ``1 / image_rate_hz`` seconds, rendered at the TRUE pose, with
    stamps half a pose period after a pose (so that the session interpolates ``A``). Stamps are
    ``start_ns`` + simulation time [ns]; at equal stamps cameras come in ``rig.cameras`` order.
    Images are rendered with ``supersample**2`` samples per pixel (:data:`DEMO_SUPERSAMPLE`),
    the pattern shifted in every pixel (``shift_pattern``, :func:`~rwhec_ros.vision.render.
    pixel_shifts`).
    """
    for name, value in (("seconds", seconds), ("image_rate_hz", image_rate_hz),
                        ("pose_rate_hz", pose_rate_hz)):
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name}: must be finite and > 0, got {value!r}")
    pose_period_ns = int(round(_NS / pose_rate_hz))
    image_period_ns = int(round(_NS / image_rate_hz))
    end_ns = int(round(seconds * _NS))
    poses = [(s, 0) for s in range(0, end_ns + 1, pose_period_ns)]
    images = [(s, 1) for s in range(pose_period_ns // 2, end_ns, image_period_ns)]
    for s, kind in sorted(poses + images):
        t = s / _NS
        if kind == 0:
            T = rig.pose_measurement(t, rng, pose_noise_m, pose_noise_rad)
            yield SimulatedSample(start_ns + s, None, T)
            continue
        T_world_rig = rig.T_world_rig(t)
        for cam in rig.cameras:
            gray = rig.render(cam, T_world_rig, rng, noise_std=image_noise_std,
                              supersample=supersample, shift_pattern=shift_pattern)
            yield SimulatedSample(start_ns + s, cam, gray)
