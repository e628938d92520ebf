"""The solve step of the session and the CLI: identifiability at the solution, the accuracy
(uncertainty, cross-validation, guidance: :mod:`.accuracy`) and the verdict, computed once here and
shared by the CLI and the node."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..core.identifiability import IdentifiabilityTracker, analyze
from ..core.problem import Problem
from ..core.result import CalibrationResult
from ..core.verdict import Verdict, VerdictOptions, assess
from ..core.verdict.exclusion import Attempt, Exclusion, exclude_misfits
from ..data.corners import pairs_at_pose
from ..data.results import plain
from .accuracy import Accuracy, AccuracyOptions, assess_accuracy
from .pooled_noise import pooled_corner_noise
from .refinement import published_result, published_uncertainty, refine_solution

__all__ = [
    "solve_options",
    "solve_problem",
    "make_tracker",
    "analyze_at_solution",
    "full_report",
    "report_dict",
    "Solved",
    "solve_and_assess",
    "verdict_options",
    "noise_options",
    "solver_alternatives",
]


def make_tracker(unknown_scale: bool) -> IdentifiabilityTracker:
    """The session's incremental identifiability tracker (Section 6), without its own pairs."""
    # the accumulator holds the pairs; the tracker keeps only its fixed-size sums
    return IdentifiabilityTracker(unknown_scale=unknown_scale, keep_pairs=False)


def analyze_at_solution(problem, result: CalibrationResult):
    """Whole-problem identifiability at the solution (``analyze(..., full=True)``, an
    :class:`~rwhec_ros.core.identifiability.IdentifiabilityReport`), or None if it fails."""
    from ..core.solve import blas_threads

    try:
        with blas_threads(1):  # small dense matrices: threads only add contention
            return analyze(problem, solution=(result.X, result.Y, float(result.scale)))
    except Exception:  # noqa: BLE001 - optional extra; the tracker's report remains
        return None


def full_report(problem, result: CalibrationResult) -> dict | None:
    """:func:`analyze_at_solution` as a plain mapping, or None."""
    return report_dict(analyze_at_solution(problem, result))


def report_dict(report) -> dict | None:
    """``report.to_dict()`` as plain YAML-safe values (None stays None)."""
    if report is None:
        return None
    return plain(report.to_dict())


def solve_options(
    problem, *, mode: str = "fast", priors=(), unobservable_std_m: float = 1.0,
    min_scale: float = 0.01, sdp_backend: str = "auto",
):
    """:class:`~rwhec_ros.core.solve.SolveOptions` for ``problem`` with the translation priors
    ``(frame, axis, value_m)`` of the frames it has and the SDP backend (returns the options and
    a note per prior whose frame has no usable edge)."""
    from ..core.certify.relaxation import SdpOptions
    from ..core.model.gauge import GaugeOptions, TranslationPrior
    from ..core.solve import SolveOptions

    kept, notes = [], []
    for frame, axis, value in priors:
        if frame in problem.frame_names:
            kept.append(TranslationPrior(frame, axis, value))
        else:
            notes.append(f"prior {frame}.{axis} = {value:g} m not used: {frame} has no usable edge")
    gauge = GaugeOptions(max_std_m=unobservable_std_m, priors=tuple(kept))
    return SolveOptions(mode=mode, gauge=gauge, min_scale=min_scale,
                        sdp=SdpOptions(backend=sdp_backend)), notes


