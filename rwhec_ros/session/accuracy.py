"""How accurate a calibration is, computed once in the solve step and shared by every output.

At the solution of :func:`~rwhec_ros.session.solving.solve_and_assess`:

* the **uncertainty** of every frame (:func:`rwhec_ros.core.analysis.uncertainty.frame_uncertainty`,
with
  the solve's priors): the 6x6 covariance on the tangent space of SE(3) in the frame's parent,
  predicted from the noise of the weights and rescaled a posteriori; unobservable axes as such;
* the **cross-validation** (:func:`rwhec_ros.core.analysis.validation.cross_validate`, ``folds``
folds,
  ``0`` for none): per edge the held-out residuals next to the in-sample ones;
* the **next-motion guidance** (:func:`rwhec_ros.core.analysis.guidance.suggest_next_motion`): the
motion
  that would most reduce the largest remaining std, in words;
* the **reprojection error per camera**
  (:func:`rwhec_ros.vision.reprojection.reprojection_errors`) of the detected corners (tags,
  boards) through the calibrated chain, when the data keep corners and intrinsics
  (:func:`rwhec_ros.data.corners.corner_observations`), with each camera's focal fit
  (:func:`rwhec_ros.vision.focal_fit.fit_focal_scale`, read by the verdict's focal check):
  about 8 per-image pose fits of at most 100 images per camera, ~0.2-0.5 s per camera on a busy
  2-core machine.

:class:`Accuracy` holds them (each None when skipped or failed, with a note saying why) and
gives the result-YAML keys (:meth:`Accuracy.frame_fields`, :meth:`Accuracy.to_dict`), the summary
lines (:func:`accuracy_lines`) and the /diagnostics values (:meth:`Accuracy.diagnostic_values`).

Cost on the paper's real data (3,230 pairs, 24 frames; single runs on a busy 2-core machine):
uncertainty ~10 ms, 5-fold cross-validation ~0.25 s, guidance ~0.6 s, against ~35 ms for the
``fast`` solve; hence the switches ``accuracy.cross_validation_folds`` and
``accuracy.guidance`` (CLI ``--folds``, ``--no-guidance``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from ..core.analysis.guidance import Guidance, GuidanceOptions, suggest_next_motion
from ..core.analysis.uncertainty import Uncertainty, UncertaintyOptions, frame_uncertainty
from ..core.analysis.validation import CrossValidation, cross_validate
from ..core.problem import Problem
from ..core.verdict.words import deg, mm
from .refinement import CornerRefinement

__all__ = ["AccuracyOptions", "Accuracy", "assess_accuracy", "accuracy_lines", "std_words",
           "unobservable_axes"]

_AXES = ("x", "y", "z")


@dataclass(frozen=True)
class AccuracyOptions:
    """What :func:`assess_accuracy` computes.

    Attributes
    ----------
    folds : int
        Cross-validation folds (``accuracy.cross_validation_folds``, 5); 0 for none.
    guidance : bool
        Compute the next-motion guidance (``accuracy.guidance``).
    seed : int
        Seed of the fold assignment (same data, same folds).
    moving : str
        ``"y"``: the camera carrier moves (a mobile rig, an arm carrying the cameras); ``"x"``:
        the tag carrier moves (a hand-held target); the guidance's sentences move that carrier.
    """

    folds: int = 5
    guidance: bool = True
    seed: int = 0
    moving: str = "y"

    def __post_init__(self) -> None:
        if int(self.folds) != self.folds or self.folds < 0 or self.folds == 1:
            raise ValueError(f"folds: must be 0 (off) or an integer >= 2, got {self.folds!r}")
        if self.moving not in ("x", "y"):
            raise ValueError(f"moving: expected 'x' or 'y', got {self.moving!r}")

    @classmethod
    def from_config(cls, c) -> AccuracyOptions:
        """``accuracy.*`` of a :class:`~rwhec_ros.config.CalibratorConfig`; the guidance moves
        the carrier that moves (the camera carrier unless only the tag carrier does)."""
        moving = "x" if c.tag_carrier.moving and not c.camera_carrier.moving else "y"
        return cls(folds=c.accuracy.cross_validation_folds, guidance=c.accuracy.guidance,
                   moving=moving)


def std_words(t_m: float, r_deg: float) -> str:
    """``+-1.2 mm, +-0.05 deg`` (``not determined`` for an infinite std)."""
    t = "translation not determined" if np.isinf(t_m) else f"+-{mm(t_m)}"
    r = "rotation not determined" if np.isinf(r_deg) else f"+-{deg(r_deg)}"
    return f"{t}, {r}"


@dataclass
class Accuracy:
    """Uncertainty, cross-validation and guidance of one solution (module docstring).

    Attributes
    ----------
    uncertainty : Uncertainty or None
    validation : CrossValidation or None
    guidance : Guidance or None
    reprojection : dict of str to CameraReprojection, or None
        Per camera (None without corners), through the certified estimate.
    refinement : CornerRefinement or None
        The corner-level refinement (:mod:`.refinement`; None when not asked for or without
        corners): which estimate is published and why.
    options : AccuracyOptions
    notes : list of str
        Why a part is missing (switched off, or failed and how).
    timing_s : dict of str to float
        Seconds per part (``uncertainty``, ``cross_validation``, ``guidance``).
    """

    uncertainty: Uncertainty | None = None
    validation: CrossValidation | None = None
    guidance: Guidance | None = None
    reprojection: dict | None = None
    refinement: CornerRefinement | None = None
    options: AccuracyOptions = field(default_factory=AccuracyOptions)
    notes: list[str] = field(default_factory=list)
    timing_s: dict[str, float] = field(default_factory=dict)

    def frame_fields(self, name: str) -> dict:
        """The uncertainty keys of frame ``name`` in the result YAML: predicted
        ``std_translation_m`` [x, y, z] (m), ``std_rotation_deg`` [x, y, z] (deg), both about
        the parent's axes, the 6x6 ``covariance`` of ``[dt, phi]`` (m, rad), the same rescaled
        under ``a_posteriori``, the ``unobservable`` axes by name (their entries ``None``), and
        ``std_kind`` saying which is which; empty without an uncertainty for it."""
        if self.uncertainty is None:
            return {}
        try:
            fu = self.uncertainty.frame(name)
        except KeyError:
            return {}
        d = {"std_kind": "predicted from the noise of the weights (estimated from the data, or "
                         "stated: sigma, kappa); a_posteriori: times the variance factor of the "
                         "residuals", **fu.to_dict()}
        return d if self.refinement is None else self.refinement.frame_fields(name, d)

    def certificate_fields(self) -> dict:
        """With a refinement, the result-YAML keys ``estimate_published`` and
        ``certificate_scope`` that go beside the certificate's
        (:meth:`~rwhec_ros.session.refinement.CornerRefinement.certificate_fields`); else
        empty."""
        return {} if self.refinement is None else self.refinement.certificate_fields()

    def to_dict(self) -> dict:
        """The top-level result-YAML keys ``uncertainty`` (convention, variance factor, scale
        std, unobservable directions in words; the frames' numbers are with the frames),
        ``cross_validation``, ``guidance`` and ``reprojection`` (per camera, through the
        certified estimate, with ``rms_px_refined`` when a refinement ran; None when not
        computed), ``accuracy_notes`` and, with a refinement, ``refinement``
        (:meth:`~rwhec_ros.session.refinement.CornerRefinement.to_dict`)."""
        unc = None
        if self.uncertainty is not None:
            unc = self.uncertainty.to_dict()
            unc.pop("frames", None)
            s = self.uncertainty.scale_std
            vf = self.uncertainty.variance_factor
            unc["scale_std_a_posteriori"] = (None if s is None or not np.isfinite(s * vf)
                                             else float(s * np.sqrt(vf)))
            unc["timing_s"] = float(self.uncertainty.timing_s)
        cv = None
        if self.validation is not None:
            cv = {"seed": int(self.options.seed), **self.validation.to_dict(),
                  "timing_s": float(self.validation.timing_s)}
        rep = None if self.reprojection is None else {
            cam: r.to_dict() for cam, r in self.reprojection.items()}
        ref = self.refinement.refinement if self.refinement is not None else None
        for cam, r in (rep or {}).items():
            if ref is not None and cam in ref.rms_px:
                r["rms_px_refined"] = float(ref.rms_px[cam])
        out = {"uncertainty": unc, "cross_validation": cv,
               "guidance": None if self.guidance is None else self.guidance.to_dict(),
               "reprojection": rep,
               "accuracy_notes": list(self.notes),
               "accuracy_timing_s": {k: float(v) for k, v in self.timing_s.items()}}
        if self.refinement is not None:
            out["refinement"] = self.refinement.to_dict()
        return out

    def worst_held_out(self):
        """The edge with the largest held-out RMS translation residual (or None)."""
        if self.validation is None:
            return None
        held = [e for e in self.validation.edges if e.held_out is not None]
        return max(held, key=lambda e: e.held_out.rms_translation_mm) if held else None

    def largest_std(self) -> tuple[str, str] | None:
        """``(words, frame)`` of the largest predicted per-axis std (translation against
        rotation by the guidance's targets, 5 mm ~ 0.25 deg), e.g. ``("tag_8 translation y
        +-35.5 mm", "tag_8")``; None without an uncertainty or when nothing is observable."""
        if self.uncertainty is None:
            return None
        g = GuidanceOptions()
        best, best_r = None, -1.0
        for fu in self.uncertainty.frames:
            for i in range(3):
                for what, v, target, words in (
                        ("translation", fu.std_translation_m[i], g.target_std_translation_m, mm),
                        ("rotation", fu.std_rotation_deg[i], g.target_std_rotation_deg, deg)):
                    if np.isfinite(v) and v / target > best_r:
                        best_r = v / target
                        best = (f"{fu.name} {what} {_AXES[i]} +-{words(v)}", fu.name)
        return best

    def diagnostic_values(self) -> list[tuple[str, str]]:
        """``(key, value)`` pairs for the /diagnostics session row: per frame its worst-direction
        std (``std <frame>``), the largest std, the worst held-out edge and the next motion."""
        out = []
        if self.uncertainty is not None:
            for fu in self.uncertainty.frames:
                out.append((f"std {fu.name}", std_words(*fu.worst_std())))
            big = self.largest_std()
            if big is not None:
                out.append(("largest_std", big[0]))
        w = self.worst_held_out()
        if w is not None:
            out.append(("worst_held_out_edge", _held_out_words(w)))
        for cam, r in (self.reprojection or {}).items():
            out.append((f"reprojection {cam}", _reprojection_words(r)))
        if self.guidance is not None:
            out.append(("next_motion", self.guidance.message))
        return out


def _held_out_words(e) -> str:
    return (f"({e.x}, {e.y}) held out {mm(e.held_out.rms_translation_mm / 1e3)}, "
            f"{deg(e.held_out.rms_rotation_deg)} RMS (in-sample "
            f"{mm(e.in_sample.rms_translation_mm / 1e3)}, {deg(e.in_sample.rms_rotation_deg)})")


def _reprojection_words(r) -> str:
    if not np.isfinite(r.rms_px):
        return f"no pair in front of the camera ({r.n_pairs} pairs)"
    return (f"RMS {r.rms_px:.2f} px, median {r.median_px:.2f} px, max {r.max_px:.1f} px over "
            f"{r.n_pairs} pairs" + (f" ({r.n_behind} behind the camera)" if r.n_behind else ""))


def _timed(acc: Accuracy, key: str, what: str, fn):
    t0 = time.perf_counter()
    try:
        return fn()
    except (ValueError, ArithmeticError, np.linalg.LinAlgError, RuntimeError) as exc:
        acc.notes.append(f"{what} failed ({type(exc).__name__}: {exc})")
        return None
    finally:
        acc.timing_s[key] = time.perf_counter() - t0


def assess_accuracy(problem: Problem, result, *, solve_options=None,
                    options: AccuracyOptions | None = None,
                    carriers: tuple[str, str] = ("the camera carrier", "the tag carrier"),
                    corners=None) -> Accuracy:
    """Uncertainty, cross-validation and guidance of ``result`` for ``problem`` (module
    docstring). ``solve_options`` (:class:`~rwhec_ros.core.solve.SolveOptions`) gives the
    priors (its ``gauge``) and the folds' solver options (mode ``fast`` there); ``carriers``
    names the camera and tag carrier in the guidance's sentences; ``corners``
    ``(observations, intrinsics)`` (a sequence of
    :class:`~rwhec_ros.vision.reprojection.CornerObservation` and camera -> intrinsics) give the
    reprojection error per camera (observations of frames the result lacks are left out). A part
    that fails leaves a note and None; nothing raises for the data's sake."""
    from ..core.model.gauge import GaugeOptions
    from ..core.solve import SolveOptions

    opts = options or AccuracyOptions()
    gauge = solve_options.gauge if solve_options is not None else GaugeOptions()
    unc_opts = UncertaintyOptions(gauge=gauge)
    acc = Accuracy(options=opts)
    acc.uncertainty = _timed(acc, "uncertainty", "the uncertainty",
                             lambda: frame_uncertainty(problem, result, unc_opts))
    if opts.folds:
        fold_opts = SolveOptions(mode="fast", gauge=gauge,
                                 min_scale=getattr(solve_options, "min_scale", 0.01))
        acc.validation = _timed(acc, "cross_validation", "the cross-validation",
                                lambda: cross_validate(problem, np.random.default_rng(opts.seed),
                                                       folds=opts.folds, result=result,
                                                       options=fold_opts))
    else:
        acc.notes.append("cross-validation off (accuracy.cross_validation_folds = 0)")
    if opts.guidance:
        g_opts = GuidanceOptions(moving=opts.moving, y_carrier=carriers[0],
                                 x_carrier=carriers[1], uncertainty=unc_opts)
        acc.guidance = _timed(acc, "guidance", "the next-motion guidance",
                              lambda: suggest_next_motion(problem, result, g_opts))
    else:
        acc.notes.append("next-motion guidance off (accuracy.guidance = false)")
    if corners is not None:
        obs, intrinsics = corners
        names = set(result.x_names) | set(result.y_names)
        obs = [o for o in obs if o.x in names and o.y in names and o.y in intrinsics]
        if obs:
            from ..vision.reprojection import reprojection_errors

            acc.reprojection = _timed(acc, "reprojection", "the reprojection error",
                                      lambda: reprojection_errors(obs, intrinsics, result))
    return acc


def unobservable_axes(uncertainty: Uncertainty) -> list[str]:
    """``cam0 translation z``, ``tag_1 rotation x``, ``the scale``: every unobservable axis of
    ``uncertainty``, by frame (axes of the frame's parent)."""
    out = []
    for fu in uncertainty.frames:
        for what, bad in (("translation", fu.unobservable_translation),
                          ("rotation", fu.unobservable_rotation)):
            axes = [a for a, b in zip(_AXES, bad, strict=True) if b]
            if axes:
                out.append(f"{fu.name} {what} {'/'.join(axes)}")
    if uncertainty.scale_std is not None and np.isnan(uncertainty.scale_std):
        out.append("the scale")
    return out


def accuracy_lines(accuracy: Accuracy | None) -> list[str]:
    """The summary's accuracy lines: the largest std (predicted and a posteriori), the worst
    held-out edge against its in-sample residuals, and the next motion in one sentence."""
    if accuracy is None:
        return []
    lines = []
    unc = accuracy.uncertainty
    big = accuracy.largest_std()
    if unc is not None and big is not None:
        vf = unc.variance_factor
        post = (f"; a posteriori x{np.sqrt(vf):.2g} (variance factor {vf:.2g} of the residuals)"
                if np.isfinite(vf) else "")
        lines.append(f"largest std: {big[0]} (1 sigma, predicted from the noise of the "
                     f"weights{post})")
    if unc is not None:
        axes = unobservable_axes(unc)
        if axes:
            lines.append("unobservable (not determined by the data, axes of the parents): "
                         + ", ".join(axes))
    w = accuracy.worst_held_out()
    # with a refinement published, these two lines are of the certified (pose-level) estimate
    of = (" of the certified estimate" if accuracy.refinement is not None
          and accuracy.refinement.published else "")
    if w is not None:
        lines.append(f"cross-validation ({accuracy.validation.folds} folds){of}, worst "
                     f"held-out edge: {_held_out_words(w)}")
    if accuracy.reprojection:
        lines.append(f"reprojection error of the detected corners through the calibration{of} "
                     "(RMS): "
                     + ", ".join(f"{cam} {r.rms_px:.2f} px" for cam, r in
                                 accuracy.reprojection.items()))
    if accuracy.refinement is not None:
        lines += accuracy.refinement.lines()
    if accuracy.guidance is not None:
        lines.append(f"next motion: {accuracy.guidance.message}")
    lines += [f"note: {n}" for n in accuracy.notes if "failed" in n]
    return lines
