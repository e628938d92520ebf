"""The verdict's check for poses out of step with the images in pairs without stamps.

:mod:`rwhec_ros.core.analysis.motion_lag` measures, from the order of each edge's pairs, how far
the residuals follow the motion between neighbouring pairs: a lag of the poses behind the images
in pair intervals, pooled over the cameras, with its ``z``, and how far taking it out would move
the frames, in their std. A caution (code ``time_offset``) when both are clear: ``|z|`` at least
``verdict.lag_sigmas`` (4: a standard normal exceeds it once in 16,000 results) and a frame
moved by at least ``verdict.lag_shift_std`` of its std (1: a lag that moves no frame by its
std leaves the result within its stated precision; the numbers are still in ``result.yaml``,
``verdict_details.motion_lag``).

With the noise estimated from the data, late poses raise every residual alike and are taken
for noise; this check is what still names them (``benchmarks/verdict.md`` section 2). Where the
pose stream is recorded (a bag, the node), each camera's offset is estimated in seconds and
applied (:mod:`rwhec_ros.session.time_offsets`), and this check finds what is left (nothing, on
the rendered rigs).
"""

from __future__ import annotations

import numpy as np

from ..analysis.motion_lag import MotionLag, motion_lag
from ..problem import Problem
from .model import Builder
from .options import VerdictOptions

__all__ = ["lag_reasons"]


def lag_reasons(b: Builder, problem: Problem, result, opts: VerdictOptions) -> MotionLag | None:
    """Measure the lag (``None`` when the check is off, fails or nothing determines it) and add
    the caution of the module docstring to ``b`` when it is clear."""
    if not opts.lag_check:
        return None
    alpha = float(result.scale) if problem.unknown_scale else 1.0
    try:
        lag = motion_lag(problem, result.X, result.Y, alpha)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError):
        return None
    if lag is None or abs(lag.z) < opts.lag_sigmas or lag.shift_std < opts.lag_shift_std:
        return lag
    side = "trail" if lag.lag < 0 else "lead"
    same = all(np.sign(z) == np.sign(lag.z) for z in lag.cameras.values())
    cams = (f"every camera alike ({len(lag.cameras)})" if same and len(lag.cameras) > 1
            else f"{len(lag.cameras)} camera{'s' if len(lag.cameras) > 1 else ''}")
    b.add("caution", "time_offset",
          f"time offset: the residuals follow the motion between neighbouring pairs: the poses "
          f"{side} the images by {abs(lag.lag):.2f} +- {lag.std:.2f} of the interval between "
          f"consecutive pairs ({abs(lag.z):.1f} std, {cams}); taking it out would move "
          f"{lag.frame} by {lag.shift_std:.1f} of its std. Record each pose at its image's "
          "time (a pose read after the image is in trails it), or calibrate from a bag or the "
          "node with the pose stream, where each camera's time offset is estimated and applied",
          why="poses out of step with the images")
    return lag