def _solve(problem: Problem, options, reject_outliers: bool, noise=None):
    """``(result, solved problem, dropped edges, notes, rejected pairs, noise estimate)``: a
    plain solve, or RANSAC + GNC-TLS whose solved problem is the inlier problem (rejected pairs:
    edge ``"(x, y)"`` -> the indices of its rejected pairs in ``problem``, ascending); with
    ``noise`` (:class:`~rwhec_ros.core.noise.NoiseOptions`, ``estimate`` on) then solved with the
    noise estimated from the data (:func:`~rwhec_ros.core.noise.solve_with_noise`: the solved
    problem carries the estimated weights; the estimate None otherwise)."""
    if noise is None or not noise.estimate:
        return (*_solve_given(problem, options, reject_outliers), None)
    import copy

    from ..core.noise import solve_with_noise

    start = copy.copy(options)
    solved, dropped, notes, rejected, warm = problem, {}, [], {}, None
    if reject_outliers:
        # the outlier thresholds of RANSAC and GNC-TLS are in units of the noise: the data's,
        # estimated first (edges far off are left out of it); then the inliers' noise
        pre = solve_with_noise(problem, start, noise)
        result, _, dropped, notes, rejected = _solve_given(pre.problem, options, True)
        solved = _inliers(problem, dropped, rejected)
        start.initial = (result.X, result.Y)
        warm = None if pre.estimate is None else pre.estimate.factors()
    ns = solve_with_noise(solved, start, noise, warm=warm)
    notes = notes + ns.notes
    return ns.result, ns.problem, dropped, notes, rejected, ns.estimate


def _inliers(problem: Problem, dropped: Mapping[str, str],
             rejected: Mapping[str, list[int]]) -> Problem:
    """``problem``'s pairs without the ``dropped`` edges and the ``rejected`` pairs (edge ->
    indices), with their given noise."""
    from ..core.outliers.pairs import restrict_problem

    masks = {}
    for e in problem.edges:
        m = np.full(e.n, e.name not in dropped)
        m[list(rejected.get(e.name, ()))] = False
        masks[e.name] = m
    return restrict_problem(problem, masks, what="outlier rejection")


def _solve_given(problem: Problem, options, reject_outliers: bool):
    """:func:`_solve` with the given noise: ``(result, solved problem, dropped edges, notes,
    rejected pairs)``."""
    from ..core.solve import solve

    if not reject_outliers:
        return solve(problem, options), problem, {}, [], {}
    from ..core.outliers import RobustOptions, robust_solve

    robust = robust_solve(problem, options=RobustOptions(solve=options))
    dropped = {}
    if robust.ransac is not None:
        dropped = {str(edge): f"outlier rejection: {reason}" for edge, reason in
                   robust.ransac.dropped}
    kept = {e.name for e in robust.inlier_problem.edges}
    for e in problem.edges:  # every pair of an edge rejected (RANSAC or GNC)
        if e.name not in kept and e.name not in dropped:
            dropped[e.name] = f"outlier rejection: all {e.n} pairs rejected"
    notes = [f"outlier rejection: {len(robust.rejected)} of {problem.n_measurements} pairs "
             f"rejected ({len(dropped)} edge{'' if len(dropped) == 1 else 's'} dropped)"]
    rejected: dict[str, list[int]] = {}
    for edge, index, _ in robust.rejected:
        rejected.setdefault(edge, []).append(int(index))
    return (robust.result, robust.inlier_problem, dropped, notes,
            {edge: sorted(indices) for edge, indices in rejected.items()})


def solve_problem(
    problem, *, mode: str = "fast", reject_outliers: bool = False, priors=(),
    unobservable_std_m: float = 1.0, min_scale: float = 0.01, sdp_backend: str = "auto",
) -> tuple[CalibrationResult, dict[str, str], list[str]]:
    """The solve step shared by the session and the CLI: ``solve`` in ``mode``, or with
    ``reject_outliers`` RANSAC (paper Section 9.1) + GNC-TLS re-certified on the inlier set
    (:func:`rwhec_ros.core.outliers.robust_solve`). ``priors`` (``(frame, axis, value_m)``) and
    ``unobservable_std_m`` fix translation directions the data do not determine
    (:mod:`rwhec_ros.core.model.gauge`); ``min_scale`` is the unknown scale's floor;
    ``sdp_backend`` the SDP's solver. Returns (result, dropped edges, notes)."""
    options, prior_notes = solve_options(problem, mode=mode, priors=priors,
                                         unobservable_std_m=unobservable_std_m,
                                         min_scale=min_scale, sdp_backend=sdp_backend)
    result, _, dropped, notes, _ = _solve_given(problem, options, reject_outliers)
    notes = prior_notes + notes
    result.notes.extend(notes)
    return result, dropped, notes


