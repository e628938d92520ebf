"""The one entry point of the solvers: :func:`solve` with modes ``sdp``, ``fast`` and ``local``.

* ``sdp`` — Algorithm 1: form ``Q'`` (eq. (48)), solve the dual SDP (Problem 7) with Clarabel,
  take the null vector of ``Z(lambda*)``, normalise it (``s = 1``, ``det R = +1``), project onto
  SO(3), recover translations and scale by eq. (47), and certify (eq. (73)).
* ``fast`` — closed-form initialisation, local Riemannian Newton refinement on the same MLE
  objective, and the SE-Sync style certificate of :mod:`local_solver`; when that certificate is
  inconclusive, fall back to ``sdp`` and say so in ``notes``.
* ``local`` — the refinement alone, reported as ``LOCAL_ONLY`` (no certificate).

All modes scale the data matrix by an upper bound on the optimum (the cost at the closed-form
estimate) before any numerical work, so that tolerances are relative to the optimal cost.

Before the reduction, translation directions the data do not determine (motion about one
axis, :mod:`rwhec_ros.core.gauge`) are fixed by the user's priors or the documented default; the
certificate (:mod:`rwhec_ros.core.certificate`) then applies to that problem and the status says
what was fixed. The primal cost ``p`` of every certificate is the cost of the returned estimate
evaluated directly from the residuals of eq. (33) (plus the prior's term), never the reduced
cost. Numerical failures (Clarabel, eigensolvers, singular systems) become the status
``solver_failed``; an exception leaves :func:`solve` only for invalid input.
"""

from __future__ import annotations

import contextlib
import functools
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg
from threadpoolctl import ThreadpoolController

from .certificate import CertificateOptions, certificate_matrix, certify
from .cost import StateLayout, build_cost_matrices, reduce_cost
from .gauge import (
    GaugeFix,
    GaugeOptions,
    axis_words,
    build_gauge_fix,
    find_unobservable_directions,
)
from .initialization import (
    closed_form_estimate,
    estimate_from_rotations,
    initial_rotations,
    primal_cost,
    proven_cost,
    rotations_from_vector,
)
from .lie import make_transform
from .local_solver import (
    LocalSolverOptions,
    _grad_hess,
    fast_certificate_multipliers,
    handedness_multipliers,
    refine_rotations,
    strengthen_certificate,
)
from .problem import Problem
from .recentre import (
    Recentring,
    far_scale_words,
    recentred_options,
    recentred_problem,
    recentring_for,
    restore_estimate,
)
from .relaxation import (
    ConstraintSet,
    SdpOptions,
    frame_constraints,
    so3_constraint_matrices,
    solve_dual_sdp,
    solve_dual_sdp_arrow,
)
from .result import CalibrationResult, Certificate, Status
from .sparse_fast import failed_result, prepare_sparse, solve_fast_sparse, use_sparse
from .sparsity import ArrowSplit, arrow_split, estimate_form_costs

__all__ = ["SolveOptions", "solve", "MODES", "blas_threads"]

MODES = ("sdp", "fast", "local")
FAST_FORMS = ("auto", "dense", "sparse")

#: Costs below this fraction of the largest entry of ``Q'`` count as zero (noise-free data).
COST_FLOOR_REL = 1e-4

#: Exceptions of the numerical back ends that become the status ``solver_failed``.
NUMERICAL_ERRORS: tuple[type[BaseException], ...] = (
    np.linalg.LinAlgError,
    scipy.sparse.linalg.ArpackError,
    scipy.sparse.linalg.ArpackNoConvergence,
    ArithmeticError,
)


