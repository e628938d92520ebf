"""The corner-level refinement in the solve step: run, decide, publish, report.

After the certified solve and its accuracy (:mod:`.accuracy`), when the data keep their corners
and the cameras' intrinsics (:func:`rwhec_ros.data.corners.corner_data`) and ``solver.refine``
is on, :func:`refine_solution` refines the frames on the reprojection error of every kept corner
(:func:`rwhec_ros.core.refine.refine_views`) and decides which estimate is published
(:func:`rwhec_ros.core.refine.decide`: the refined one when it lowers the corner residual,
every frame stays within the uncertainties of the certified one and it predicts the corners of
held-out pose samples no worse than the pose-level solve of the other samples,
:func:`pose_level_fit`). :func:`published_result` is the
:class:`~rwhec_ros.core.result.CalibrationResult` that the outputs publish: the certified one, or
a copy with the refined frames whose certificate is still the pose-level one and whose notes say
so (:data:`~rwhec_ros.core.refine.SCOPE`). :class:`CornerRefinement` gives the result-YAML
section ``refinement`` (both estimates, their corner RMS per camera, the noise, the reason), the
summary lines and the frames' uncertainty keys of a published refinement.

Data without corners (CSV pose pairs, pose lists) never get here: their path is unchanged.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from ..core.analysis.uncertainty import CONVENTION
from ..core.analysis.worst_direction import block_variances
from ..core.lie import transform_to_quat_xyzw
from ..core.refine import (
    SCOPE,
    Decision,
    PoseLevelFit,
    Refinement,
    RefinementFailed,
    RefineOptions,
    corner_views,
    decide,
    refine_views,
)
from ..core.result import CalibrationResult
from ..vision.projection import IntrinsicsProjector

__all__ = ["CornerRefinement", "refine_solution", "published_result", "pose_level_fit"]

#: ``std_kind`` of a frame whose published estimate is the refined one, per kept fit.
REFINED_STD_KIND = {
    "pose_noise": "corner-level model of the published refined estimate: (J^T W J)^-1 with the "
                  "corner noise per camera and the pose stream's noise estimated from the "
                  "residuals, the pose errors marginalised (a posteriori = predicted); "
                  "pose_level: the certified estimate's",
    "plain": "corner-level model of the published refined estimate (plain reprojection fit): "
             "its spread H^-1 (H + sum_g B_g Sigma_A B_g^T) H^-1 under the corner noise per "
             "camera and the pose stream's noise estimated from the residuals, the corners of "
             "one pose sample sharing its error (a posteriori = predicted); pose_level: the "
             "certified estimate's"}

_MODEL_WORDS = {"pose_noise": "corners with the pose stream's noise",
                "plain": "plain reprojection error"}


def _pose(T: np.ndarray) -> dict:
    q, t = transform_to_quat_xyzw(T)
    return {"translation": [float(v) for v in t], "quaternion_xyzw": [float(v) for v in q]}


@dataclass
class CornerRefinement:
    """What the refinement did (module docstring).

    Attributes
    ----------
    refinement : Refinement or None
        None when it did not run (``skipped`` says why).
    decision : Decision or None
    skipped : str
        Why no refinement ran or why it failed ("" when it ran).
    scope : str
        What the certificate proves, in words.
    certified : CalibrationResult or None
        The certified estimate the refinement started from.
    timing_s : float
    """

    refinement: Refinement | None = None
    decision: Decision | None = None
    skipped: str = ""
    scope: str = ""
    certified: CalibrationResult | None = None
    timing_s: float = 0.0

    @property
    def published(self) -> bool:
        """The refined estimate is published."""
        return self.decision is not None and self.decision.refined

    @property
    def reason(self) -> str:
        return self.skipped if self.decision is None else self.decision.reason

    def to_dict(self) -> dict:
        """The result-YAML section ``refinement``."""
        out = {"published": "refined" if self.published else "certified",
               "reason": self.reason, "certificate_scope": self.scope,
               "timing_s": float(self.timing_s)}
        r, result = self.refinement, self.certified
        if r is None:
            return out
        dist = {} if self.decision is None else self.decision.distances
        out.update({
            "model": r.model, "model_words": _MODEL_WORDS[r.model],
            "held_out_rms_px": {k: float(v) for k, v in r.held_out_rms_px.items()},
            "noise": {"sigma_px": {k: float(v) for k, v in r.sigma_px.items()},
                      "pose_sigma_m": float(r.sigma_pose_m),
                      "pose_sigma_deg": float(np.degrees(r.sigma_pose_rad))},
            "cameras": {cam: {"n_corners": int(r.n_corners[cam]),
                              "rms_px_certified": float(r.rms_start_px[cam]),
                              "rms_px_refined": float(r.rms_px[cam])} for cam in r.rms_px},
            "corner_cost": {"certified": float(r.cost_start), "refined": float(r.cost)},
            "convention": CONVENTION,
            "frames": {name: {
                "certified": _pose(result.transform(name)),
                "refined": {**_pose(r.transform(name)), **_std(r.frame_covariance(name))},
                "mahalanobis_squared": None if name not in dist else float(dist[name])}
                for name in r.names},
            "converged": bool(r.converged), "rounds": int(r.rounds),
            "n_downweighted": int(r.n_downweighted), "notes": list(r.notes),
            "message": r.message,
            "fold_spread": None if r.spread is None else r.spread.to_dict()})
        if r.scale_std is not None:
            out["scale"] = {"certified": float(result.scale), "refined": float(r.scale),
                            "refined_std": float(r.scale_std)}
        return out

    def certificate_fields(self) -> dict:
        """The result-YAML keys beside the certificate's (``certified``, ``status``):
        ``estimate_published`` (``refined`` or ``certified``) and ``certificate_scope``, what
        the certificate covers in words, so that a reader of the top of ``result.yaml`` does not
        take refined frames for certified ones."""
        if self.published:
            scope = self.scope
        else:
            cert = self.certified is not None and self.certified.certified
            scope = (f"the published frames are the pose-level estimate "
                     f"({'certified global optimum' if cert else 'not certified'}); "
                     f"the corner-level refinement is not published: {self.reason}")
        return {"estimate_published": "refined" if self.published else "certified",
                "certificate_scope": scope}

    def frame_fields(self, name: str, pose_level: dict) -> dict:
        """The uncertainty keys of frame ``name`` in the result YAML: the refined estimate's
        when it is published (``pose_level`` then holds the certified one's), else
        ``pose_level`` unchanged."""
        if not self.published or name not in self.refinement.names:
            return pose_level
        std = _std(self.refinement.frame_covariance(name))
        kind = REFINED_STD_KIND[self.refinement.model]
        spread = self.refinement.spread
        if spread is not None and spread.significant:
            kind += (f"; scaled by {spread.factor:.3g} (variance) to the spread of the "
                     f"{spread.folds} cross-validation folds' estimates, which exceeds the "
                     "model's")
        return {"std_kind": kind, **std,
                "a_posteriori": dict(std), "unobservable": {"translation": [], "rotation": []},
                "pose_level": pose_level}

    def lines(self) -> list[str]:
        """The summary's lines: what is published and why, the certificate's scope, the corner
        RMS per camera of both estimates."""
        r = self.refinement
        if r is None:
            return [f"corner-level refinement not run: {self.skipped}"] if self.skipped else []
        which = ("the refined estimate published" if self.published else
                 "the certified estimate published")
        out = [f"corner-level refinement ({_MODEL_WORDS[r.model]}): {which}: {self.reason}"]
        out.append("corner reprojection RMS per camera, certified -> refined: " + ", ".join(
            f"{cam} {r.rms_start_px[cam]:.2f} -> {r.rms_px[cam]:.2f} px" for cam in r.rms_px))
        return out


def _std(C: np.ndarray) -> dict:
    d = np.sqrt(np.maximum(np.diag(C), 0.0))
    return {"std_translation_m": [float(v) for v in d[:3]],
            "std_rotation_deg": [float(v) for v in np.degrees(d[3:])],
            "covariance": np.asarray(C, float).tolist()}


def _scope(result: CalibrationResult) -> str:
    if result.certified:
        return SCOPE
    return (f"the pose-level estimate is NOT certified ({result.certificate.status.value}); the "
            "corner-level refinement started from it (a local estimate, not certified)")


def pose_level_fit(problem, options) -> PoseLevelFit:
    """The pose-level estimate of ``problem`` (the weighted pairs the certified estimate was
    solved on) without given pose samples, for the refinement's cross-validation
    (:data:`~rwhec_ros.core.refine.PoseLevelFit`): the pairs whose ``A`` is bit for bit one of
    the held-out ``A`` (the views' ``A`` are their pairs') are left out and the rest solved with
    ``options`` (:class:`~rwhec_ros.core.solve.SolveOptions`, mode ``fast``). None when a
    held-out ``A`` matches no pair (the fold would score data it was fitted to), a frame loses
    every pair, or the solve fails."""
    from ..core.outliers.pairs import restrict_problem
    from ..core.solve import solve

    keys = {e.name: [np.ascontiguousarray(A).tobytes() for A in e.A] for e in problem.edges}

    def fit(held_A: np.ndarray):
        held = {np.ascontiguousarray(A).tobytes() for A in np.asarray(held_A, float)}
        masks = {n: np.array([k not in held for k in ks], bool) for n, ks in keys.items()}
        matched = {k for ks in keys.values() for k in ks if k in held}
        if matched != held:
            return None
        try:
            sub = restrict_problem(problem, masks, what="refinement cross-validation")
            if {e.x for e in sub.edges} != set(problem.x_names) or \
                    {e.y for e in sub.edges} != set(problem.y_names):
                return None
            res = solve(sub, options)
        except (ValueError, ArithmeticError, np.linalg.LinAlgError):
            return None
        if not (np.isfinite(res.X).all() and np.isfinite(res.Y).all()):
            return None
        return np.array(res.X), np.array(res.Y), float(res.scale)

    return fit


def refine_solution(problem, result: CalibrationResult, corners, uncertainty=None,
                    moving: str = "y", pose_level_options=None) -> CornerRefinement:
    """Refine ``result`` on ``corners`` ``(observations, intrinsics)`` and decide what is
    published (module docstring). ``uncertainty`` (the certified estimate's
    :class:`~rwhec_ros.core.analysis.uncertainty.Uncertainty`) enters the consistency check
    a posteriori; ``moving`` is the carrier that moves (``"y"`` cameras, ``"x"`` targets);
    ``pose_level_options`` (:class:`~rwhec_ros.core.solve.SolveOptions`; None: not compared)
    solve ``problem`` without each cross-validation fold's pose samples, so that the refinement
    is published only where it predicts unseen corners no worse than the pose-level estimate
    (:func:`pose_level_fit`, :func:`~rwhec_ros.core.refine.decide`).
    Never raises for the data's sake: a refinement that cannot run says why."""
    t0 = time.perf_counter()
    out = CornerRefinement(scope=_scope(result), certified=result)
    if result.unobservable:
        out.skipped = ("a translation the data do not determine is fixed by a prior or the "
                       "default; the corner-level refinement would move it")
        return out
    obs, intrinsics = corners
    views = corner_views([o for o in obs if o.y in intrinsics], result.x_names, result.y_names)
    cameras = {n: IntrinsicsProjector(intrinsics[n]) for n in result.y_names if n in intrinsics}
    try:
        ref = refine_views(views, cameras, result.X, result.Y, float(result.scale),
                           bool(problem.unknown_scale), RefineOptions(moving=moving),
                           pose_level=None if pose_level_options is None else
                           pose_level_fit(problem, pose_level_options))
    except (RefinementFailed, ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
        out.skipped = f"the refinement failed ({exc})"
        out.timing_s = time.perf_counter() - t0
        return out
    cov = scale_std = None
    if uncertainty is not None:
        vf = float(uncertainty.variance_factor)
        k = vf if np.isfinite(vf) and vf > 0 else 1.0
        cov = {f.name: k * f.covariance for f in uncertainty.frames}
        if uncertainty.scale_std is not None:
            scale_std = float(uncertainty.scale_std) * np.sqrt(k)
    out.refinement = ref
    out.decision = decide(ref, result, cov, scale_std)
    out.timing_s = time.perf_counter() - t0
    return out


#: The start of the note of a result whose frames are the refinement (:func:`published_result`).
PUBLISHED_NOTE = "the published frames are the corner-level refinement"


def published_result(result: CalibrationResult, refinement: CornerRefinement | None
                     ) -> CalibrationResult:
    """``result`` itself, or with a published refinement a copy holding the refined frames and
    scale, the same (pose-level) certificate and a note saying what it covers."""
    if refinement is None or not refinement.published:
        return result
    r = refinement.refinement
    return replace(result, X=np.array(r.X), Y=np.array(r.Y), scale=float(r.scale),
                   notes=[*result.notes, f"{PUBLISHED_NOTE}: {refinement.scope}"],
                   timing_s={**result.timing_s, "refine": float(refinement.timing_s)})


def published_uncertainty(uncertainty, refinement: CornerRefinement | None):
    """The uncertainty the verdict judges the published frames by: ``uncertainty`` (the
    certified estimate's :class:`~rwhec_ros.core.analysis.uncertainty.Uncertainty`) itself, or
    with a published refinement a copy whose frames' translation and rotation blocks are
    widened where the refinement's std in the worst direction is larger (each block scaled by
    the squared ratio): the verdict's precision (the first line, each frame's ``+-``) then holds
    for the frames published, refined or not. (The scale's std stays the certified one's: the
    verdict's scale check judges the certified scale; the summary prints the published one's.)
    The refined covariance is a posteriori already; the verdict's factor on top only widens it."""
    if uncertainty is None or refinement is None or not refinement.published:
        return uncertainty
    ref = refinement.refinement
    frames = []
    for f in uncertainty.frames:
        C = np.array(f.covariance, dtype=float)
        if f.name in ref.names:
            ours = block_variances(C)
            theirs = block_variances(ref.frame_covariance(f.name))
            for sl, a, b in zip((slice(0, 3), slice(3, 6)), ours, theirs, strict=True):
                if np.isfinite(a) and np.isfinite(b) and b > a > 0:
                    C[sl, :] *= np.sqrt(b / a)
                    C[:, sl] *= np.sqrt(b / a)
        frames.append(replace(f, covariance=C))
    return replace(uncertainty, frames=frames)