@dataclass
class Solved:
    """A solved and assessed problem (:func:`solve_and_assess`).

    Attributes
    ----------
    result : CalibrationResult
        The published estimate: the certified solve, or its corner-level refinement when that
        is published (``accuracy.refinement`` says which and why; the certificate is the
        pose-level one either way).
    problem : Problem
        The pairs the result solves (with outlier rejection: the inlier problem).
    dropped : dict of str to str
        Edges ``"(x, y)"`` the outlier rejection left out, and why.
    notes : list of str
    identifiability : IdentifiabilityReport or None
        At the solution (with the numeric check).
    verdict : Verdict
    accuracy : Accuracy or None
        Per-frame uncertainty, cross-validation and guidance (:mod:`.accuracy`); None when not
        asked for.
    rejected_pairs : dict of str to list of int
        With outlier rejection: edge ``"(x, y)"`` -> the indices of its pairs the rejection left
        out (indices into the problem given to :func:`solve_and_assess`, i.e. the data set's
        pairs of that edge), ascending; edges with none rejected are not listed.
    exclusion : Exclusion or None
        What was excluded because it did not fit, before ``result`` was solved, the frames'
        shifts and the all-data solve's key numbers
        (:func:`~rwhec_ros.core.verdict.exclusion.exclude_misfits`; also ``verdict.exclusion``);
        None when ``verdict.exclude_misfits`` is off. Its edges are in ``dropped``.
    noise : NoiseEstimate or None
        The noise per group estimated from the data (:mod:`rwhec_ros.core.noise`); ``problem``
        then has those weights. None when not estimated.
    """

    result: CalibrationResult
    problem: Problem
    dropped: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    identifiability: object = None
    verdict: Verdict | None = None
    accuracy: Accuracy | None = None
    rejected_pairs: dict[str, list[int]] = field(default_factory=dict)
    exclusion: Exclusion | None = None
    noise: Any = None

    @property
    def identifiability_dict(self) -> dict | None:
        return report_dict(self.identifiability)


def verdict_options(section: Mapping[str, Any] | None) -> VerdictOptions:
    """:class:`VerdictOptions` from a configuration's ``verdict`` thresholds (short names of the
    ``verdict.*`` parameters, :attr:`CalibratorConfig.verdict`); None or empty: the defaults."""
    return VerdictOptions(**dict(section or {}))


def noise_options(noise_config, kinds=(), **overrides):
    """:class:`~rwhec_ros.core.noise.NoiseOptions` from a configuration's ``noise`` section
    (:class:`~rwhec_ros.config.sections.NoiseConfig`): ``estimate``, ``groups`` and what the
    pairs' ``sigma``/``kappa`` are (stated, from the reprojection, start values); ``kinds``:
    the targets' kinds (:attr:`~rwhec_ros.config.CalibratorConfig.target_kinds`);
    ``overrides`` replace fields (e.g. ``information="edge_blocks"``)."""
    from ..core.noise import NoiseOptions

    return NoiseOptions(**{"estimate": noise_config.estimate, "groups": noise_config.groups,
                           "given": noise_config.given, "kinds": tuple(kinds), **overrides})


def config_noise(config, **overrides):
    """:func:`noise_options` of a :class:`~rwhec_ros.config.CalibratorConfig`: its ``noise``
    section and its targets' kinds."""
    return noise_options(config.noise, config.target_kinds, **overrides)


#: What :func:`solve_and_assess` computes by default: uncertainty, 5-fold cross-validation,
#: guidance (frozen, so safe as a default argument).
DEFAULT_ACCURACY = AccuracyOptions()


