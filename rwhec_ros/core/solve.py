"""The one entry point of the solvers: :func:`solve` with modes ``sdp``, ``fast`` and ``local``.

A solve runs the stages of :mod:`rwhec_ros.core` in order:

1. **the model** (:mod:`~rwhec_ros.core.model`): re-centre data far from a carrier's origin,
   build the cost of eq. (42), fix the translation directions the data do not determine (the
   user's priors or the documented default) and, on the dense path, reduce it to ``Q'`` (eq.
   (48));
2. **the initial estimate** (:mod:`~rwhec_ros.core.initial`): the closed-form (or given)
   rotations, translations and scale by eq. (47); its cost scales the data, so that every
   tolerance is relative to the optimal cost;
3. **the local solve** (:mod:`~rwhec_ros.core.local`): Riemannian Newton on SO(3)^n (``fast``,
   ``local``), or the dual SDP of Algorithm 1 (``sdp``, and ``fast`` when its certificate is
   inconclusive), solved by the structured interior-point method of
   :mod:`~rwhec_ros.core.certify.sdp_ipm` or cvxpy + Clarabel (``SdpOptions.backend``);
4. **the certificate** (:mod:`~rwhec_ros.core.certify`): a dual bound that holds in floating
   point, with ``p`` the cost of the returned estimate evaluated directly from the residuals of
   eq. (33) (plus the prior's term), never the reduced cost;
5. **the statuses the certificate cannot know** (:mod:`~rwhec_ros.core.pipeline.statuses`):
   directions fixed by default, an unobservable or non-positive scale, undetermined rotations.

Steps 1-4 run on the dense reduced ``Q'`` (:mod:`~rwhec_ros.core.pipeline.dense`) or, for large
rigs, on the sparse unreduced cost (:mod:`~rwhec_ros.core.pipeline.sparse`, chosen by
:func:`~rwhec_ros.core.pipeline.sparse.use_sparse`). ``local`` stops after step 3 and reports
``LOCAL_ONLY``. Numerical failures (Clarabel, eigensolvers, singular systems) become the status
``solver_failed``; an exception leaves :func:`solve` only for invalid input. The analyses of a
solved calibration (uncertainty, validation, guidance) are :mod:`rwhec_ros.core.analysis`.
"""

from __future__ import annotations

import time

from .initial.closed_form import proven_cost
from .model.recentre import (
    Recentring,
    far_scale_words,
    recentred_options,
    recentred_problem,
    recentring_for,
    restore_estimate,
)
from .numerics.blas import blas_threads
from .pipeline.dense import prepare_dense, solve_fast_dense, solve_sdp
from .pipeline.options import MODES, SolveOptions
from .pipeline.sparse import solve_sparse, use_sparse
from .pipeline.statuses import check_identifiability
from .problem import Problem
from .result import CalibrationResult, Status

__all__ = ["SolveOptions", "solve", "MODES", "blas_threads"]


def solve(problem: Problem, options: SolveOptions | None = None) -> CalibrationResult:
    """Solve a generalized RWHEC problem (Problem 3/4) and certify the solution.

    Parameters
    ----------
    problem : Problem
    options : SolveOptions, optional

    Returns
    -------
    CalibrationResult
        ``X`` (M, 4, 4), ``Y`` (P, 4, 4), ``scale`` and a :class:`Certificate`; a solution that
        could not be certified carries status NOT_TIGHT, SOLVER_INACCURATE or LOCAL_ONLY, never
        CERTIFIED_OPTIMAL.
    """
    options = options or SolveOptions()
    with blas_threads(options.blas_threads):
        rc = None if options.gauge.priors else recentring_for(problem)
        if rc is None:
            return _solve(problem, options)
        res, why_not = _solve_recentred(problem, options, rc)
        if res is not None:
            return res
        res = _solve(problem, options)
        if why_not and res.certificate.status is Status.NOT_IDENTIFIABLE:
            res.certificate.message = res.certificate.message.rstrip(".") + "; " + why_not
        return res


def _solve_recentred(problem: Problem, options: SolveOptions, rc: Recentring
                     ) -> tuple[CalibrationResult | None, str]:
    """:func:`_solve` of the problem about ``rc``'s point (:mod:`rwhec_ros.core.model.recentre`),
    mapped back to the given frames with a certificate of the given problem and the returned
    estimate; ``(None, words)`` to solve as given: when the re-centred solve finds an unobservable
    translation direction (fixed by a default about the given origin; words empty) or, with
    unknown scale, no bound on the scale could be proven (words for a not-identifiable status:
    the coordinates may be the cause)."""
    t0 = time.perf_counter()
    recentred, E = recentred_problem(problem, rc)
    res = _solve(recentred, recentred_options(options, rc))
    if res.unobservable:
        return None, ""
    if not restore_estimate(res, problem, recentred, rc, E, proven_cost):
        return None, far_scale_words(rc)
    res.timing_s["total"] = time.perf_counter() - t0
    return res, ""


def _solve(problem: Problem, options: SolveOptions) -> CalibrationResult:
    """Steps 1-5 of the module docstring on the dense or the sparse path."""
    t_start = time.perf_counter()
    notes: list[str] = []
    if options.mode != "sdp" and use_sparse(problem, options.fast_form):
        prep, res = solve_sparse(problem, options, notes)
    else:
        prep = prepare_dense(problem, options)
        if options.mode == "sdp":
            res = solve_sdp(prep, options, notes)
        else:
            res = solve_fast_dense(prep, options, notes)
    if prep is not None:
        check_identifiability(prep, options, res)
    res.timing_s["total"] = time.perf_counter() - t_start
    return res