@dataclass
class SolveOptions:
    """Options of :func:`solve`.

    Attributes
    ----------
    mode : str
        ``"fast"`` (default), ``"sdp"`` or ``"local"``.
    sdp : SdpOptions
        Clarabel settings for the SDP.
    certificate : CertificateOptions
        Tolerances of the certificate.
    local : LocalSolverOptions
        Options of the local refinement.
    initial : tuple (X (M,4,4), Y (P,4,4)) or None
        Start for ``fast``/``local`` instead of the closed-form estimate (rotations are used).
    fallback_to_sdp : bool
        In ``fast`` mode, run the SDP when the fast certificate is inconclusive (True).
    blas_threads : int or None
        BLAS threads during the solve (default 1). Multi-threaded BLAS only added contention in
        every measurement on the 2-core target machines (real 16x8 data: 24 ms single-threaded
        vs. 60-600 ms with two threads on a busy machine; 100 cameras: 1.9 s vs. 9.1 s); ``None``
        leaves the BLAS library's own setting.
    gauge : GaugeOptions
        When a translation direction counts as unobservable, and the user's priors that fix such
        directions (:mod:`rwhec_ros.core.gauge`).
    min_scale : float
        Unknown scale only: an estimate ``alpha`` at or below this positive floor (0.01: tags 100
        times smaller than their nominal size) is never certified -- the data do not determine
        the scale (noise, outliers, too little translation).
    fast_form : str
        How ``fast`` and ``local`` represent the problem: ``"dense"`` (the reduced ``Q'`` of eq.
        (48)), ``"sparse"`` (the unreduced sparse cost and certificate of
        :mod:`rwhec_ros.core.sparse_fast`, for large rigs) or ``"auto"`` (default: sparse from
        :data:`~rwhec_ros.core.sparse_fast.SPARSE_MIN_FRAMES` frames when the camera-tag graph
        keeps a sparse factorisation sparse).
    sdp_fallback_max_frames : int
        On the sparse path, an inconclusive certificate is followed by the dense path (and its SDP
        fallback) only up to this many frames (400); above, the uncertified result is returned
        with a note (the dense path would need minutes and gigabytes).
    """

    mode: str = "fast"
    sdp: SdpOptions = field(default_factory=SdpOptions)
    certificate: CertificateOptions = field(default_factory=CertificateOptions)
    local: LocalSolverOptions = field(default_factory=LocalSolverOptions)
    initial: tuple[np.ndarray, np.ndarray] | None = None
    fallback_to_sdp: bool = True
    blas_threads: int | None = 1
    gauge: GaugeOptions = field(default_factory=GaugeOptions)
    min_scale: float = 0.01
    fast_form: str = "auto"
    sdp_fallback_max_frames: int = 400

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"mode: expected one of {MODES}, got {self.mode!r}")
        if self.fast_form not in FAST_FORMS:
            raise ValueError(f"fast_form: expected one of {FAST_FORMS}, got {self.fast_form!r}")
        if int(self.sdp_fallback_max_frames) < 0:
            raise ValueError(f"sdp_fallback_max_frames: must be >= 0, got "
                             f"{self.sdp_fallback_max_frames!r}")
        if not (np.isfinite(self.min_scale) and self.min_scale > 0):
            raise ValueError(f"min_scale: must be finite and > 0, got {self.min_scale!r}")


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


def _prepare(problem: Problem, options: SolveOptions) -> _Prepared:
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


