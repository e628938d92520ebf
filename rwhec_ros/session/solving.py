"""The solve step shared by the session and the CLI, and the identifiability around it."""

from __future__ import annotations

from ..core.identifiability import IdentifiabilityTracker, analyze
from ..core.result import CalibrationResult
from ..data.results import plain

__all__ = [
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


def solve_problem(
    problem, *, mode: str = "fast", reject_outliers: bool = False
) -> tuple[CalibrationResult, dict[str, str], list[str]]:
    """The solve step shared by the session and the CLI: ``solve`` in ``mode``, or with
    ``reject_outliers`` RANSAC (paper Section 9.1) + GNC-TLS re-certified on the inlier set
    (:func:`rwhec_ros.core.outliers.robust_solve`). Returns (result, dropped edges, notes)."""
    from ..core.solve import SolveOptions, solve

    options = SolveOptions(mode=mode)
    if not reject_outliers:
        return solve(problem, options), {}, []
    from ..core.outliers import RobustOptions, robust_solve

    robust = robust_solve(problem, options=RobustOptions(solve=options))
    dropped = {}
    if robust.ransac is not None:
        dropped = {str(edge): f"outlier rejection: {reason}" for edge, reason in
                   robust.ransac.dropped}
    notes = [f"outlier rejection: {len(robust.rejected)} of {problem.n_measurements} pairs "
             f"rejected ({len(dropped)} edges dropped)"]
    robust.result.notes.extend(notes)
    return robust.result, dropped, notes

