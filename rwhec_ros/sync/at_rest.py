"""Stop-and-go: an image taken while the pose stream is at rest pairs with the pose at rest.

The pose buffer (:class:`~rwhec_ros.sync.buffer.PoseBuffer`) serves an image stamp ``s`` by
interpolating between the two samples around it when they are at most ``sync.max_gap_s`` apart,
or with a sample within ``sync.extrapolation_tolerance_s``. An arm driven through poses and
stopped for each image often publishes its pose slowly (tf from joint states at 10-50 Hz, a
driver that publishes only on change), so the samples around an image taken at rest can be
further apart than ``max_gap_s``: the image would be rejected although the arm did not move.

The rule (:class:`AtRestRule`), applied only where the buffer's own lookup fails:

* **bridge**: the samples ``(t0, P0)`` and ``(t1, P1)`` just before and just after ``s``
  (``t0 < s < t1``) are at most ``max_gap_ns`` apart and agree, ``P0 ~ P1``: the rotation
  between them at most ``rotation_rad`` (geodesic angle) and their translations at most
  ``translation_m`` apart. The stream was at rest across the image, so ``s`` gets the pose
  interpolated between them (:func:`~rwhec_ros.sync.interpolation.interpolate_se3`; within the
  tolerance of both samples);
* **wait**: ``s`` is newer than the newest sample ``t_n`` by more than the buffer's
  ``max_gap_ns`` but at most the rule's, and the stream may be at rest at ``t_n``: the two newest
  samples agree, or they are further apart than the buffer's ``max_gap_ns`` (a slow or sparse
  stream, which cannot show its rest before the next sample), or there is only one. A later
  sample may then still bridge the image, so it waits for it (bounded by the caller,
  ``sync.max_pending_images``) instead of being rejected at once. A dense stream that moved up
  to ``t_n`` and then stopped (a dropout) does not make images wait: they are rejected at once
  as before.

An image is never paired with a pose at rest without a sample *after* it: a robot that starts
to move right after its last sample would otherwise be paired with a stale pose. The rule never
changes a stamp the buffer serves itself, so with moving poses nothing changes.

Hooked in (only): :meth:`rwhec_ros.session.image_input.ImageInput._pose_at` and ``_waits``
(the session's pose buffer: ``pose_source.type: topic`` in the node, ``bag`` and the CLI) and
:meth:`rwhec_ros.data.rosbag.TfTree._to_root` (each dynamic tf link of ``bag``). The node's tf2
lookup interpolates across any gap by itself.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .interpolation import interpolate_se3

__all__ = ["AtRestRule", "same_pose", "at_rest_lookup", "waits_at_rest"]

_NS_PER_S = 1_000_000_000


@dataclass(frozen=True)
class AtRestRule:
    """When two pose samples count as the same pose at rest (module docstring).

    Attributes
    ----------
    max_gap_ns : int
        Largest distance [ns] between two agreeing samples bridged (0: the rule is off).
    translation_m : float
        Largest distance [m] between the translations of two samples at rest.
    rotation_rad : float
        Largest geodesic angle [rad] between the rotations of two samples at rest.
    """

    max_gap_ns: int
    translation_m: float
    rotation_rad: float

    def __post_init__(self) -> None:
        if isinstance(self.max_gap_ns, bool) or int(self.max_gap_ns) != self.max_gap_ns \
                or self.max_gap_ns < 0:
            raise ValueError(f"max_gap_ns: expected an integer >= 0, got {self.max_gap_ns!r}")
        for name in ("translation_m", "rotation_rad"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ValueError(f"{name}: expected a finite number >= 0, got {value!r}")

    @property
    def enabled(self) -> bool:
        return self.max_gap_ns > 0

    @staticmethod
    def from_sync(sync) -> AtRestRule:
        """The rule of a configuration's ``sync`` section (``sync.at_rest_*``)."""
        return AtRestRule(max_gap_ns=int(round(sync.at_rest_max_gap_s * _NS_PER_S)),
                          translation_m=float(sync.at_rest_translation_m),
                          rotation_rad=float(sync.at_rest_rotation_rad))


def same_pose(T0: np.ndarray, T1: np.ndarray, rule: AtRestRule) -> bool:
    """True when the rigid transforms ``T0`` and ``T1`` (4, 4) agree within ``rule``'s
    translation and rotation tolerances."""
    shift = float(np.linalg.norm(T1[:3, 3] - T0[:3, 3]))
    if shift > rule.translation_m:
        return False
    Rel = T0[:3, :3].T @ T1[:3, :3]
    s = 0.5 * math.sqrt((Rel[2, 1] - Rel[1, 2]) ** 2 + (Rel[0, 2] - Rel[2, 0]) ** 2
                        + (Rel[1, 0] - Rel[0, 1]) ** 2)
    c = 0.5 * (Rel[0, 0] + Rel[1, 1] + Rel[2, 2] - 1.0)
    return math.atan2(s, c) <= rule.rotation_rad


def _sample(buffer, stamp: int) -> np.ndarray | None:
    """The buffer's sample at exactly ``stamp`` (a copy), through its public lookup."""
    return buffer.lookup(int(stamp), count=False)


def at_rest_lookup(buffer, stamp_ns: int, rule: AtRestRule | None) -> np.ndarray | None:
    """The pose at ``stamp_ns`` by the bridge rule (module docstring), or None.

    Parameters
    ----------
    buffer : PoseBuffer
        Read through ``stamps()`` and ``lookup(stamp, count=False)`` only.
    stamp_ns : int
        The image stamp [ns].
    rule : AtRestRule or None
        None or disabled: always None.

    Returns
    -------
    ndarray (4, 4) or None
        Interpolated between the samples just before and just after the stamp when they agree
        within the rule and are at most ``rule.max_gap_ns`` apart; None otherwise (no sample on
        one side, too far apart, or the stream moved).
    """
    if rule is None or not rule.enabled:
        return None
    stamps = buffer.stamps()
    s = int(stamp_ns)
    i = int(np.searchsorted(stamps, s, side="left"))
    if i == 0 or i >= len(stamps) or stamps[i] == s:
        return None
    t0, t1 = int(stamps[i - 1]), int(stamps[i])
    if t1 - t0 > rule.max_gap_ns:
        return None
    P0, P1 = _sample(buffer, t0), _sample(buffer, t1)
    if P0 is None or P1 is None or not same_pose(P0, P1, rule):
        return None
    return interpolate_se3(P0, P1, (s - t0) / (t1 - t0))


def waits_at_rest(buffer, stamp_ns: int, rule: AtRestRule | None) -> bool:
    """True when an image at ``stamp_ns``, newer than the newest sample, should wait for a later
    one by the wait rule (module docstring): at most ``rule.max_gap_ns`` after the newest
    sample, and the two newest samples agree, or are further apart than the buffer's
    ``max_gap_ns``, or there is only one."""
    if rule is None or not rule.enabled:
        return False
    newest = buffer.newest_ns
    s = int(stamp_ns)
    if newest is None or s <= newest or s - newest > rule.max_gap_ns:
        return False
    stamps = buffer.stamps()
    if len(stamps) < 2 or int(stamps[-1] - stamps[-2]) > int(getattr(buffer, "max_gap_ns", 0)):
        return True
    P0, P1 = _sample(buffer, int(stamps[-2])), _sample(buffer, int(stamps[-1]))
    return P0 is not None and P1 is not None and same_pose(P0, P1, rule)
