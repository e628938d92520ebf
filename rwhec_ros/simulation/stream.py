"""The sensor stream of a simulated rig: measured poses and rendered images in stamp order."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
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
    stamp_offsets_s: Mapping[str, float] | None = None,
    image_times: Callable[[float], bool] | None = None,
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

    ``stamp_offsets_s`` (camera -> ``delta`` [s]) plants time offsets: that camera's image taken
    at simulation time ``t`` is stamped ``t - delta``, so that ``t_pose = t_image + delta`` finds
    its pose (``delta < 0``: stamped late). Given (even empty), every image's noise comes from
    its own generator seeded from ``rng`` before anything else, in the order the images are
    taken, so that the same ``rng`` gives the same images and poses whatever the offsets (only
    the stamps differ); without it, one generator in stamp order (as before). ``image_times``
    (``t -> bool``) keeps only the images taken at the times it accepts (e.g. those at rest of
    a stop-and-go trajectory).
    """
    for name, value in (("seconds", seconds), ("image_rate_hz", image_rate_hz),
                        ("pose_rate_hz", pose_rate_hz)):
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name}: must be finite and > 0, got {value!r}")
    offsets = dict(stamp_offsets_s or {})
    for cam, value in offsets.items():
        if cam not in rig.cameras:
            raise ValueError(f"stamp_offsets_s: {cam!r} is not a camera of the rig "
                             f"{list(rig.cameras)}")
        if not (np.isfinite(value) and abs(value) < 1.0):
            raise ValueError(f"stamp_offsets_s[{cam!r}]: must be finite and within +-1 s, "
                             f"got {value!r}")
    pose_period_ns = int(round(_NS / pose_rate_hz))
    image_period_ns = int(round(_NS / image_rate_hz))
    end_ns = int(round(seconds * _NS))
    events = [(s, 0, -1, s) for s in range(0, end_ns + 1, pose_period_ns)]
    for s in range(pose_period_ns // 2, end_ns, image_period_ns):
        if image_times is not None and not image_times(s / _NS):
            continue
        for k, cam in enumerate(rig.cameras):
            stamp = s - int(round(offsets.get(cam, 0.0) * _NS))
            if stamp >= -start_ns:
                events.append((stamp, 1, k, s))
    seeds = {}
    if stamp_offsets_s is not None:  # one seed per image, drawn in the order they are taken
        taken = sorted((s, k) for _, kind, k, s in events if kind == 1)
        seeds = dict(zip(taken, rng.integers(0, 2**63, size=len(taken)).tolist(), strict=True))
    for stamp, kind, k, s in sorted(events):
        t = s / _NS
        if kind == 0:
            T = rig.pose_measurement(t, rng, pose_noise_m, pose_noise_rad)
            yield SimulatedSample(start_ns + stamp, None, T)
            continue
        cam = rig.cameras[k]
        image_rng = np.random.default_rng(seeds[(s, k)]) if seeds else rng
        gray = rig.render(cam, rig.T_world_rig(t), image_rng, noise_std=image_noise_std,
                          supersample=supersample, shift_pattern=shift_pattern)
        yield SimulatedSample(start_ns + stamp, cam, gray)
