"""A primal-dual interior-point method for Problem 7 that exploits its frame-block structure.

Solves the pair of :mod:`rwhec_ros.core.certify.sdp_structure` on the reduced ``Q'`` (eq. (48))::

    min <Q', X>  s.t.  A(X) = b,  X >= 0        max y_s  s.t.  S = Q' - A^T(y) >= 0,

whose dual is Problem 7 (``y`` = the multipliers ``lambda``, ``S`` = the certificate matrix
``Z(lambda)`` of eq. (51)), with the Nesterov-Todd search direction computed as in SDPT3 (Todd,
Toh and Tutuncu 1998: ``G = L_X V D^{-1/2}`` from the SVD ``L_S^T L_X = U D V^T``, so that
``G^T S G = G^{-1} X G^{-T} = D``) and Mehrotra's predictor-corrector. Per iteration: Cholesky
factorisations of ``X`` and ``S`` (``d = 9 n + 1``), one SVD, the Schur complement ``M_ij = <A_i,
W A_j W>`` (``W = G G^T``) of size ``m = 20 n + 1`` assembled from ``10 x 10`` blocks
(:meth:`~rwhec_ros.core.certify.sdp_structure.FrameBlocks.schur`), one Cholesky factorisation
of ``M`` for
both directions: ``O(d^3 + m^3)`` flops and ``O(d^2 + m^2)`` memory, where a general conic solver
needs a PSD cone of dimension ``d (d + 1) / 2``. (The HKM direction was tried first: it stalled
at gaps of about ``1e-7`` on small problems, where NT reached ``1e-8``.)

Both problems have an obvious strictly feasible point, so the method never leaves feasibility:

* ``X_0 = diag(I_{9n} / 3, 1)``: ``R R^T = R^T R = s^2 I`` and the handedness constraints hold
  (every off-diagonal entry is 0), ``s^2 = 1``;
* ``y_0``: ``-tau`` on the three diagonal constraints (50a) of every frame and ``-(3 n + 1) tau``
  on ``s^2 = 1``, so that ``S_0 = Q' + tau I`` (the (50a) diagonals sum to ``I_9 - 3 e_s e_s^T``
  per frame).

``S`` is always recomputed as ``Q' - A^T(y)`` from ``y`` (never updated on its own), so the
dual iterate is exactly the ``Z(lambda)`` the certificate evaluates; the primal residual
``b - A(X)`` (rounding only) is carried in the right-hand side.

The relaxation is primal degenerate at a rank-one optimum (``m > d``), and the Newton systems lose
accuracy as the gap closes. So once the gap is below :attr:`IpmOptions.polish_gap`, every
iteration also tries :func:`~rwhec_ros.core.certify.sdp_polish.polish` (round, refine, move the
multipliers so that the refined rounding is a null vector of ``Z``) and stops as soon as the
polished multipliers close the gap to the rounded estimate within the tolerances; otherwise the
method runs to its own tolerances.

Nothing here certifies anything: the multipliers go to :mod:`rwhec_ros.core.certificate`, which
proves a bound from them in floating point whatever this method's tolerances. The status
``"optimal"`` (gap and feasibility within the tolerances, by the iterates or by a polished pair)
is what the solve calls a reliable solver; ``"optimal_inaccurate"`` (iteration limit, stall,
lost factorisation) gives ``solver_inaccurate``, and a failure to start (non-finite data, no
factorisation) returns non-finite multipliers (``solver_failed``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.linalg

from .relaxation import DualSolution
from .sdp_polish import polish
from .sdp_structure import FrameBlocks, frame_blocks

_DEBUG = False

__all__ = ["IpmOptions", "IpmTrace", "solve_dual_sdp_structured", "initial_point",
           "structured_cost", "structured_is_cheaper", "STRUCTURED_COST_RATIO"]


@dataclass
class IpmOptions:
    """Options of :func:`solve_dual_sdp_structured` (scaled problem, optimum ``O(1)``).

    Attributes
    ----------
    tol_gap_rel, tol_gap_abs : float
        Stop when the duality gap is at most ``tol_gap_abs`` or ``tol_gap_rel`` times the primal
        objective (1e-8 both: Clarabel's defaults, the tolerances of the cvxpy path, 100 times
        below the certificate's ``rho_tol`` 1e-6) ...
    tol_feas : float
        ... and ``|b - A(X)|_inf <= tol_feas`` (1e-8; the dual is feasible by construction).
    max_iter : int
        Iteration limit (60; 10-25 are typical).
    polish_gap : float
        Try the polished multipliers once the gap ``<Q', X> - y_s`` is at most this, in units of
        the closed-form estimate's cost (by which the data are scaled): 100, tried from about the
        third iteration on; a failed try costs about one iteration. On the paper's data 4
        iterations then (0.8-1.2 s at a load of 14 on 2 cores), 6 with 10, 7 with 1 (1.8-2.7
        s). ``0`` never polishes.
    polish_min_eig : float
        ... and accept them only if the second smallest eigenvalue of their ``Z`` is at least
        this (1e-4, 100 times the certificate's default ``null_tol``): the rounded estimate
        spans the null space with a clear margin, as at the centre of the optimal face the
        interior-point method tends to. Otherwise the method goes on to its own tolerances.
    """

    tol_gap_rel: float = 1e-8
    tol_gap_abs: float = 1e-8
    tol_feas: float = 1e-8
    max_iter: int = 60
    polish_gap: float = 100.0
    polish_min_eig: float = 1e-4

    def __post_init__(self) -> None:
        for name in ("tol_gap_rel", "tol_gap_abs", "tol_feas"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name}: must be finite and > 0, got {v!r}")
        for name in ("polish_gap", "polish_min_eig"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"{name}: must be finite and >= 0, got {v!r}")
        if int(self.max_iter) < 1:
            raise ValueError(f"max_iter: must be >= 1, got {self.max_iter!r}")


@dataclass
class IpmTrace:
    """What the method ended with (for tests and notes): objectives of the last iterate, its gap
    ``<X, S>`` and primal residual ``|b - A(X)|_inf``; whether the returned multipliers are the
    polished ones, with the rounded estimate's cost; the last ``X`` and the returned ``S = Q' -
    A^T(y)``."""

    pobj: float
    dobj: float
    gap: float
    primal_residual: float
    polished: bool
    polished_cost: float
    X: np.ndarray
    S: np.ndarray


def initial_point(C: np.ndarray, fb: FrameBlocks, tau: float = 1.0
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The strictly feasible start ``(X_0, y_0, S_0 = C + tau I)`` of the module docstring.

    ``tau = 1`` is the scale of the data (the closed-form estimate costs 1), and ``C = Q'`` is
    positive semidefinite, so ``S_0 >= I`` up to rounding; it took the fewest iterations of
    the choices tried (1, the mean or largest diagonal entry, the largest absolute row sum).
    The caller falls back to the largest absolute row sum (``S_0 >= 0`` by Gershgorin, whatever
    ``C``) if ``S_0`` does not factorise."""
    n = fb.n
    X = np.diag(np.r_[np.full(9 * n, 1.0 / 3.0), 1.0])
    y = np.zeros(fb.m)
    y[:-1].reshape(n, fb.k)[:, [0, 3, 5]] = -tau  # (50a) diagonals (0,0), (1,1), (2,2)
    y[-1] = -(3 * n + 1) * tau
    return X, y, C - fb.adjoint(y)


def _chol(A: np.ndarray) -> np.ndarray | None:
    """Lower Cholesky factor of ``A`` (LAPACK ``potrf``; entries above the diagonal are zero),
    or None when it is not (numerically) positive definite."""
    L, info = scipy.linalg.lapack.dpotrf(A, lower=1, clean=1)
    if info != 0 or not np.all(np.isfinite(np.diagonal(L))):
        return None
    return L


def _sym(A: np.ndarray) -> np.ndarray:
    return 0.5 * (A + A.T)


class _Schur:
    """The Schur complement, diagonally scaled, factorised by Cholesky; when that fails (the
    degenerate end game), with a regularisation of ``1e-12``, ``1e-10`` then ``1e-8`` of the
    scaled diagonal, and as a last resort by LU."""

    def __init__(self, M: np.ndarray) -> None:
        self.dinv = 1.0 / np.sqrt(np.maximum(np.diag(M), 1e-300))
        Ms = M * self.dinv[:, None] * self.dinv[None, :]
        self.chol = self.lu = None
        for reg in (0.0, 1e-12, 1e-10, 1e-8):
            try:
                self.chol = scipy.linalg.cho_factor(Ms + reg * np.eye(Ms.shape[0]) if reg else Ms,
                                                    lower=True, check_finite=False)
                return
            except np.linalg.LinAlgError:
                continue
        self.lu = scipy.linalg.lu_factor(Ms, check_finite=False)

    def solve(self, r: np.ndarray) -> np.ndarray:
        if self.chol is not None:
            x = scipy.linalg.cho_solve(self.chol, r * self.dinv, check_finite=False)
        else:
            x = scipy.linalg.lu_solve(self.lu, r * self.dinv, check_finite=False)
        return self.dinv * x


#: Step lengths are resolved up to this one (a full step is taken at a fraction >= 0.9 of it).
_STEP_CAP = 1.2
#: Up to this size the step length comes from all eigenvalues (LAPACK ``syevd``); above it from
#: Cholesky factorisations (level-3 BLAS, cheaper than a tridiagonal reduction from ``d`` of
#: about 200 on).
_EIG_STEP_MAX_D = 250


def _scaled_step(D: np.ndarray, dV: np.ndarray) -> float:
    """A lower bound on the largest ``alpha <= 1.2`` with ``diag(D) + alpha dV >= 0`` (``D >
    0``): ``-1 / lambda_min(B)`` with ``B = D^{-1/2} dV D^{-1/2}`` up to ``d = 250``; above,
    Cholesky factorisations of ``I + alpha B``, halving ``alpha`` from 1.2 until one succeeds,
    then four geometric bisections (within 5 %). 0 when not even ``1e-12`` is feasible."""
    r = 1.0 / np.sqrt(D)
    B = _sym(dV * r[:, None] * r[None, :])
    if D.size <= _EIG_STEP_MAX_D:
        lam = float(np.linalg.eigvalsh(B)[0] if D.size <= 64 else scipy.linalg.eigh(
            B, eigvals_only=True, subset_by_index=[0, 0], check_finite=False, driver="evr")[0])
        return _STEP_CAP if lam >= -1.0 / _STEP_CAP else -1.0 / lam
    eye = np.eye(D.size)

    def feasible(alpha: float) -> bool:
        return _chol(eye + alpha * B) is not None

    hi = _STEP_CAP
    if feasible(hi):
        return hi
    lo = 0.5 * hi
    while not feasible(lo):
        hi, lo = lo, 0.5 * lo
        if lo < 1e-12:
            return 0.0
    for _ in range(4):
        mid = float(np.sqrt(lo * hi))
        lo, hi = (mid, hi) if feasible(mid) else (lo, mid)
    return lo


def _nt_scaling(Lx: np.ndarray, Ls: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(G, D)`` with ``G^T S G = G^{-1} X G^{-T} = diag(D)``: ``G = L_X V D^{-1/2}`` from
    ``L_X^T S L_X = V D^2 V^T``. Near the central path ``D^2`` is nearly ``mu I`` and that
    symmetric eigenproblem (a third of the time of an SVD) is accurate; when ``D^2`` spreads
    over more than six orders of magnitude, the SVD ``L_S^T L_X = U D V^T`` (which does not
    square the condition number) is used instead."""
    K = Ls.T @ Lx
    D2, V = scipy.linalg.eigh(K.T @ K, check_finite=False, driver="evd")
    if D2[0] > 1e-6 * D2[-1]:
        D = np.sqrt(D2)
    else:
        _, D, Vt = scipy.linalg.svd(K, check_finite=False, lapack_driver="gesdd")
        V = Vt.T
    if not D[-1] > 0 or not np.all(np.isfinite(D)):
        raise np.linalg.LinAlgError("the scaling matrix is singular")
    D = np.maximum(D, D[-1] * 1e-300)
    return (Lx @ V) * (1.0 / np.sqrt(D))[None, :], D


def _nt_step(fb: FrameBlocks, X: np.ndarray, Lx: np.ndarray, Ls: np.ndarray, rp: np.ndarray,
             mu: float):
    """One Mehrotra predictor-corrector NT direction: ``(dX, dy, alpha_p max, alpha_d max)``."""
    d = X.shape[0]
    G, D = _nt_scaling(Lx, Ls)
    schur = _Schur(fb.schur(G @ G.T))
    Gi = G[fb.index]                                   # (n, 10, d): the rows of each block

    def direction(rhs: np.ndarray):
        # A(dX) = rp with dX = G T G^T - W dS W, dS = -A^T(dy): M dy = rp - A(G T G^T)
        dy = schur.solve(rhs)
        dSt = _sym(G.T @ (-fb.adjoint(dy)) @ G)       # scaled dS = G^T dS G
        return dy, dSt

    def block_apply(T: np.ndarray) -> np.ndarray:
        """``A(G T G^T)`` from the diagonal blocks ``G_I T G_I^T`` alone."""
        GT = (Gi.reshape(-1, d) @ T).reshape(Gi.shape)
        Bd = np.matmul(GT, Gi.transpose(0, 2, 1))      # (n, 10, 10)
        out = np.empty(fb.m)
        out[:-1] = (Bd.reshape(fb.n, -1) @ fb.A.reshape(fb.k, -1).T).ravel()
        out[-1] = Bd[0, 9, 9]
        return out

    # predictor: D dX~ + dX~ D + D dS~ + dS~ D = -2 D^2, i.e. T = -D and G T G^T = -X
    Dm = np.diag(D)
    dy, dSt = direction(rp + fb.apply(X))
    dXt = -Dm - dSt
    ap = min(1.0, _scaled_step(D, dXt))
    ad = min(1.0, _scaled_step(D, dSt))
    mu_aff = float(np.vdot(Dm + ap * dXt, Dm + ad * dSt)) / d
    sigma = float(np.clip((mu_aff / mu) ** 3, 0.0, 1.0))
    # corrector: right-hand side 2 sigma mu I - 2 D^2 - (dX~ dS~ + dS~ dX~), T = rhs / (D_i + D_j)
    P = dXt @ dSt
    T = -(P + P.T)
    T[np.diag_indices(d)] += 2.0 * sigma * mu - 2.0 * D * D
    T /= D[:, None] + D[None, :]
    dy, dSt = direction(rp - block_apply(T))
    dXt = T - dSt
    return _sym(G @ dXt @ G.T), dy, _scaled_step(D, dXt), _scaled_step(D, dSt)


def _failed(m_full: int, t0: float, words: str) -> DualSolution:
    t = time.perf_counter() - t0
    return DualSolution(lam=np.full(m_full, np.nan), status="solver_error", compile_s=0.0,
                        solve_s=t, iterations=0, total_s=t, warnings=[words])


def _gap_closed(p: float, d: float, opts: IpmOptions) -> bool:
    return p - d <= opts.tol_gap_abs or p - d <= opts.tol_gap_rel * abs(p)


def solve_dual_sdp_structured(Q: np.ndarray, n_frames: int, options: IpmOptions | None = None,
                              *, trace: list | None = None) -> DualSolution:
    """Solve Problem 7 on the reduced ``Q'`` with the structured interior-point method.

    Parameters
    ----------
    Q : ndarray, shape (9 n + 1, 9 n + 1)
        The scaled reduced cost ``Q'`` (``s`` last), symmetric.
    n_frames : int
        ``n``, the number of rotations.
    options : IpmOptions, optional
    trace : list, optional
        If given, an :class:`IpmTrace` of the end is appended.

    Returns
    -------
    DualSolution
        Multipliers in the order of :func:`~rwhec_ros.core.relaxation.frame_constraints`
        (``lam[-1] = lambda_s``), status ``"optimal"``, ``"optimal_inaccurate"`` or
        ``"solver_error"`` (then ``lam`` is NaN); ``iterations`` counts the interior-point
        iterations, ``warnings`` says why it stopped short and whether it polished.
    """
    opts = options or IpmOptions()
    t0 = time.perf_counter()
    fb = frame_blocks(n_frames)
    d = fb.d
    m_full = 21 * fb.n + 1
    C = np.asarray(Q.toarray() if hasattr(Q, "toarray") else Q, dtype=float)
    if C.shape != (d, d):
        raise ValueError(f"Q: expected shape ({d}, {d}) for {n_frames} frames, got {C.shape}")
    with np.errstate(over="ignore", invalid="ignore"):
        C = _sym(C)
    if not np.all(np.isfinite(C)):
        return _failed(m_full, t0, "the SDP data are not finite (or overflow)")
    b = fb.b()
    X, y, S = initial_point(C, fb)
    Ls = _chol(S)
    if Ls is None:
        X, y, S = initial_point(C, fb, 2.0 * max(1.0, float(np.abs(C).sum(axis=1).max())))
        Ls = _chol(S)
    if Ls is None:
        return _failed(m_full, t0, "no positive definite dual start (the data are too large or "
                       "too ill-conditioned for double precision)")
    status, words, polished = "optimal_inaccurate", "", None
    it = 0
    pobj = dobj = gap = res_p = float("nan")
    Lx = _chol(X)
    while True:
        gap = float(np.vdot(X, S))
        pobj = float(np.vdot(C, X))
        dobj = float(y[-1])
        rp = b - fb.apply(X)
        res_p = float(np.abs(rp).max())
        if not np.all(np.isfinite([gap, pobj, dobj, res_p])):
            words = "a non-finite iterate"
            break
        if _gap_closed(pobj, dobj, opts) and res_p <= opts.tol_feas:
            status = "optimal"
            break
        if opts.polish_gap > 0 and pobj - dobj <= opts.polish_gap:
            pol = polish(C, fb, X, y)
            if _DEBUG:
                print(it, pobj - dobj, pol and (pol.cost - pol.bound, pol.lambda_min, pol.lambda_2))
            if pol is not None and _gap_closed(pol.cost, pol.bound, opts) \
                    and pol.lambda_2 >= opts.polish_min_eig:
                status, polished = "optimal", pol
                break
        if it == opts.max_iter:
            words = f"the iteration limit ({opts.max_iter})"
            break
        try:
            dX, dy, ap_max, ad_max = _nt_step(fb, X, Lx, Ls, rp, gap / d)
        except (np.linalg.LinAlgError, ValueError, ArithmeticError) as exc:
            words = f"the Newton system could not be solved ({exc})"
            break
        frac = 0.9 + 0.09 * min(1.0, ap_max, ad_max)
        ap = min(1.0, frac * ap_max)
        ad = min(1.0, frac * ad_max)
        X_new = _sym(X + ap * dX)
        Lx_new = _chol(X_new)
        while Lx_new is None and ap > 1e-12:  # rounding at the boundary: step back
            ap *= 0.5
            X_new = _sym(X + ap * dX)
            Lx_new = _chol(X_new)
        for _ in range(8):  # the dual iterate is y; S is recomputed from it and must factor
            y_new = y + ad * dy
            S_new = C - fb.adjoint(y_new)
            Ls_new = _chol(S_new)
            if Ls_new is not None:
                break
            ad *= 0.5
        else:
            words = "the dual step could not keep S positive definite"
            break
        it += 1
        if ap < 1e-10 and ad < 1e-10:
            words = "the steps stalled"
            break
        if Lx_new is None:
            words = "the primal iterate lost positive definiteness"
            break
        X, y, S, Ls, Lx = X_new, y_new, S_new, Ls_new, Lx_new
    total = time.perf_counter() - t0
    y_out = polished.y if polished is not None else y
    if trace is not None:
        trace.append(IpmTrace(pobj, dobj, gap, res_p, polished is not None,
                              polished.cost if polished is not None else float("nan"), X,
                              C - fb.adjoint(y_out)))
    notes = []
    if polished is not None:
        notes.append(f"the structured SDP solver closed the gap at the refined rounding of its "
                     f"iterate {it} (interior-point gap {pobj - dobj:.2g}, polished gap "
                     f"{polished.cost - polished.bound:.2g})")
    elif status != "optimal":
        notes.append(f"the structured SDP solver stopped before its tolerances ({words}; gap "
                     f"{pobj - dobj:.2g}, primal residual {res_p:.2g}); its multipliers are used "
                     "only if the certificate proves the bound")
    return DualSolution(lam=fb.full_multipliers(y_out), status=status, compile_s=0.0,
                        solve_s=total, iterations=it, total_s=total, warnings=notes)


#: The structured method is chosen by ``backend="auto"`` when :func:`structured_cost` is at
#: most this times Clarabel's estimated cost of its cheapest form
#: (:func:`rwhec_ros.core.sparsity.estimate_form_costs`): the ratio of their measured seconds
#: per unit of estimated cost (see ``docs/sdp.md``).
STRUCTURED_COST_RATIO = 0.8


def structured_cost(n_frames: int) -> float:
    """Relative cost of one iteration of the structured method on ``n`` frames: ``d^3 + m^3 /
    3`` (the dense factorisations of size ``d = 9 n + 1`` and the Cholesky factorisation of the
    Schur complement of size ``m = 20 n + 1``), in the units of
    :func:`~rwhec_ros.core.sparsity.cone_cost`."""
    d, m = 9 * n_frames + 1, 20 * n_frames + 1
    return float(d) ** 3 + float(m) ** 3 / 3.0


def structured_is_cheaper(n_frames: int, clarabel_cost: float) -> bool:
    """Whether ``backend="auto"`` takes the structured method (:data:`STRUCTURED_COST_RATIO`)."""
    return structured_cost(n_frames) <= STRUCTURED_COST_RATIO * clarabel_cost
