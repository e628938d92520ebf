"""Mode ``fast`` (and ``local``) for large rigs: the unreduced sparse path and when to take it.

The dense path (:mod:`rwhec_ros.core.pipeline.dense`) forms the reduced cost ``Q'`` of eq. (48):
``9 n + 1`` square and dense as soon as many cameras share a target, so its local solve and
certificate cost ``O(n^3)`` time and ``O(n^2)`` memory (1,000 cameras with one target: ~40 s, 650 MB
per copy). This path never forms ``Q'``:

1. the cost on the unreduced variables with the gauge penalty as sparse springs
   (:mod:`rwhec_ros.core.model.sparse_cost`); unobservable translations found by a sparse ``L D
   L^T`` and Lanczos (:mod:`rwhec_ros.core.model.gauge`);
2. the closed-form start by shift-invert Lanczos on the sparse rotation-only cost;
3. Riemannian Newton with variable projection (:mod:`rwhec_ros.core.local.sparse`);
4. the certificate proven on the sparse ``Z(lambda)`` (:mod:`rwhec_ros.core.certify.sparse`),
   with ``p`` the direct cost of the returned estimate, as on the dense path.

When that certificate is inconclusive and the problem has at most ``sdp_fallback_max_frames``
frames, the dense path (with its SDP fallback) is run instead;
larger problems return the uncertified result with a note.

**Automatic choice** (``SolveOptions.fast_form = "auto"``): the sparse path when the problem has
at least :data:`SPARSE_MIN_FRAMES` frames and a sparse factorisation stays sparse: the work of a
minimum-degree elimination of the camera-tag graph at the level of frames
(:func:`~rwhec_ros.core.certify.sparsity.elimination_front`) is at most :data:`SPARSE_MAX_WORK`
``n^3``, or the problem has :data:`SPARSE_ALWAYS_FRAMES` frames or more.
One target seen by every camera: fronts of one frame; 16 targets each seen by 3 of 1,000 cameras:
fronts of at most 15 frames; a random graph of 100 cameras and 100 tags, 5 tags per camera:
fronts of 64 frames (0.017 n^3); 50 x 50 of the same kind (0.022 n^3) is where LAPACK on the dense
``Q'`` becomes as fast as QDLDL's scalar loops on the large sparse fronts.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ..certify.sparse import CertificatePattern, certify_sparse
from ..certify.sparsity import elimination_front
from ..initial.closed_form import initial_rotations, primal_cost
from ..local.sparse import NewtonSystem, refine_rotations_sparse, rotation_blocks
from ..model.cost import StateLayout, edge_blocks
from ..model.estimate import Estimate
from ..model.gauge import GaugeFix, build_gauge_fix, find_unobservable_directions
from ..model.sparse_cost import FullForm, build_full_form, pruned_gauge, translation_block
from ..numerics.verified import lanczos_start
from ..problem import Problem
from ..result import CalibrationResult, Certificate
from .common import COST_FLOOR_REL, NUMERICAL_ERRORS, calibration_result, failed_certificate
from .dense import prepare_dense, solve_fast_dense
from .options import SolveOptions

__all__ = ["SPARSE_MIN_FRAMES", "SPARSE_MAX_WORK", "SPARSE_ALWAYS_FRAMES", "use_sparse",
           "SparsePrepared", "prepare_sparse", "estimate_sparse", "solve_fast_sparse",
           "failed_result", "solve_sparse"]

#: Fewest frames for which ``auto`` takes the sparse path (measured, one target seen by every
#: camera, best of 5 on 2 busy cores: 21 frames dense 17 ms / sparse 19 ms, 41 frames 53 / 26 ms,
#: 101 frames 383 / 49 ms; 4 targets x 30 cameras, all edges: dense 38 ms, sparse 64 ms).
SPARSE_MIN_FRAMES = 40
#: ``auto`` takes the sparse path while the work of a sparse factorisation, ``sum (front + 1)^2``
#: over a minimum-degree elimination of the frame graph
#: (:func:`~rwhec_ros.core.certify.sparsity.elimination_front`), is at most this times ``n^3`` (the
#: dense path's ``O(n^3)``). Measured on random camera-tag graphs, 5 tags per camera: 50 x 50
#: (0.022 n^3) 265 ms dense / 264 ms sparse, 100 x 100 (0.017 n^3) 1.77 s / 1.2 s (best of 3,
#: three alternations); 30 x 30 with 3 tags per camera (0.007 n^3) 75 / 47 ms. One target and
#: 3,000 cameras: 4e-7 n^3.
SPARSE_MAX_WORK = 0.02
#: From this many frames ``auto`` takes the sparse path whatever the fill: the dense ``Q'`` (9 n + 1
#: square) then costs more than the fill of a sparse factorisation (random graphs with 5 tags per
#: camera: 150 x 150, 20 s and 466 MB dense / 7.8 s and 151 MB sparse; 300 x 300, dense
#: unfinished after 36 min at 1.8 GB / sparse 129 s and 316 MB; busy 2-core machine).
SPARSE_ALWAYS_FRAMES = 250


def use_sparse(problem: Problem, fast_form: str) -> bool:
    """Whether ``fast``/``local`` take the sparse path (module docstring)."""
    if fast_form != "auto":
        return fast_form == "sparse"
    if problem.n_frames < SPARSE_MIN_FRAMES:
        return False
    if problem.n_frames >= SPARSE_ALWAYS_FRAMES:
        return True
    n = problem.n_frames
    limit = SPARSE_MAX_WORK * float(n) ** 3
    _, work = elimination_front(problem.M, problem.P, problem.edge_x, problem.edge_y,
                                max_work=limit)
    return work <= limit


@dataclass
class SparsePrepared:
    """What the sparse path shares between its steps (the counterpart of the dense
    ``_Prepared``): the problem, the unreduced cost (unscaled ``form.Q``, scaled ``Qs``), the data
    scale, the start, the timings, the cost floor and the gauge fix."""

    problem: Problem
    layout: StateLayout
    form: FullForm
    scale: float
    Qs: sp.csr_matrix
    init_R: np.ndarray
    timing: dict
    cost_floor: float
    gauge: GaugeFix
    _pattern: CertificatePattern | None = field(default=None, repr=False)

    def pattern(self) -> CertificatePattern:
        if self._pattern is None:
            self._pattern = CertificatePattern(self.form, self.Qs)
        return self._pattern

    def hessian_eigenpairs(self, R: np.ndarray, null_tol: float) -> tuple[np.ndarray, np.ndarray]:
        """The smallest eigenpairs of the Riemannian Hessian of the scaled reduced cost at ``R``
        (shift-invert Lanczos on the sparse Newton system around ``-10 null_tol``); a first
        eigenvalue ``-inf`` when the Hessian has one below ``-10 null_tol`` (a saddle)."""
        n, nf = self.problem.n_frames, self.form.n_free
        z = self.form.state(R)
        system = NewtonSystem(self.Qs, nf, n)
        system.assemble(R, rotation_blocks(self.Qs @ z, nf, n))
        sig = 10.0 * null_tol
        factor = system.factor(sig)
        if not factor.positive_definite:
            return np.array([-np.inf]), np.zeros((3 * n, 1))
        m = 3 * n

        def op(b: np.ndarray) -> np.ndarray:
            return factor.solve(np.concatenate([np.zeros(nf), b]))[nf:]

        def no_matvec(_b: np.ndarray) -> np.ndarray:  # never called in shift-invert mode
            raise RuntimeError("matvec of the reduced Hessian is not available")

        w, V = spla.eigsh(spla.LinearOperator((m, m), matvec=no_matvec, dtype=float),
                          k=min(6, m - 1), sigma=-sig, which="LM",
                          OPinv=spla.LinearOperator((m, m), matvec=op, dtype=float),
                          v0=lanczos_start(m))
        order = np.argsort(w)
        return w[order], V[:, order]


def prepare_sparse(problem: Problem, options) -> SparsePrepared:
    """Cost on the unreduced variables, the gauge fix, the closed-form (or given) start and the
    data scale (cf. :func:`~rwhec_ros.core.pipeline.dense.prepare_dense`). Raises a
    ``numpy.linalg.LinAlgError`` subclass when the translation block cannot be factorised."""
    timing: dict[str, float] = {}
    t0 = time.perf_counter()
    layout = StateLayout(problem.M, problem.P)
    blocks = edge_blocks(problem)
    Qt = translation_block(problem, blocks)
    V_w, w_w, directions, w_max = find_unobservable_directions(Qt, layout, problem,
                                                               options.gauge)
    gauge = pruned_gauge(build_gauge_fix(problem, V_w, w_w, directions, w_max,
                                         options.gauge.priors), problem.n_frames)
    form = build_full_form(problem, gauge, blocks)
    form.factor_free()
    timing["build"] = time.perf_counter() - t0
    t1 = time.perf_counter()
    if options.initial is not None:
        R0 = initial_rotations(problem, options.initial)
    else:
        R0 = form.closed_form_rotations()
    init = form.estimate(R0)
    timing["initialise"] = time.perf_counter() - t1
    # as on the dense path, scale by the cost at the start, floored relative to the data: here
    # 1e-4 of the largest rotation entry of the diagonal of Q (an upper bound on that of Q')
    nf = form.n_free
    diag = form.Q.diagonal()[nf: nf + 9 * problem.n_frames]
    floor = COST_FLOOR_REL * max(float(np.abs(diag).max(initial=0.0)), 1e-300)
    scale = max(float(init.cost), floor)
    return SparsePrepared(problem, layout, form, scale, (form.Q / scale).tocsr(), init.R,
                          timing, floor, gauge)


def estimate_sparse(prep: SparsePrepared, R: np.ndarray) -> tuple[Estimate, float]:
    """Translations and scale for rotations ``R`` and the direct cost ``p`` (eq. (33) plus the
    prior's term), as the dense path's ``_estimate``."""
    est = prep.form.estimate(R)
    return est, primal_cost(prep.problem, est, prep.gauge)


def solve_fast_sparse(prep: SparsePrepared, options, notes: list[str]
                      ) -> tuple[object, CalibrationResult]:
    """Local solve and certificate on the sparse path; returns the prepared data the result
    belongs to (the dense one when the dense path was run as the fallback) and the result."""
    n = prep.problem.n_frames
    notes.append(f"sparse unreduced path ({n} frames, {prep.form.size} variables)")
    t0 = time.perf_counter()
    try:
        loc = refine_rotations_sparse(prep.form, prep.Qs, prep.init_R, options.local,
                                      f_floor=prep.cost_floor / prep.scale)
    except NUMERICAL_ERRORS as exc:
        notes.append(f"local solver failed ({type(exc).__name__}: {exc})")
        est, p = estimate_sparse(prep, prep.init_R)
        cert = failed_certificate(options, p, f"the local solver failed: {exc}")
        return prep, calibration_result(prep, est, cert, options.mode, "failed", 0.0, notes)
    prep.timing["local"] = time.perf_counter() - t0
    status = "converged" if loc.converged else "not converged"
    if not loc.converged:
        notes.append(f"local solver stopped after {loc.iterations} iterations without "
                     f"converging (gradient norm {loc.gradient_norm:.3g})")
    est, p = estimate_sparse(prep, loc.R)
    if options.mode == "local":
        return prep, calibration_result(prep, est, Certificate.local_only(p), "local", status, 0.0,
                                        notes)
    t1 = time.perf_counter()
    try:
        cert, strengthened = certify_sparse(
            prep.form, prep.Qs, prep.pattern(), loc.R, p, prep.scale,
            homogeneous=prep.problem.unknown_scale, cost_floor=prep.cost_floor,
            options=options.certificate)
        if strengthened:
            notes.append("fast certificate strengthened with handedness multipliers")
    except NUMERICAL_ERRORS as exc:
        cert = failed_certificate(options, p, f"the certificate's eigen-analysis failed "
                                   f"({type(exc).__name__}: {exc})")
    prep.timing["certify"] = time.perf_counter() - t1
    if cert.certified or not options.fallback_to_sdp:
        return prep, calibration_result(prep, est, cert, "fast", status, 0.0, notes)
    if n > options.sdp_fallback_max_frames:
        notes.append(f"sparse certificate inconclusive; the dense path and the SDP are skipped "
                     f"above sdp_fallback_max_frames={options.sdp_fallback_max_frames} frames")
        return prep, calibration_result(prep, est, cert, "fast", status, 0.0, notes)
    notes.append(f"sparse certificate inconclusive ({cert.message}); solved again by the dense "
                 "path")
    dense = prepare_dense(prep.problem, options)
    return dense, solve_fast_dense(dense, options, notes)


def failed_result(problem: Problem, options, message: str, notes: list[str]) -> CalibrationResult:
    """A ``solver_failed`` result when the sparse path cannot even start (the translation block
    could not be factorised) and the problem is too large for the dense path: identity
    transforms, the message says why."""
    n = problem.n_frames
    eye = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
    cert = failed_certificate(options, float("nan"), message)
    return CalibrationResult(x_names=problem.x_names, y_names=problem.y_names, X=eye[:problem.M],
                             Y=eye[problem.M:], scale=1.0, certificate=cert, mode=options.mode,
                             timing_s={}, solver_status="failed", rounding_displacement=0.0,
                             notes=notes)


def solve_sparse(problem: Problem, options: SolveOptions, notes: list[str]):
    """The sparse path as a whole: :func:`prepare_sparse` and :func:`solve_fast_sparse`; when its
    translation block cannot be factorised, the dense path (which reports why) up to
    ``sdp_fallback_max_frames`` frames,
    else a ``solver_failed`` result."""
    try:
        prep = prepare_sparse(problem, options)
    except NUMERICAL_ERRORS as exc:
        msg = f"the sparse path could not start ({type(exc).__name__}: {exc})"
        notes.append(msg)
        if problem.n_frames > options.sdp_fallback_max_frames:
            return None, failed_result(problem, options, msg, notes)
        prep = prepare_dense(problem, options)
        return prep, solve_fast_dense(prep, options, notes)
    return solve_fast_sparse(prep, options, notes)
