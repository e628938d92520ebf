"""Which stream rates the time offsets may use: plausible motion, no glitch in the window.

The offsets' Jacobian is the pose stream's twist rate at each pair
(:mod:`rwhec_ros.core.analysis.time_offset`; the rate:
:meth:`~rwhec_ros.sync.pose_track.PoseTrackData.rates`).
A wrong sample between good ones (a glitch of the pose source) makes that rate, and the offsets,
wrong: the pairs whose rate window holds one are left out of the offsets (:func:`glitch_free`).
"""

from __future__ import annotations

import numpy as np

from ..sync.pose_track import RATE_HALF_STEP_NS, PoseTrackData

__all__ = ["MAX_SPEED_M_S", "MAX_RATE_RAD_S", "plausible", "glitch_free"]

#: A stream rate beyond these [m/s, rad/s] is a glitch of the stream (a wrong sample between
#: good ones), not motion: the pair is left out of the offsets (1,700 deg/s; the translation rate
#: of ``A`` includes the lever arm of the far carrier's origin, hence the generous bound).
MAX_SPEED_M_S = 50.0
MAX_RATE_RAD_S = 30.0


def plausible(xi: np.ndarray) -> np.ndarray:
    """Rates (N, 6) within :data:`MAX_SPEED_M_S` and :data:`MAX_RATE_RAD_S` (NaN: False)."""
    with np.errstate(invalid="ignore"):
        return ((np.linalg.norm(xi[:, :3], axis=1) <= MAX_SPEED_M_S)
                & (np.linalg.norm(xi[:, 3:], axis=1) <= MAX_RATE_RAD_S))


#: Half step [ns] of the short central differences that screen a rate's window for glitches.
_GLITCH_HALF_STEP_NS = 10_000_000


def glitch_free(track: PoseTrackData, q: np.ndarray) -> np.ndarray:
    """Whether the stream is free of glitches over the window of each stamp's rate (N,).

    The rate's 60 ms central difference (``RATE_HALF_STEP_NS``) dilutes a wrong sample between
    good ones (a pose 90 deg off reads 26 rad/s, below :data:`MAX_RATE_RAD_S`), and such a rate
    made ``--robust``'s offsets 27 ms, applied, in ``test_cli.py``'s corrupted stream. The 20 ms
    differences at ``s - d``, ``s`` and ``s + d`` (``d`` = 20 ms: the rate's half step less the
    short one's) cover the rate's window ``s +- 30 ms`` at the bounds' own scale (the 90 deg
    pose reads ~78 rad/s there): a pair whose window holds an implausible one is left out of
    the offsets."""
    d = max(RATE_HALF_STEP_NS - _GLITCH_HALF_STEP_NS, 0)
    ok = np.ones(q.shape[0], dtype=bool)
    for shift in (-d, 0, d):
        xi, covered = track.rates(q + shift, _GLITCH_HALF_STEP_NS)
        ok &= ~covered | plausible(xi)
    return ok
