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
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from threadpoolctl import ThreadpoolController

from .certificate import CertificateOptions, certify_from_Z
from .cost import StateLayout, build_cost_matrices, reduce_cost
from .initialization import closed_form_estimate, estimate_from_rotations, rotations_from_vector
from .lie import make_transform
from .local_solver import (
    LocalSolverOptions,
    fast_certificate_matrix,
    refine_rotations,
    strengthen_certificate,
)
from .problem import Problem
from .relaxation import (
    SdpOptions,
    evaluate_Z,
    so3_constraint_matrices,
    solve_dual_sdp,
    solve_dual_sdp_arrow,
)
from .result import CalibrationResult, Certificate, Status
from .sparsity import ArrowSplit, arrow_split, estimate_form_costs

__all__ = ["SolveOptions", "solve", "MODES"]

MODES = ("sdp", "fast", "local")

#: Costs below this fraction of the largest entry of ``Q'`` count as zero (noise-free data).
COST_FLOOR_REL = 1e-4


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
    """

    mode: str = "fast"
    sdp: SdpOptions = field(default_factory=SdpOptions)
    certificate: CertificateOptions = field(default_factory=CertificateOptions)
    local: LocalSolverOptions = field(default_factory=LocalSolverOptions)
    initial: tuple[np.ndarray, np.ndarray] | None = None
    fallback_to_sdp: bool = True
    blas_threads: int | None = 1

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"mode: expected one of {MODES}, got {self.mode!r}")


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


def _prepare(problem: Problem, options: SolveOptions) -> _Prepared:
    timing: dict[str, float] = {}
    t0 = time.perf_counter()
    layout = StateLayout(problem.M, problem.P)
    Q, Q_rot = build_cost_matrices(problem)
    reduced = reduce_cost(Q, layout, problem.unknown_scale)
    timing["build"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    if options.initial is not None:
        X0, Y0 = options.initial
        R0 = np.concatenate([np.asarray(X0, float), np.asarray(Y0, float)])[:, :3, :3]
        if R0.shape != (problem.n_frames, 3, 3):
            raise ValueError(f"initial: expected {problem.M} X and {problem.P} Y transforms, "
                             f"got {R0.shape[0]} in total")
        init = estimate_from_rotations(problem, reduced, R0)
    else:
        init = closed_form_estimate(problem, reduced, Q_rot)
    timing["initialise"] = time.perf_counter() - t1
    # Scale by an upper bound on the optimum (cost at a feasible point), floored relative to the
    # data (1e-4 of the largest entry of Q') so that noise-free problems (optimum 0) stay well
    # conditioned; the same floor is the "zero cost" of the certificate.
    floor = COST_FLOOR_REL * max(float(np.abs(reduced.Qr).max()), 1e-300)
    scale = max(float(init.cost), floor)
    return _Prepared(problem, layout, reduced, scale, reduced.Qr / scale, init.R, timing, floor,
                     Q)


def _result(prep: _Prepared, R: np.ndarray, cert: Certificate, mode: str, solver_status: str,
            moved: float, notes: list[str], est=None) -> CalibrationResult:
    """The result for rotations ``R`` (translations and scale by eq. (47); ``est`` if already
    computed for these rotations)."""
    if est is None:
        est = estimate_from_rotations(prep.problem, prep.reduced, R)
    T = make_transform(est.R, est.t)
    M = prep.problem.M
    return CalibrationResult(
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


def _certify(prep: _Prepared, options: SolveOptions, Z: np.ndarray, lambda_s: float,
             cost: float, solver_ok: bool = True, solver_status: str = "local") -> Certificate:
    """:func:`certify_from_Z` with this problem's scale, size, cost floor and options."""
    return certify_from_Z(Z, lambda_s, cost, prep.scale, prep.problem.n_frames,
                          solver_ok=solver_ok, solver_status=solver_status,
                          homogeneous=prep.problem.unknown_scale, cost_floor=prep.cost_floor,
                          options=options.certificate)


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
    d = 9 * n + 1
    t0 = time.perf_counter()
    cons = so3_constraint_matrices(np.arange(n) * 9, d, d - 1)
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
    if form == "full":
        sol = solve_dual_sdp(Qf, cons_f, options.sdp)
    elif form == "arrow":
        sol = solve_dual_sdp_arrow(prep.Qs, cons, split, options.sdp)
    else:
        sol = solve_dual_sdp(prep.Qs, cons, options.sdp)
    notes.append(f"SDP form: {form}")
    notes.append(f"Clarabel: {sol.iterations} iterations, status '{sol.status}'")
    prep.timing["compile"] = sol.compile_s
    prep.timing["solve"] = sol.solve_s
    t1 = time.perf_counter()
    solver_ok = sol.status == "optimal" and bool(np.all(np.isfinite(sol.lam)))
    if not np.all(np.isfinite(sol.lam)):
        cert = Certificate(Status.SOLVER_INACCURATE, float("nan"), float("nan"), float("nan"),
                           float("nan"), np.zeros(0), -1, options.certificate.rho_tol,
                           f"SDP solver returned no solution (status '{sol.status}')")
        R = prep.init_R
        prep.timing["extract"] = time.perf_counter() - t1
        notes.append("SDP failed; returning the closed-form estimate")
        return _result(prep, R, cert, "sdp", sol.status, 0.0, notes)
    Z = evaluate_Z(prep.Qs, cons, sol.lam)
    w, V = np.linalg.eigh(Z)
    v = V[:, 0]
    # Algorithm 1 step 6: scale the null vector so that s = 1 (sign and magnitude), then fix
    # det R = +1 via the mean cube-root determinant and project each block onto SO(3).
    if abs(v[-1]) > 1e-8 * np.linalg.norm(v):
        v = v / v[-1]
    R_raw, moved = rotations_from_vector(v[:-1], n)
    prep.timing["extract"] = time.perf_counter() - t1
    t2 = time.perf_counter()
    est = estimate_from_rotations(prep.problem, prep.reduced, R_raw)
    cert = _certify(prep, options, Z, sol.lambda_s, est.cost, solver_ok, sol.status)
    prep.timing["certify"] = time.perf_counter() - t2
    return _result(prep, R_raw, cert, "sdp", sol.status, moved, notes, est)


