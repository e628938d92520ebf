"""The reprojection check: does a camera's corners reproject far worse than the others'?

When the data keep the detected corners (tags, boards) and the intrinsics, the reprojection
error per camera through the calibrated chain (``T_cam_tag = Y^-1 A X``,
:func:`rwhec_ros.vision.reprojection.reprojection_errors`) is the residual of the whole
calibration in pixels. The cameras of one rig see similar targets at similar distances, so their
RMS errors are alike on good data (0.3-0.5 px on every camera of the rendered demo rig); a camera
whose RMS is ``VerdictOptions.reprojection_ratio`` (5) times the median of the other cameras' and
above ``VerdictOptions.reprojection_min_px`` (2 px) is named, a ``caution`` for that camera: a
target it sees does not fit (a wrong size, a move, a flip: the tag named by the reason, when the
error is concentrated on one), its time stamps are off, or its intrinsics are wrong (the focal
check, :mod:`.focal_check`, says which when it is the focal length).

Measured on the rendered demo rig with one tag's size configured 25 % too small and outlier
rejection on (the tag kept on one edge): 23 px on the camera that sees it most against 3.5 and
4.7 px. Skipped without corners, or with fewer than two cameras that have them.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from .model import Builder
from .options import VerdictOptions

__all__ = ["reprojection_outliers", "reprojection_reasons"]


def reprojection_outliers(reprojection: Mapping | None, opts: VerdictOptions
                          ) -> dict[str, tuple[float, float]]:
    """Camera -> ``(its RMS, the median RMS of the other cameras)`` [px] for every camera that
    reprojects far worse than the others (module docstring)."""
    rms = {cam: float(getattr(r, "rms_px", np.nan)) for cam, r in (reprojection or {}).items()}
    rms = {cam: v for cam, v in rms.items() if np.isfinite(v)}
    out = {}
    for cam, v in rms.items():
        others = [w for c, w in rms.items() if c != cam]
        if not others:
            continue
        ref = float(np.median(others))
        if v >= opts.reprojection_min_px and v >= opts.reprojection_ratio * ref:
            out[cam] = (v, ref)
    return out


def reprojection_reasons(b: Builder, reprojection: Mapping | None, opts: VerdictOptions) -> None:
    """A ``caution`` (code ``reprojection``) per camera that reprojects far worse than the
    others, naming the target whose corners are worst when the reprojection has them per
    target (``CameraReprojection.per_target_rms_px``)."""
    for cam, (v, ref) in reprojection_outliers(reprojection, opts).items():
        if cam not in b.frames:
            continue
        per = dict(getattr(reprojection[cam], "per_target_rms_px", None) or {})
        worst = ""
        if len(per) >= 2:
            tag = max(per, key=per.get)
            worst = f", worst on {tag} ({per[tag]:.1f} px)"
        b.add("caution", "reprojection",
              f"{cam}: its detected corners reproject through the calibration with {v:.1f} px "
              f"RMS, {v / ref:.0f}x the other cameras' ({ref:.2f} px){worst}: a target it sees "
              "does not fit (a wrong size, a tag that moved or whose pose flips), its images are "
              f"not in time with the pose stream, or its intrinsics are wrong; check {cam} and "
              "the targets it sees", [cam], why=f"reprojects {v:.1f} px")