def solve_and_assess(
    problem: Problem,
    *,
    mode: str = "fast",
    reject_outliers: bool = False,
    priors=(),
    unobservable_std_m: float = 1.0,
    min_scale: float = 0.01,
    sdp_backend: str = "auto",
    thresholds: VerdictOptions | None = None,
    expected_x: Iterable[str] = (),
    expected_y: Iterable[str] = (),
    excluded: Mapping[str, str] | None = None,
    carriers: tuple[str, str] = ("the camera carrier", "the tag carrier"),
    accuracy: AccuracyOptions | None = DEFAULT_ACCURACY,
    corners=None,
    noise=None,
    on_phase: Callable[[str], None] | None = None,
    refine: bool = True,
) -> Solved:
    """Solve ``problem`` (as :func:`solve_problem`: ``mode``, ``reject_outliers``, ``priors``,
    ``unobservable_std_m``, ``min_scale``, ``sdp_backend``), analyse identifiability at the
    solution and :func:`~rwhec_ros.core.verdict.assess` it with ``thresholds``.
    ``expected_x``/``expected_y`` are the tags and cameras the user asked for, ``excluded`` the
    edges left out before the solve (with reasons), ``carriers`` the camera and tag carrier frame
    names. ``accuracy`` says what of the per-frame uncertainty, cross-validation and guidance to
    compute (:func:`~rwhec_ros.session.accuracy.assess_accuracy`; None: none of it); the
    verdict's precision uses that uncertainty; ``corners`` ``(observations, intrinsics)`` add the
    reprojection error per camera and the verdict's focal check (with ``accuracy`` only), and
    with ``refine`` the corner-level refinement (:mod:`.refinement`), whose estimate becomes the
    result when it is published (the verdict judges the certified solve).
    ``noise`` (:class:`~rwhec_ros.core.noise.NoiseOptions`; None: off): the noise of each group
    estimated from the data and the final solve with it (after any outlier rejection); the
    uncertainty and the verdict are then those of the estimated weights, and the verdict compares
    a stated noise with the estimate. A target or an edge that does not fit is excluded and the
    rest solved again (``thresholds.exclude_misfits``, each solve with its own noise estimate).
    ``on_phase`` is called with ``"analysing"`` when the solver returned. Exceptions of the
    solver propagate."""
    from ..core.solve import blas_threads

    if noise is not None and noise.given == "reprojection" and corners is not None:
        problem = pooled_corner_noise(problem, corners, noise.min_redundancy)  # few corners
    options, prior_notes = solve_options(problem, mode=mode, priors=priors,
                                         unobservable_std_m=unobservable_std_m,
                                         min_scale=min_scale, sdp_backend=sdp_backend)
    first = _solve(problem, options, reject_outliers, noise)
    exclusion = None
    if (thresholds or VerdictOptions()).exclude_misfits:
        exclusion, first = _exclude(problem, first, options, reject_outliers, thresholds, noise)
    result, solved, dropped, notes, rejected, estimate = first
    notes = prior_notes + notes
    result.notes.extend(notes)
    if on_phase is not None:
        on_phase("analysing")
    ident = analyze_at_solution(solved, result)
    corners = _kept_corners(corners, problem, dropped, rejected)
    acc = None
    if accuracy is not None:
        acc = assess_accuracy(solved, result, solve_options=options, options=accuracy,
                              carriers=carriers, corners=corners)
    if acc is not None and corners is not None and refine:  # the corner-level refinement
        acc.refinement = refine_solution(
            solved, result, corners, acc.uncertainty, accuracy.moving,
            pose_level_options=replace(options, mode="fast", fallback_to_sdp=False,
                                       initial=(result.X, result.Y)))
    with blas_threads(1):  # the precision judged: that of the frames published
        verdict = assess(result, solved, identifiability=ident, options=thresholds,
                         uncertainty=None if acc is None else published_uncertainty(
                             acc.uncertainty, acc.refinement),
                         reprojection=None if acc is None else acc.reprojection,
                         intrinsics=None if corners is None else corners[1],
                         expected_x=[*expected_x, *problem.x_names],
                         expected_y=[*expected_y, *problem.y_names],
                         excluded={**dict(excluded or {}), **dropped}, carriers=carriers,
                         exclusion=exclusion, noise=estimate)
    result = published_result(result, None if acc is None else acc.refinement)
    return Solved(result, solved, dropped, notes, ident, verdict, acc, rejected, exclusion,
                  estimate)