def _result(prep: _Prepared, est, cert: Certificate, mode: str, solver_status: str,
            moved: float, notes: list[str]) -> CalibrationResult:
    """The result for the estimate ``est`` (rotations, translations and scale)."""
    T = make_transform(est.R, est.t)
    M = prep.problem.M
    res = CalibrationResult(
        x_names=prep.problem.x_names,
        y_names=prep.problem.y_names,
        X=T[:M],
        Y=T[M:],
        scale=float(est.alpha),
        certificate=cert,
        mode=mode,
        timing_s=dict(prep.timing),
        solver_status=solver_status,
        rounding_displacement=moved,
        notes=notes,
    )
    return res


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
        return _failed_certificate(options, cost, f"the certificate's eigen-analysis failed "
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
    (:func:`~rwhec_ros.core.cost.reduce_cost` with ``residual="extended"``), once per problem;
    False when it was done already or the reduction is not the same bit for bit (then the
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


def _failed_certificate(options: SolveOptions, cost: float, message: str) -> Certificate:
    return Certificate(Status.SOLVER_FAILED, float(cost), float("nan"), float("nan"),
                       float("nan"), np.zeros(0), -1, options.certificate.rho_tol, message)


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
    iteration (:func:`rwhec_ros.core.sparsity.estimate_form_costs`), with the estimates and the
    hub/leaf split; ``reduced`` for up to three frames, where every form is a few milliseconds.
    Measured in ``benchmarks/sdp_forms.md``: the paper's 16 targets x 8 cameras pick ``arrow``,
    one target seen by many cameras (Y) picks ``full``."""
    n = prep.problem.n_frames
    if n <= 3:
        return "reduced", {}, None
    split = arrow_split(prep.Qs, n)
    Qf, _, df = _full_form(prep)
    costs = estimate_form_costs(prep.Qs, n, Qf, _full_groups(prep, df), split)
    return min(costs, key=costs.get), costs, split


def _solve_sdp(prep: _Prepared, options: SolveOptions, notes: list[str]) -> CalibrationResult:
    n = prep.problem.n_frames
    t0 = time.perf_counter()
    cons = prep.cons()
    form, split = options.sdp.form, None
    if form == "auto":
        form, _, split = _form_costs(prep)
    if form == "arrow" and split is None:
        split = arrow_split(prep.Qs, n)
        if split is None:
            form = "reduced"
    if form == "full":
        Qf, offsets, df = _full_form(prep)
        cons_f = so3_constraint_matrices(offsets, df, df - 1)
    prep.timing["constraints"] = time.perf_counter() - t0
    try:
        if form == "full":
            sol = solve_dual_sdp(Qf, cons_f, options.sdp)
        elif form == "arrow":
            sol = solve_dual_sdp_arrow(prep.Qs, cons, split, options.sdp)
        else:
            sol = solve_dual_sdp(prep.Qs, cons, options.sdp)
    except Exception as exc:  # noqa: BLE001 - cvxpy/Clarabel raise SolverError and others
        # the error's first sentence only: the rest is cvxpy's advice for its own users
        brief = f"{type(exc).__name__}: {str(exc).split('. ')[0].rstrip('.')}"
        notes.append(f"SDP form: {form}")
        notes.append(f"the SDP solver stopped with an error ({brief}); returning the "
                     "closed-form estimate")
        est, p = _estimate(prep, prep.init_R)
        what = ("the fast solver's certificate was inconclusive and its SDP fallback (Clarabel)"
                if options.mode != "sdp" else "the SDP solver (Clarabel)")
        cert = _failed_certificate(options, p, f"{what} stopped with an error ({brief})")
        return _result(prep, est, cert, "sdp", "failed", 0.0, notes)
    notes.append(f"SDP form: {form}")
    notes.append(f"Clarabel: {sol.iterations} iterations, status '{sol.status}'")
    notes.extend(sol.warnings)
    prep.timing["compile"] = sol.compile_s
    prep.timing["solve"] = sol.solve_s
    t1 = time.perf_counter()
    if not np.all(np.isfinite(sol.lam)):
        est, p = _estimate(prep, prep.init_R)
        cert = _failed_certificate(options, p, f"the SDP solver returned no solution (status "
                                   f"'{sol.status}'); the closed-form estimate is returned")
        prep.timing["extract"] = time.perf_counter() - t1
        notes.append("SDP failed; returning the closed-form estimate")
        return _result(prep, est, cert, "sdp", sol.status, 0.0, notes)
    solver_ok = sol.status == "optimal"
    try:
        Z, _ = certificate_matrix(prep.Qs, cons, sol.lam)
        w, V = np.linalg.eigh(Z)
    except NUMERICAL_ERRORS as exc:
        est, p = _estimate(prep, prep.init_R)
        cert = _failed_certificate(options, p, f"eigendecomposition of Z failed: {exc}")
        return _result(prep, est, cert, "sdp", sol.status, 0.0, notes)
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
    return _result(prep, est, cert, "sdp", sol.status, moved, notes)


def _solve_local(prep: _Prepared, options: SolveOptions) -> tuple[np.ndarray, object]:
    t0 = time.perf_counter()
    loc = refine_rotations(prep.Qs, prep.init_R, options.local)
    prep.timing["local"] = time.perf_counter() - t0
    return loc.R, loc


def _solve_fast(prep: _Prepared, options: SolveOptions, notes: list[str]) -> CalibrationResult:
    """Closed-form start, Riemannian Newton, fast certificate (strengthened if needed), and the
    SDP when it is inconclusive."""
    try:
        R, loc = _solve_local(prep, options)
    except NUMERICAL_ERRORS as exc:
        notes.append(f"local solver failed ({type(exc).__name__}: {exc})")
        if not options.fallback_to_sdp or options.mode == "local":
            est, p = _estimate(prep, prep.init_R)
            cert = _failed_certificate(options, p, f"the local solver failed: {exc}")
            return _result(prep, est, cert, options.mode, "failed", 0.0, notes)
        res = _solve_sdp(prep, options, notes)
        res.mode = "fast"
        return res
    status = "converged" if loc.converged else "not converged"
    if not loc.converged:
        notes.append(f"local solver stopped after {loc.iterations} iterations without "
                     f"converging (gradient norm {loc.gradient_norm:.3g})")
    est, p = _estimate(prep, R)
    if options.mode == "local":
        return _result(prep, est, Certificate.local_only(p), "local", status, 0.0, notes)
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
        return _result(prep, est, cert, "fast", status, 0.0, notes)
    notes.append(f"fast certificate inconclusive ({cert.message}); fell back to the SDP "
                 "relaxation")
    res = _solve_sdp(prep, options, notes)
    res.mode = "fast"
    return res


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
    """:func:`_solve` of the problem about ``rc``'s point (:mod:`rwhec_ros.core.recentre`), mapped
    back to the given frames with a certificate of the given problem and the returned estimate;
    ``(None, words)`` to solve as given: when the re-centred solve finds an unobservable
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


@functools.lru_cache(maxsize=1)
def _blas_controller() -> ThreadpoolController:
    """One controller per process: scanning the loaded libraries costs ~3 ms, limiting is cheap."""
    return ThreadpoolController()


def blas_threads(threads: int | None):
    """Context manager limiting BLAS to ``threads`` threads (``None``: leave it as it is); see
    :attr:`SolveOptions.blas_threads` for why one thread is the default everywhere. Nothing
    to do (no set and restore) when every BLAS already runs ``threads`` threads, e.g. nested
    inside a caller's limit."""
    if threads is None:
        return contextlib.nullcontext()
    ctl = _blas_controller()
    if all(lib.num_threads == threads for lib in ctl.select(user_api="blas").lib_controllers):
        return contextlib.nullcontext()
    return ctl.limit(limits=threads, user_api="blas")


def _solve(problem: Problem, options: SolveOptions) -> CalibrationResult:
    t_start = time.perf_counter()
    notes: list[str] = []
    if options.mode != "sdp" and use_sparse(problem, options.fast_form):
        prep, res = _solve_sparse(problem, options, notes)
    else:
        prep = _prepare(problem, options)
        if options.mode == "sdp":
            res = _solve_sdp(prep, options, notes)
        else:
            res = _solve_fast(prep, options, notes)
    if prep is not None:
        _check_identifiability(prep, options, res)
    res.timing_s["total"] = time.perf_counter() - t_start
    return res


def _solve_sparse(problem: Problem, options: SolveOptions, notes: list[str]):
    """The sparse path of :mod:`rwhec_ros.core.sparse_fast`; when its translation block cannot be
    factorised, the dense path (which reports why) up to ``sdp_fallback_max_frames`` frames,
    else a ``solver_failed`` result."""
    try:
        prep = prepare_sparse(problem, options)
    except NUMERICAL_ERRORS as exc:
        msg = f"the sparse path could not start ({type(exc).__name__}: {exc})"
        notes.append(msg)
        if problem.n_frames > options.sdp_fallback_max_frames:
            return None, failed_result(problem, options, msg, notes)
        prep = _prepare(problem, options)
        return prep, _solve_fast(prep, options, notes)
    return solve_fast_sparse(prep, options, notes)


def _downgrade(res: CalibrationResult, status: Status, message: str) -> None:
    """Replace a certificate's status and message by a more specific one (keeping its numbers);
    the certified part, if any, is quoted in the message."""
    cert = res.certificate
    if cert.status in (Status.SOLVER_FAILED, Status.LOCAL_ONLY):
        res.notes.append(message)
        return
    if cert.status is Status.CERTIFIED_OPTIMAL:
        tail = (f" With that, the rest is certified optimal "
                f"(rho_hat={cert.suboptimality_bound:.3g}).")
    else:
        tail = f" [{cert.message}]"
    cert.message = message + tail
    cert.status = status


def _check_identifiability(prep: _Prepared, options: SolveOptions,
                           res: CalibrationResult) -> None:
    """Statuses the certificate alone cannot know: translation directions fixed by default, an
    unobservable scale, a non-positive unknown scale, a rotation the data do not determine."""
    problem = prep.problem
    gauge = prep.gauge
    reasons: list[str] = []
    cert = res.certificate
    if not cert.certified and cert.null_space_dim > 1:
        words = _rotation_gauge_words(prep, res, options.certificate.null_tol)
        if words:
            reasons.append(words)
    if gauge is not None and not gauge.empty:
        t = np.concatenate([res.X, res.Y])[:, :3, 3].reshape(-1)
        translations = {name: T[:3, 3] for name, T in zip(
            problem.frame_names, np.concatenate([res.X, res.Y]), strict=True)}
        for d in gauge.directions:
            d.value_m = d.component_of(translations)
        res.unobservable = list(gauge.directions)
        words = "; ".join(d.describe(x_names=problem.x_names) for d in gauge.directions)
        if any(d.involves_scale for d in gauge.directions):
            reasons.append(words)
        elif gauge.pinned:
            res.notes.append(f"{words}: fixed by the given priors (certificate with the priors)")
            for p, row in gauge.prior_rows:
                got = float(row @ t)
                if abs(got - p.value_m) > 1e-4:
                    res.notes.append(f"prior {p.frame} {np.round(p.axis, 3).tolist()} = "
                                     f"{p.value_m:.4f} m: estimate {got:.4f} m (the priors "
                                     "disagree with each other or with the data)")
        else:
            reasons.append(f"{words}. It was set by default (the cameras' translations along it "
                           "are zero on average); give a prior for it (a known translation "
                           "component of one of these frames)")
    if problem.unknown_scale and not res.scale > options.min_scale:
        reasons.append(f"the estimated scale alpha = {res.scale:.4g} is not above the floor "
                       f"{options.min_scale:g}: the data do not determine the scale (too much "
                       "noise, outliers, or too little translation relative to the tags)")
    if reasons:
        _downgrade(res, Status.NOT_IDENTIFIABLE, "not identifiable: " + "; ".join(reasons) + ".")


def _rotation_gauge_words(prep, res: CalibrationResult, null_tol: float) -> str:
    """Words for rotation directions the data do not determine (near-null directions of the
    Riemannian Hessian of the reduced cost at the estimate, at a minimum), or ``""``."""
    R = np.concatenate([res.X, res.Y])[:, :3, :3]
    try:
        w, V = prep.hessian_eigenpairs(R, null_tol)
    except NUMERICAL_ERRORS:
        return ""
    # flat directions of the scaled cost: the Riemannian Hessian is ~4 Z on the tangent space
    # (|d vec(R w^)/d w|^2 = 2), so a second null direction of Z that is a rotation of the frames
    # shows as an eigenvalue of H within a few null_tol
    if w[0] < -10.0 * null_tol:  # a saddle point, not a flat minimum
        return ""
    weak = np.where(np.abs(w) <= 10.0 * null_tol)[0]
    names = prep.problem.frame_names
    parts = []
    for i in weak:
        v = V[:, i].reshape(-1, 3)
        frames = [f for f in range(len(names)) if np.linalg.norm(v[f]) >= 0.1]
        # right perturbation R exp(w^): the axis in the frame's parent is R w (sign canonical:
        # the largest component of the first frame's axis positive)
        par = [R[f] @ v[f] for f in frames]
        if par and par[0][int(np.argmax(np.abs(par[0])))] < 0:
            par = [-a for a in par]
        axes = {axis_words(a) for a in par}
        about = axes.pop() if len(axes) == 1 else "different axes"
        parts.append(f"rotation of {', '.join(names[f] for f in frames)} about {about} (in "
                     "their carriers) not determined by the data")
    return "; ".join(parts)
