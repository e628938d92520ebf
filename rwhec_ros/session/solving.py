"""The solve step shared by the session and the CLI, and the identifiability around it."""

from __future__ import annotations

from ..core.identifiability import IdentifiabilityTracker, analyze
from ..core.result import CalibrationResult
from ..data.results import plain

__all__ = [
    "solve_options",
    "solve_problem",
    "make_tracker",
    "analyze_at_solution",
    "full_report",
    "report_dict",
]


def make_tracker(unknown_scale: bool) -> IdentifiabilityTracker:
    """The session's incremental identifiability tracker (Section 6), without its own pairs."""
    # the accumulator holds the pairs; the tracker keeps only its fixed-size sums
    return IdentifiabilityTracker(unknown_scale=unknown_scale, keep_pairs=False)


def analyze_at_solution(problem, result: CalibrationResult):
    """Whole-problem identifiability at the solution (``analyze(..., full=True)``, an
    :class:`~rwhec_ros.core.identifiability.IdentifiabilityReport`), or None if it fails."""
    try:
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
    min_scale: float = 0.01,
):
    """:class:`~rwhec_ros.core.solve.SolveOptions` for ``problem`` with the translation priors
    ``(frame, axis, value_m)`` of the frames it has (returns the options and a note per prior
    whose frame has no usable edge)."""
    from ..core.gauge import GaugeOptions, TranslationPrior
    from ..core.solve import SolveOptions

    kept, notes = [], []
    for frame, axis, value in priors:
        if frame in problem.frame_names:
            kept.append(TranslationPrior(frame, axis, value))
        else:
            notes.append(f"prior {frame}.{axis} = {value:g} m not used: {frame} has no usable edge")
    gauge = GaugeOptions(max_std_m=unobservable_std_m, priors=tuple(kept))
    return SolveOptions(mode=mode, gauge=gauge, min_scale=min_scale), notes


def solve_problem(
    problem, *, mode: str = "fast", reject_outliers: bool = False, priors=(),
    unobservable_std_m: float = 1.0, min_scale: float = 0.01,
) -> tuple[CalibrationResult, dict[str, str], list[str]]:
    """The solve step shared by the session and the CLI: ``solve`` in ``mode``, or with
    ``reject_outliers`` RANSAC (paper Section 9.1) + GNC-TLS re-certified on the inlier set
    (:func:`rwhec_ros.core.outliers.robust_solve`). ``priors`` (``(frame, axis, value_m)``) and
    ``unobservable_std_m`` fix translation directions the data do not determine
    (:mod:`rwhec_ros.core.gauge`); ``min_scale`` is the unknown scale's floor. Returns (result,
    dropped edges, notes)."""
    from ..core.solve import solve

    options, prior_notes = solve_options(problem, mode=mode, priors=priors,
                                         unobservable_std_m=unobservable_std_m,
                                         min_scale=min_scale)
    if not reject_outliers:
        result = solve(problem, options)
        result.notes.extend(prior_notes)
        return result, {}, list(prior_notes)
    from ..core.outliers import RobustOptions, robust_solve

    robust = robust_solve(problem, options=RobustOptions(solve=options))
    dropped = {}
    if robust.ransac is not None:
        dropped = {str(edge): f"outlier rejection: {reason}" for edge, reason in
                   robust.ransac.dropped}
    notes = prior_notes + [f"outlier rejection: {len(robust.rejected)} of "
                           f"{problem.n_measurements} pairs rejected ({len(dropped)} edges "
                           "dropped)"]
    robust.result.notes.extend(notes)
    return robust.result, dropped, notes