def _solve_local(prep: _Prepared, options: SolveOptions) -> tuple[np.ndarray, object]:
    t0 = time.perf_counter()
    loc = refine_rotations(prep.Qs, prep.init_R, options.local)
    prep.timing["local"] = time.perf_counter() - t0
    return loc.R, loc


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
    threads = options.blas_threads
    if threads is None:
        return _solve(problem, options)
    with _blas_controller().limit(limits=threads, user_api="blas"):
        return _solve(problem, options)


@functools.lru_cache(maxsize=1)
def _blas_controller() -> ThreadpoolController:
    """One controller per process: scanning the loaded libraries costs ~3 ms, limiting is cheap."""
    return ThreadpoolController()


def _solve(problem: Problem, options: SolveOptions) -> CalibrationResult:
    t_start = time.perf_counter()
    prep = _prepare(problem, options)
    notes: list[str] = []
    if options.mode == "sdp":
        res = _solve_sdp(prep, options, notes)
    else:
        R, loc = _solve_local(prep, options)
        if not loc.converged:
            notes.append(f"local solver stopped after {loc.iterations} iterations without "
                         f"converging (gradient norm {loc.gradient_norm:.3g})")
        if options.mode == "local":
            est = estimate_from_rotations(problem, prep.reduced, R)
            res = _result(prep, R, Certificate.local_only(est.cost), "local",
                          "converged" if loc.converged else "not converged", 0.0, notes, est)
        else:
            t0 = time.perf_counter()
            Z, lam_s = fast_certificate_matrix(prep.Qs, R)
            est = estimate_from_rotations(problem, prep.reduced, R)
            cert = _certify(prep, options, Z, lam_s, est.cost)
            prep.timing["certify"] = time.perf_counter() - t0
            if not cert.certified and cert.lambda_min >= -options.certificate.null_tol:
                # PSD but a larger null space: try the handedness multipliers (cheap 1-D search)
                t1 = time.perf_counter()
                Z2, _ = strengthen_certificate(Z, R, null_tol=options.certificate.null_tol)
                cert2 = _certify(prep, options, Z2, lam_s, est.cost)
                prep.timing["strengthen"] = time.perf_counter() - t1
                if cert2.certified:
                    cert = cert2
                    notes.append("fast certificate strengthened with handedness multipliers")
            if cert.certified or not options.fallback_to_sdp:
                res = _result(prep, R, cert, "fast",
                              "converged" if loc.converged else "not converged", 0.0, notes,
                              est)
            else:
                notes.append(f"fast certificate inconclusive ({cert.message}); fell back to the "
                             "SDP relaxation")
                res = _solve_sdp(prep, options, notes)
                res.mode = "fast"
    res.timing_s["total"] = time.perf_counter() - t_start
    return res
