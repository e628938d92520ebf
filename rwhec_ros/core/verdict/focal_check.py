"""The focal check: do the detected corners fit the configured focal length of each camera?

When the data keep the tag (or board) corners and the cameras' intrinsics (data sets recorded
from images),
:func:`rwhec_ros.vision.focal_fit.fit_focal_scale` finds, per camera, the factor ``s`` on the
focal length that the corners fit best, each image through its own best pose, with its standard
deviation. The check reads it from the reprojection error per camera
(:class:`~rwhec_ros.vision.reprojection.CameraReprojection`, ``focal``): a factor beyond
``VerdictOptions.focal_caution`` (2 %) from 1 and beyond ``VerdictOptions.focal_sigmas`` (4)
standard deviations makes that camera a ``caution``, with a reason naming the camera, the focal
length the corners fit, and the reprojection errors (per image as configured, per image as
fitted, through the calibrated chain).

Why not the goodness of fit of the solve: a focal length ``f`` off by 5 % scales the depth of
each PnP pose by 5 % and leaves its lateral position; the calibration absorbs part of it, and
what is left (a few mm on the demo rig) hides below a stated noise of 5 mm (a-posteriori variance
factor ~0.45x) and barely moves the scale (~1.01). In the images the same error is plain: with
the wrong focal length no pose of a square explains a tag seen at an angle. The check needs no
``sigma``/``kappa``, and a wrong tag size or a late pose stream do not trigger it (they leave the
corners of each image consistent). Measured on the rendered demo rig (the streams of
``benchmarks/verdict.py`` section 3, 6 seeds x 12 configurations x 3 cameras, 15-32 images per
camera): good runs ``|s - 1|`` <= 0.23 % (at most 2 standard deviations, std 0.04-0.26 %); a
focal length 5 % too large ``s`` = 0.952-0.955 (the truth is 1/1.05 = 0.952), 5 % too small
1.053-1.055 (>= 31 standard deviations); wrong tag sizes, late stamps, moved and turned tags
``|s - 1|`` <= 0.16 %. The standard deviation grows linearly with the corner noise: the rendered
corners scatter by ~0.03-0.05 px; with 0.2 px (projected corners, 33 views of one camera) it is
~1 %, and a 5 % error is 4-6 standard deviations, near the test's edge: record more views, at an
angle, for a sharper check.

Skipped, silently (the verdict's ``focal_check`` says why), when the data keep no corners (the
paper's CSV data, data sets of poses only) or ``VerdictOptions.focal_check`` is off.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .model import Builder
from .options import VerdictOptions

__all__ = ["FocalCheck", "focal_checks", "focal_reasons", "focal_summary", "NOT_CHECKED"]

#: What the verdict's ``focal_check`` says when the data keep no tag corners.
NOT_CHECKED = "not checked: the data keep no tag or board corners with intrinsics"


@dataclass(frozen=True)
class FocalCheck:
    """The focal fit of one camera, as the verdict uses it.

    Attributes
    ----------
    camera : str
    scale : float
        The factor on the configured focal length that the corners fit best (NaN: not
        determined, e.g. tags seen face-on).
    std : float
        Its standard deviation.
    fx_px : float
        The configured focal length ``fx`` (pixels; NaN when unknown).
    image_rms_px, fitted_rms_px : float
        RMS corner error of the per-image poses with the configured and the fitted focal length.
    chain_rms_px : float
        RMS corner error through the calibrated chain (camera <- carrier <- pose stream <- tag
        carrier <- tag) with the configured intrinsics.
    n_images : int
    """

    camera: str
    scale: float
    std: float
    fx_px: float
    image_rms_px: float
    fitted_rms_px: float
    chain_rms_px: float
    n_images: int

    @property
    def deviation(self) -> float:
        """``s - 1`` (NaN when not determined)."""
        return self.scale - 1.0

    @property
    def sigmas(self) -> float:
        """``|s - 1|`` in standard deviations (0 when not determined; inf for noise-free
        corners, std 0, that fit another focal length)."""
        if not (np.isfinite(self.scale) and np.isfinite(self.std) and self.std >= 0):
            return 0.0
        dev = abs(self.deviation)
        return dev / self.std if self.std > 0 else (np.inf if dev > 0 else 0.0)

    def flagged(self, opts: VerdictOptions) -> bool:
        return (np.isfinite(self.scale) and abs(self.deviation) > opts.focal_caution
                and self.sigmas > opts.focal_sigmas)

    def to_dict(self) -> dict:
        return {"focal_scale": float(self.scale), "focal_scale_std": float(self.std),
                "fx_px": float(self.fx_px), "image_fit_rms_px": float(self.image_rms_px),
                "fitted_rms_px": float(self.fitted_rms_px),
                "chain_rms_px": float(self.chain_rms_px), "n_images": int(self.n_images)}


def focal_checks(reprojection: Mapping | None, intrinsics: Mapping | None = None
                 ) -> dict[str, FocalCheck]:
    """Camera -> :class:`FocalCheck` from a reprojection error per camera (camera ->
    :class:`~rwhec_ros.vision.reprojection.CameraReprojection`, whose ``focal`` holds the fit;
    cameras without one are left out) and the configured intrinsics (camera -> object with
    ``K``, for ``fx`` in the message; optional)."""
    out = {}
    for cam, rep in (reprojection or {}).items():
        fit = getattr(rep, "focal", None)
        if fit is None:
            continue
        K = getattr((intrinsics or {}).get(cam), "K", None)
        fx = float(np.asarray(K)[0, 0]) if K is not None else float("nan")
        out[cam] = FocalCheck(cam, float(fit.scale), float(fit.scale_std), fx,
                              float(fit.rms_px), float(fit.fitted_rms_px), float(rep.rms_px),
                              int(fit.n_images))
    return out


def focal_reasons(b: Builder, checks: Mapping[str, FocalCheck], opts: VerdictOptions) -> None:
    """A ``caution`` (code ``intrinsics``) for every camera whose corners fit another focal
    length (module docstring)."""
    for cam, c in checks.items():
        if not c.flagged(opts) or cam not in b.frames:
            continue
        dev = c.deviation
        word = "shorter" if dev < 0 else "longer"
        fx = (f"fx {c.fx_px:.1f} px configured, {c.scale * c.fx_px:.1f} px fits"
              if np.isfinite(c.fx_px) else f"a factor {c.scale:.3f}")
        chain = (f", {c.chain_rms_px:.2f} px through the calibration"
                 if np.isfinite(c.chain_rms_px) else "")
        b.add("caution", "intrinsics",
              f"{cam}: the detected corners fit a focal length {100 * abs(dev):.1f} % {word} than "
              f"its camera info says ({fx}, +-{100 * c.std:.1f} %, {c.sigmas:.0f} std): they "
              f"reproject with {c.image_rms_px:.2f} px RMS per image as configured against "
              f"{c.fitted_rms_px:.2f} px with the fitted focal length{chain}; check the "
              f"intrinsics of {cam} (calibrate it again, and check that its camera info is that "
              "of the recorded resolution); a wrong focal length scales the camera-tag "
              "distances", frames=(cam,), why=f"focal length {100 * dev:+.1f} %")


def focal_summary(checks: Mapping[str, FocalCheck], opts: VerdictOptions) -> str:
    """``the detected corners fit the configured focal lengths (within 0.3 %)`` when every
    checked camera passes (the largest deviation rounded up to 0.1 %, so that the words stay
    true); where a camera passes only because its fit is imprecise (off by more than
    ``verdict.focal_caution``, within ``verdict.focal_sigmas`` std), that the corners cannot
    check it; empty otherwise (the reasons say it) or when none was checked."""
    known = [c for c in checks.values() if np.isfinite(c.scale)]
    if not known or any(c.flagged(opts) for c in known):
        return ""
    loose = [c for c in known if abs(c.deviation) > opts.focal_caution]
    if loose:
        # off by more than the caution but not significantly: the corners are too few or too
        # noisy to check (a single marker's 4 corners per image, a lens model that misfits)
        words = ", ".join(f"{c.camera} {100 * c.deviation:+.1f} % +-{100 * c.std:.1f} %"
                          for c in loose)
        return ("the detected corners are too few or too noisy to check the focal lengths "
                f"({words}: not significant)")
    worst = max(abs(c.deviation) for c in known)
    within = max(math.ceil(round(1000 * worst, 6)) / 10, 0.1)
    return f"the detected corners fit the configured focal lengths (within {within:.1f} %)"
