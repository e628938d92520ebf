"""The dense path of :func:`rwhec_ros.core.solve.solve`: modes ``sdp``, ``fast`` and ``local`` on
the reduced cost ``Q'`` of eq. (48).

* :func:`prepare_dense` -- the model and the initial estimate: cost matrices, the fix of
  unobservable translation directions, the Schur reduction, the closed-form (or given) start and
  the data scale;
* :func:`solve_fast_dense` -- ``fast`` and ``local``: Riemannian Newton from the start, the
  SE-Sync style certificate (strengthened with the handedness multipliers when its null space is
  too large) and, when it is inconclusive, the SDP;
* :func:`solve_sdp` -- ``sdp``, Algorithm 1: the dual SDP (Problem 7) in its cheapest exact form,
  the null vector of ``Z(lambda*)`` normalised (``s = 1``, ``det R = +1``) and projected onto
  SO(3), translations and scale by eq. (47), and the certificate (eq. (73)).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..certify.dense import certificate_matrix, certify
from ..certify.multipliers import (
    fast_certificate_multipliers,
    handedness_multipliers,
    strengthen_certificate,
)
from ..certify.relaxation import (
    ConstraintSet,
    frame_constraints,
    so3_constraint_matrices,
    solve_dual_sdp,
    solve_dual_sdp_arrow,
)
from ..certify.sdp_ipm import IpmOptions, solve_dual_sdp_structured, structured_is_cheaper
from ..certify.sparsity import ArrowSplit, arrow_split, estimate_form_costs
from ..initial.closed_form import (
    closed_form_estimate,
    estimate_from_rotations,
    initial_rotations,
    primal_cost,
)
from ..local.dense import _grad_hess, refine_rotations
from ..model.cost import StateLayout, build_cost_matrices
from ..model.estimate import rotations_from_vector
from ..model.gauge import GaugeFix, build_gauge_fix, find_unobservable_directions
from ..model.reduction import reduce_cost
from ..problem import Problem
from ..result import CalibrationResult, Certificate, Status
from .common import COST_FLOOR_REL, NUMERICAL_ERRORS, calibration_result, failed_certificate
from .options import SolveOptions

__all__ = ["prepare_dense", "solve_fast_dense", "solve_sdp"]


@dataclass
class _Prepared:
    problem: Problem
    layout: StateLayout
    reduced: object
    scale: float
    Qs: np.ndarray
    init_R: np.ndarray
    timing: dict
    cost_floor: float
    Q: object = None
    full: tuple | None = None  # the ``full`` form's data, built once by :func:`_full_form`
    gauge: GaugeFix | None = None
    constraints: ConstraintSet | None = None
    tightened: bool = False  # the reduction's residual bound is the extended-precision one

    def hessian_eigenpairs(self, R: np.ndarray, null_tol: float) -> tuple[np.ndarray, np.ndarray]:
        """All eigenpairs (ascending) of the Riemannian Hessian of the scaled reduced cost at
        rotations ``R`` (``null_tol`` is not needed by the dense analysis)."""
        _, _, H = _grad_hess(self.Qs, R)
        return np.linalg.eigh(H)

    def cons(self) -> ConstraintSet:
        """The constraints of eq. (50) on the reduced ``[vec R; s]`` (built once)."""
        if self.constraints is None:
            self.constraints = frame_constraints(self.problem.n_frames)  # cached per count
        return self.constraints


def prepare_dense(problem: Problem, options: SolveOptions) -> _Prepared:
    """Cost matrices, the fix of unobservable translation directions, the Schur reduction, the
    closed-form (or given) start and the data scale."""
    timing: dict[str, float] = {}
    t0 = time.perf_counter()
    layout = StateLayout(problem.M, problem.P)
    # the rotation-only part is the closed-form start's alone: not built for a given start
    Q, Q_rot = build_cost_matrices(problem, with_rotation=options.initial is None)
    V_w, w_w, directions, w_max = find_unobservable_directions(Q, layout, problem, options.gauge)
    gauge = build_gauge_fix(problem, V_w, w_w, directions, w_max, options.gauge.priors)
    if gauge.has_penalty:
        pen = gauge.penalty_matrix(layout)
        Q = (sp.csr_matrix(Q) + pen).tocsr() if sp.issparse(Q) else Q + pen.toarray()
    reduced = reduce_cost(Q, layout, problem.unknown_scale)
    timing["build"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    if options.initial is not None:
        init = estimate_from_rotations(problem, reduced,
                                       initial_rotations(problem, options.initial))
    else:
        init = closed_form_estimate(problem, reduced, Q_rot)
    timing["initialise"] = time.perf_counter() - t1
    # Scale by an upper bound on the optimum (cost at a feasible point), floored relative to the
    # data (1e-4 of the largest entry of Q') so that noise-free problems (optimum 0) stay well
    # conditioned; the same floor is the "zero cost" of the certificate.
    floor = COST_FLOOR_REL * max(float(np.abs(reduced.Qr).max()), 1e-300)
    scale = max(float(init.cost), floor)
    return _Prepared(problem, layout, reduced, scale, reduced.Qr / scale, init.R, timing, floor,
                     Q, gauge=gauge)


def _estimate(prep: _Prepared, R: np.ndarray):
    """Translations and scale for rotations ``R`` (eq. (47)) and the cost ``p`` of that
    estimate evaluated directly (eq. (33) plus the prior's term)."""
    est = estimate_from_rotations(prep.problem, prep.reduced, R)
    return est, primal_cost(prep.problem, est, prep.gauge)



def _certify(prep: _Prepared, options: SolveOptions, lam: np.ndarray, cost: float,
             solver_ok: bool = True, solver_status: str = "local") -> Certificate:
    """:func:`certify` with this problem's reduction, scale, cost floor and options; a numerical
    failure of the eigen-analysis becomes ``solver_failed``."""
    try:
        cert = certify(prep.reduced, prep.scale, prep.Qs, prep.cons(), lam, cost,
                       solver_ok=solver_ok, solver_status=solver_status,
                       homogeneous=prep.problem.unknown_scale, cost_floor=prep.cost_floor,
                       options=options.certificate)
        if _residual_bound_decides(cert, options, prep.cost_floor) and _tighten_reduction(prep):
            cert = certify(prep.reduced, prep.scale, prep.Qs, prep.cons(), lam, cost,
                           solver_ok=solver_ok, solver_status=solver_status,
                           homogeneous=prep.problem.unknown_scale, cost_floor=prep.cost_floor,
                           options=options.certificate)
        return cert
    except NUMERICAL_ERRORS as exc:
        return failed_certificate(options, cost, f"the certificate's eigen-analysis failed "
                                   f"({type(exc).__name__}: {exc})")


def _residual_bound_decides(cert: Certificate, options: SolveOptions,
                            cost_floor: float = 0.0) -> bool:
    """The certificate failed on its bound alone (PSD, one-dimensional null space, finite
    bound, a reliable solver) and the reduction's rounding and Schur terms take more than a
    tenth of the gap it allows (``rho_tol`` times the bound's denominator, the dual bound or
    the cost floor): a tighter bound on the recovery's residual may certify it."""
    if cert.status is not Status.NOT_TIGHT or cert.null_space_dim != 1:
        return False
    margins = cert.margins or {}
    allowed = options.certificate.rho_tol * max(abs(cert.dual_bound), cost_floor, 1e-300)
    return margins.get("rounding", 0.0) + margins.get("schur", 0.0) > 0.1 * allowed


def _tighten_reduction(prep: _Prepared) -> bool:
    """Replace the reduction's residual bound by the extended-precision one
    (:func:`~rwhec_ros.core.model.reduction.reduce_cost` with ``residual="extended"``), once per
    problem; False when it was done already or the reduction is not the same bit for bit (then the
    bound would not be about the matrix the solvers used, and nothing changes)."""
    if prep.tightened or prep.Q is None or not prep.reduced.verified:
        return False
    prep.tightened = True
    t0 = time.perf_counter()
    tight = reduce_cost(prep.Q, prep.layout, prep.problem.unknown_scale, residual="extended")
    if not (tight.verified and np.array_equal(tight.Qr, prep.reduced.Qr)
            and np.array_equal(tight.recover, prep.reduced.recover)):
        return False
    prep.reduced = tight
    prep.timing["tighten"] = time.perf_counter() - t0
    return True



def _full_form(prep: _Prepared) -> tuple[sp.csr_matrix, np.ndarray, int]:
    """The unreduced SDP data: ``Q`` of eq. (42) on ``z = [t; (alpha); vec R; s]`` (scaled), the
    offsets of the rotations in ``z`` and its size. For known scale ``alpha`` is ``s``."""
    if prep.full is not None:
        return prep.full
    layout = prep.layout
    Q = sp.csr_matrix(prep.Q) / prep.scale
    n_t, n = layout.n_t, layout.n_frames
    rot = np.arange(layout.r0, layout.size)
    if prep.problem.unknown_scale:
        perm = np.concatenate([np.arange(n_t + 1), rot])
        Qf = sp.block_diag([Q[perm][:, perm], sp.csr_matrix((1, 1))]).tocsr()
        offsets = n_t + 1 + 9 * np.arange(n)
    else:
        perm = np.concatenate([np.arange(n_t), rot, [layout.alpha]])
        Qf = Q[perm][:, perm].tocsr()
        offsets = n_t + 9 * np.arange(n)
    prep.full = (Qf, offsets, Qf.shape[0])
    return prep.full


def _full_groups(prep: _Prepared, df: int) -> list[np.ndarray]:
    """Variable groups of the ``full`` form's ``z = [t; (alpha); vec R; s]``: each frame's
    translation, ``alpha`` (unknown scale), each rotation and ``s``."""
    n, n_t = prep.problem.n_frames, prep.layout.n_t
    groups = [np.arange(3 * f, 3 * f + 3) for f in range(n)]
    r0 = n_t
    if prep.problem.unknown_scale:
        groups.append(np.array([n_t]))
        r0 += 1
    groups += [np.arange(r0 + 9 * f, r0 + 9 * f + 9) for f in range(n)]
    groups.append(np.array([df - 1]))
    return groups


def _form_costs(prep: _Prepared) -> tuple[str, dict[str, float], ArrowSplit | None]:
    """``auto`` rule: the form of Problem 7 with the smallest estimated cost per Clarabel
    iteration (:func:`rwhec_ros.core.certify.sparsity.estimate_form_costs`), with the estimates and
    the hub/leaf split; ``reduced`` for up to three frames, where every form is a few milliseconds.
    Measured in ``benchmarks/sdp_forms.md``: the paper's 16 targets x 8 cameras pick ``arrow``,
    one target seen by many cameras (Y) picks ``full``."""
    n = prep.problem.n_frames
    if n <= 3:
        return "reduced", {}, None
    split = arrow_split(prep.Qs, n)
    Qf, _, df = _full_form(prep)
    costs = estimate_form_costs(prep.Qs, n, Qf, _full_groups(prep, df), split)
    return min(costs, key=costs.get), costs, split


#: The solver of each SDP backend, in notes and messages.
_SOLVER_NAMES = {"structured": "structured IPM", "cvxpy": "Clarabel"}


def _sdp_backend(prep: _Prepared, options: SolveOptions) -> tuple[str, str, ArrowSplit | None]:
    """``(backend, form, split)``: the ``auto`` backend is the structured method unless a form
    is asked for (a cvxpy setting) or Clarabel's cheapest form is estimated cheaper
    (:func:`~rwhec_ros.core.certify.sdp_ipm.structured_is_cheaper`)."""
    backend, form, split = options.sdp.backend, options.sdp.form, None
    if backend == "auto":
        if form != "auto":
            return "cvxpy", form, None
        if prep.problem.n_frames <= 3:
            return "structured", "reduced", None
        form, costs, split = _form_costs(prep)
        backend = ("structured" if structured_is_cheaper(prep.problem.n_frames, costs[form])
                   else "cvxpy")
    if backend == "structured":
        return backend, "reduced", None
    if form == "auto":
        form, _, split = _form_costs(prep)
    return backend, form, split


def solve_sdp(prep: _Prepared, options: SolveOptions, notes: list[str]) -> CalibrationResult:
    n = prep.problem.n_frames
    t0 = time.perf_counter()
    cons = prep.cons()
    backend, form, split = _sdp_backend(prep, options)
    if form == "arrow" and split is None:
        split = arrow_split(prep.Qs, n)
        if split is None:
            form = "reduced"
    if form == "full":
        Qf, offsets, df = _full_form(prep)
        cons_f = so3_constraint_matrices(offsets, df, df - 1)
    prep.timing["constraints"] = time.perf_counter() - t0
    try:
        if backend == "structured":
            sol = solve_dual_sdp_structured(prep.Qs, n, IpmOptions(**options.sdp.ipm))
        elif form == "full":
            sol = solve_dual_sdp(Qf, cons_f, options.sdp)
        elif form == "arrow":
            sol = solve_dual_sdp_arrow(prep.Qs, cons, split, options.sdp)
        else:
            sol = solve_dual_sdp(prep.Qs, cons, options.sdp)
    except Exception as exc:  # noqa: BLE001 - cvxpy/Clarabel raise SolverError and others
        notes.append(f"SDP form: {form}")
        # the error's first sentence only: the rest is cvxpy's advice for its own users
        brief = f"{type(exc).__name__}: {str(exc).split('. ')[0].rstrip('.')}"
        notes.append(f"the SDP solver stopped with an error ({brief}); returning the "
                     "closed-form estimate")
        est, p = _estimate(prep, prep.init_R)
        solver = _SOLVER_NAMES[backend]
        what = (f"the fast solver's certificate was inconclusive and its SDP fallback ({solver})"
                if options.mode != "sdp" else f"the SDP solver ({solver})")
        cert = failed_certificate(options, p, f"{what} stopped with an error ({brief})")
        return calibration_result(prep, est, cert, "sdp", "failed", 0.0, notes)
    notes.append(f"SDP form: {form}")
    notes.append(f"SDP backend: {backend}")
    notes.append(f"{_SOLVER_NAMES[backend]}: {sol.iterations} iterations, status "
                 f"'{sol.status}'")
    notes.extend(sol.warnings)
    prep.timing["compile"] = sol.compile_s
    prep.timing["solve"] = sol.solve_s
    t1 = time.perf_counter()
    if not np.all(np.isfinite(sol.lam)):
        est, p = _estimate(prep, prep.init_R)
        cert = failed_certificate(options, p, f"the SDP solver returned no solution (status "
                                   f"'{sol.status}'); the closed-form estimate is returned")
        prep.timing["extract"] = time.perf_counter() - t1
        notes.append("SDP failed; returning the closed-form estimate")
        return calibration_result(prep, est, cert, "sdp", sol.status, 0.0, notes)
    solver_ok = sol.status == "optimal"
    try:
        Z, _ = certificate_matrix(prep.Qs, cons, sol.lam)
        w, V = np.linalg.eigh(Z)
    except NUMERICAL_ERRORS as exc:
        est, p = _estimate(prep, prep.init_R)
        cert = failed_certificate(options, p, f"eigendecomposition of Z failed: {exc}")
        return calibration_result(prep, est, cert, "sdp", sol.status, 0.0, notes)
    v = V[:, 0]
    # Algorithm 1 step 6: scale the null vector so that s = 1 (sign and magnitude), then fix
    # det R = +1 via the mean cube-root determinant and project each block onto SO(3).
    if abs(v[-1]) > 1e-8 * np.linalg.norm(v):
        v = v / v[-1]
    R_raw, moved = rotations_from_vector(v[:-1], n)
    prep.timing["extract"] = time.perf_counter() - t1
    t2 = time.perf_counter()
    est, p = _estimate(prep, R_raw)
    cert = _certify(prep, options, sol.lam, p, solver_ok, sol.status)
    prep.timing["certify"] = time.perf_counter() - t2
    return calibration_result(prep, est, cert, "sdp", sol.status, moved, notes)


def _solve_local(prep: _Prepared, options: SolveOptions) -> tuple[np.ndarray, object]:
    t0 = time.perf_counter()
    loc = refine_rotations(prep.Qs, prep.init_R, options.local)
    prep.timing["local"] = time.perf_counter() - t0
    return loc.R, loc


def solve_fast_dense(prep: _Prepared, options: SolveOptions, notes: list[str]) -> CalibrationResult:
    """Closed-form start, Riemannian Newton, fast certificate (strengthened if needed), and the
    SDP when it is inconclusive."""
    try:
        R, loc = _solve_local(prep, options)
    except NUMERICAL_ERRORS as exc:
        notes.append(f"local solver failed ({type(exc).__name__}: {exc})")
        if not options.fallback_to_sdp or options.mode == "local":
            est, p = _estimate(prep, prep.init_R)
            cert = failed_certificate(options, p, f"the local solver failed: {exc}")
            return calibration_result(prep, est, cert, options.mode, "failed", 0.0, notes)
        res = solve_sdp(prep, options, notes)
        res.mode = "fast"
        return res
    status = "converged" if loc.converged else "not converged"
    if not loc.converged:
        notes.append(f"local solver stopped after {loc.iterations} iterations without "
                     f"converging (gradient norm {loc.gradient_norm:.3g})")
    est, p = _estimate(prep, R)
    if options.mode == "local":
        return calibration_result(prep, est, Certificate.local_only(p), "local", status, 0.0, notes)
    t0 = time.perf_counter()
    lam = fast_certificate_multipliers(prep.Qs, R)
    cert = _certify(prep, options, lam, p)
    prep.timing["certify"] = time.perf_counter() - t0
    if cert.status is Status.NOT_TIGHT and cert.lambda_min >= -options.certificate.null_tol:
        # PSD but a larger null space: try the handedness multipliers (cheap 1-D search)
        t1 = time.perf_counter()
        try:
            Z, _ = certificate_matrix(prep.Qs, prep.cons(), lam)
            t_step, _ = strengthen_certificate(Z, R, null_tol=options.certificate.null_tol)
            cert2 = _certify(prep, options, lam + t_step * handedness_multipliers(R), p)
        except NUMERICAL_ERRORS:
            cert2 = None
        prep.timing["strengthen"] = time.perf_counter() - t1
        if cert2 is not None and cert2.certified:
            cert = cert2
            notes.append("fast certificate strengthened with handedness multipliers")
    if cert.certified or not options.fallback_to_sdp:
        return calibration_result(prep, est, cert, "fast", status, 0.0, notes)
    notes.append(f"fast certificate inconclusive ({cert.message}); fell back to the SDP "
                 "relaxation")
    res = solve_sdp(prep, options, notes)
    res.mode = "fast"
    return res