def _kept_corners(corners, problem: Problem, dropped: Mapping[str, str],
                  rejected: Mapping[str, list[int]]):
    """``corners`` (``(observations, intrinsics)`` or None) without those of the ``dropped``
    edges (excluded for their misfit, wholly rejected) and of the pairs the outlier rejection
    left out (``rejected``: edge -> indices into ``problem``'s edge, matched by the pair's
    ``A``): the refinement and the reprojection figures use the corners of the pairs solved.
    A flipped tag pose rendered as such has corners of the flipped pose; with ``--robust`` the
    rejection left its pairs out and the refinement, using their corners, published cameras 3-5
    of their std off (``benchmarks/verdict.md`` section 4)."""
    if corners is None or not (dropped or rejected):
        return corners
    edges = {e.name: e for e in problem.edges}
    left_out = {name: edges[name].A[list(idx)] for name, idx in rejected.items()
                if name in edges and len(idx)}

    def solved(o) -> bool:
        name = f"({o.x}, {o.y})"
        if name in dropped:
            return False
        gone = left_out.get(name)
        return gone is None or not len(pairs_at_pose(gone, o.A))

    return [o for o in corners[0] if solved(o)], corners[1]


def _exclude(problem: Problem, first: tuple, options, reject_outliers: bool,
             thresholds: VerdictOptions | None, noise=None) -> tuple[Exclusion, tuple]:
    """:func:`~rwhec_ros.core.verdict.exclusion.exclude_misfits` with this module's solve
    (``options``, ``reject_outliers``, ``noise``: each re-solve estimates its own): the
    exclusion and the ``_solve`` tuple to publish, whose ``dropped`` also holds the excluded
    edges and whose notes say what the certificate is for."""
    from ..core.pipeline.options import SolveOptions

    def attempt(out: tuple, given: Problem) -> Attempt:
        result, solved, dropped, _, rejected, estimate = out
        counts = {k: len(v) for k, v in rejected.items()}
        sizes = {e.name: e.n for e in given.edges}
        for edge in dropped:  # wholly rejected edges
            if edge in sizes:
                counts[edge] = sizes[edge]
        return Attempt(result, solved, counts, out,
                       noise_estimated=estimate is not None and estimate.estimated,
                       noise=estimate)

    trial = SolveOptions(mode="fast", gauge=options.gauge, min_scale=options.min_scale,
                         sdp=options.sdp)  # the configured SDP backend for a fallback
    exclusion, final = exclude_misfits(
        problem, attempt(first, problem),
        lambda p: attempt(_solve(p, options, reject_outliers, noise), p),
        options=thresholds, solve_options=trial)
    result, solved, dropped, notes, rejected, estimate = final.extra
    if exclusion.excluded:
        dropped = {**dropped, **exclusion.dropped()}
        notes = [*notes, f"exclusion: {exclusion.certificate_note()}"]
    return exclusion, (result, solved, dropped, notes, rejected, estimate)


def solver_alternatives(mode: str, robust: bool, mode_option: str = "--mode",
                        robust_option: str = "--robust") -> str:
    """What is left to try after the solver stopped with an error in ``mode`` (with or
    without outlier rejection), naming the option (``mode_option``, ``robust_option``) and its
    current value; never what already ran."""
    tries = []
    if mode == "sdp":
        tries.append(f"{mode_option} fast (now sdp)")
    elif mode == "local":
        tries.append(f"{mode_option} fast (now local: with a certificate and the SDP fallback)")
    if not robust:
        tries.append(f"{robust_option} (outlier rejection, now off)")
    tries.append("more pairs from motion that rotates about two axes")
    return "left to try: " + "; ".join(tries)
