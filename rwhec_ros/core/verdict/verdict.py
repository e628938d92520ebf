"""The verdict a user can act on: use this calibration or not, and why (:func:`assess`).

It combines, for a solution of a :class:`~rwhec_ros.core.problem.Problem`:

* the certificate status (:class:`~rwhec_ros.core.result.Status`);
* identifiability at the solution: frames the data do not determine (``result.unobservable``,
  the numeric check's null directions, undetermined components) are **not calibrated**;
* the goodness of fit (:mod:`.fit`): the noise the residuals imply against the stated one,
  globally (chi-square test on the a-posteriori variance factor) and per edge (edges far beyond
  the median edge are named); with the noise estimated from the data (:mod:`.noise_check`), a
  stated noise compared with the estimate per noise group, and a camera far noisier than the
  others named;
* the scale check of a known-scale problem (:mod:`.scale_check`);
* a gross mistake in the inputs (:mod:`.input_check`): the pairs fit far better with the poses
  inverted, in other units or paired with the view before or after;
* the precision of each frame (:mod:`.precision`, from the per-frame covariance of
  :mod:`rwhec_ros.core.analysis.uncertainty`);
* when the data keep the tag corners: the focal length each camera's corners fit
  (:mod:`.focal_check`);
* the frames the user asked for that got no estimate at all;
* when the data keep the corners: a camera whose corners reproject far worse than the others'
  (:mod:`.reprojection_check`);
* what was excluded before this solve because it did not fit (:mod:`.exclusion`), and how far
  the frames moved when it was; after an exclusion, a camera still on a misfitting edge or
  target is not usable.

The result is a :class:`Verdict`: a level (``good``, ``caution``, ``unusable``), the reasons as
sentences (what, which frame or edge, the number, the likely cause, what to do), and a
:class:`FrameVerdict` per frame. ``good`` and ``caution`` are usable; a frame marked ``unusable``
must not be used (the node leaves it off ``/tf_static``). The cameras decide: the whole result
is ``unusable`` as soon as one camera is (or a reason about the whole result is, e.g. a fit far
beyond the stated noise); a tag that is not calibrated or not usable is named and left out, and
makes the result a ``caution`` only (spare tags, tags seen a few times, are common).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np

from ..noise.words import short_summary
from ..problem import Problem
from ..result import CalibrationResult
from .exclusion import exclusion_reasons
from .fit import FitStatistics, goodness_of_fit
from .focal_check import NOT_CHECKED, focal_checks, focal_reasons, focal_summary
from .input_check import check_inputs, input_reasons
from .lag_check import lag_reasons
from .model import Builder, FrameVerdict, Reason, Verdict
from .noise_check import noise_reasons, precision_factors, stated_scale
from .options import VerdictOptions
from .pair_check import pair_reasons
from .reasons import (
    all_determined,
    certificate_reasons,
    edge_reasons,
    fit_reasons,
    identifiability_reasons,
    missing_frames,
    pinned_frames,
    precision_reasons,
    scale_reason,
)
from .reprojection_check import reprojection_reasons
from .scale_check import ScaleCheck, check_scale
from .words import deg, mm

__all__ = ["Reason", "FrameVerdict", "Verdict", "assess"]

def assess(
    result: CalibrationResult,
    problem: Problem,
    *,
    identifiability=None,
    options: VerdictOptions | None = None,
    expected_x: Iterable[str] = (),
    expected_y: Iterable[str] = (),
    excluded: Mapping[str, str] | None = None,
    carriers: tuple[str, str] = ("the camera carrier", "the tag carrier"),
    scale_check: ScaleCheck | None = None,
    uncertainty=None,
    reprojection: Mapping | None = None,
    intrinsics: Mapping | None = None,
    exclusion=None,
    noise=None,
) -> Verdict:
    """The verdict of ``result``, the solution of ``problem``.

    Parameters
    ----------
    result : CalibrationResult
    problem : Problem
        The pairs that were solved (for a robust solve: the inlier problem).
    identifiability : IdentifiabilityReport, optional
        At the solution, with the numeric check
        (``analyze(problem, solution=(X, Y, scale))``); computed here when None.
    options : VerdictOptions, optional
    expected_x, expected_y : iterable of str
        Every tag (X) and camera (Y) the user asked for; those without an estimate are reported
        as not calibrated (default: the problem's frames).
    excluded : mapping of str to str, optional
        Edges ``"(x, y)"`` left out of the problem, and why (to say why a frame is missing).
    carriers : (str, str)
        Names of the camera and tag carrier frames, for directions in words.
    scale_check : ScaleCheck, optional
        A scale check already made (known scale); made here when None and enabled.
    uncertainty : Uncertainty, optional
        The per-frame covariance at the solution
        (:func:`~rwhec_ros.core.analysis.uncertainty.frame_uncertainty`, ideally with the solve's
        ``GaugeOptions`` so that the priors count); computed here (without priors) when None.
    reprojection : mapping of str to CameraReprojection, optional
        The reprojection error per camera with its focal fit
        (:func:`rwhec_ros.vision.reprojection.reprojection_errors`), for the focal check; None
        (data without tag corners): the check is skipped and ``Verdict.focal_check`` says so.
    intrinsics : mapping of str to CameraIntrinsics, optional
        The configured intrinsics (for ``fx`` in the focal check's words).
    exclusion : Exclusion, optional
        What :func:`~.exclusion.exclude_misfits` excluded before ``result`` was solved (its
        reasons, and the excluded tags not calibrated); given, a camera still on a flagged edge
        or target is not usable (the exclusion could not remove it).
    noise : NoiseEstimate, optional
        The noise per group estimated from the data, whose weights ``problem`` carries
        (:func:`~rwhec_ros.core.noise.solve_with_noise`): the fit compares a stated noise with it
        and the precision check uses its degrees of freedom (:mod:`.noise_check`); None: the
        problem's noise as stated.
    """
    opts = options or VerdictOptions()
    xs = list(dict.fromkeys([*expected_x, *problem.x_names]))
    ys = list(dict.fromkeys([*expected_y, *problem.y_names]))
    b = Builder(xs, ys)
    certificate_reasons(b, result)
    if identifiability is None:
        identifiability = _analyze(problem, result)
    identifiability_reasons(b, result, problem, identifiability, carriers)
    exclusion_reasons(b, exclusion)
    missing_frames(b, problem, xs, ys, excluded or {})
    fit = None
    try:
        fit = goodness_of_fit(problem, result, opts,
                              noise_estimated=noise is not None and noise.estimated,
                              stated_scale=stated_scale(noise))
    except (ValueError, FloatingPointError) as exc:
        b.add("caution", "check_failed", f"the goodness of fit could not be computed ({exc})",
              why="fit not checked")
    if (scale_check is None and opts.scale_check and not problem.unknown_scale
            and fit is not None and fit.testable and all_determined(b, problem)):
        try:
            scale_check = check_scale(problem)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            scale_check = ScaleCheck(float("nan"), float("inf"), message=str(exc))
    if scale_check is not None:
        scale_reason(b, scale_check, opts, fit)
    if fit is not None:
        edge_reasons(b, fit, problem, opts, strict=exclusion is not None,
                     noise_estimated=noise is not None and noise.estimated)
        fit_reasons(b, fit, opts, scale_check)
    inputs = _check_inputs(problem, result, camera_poses_given=reprojection is None)
    input_reasons(b, inputs, scale_checked=scale_check is not None and scale_check.available)
    far = pair_reasons(b, problem, result, fit, opts) if fit is not None else []
    lag = lag_reasons(b, problem, result, opts)
    noise_reasons(b, noise, problem, opts)
    if uncertainty is None:
        uncertainty = _uncertainty(problem, result)
    if uncertainty is None:
        b.add("caution", "check_failed", "the uncertainty at the solution could not be "
              "computed, so the precision of the frames is unknown", why="precision unknown")
    precision_reasons(b, uncertainty, fit, opts, problem, pinned_frames(result),
                      float(result.scale), factors=precision_factors(noise, problem, opts),
                      noise_estimated=noise is not None and noise.estimated)
    focal: dict | str = "off (verdict.focal_check false)"
    if opts.focal_check:
        focal = focal_checks(reprojection, intrinsics) or NOT_CHECKED
        if not isinstance(focal, str):
            focal_reasons(b, focal, opts)
    reprojection_reasons(b, reprojection, opts)
    summary = _summary(result, fit, b, noise)
    if not isinstance(focal, str) and focal_summary(focal, opts):
        summary += "; " + focal_summary(focal, opts)
    verdict = b.verdict(fit, scale_check, summary, opts)
    verdict.focal_check = focal
    verdict.exclusion = exclusion
    verdict.noise = noise
    verdict.motion_lag = lag
    verdict.far_pairs = far
    verdict.input_check = inputs
    return verdict


def _check_inputs(problem: Problem, result: CalibrationResult, *, camera_poses_given: bool):
    if not (np.all(np.isfinite(result.X)) and np.all(np.isfinite(result.Y))):
        return None
    try:
        return check_inputs(problem, camera_poses_given=camera_poses_given)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError):
        return None


def _analyze(problem: Problem, result: CalibrationResult):
    from ..identifiability import analyze

    try:
        return analyze(problem, solution=(result.X, result.Y, float(result.scale)))
    except (ValueError, ArithmeticError, np.linalg.LinAlgError):
        return None


def _uncertainty(problem: Problem, result: CalibrationResult):
    from ..analysis.uncertainty import frame_uncertainty

    try:
        return frame_uncertainty(problem, result)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError):
        return None


def _summary(result: CalibrationResult, fit: FitStatistics | None, b: Builder,
             noise=None) -> str:
    c = result.certificate
    parts = [f"certified globally optimal (rho_hat={c.suboptimality_bound:.2g})"
             if c.certified else f"not certified ({c.status.value})"]
    if noise is not None and noise.estimated:
        parts.append(short_summary(noise))
    elif fit is not None and fit.testable:
        parts.append(f"the data fit {fit.noise_ratio_translation:.2g}x the stated translation "
                     f"noise and {fit.noise_ratio_rotation:.2g}x the rotation noise")
    known = [f for f in b.frames.values() if f.calibrated and np.isfinite(f.std_translation_m)
             and np.isfinite(f.std_rotation_deg)]
    if known:
        wt = max(known, key=lambda f: f.std_translation_m)
        wr = max(known, key=lambda f: f.std_rotation_deg)
        parts.append(f"every frame within +-{mm(wt.std_translation_m)} ({wt.name}) and "
                     f"+-{deg(wr.std_rotation_deg)} ({wr.name})")
    return "; ".join(parts)
