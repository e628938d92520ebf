"""The SDP relaxation of generalized RWHEC: the dual Problem 7 with the redundant SO(3)
constraints of eq. (50), solved with cvxpy + Clarabel (paper Section 5, Algorithm 1).

The homogenised variable is ``z = [..., vec(R_1), ..., vec(R_n), ..., s]`` with ``s^2 = 1``. Every
SO(3) constraint of eq. (50) is a homogeneous quadratic form ``z^T A_c z = 0``:

* (50a) ``R R^T = s^2 I``   (6 per rotation),
* (50b) ``R^T R = s^2 I``   (6 per rotation),
* (50c) ``R_a x R_b = s R_c`` for the cyclic (a, b, c)  (9 per rotation),

and ``s^2 = 1`` is ``z^T E_ss z = 1``. The Lagrangian dual (Problem 7) is::

    max lambda_s   s.t.   Z(lambda) = Q - lambda_s E_ss - sum_c lambda_c A_c  >=  0,

eq. (51)-(56) (``P_1``, ``P_2`` of eqs. (52)-(55) are these ``sum lambda_c A_c`` written out).
``Z(lambda)`` is formed as ONE cvxpy expression ``Q - reshape(C @ lambda)`` from a sparse constant
``C`` whose columns are ``vec(A_c)``, which keeps cvxpy's compile time small.

Two forms are supported:

* ``reduced``: ``Q'`` of eq. (48) on ``[vec R; s]`` (translations eliminated): smallest PSD block,
  dense when several Y share targets (paper Fig. 4).
* ``full``: ``Q`` of eq. (42) on ``[t; (alpha); vec R; s]``: larger but as sparse as the graph,
  which Clarabel's chordal decomposition exploits.
* ``arrow``: ``Q'`` again, with the PSD constraint on ``Z(lambda)`` written as one cone for the
  hub rotations and ``s`` plus one cone of size <= 19 per leaf rotation (an exact
  reformulation, :mod:`rwhec_ros.core.certify.sparsity`); on a target/camera graph the targets are
  the leaves, whatever the number of cameras each is seen by.

All give the same optimum; certification is always done on the reduced form (rotation
constraints do not involve translations, so the Schur complement of ``Z_full`` over the
translation block is ``Z_reduced`` with the same multipliers).
"""

from __future__ import annotations

import functools
import time
import warnings
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp

from .sparsity import ArrowSplit

__all__ = [
    "so3_constraint_matrices",
    "frame_constraints",
    "ConstraintSet",
    "DualSolution",
    "SdpOptions",
    "SDP_BACKENDS",
    "solve_dual_sdp",
    "solve_dual_sdp_arrow",
    "evaluate_Z",
]

_CYCLIC = ((0, 1, 2), (1, 2, 0), (2, 0, 1))

#: Accepted values of :attr:`SdpOptions.form`.
SDP_FORMS = ("auto", "reduced", "full", "arrow")
#: Accepted values of :attr:`SdpOptions.backend`.
SDP_BACKENDS = ("auto", "structured", "cvxpy")


@dataclass(frozen=True)
class ConstraintSet:
    """Homogeneous constraint matrices of eq. (50) for rotations at given offsets of ``z``.

    Attributes
    ----------
    C : scipy.sparse.csc_matrix, shape (d * d, m)
        Column ``c`` is ``vec(A_c)`` (symmetric ``A_c``); the LAST column is ``E_ss``.
    d : int
        Size of ``z``.
    s_index : int
        Index of the homogenising variable ``s`` in ``z``.
    n_rotations : int
    """

    C: sp.csc_matrix
    d: int
    s_index: int
    n_rotations: int

    @property
    def m(self) -> int:
        return self.C.shape[1]

    def apply(self, lam: np.ndarray) -> np.ndarray:
        """``lambda_s E_ss + sum_c lambda_c A_c`` as a dense (d, d) matrix."""
        return np.asarray(self.C @ lam).reshape(self.d, self.d, order="F")

    @functools.cached_property
    def abs_C(self) -> sp.csc_matrix:
        """``|C|`` entrywise (for rounding bounds; computed once per set)."""
        return abs(self.C)

    @functools.cached_property
    def max_terms(self) -> int:
        """The largest number of constraints touching one entry of ``z z^T`` (nonzeros in a row
        of ``C``, at least 1): the length of the dot products that form ``K(lambda)``."""
        return int(np.diff(self.C.tocsr().indptr).max(initial=1))


def _one_rotation_pattern() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Entries ``(p, q, value, constraint)`` of the 21 constraint matrices of one rotation with
    ``vec(R)`` at local indices 0..8 and ``s`` at local index 9 (symmetric entries split in
    halves), in the order (50a) rows ``i <= j``, (50b) columns ``a <= b``, (50c) cyclic ``(a, b,
    c)`` and component ``k``."""
    P: list[int] = []
    Qi: list[int] = []
    V: list[float] = []
    Ci: list[int] = []
    s = 9

    def add(p: int, q: int, v: float, con: int) -> None:
        if p == q:
            P.append(p)
            Qi.append(p)
            V.append(v)
            Ci.append(con)
        else:
            P.extend((p, q))
            Qi.extend((q, p))
            V.extend((0.5 * v, 0.5 * v))
            Ci.extend((con, con))

    idx = lambda i, c: 3 * c + i  # noqa: E731
    con = 0
    for i in range(3):  # (50a) R R^T = s^2 I: rows i, j
        for j in range(i, 3):
            for c in range(3):
                add(idx(i, c), idx(j, c), 1.0, con)
            if i == j:
                add(s, s, -1.0, con)
            con += 1
    for a in range(3):  # (50b) R^T R = s^2 I: columns a, b
        for b in range(a, 3):
            for i in range(3):
                add(idx(i, a), idx(i, b), 1.0, con)
            if a == b:
                add(s, s, -1.0, con)
            con += 1
    for a, b, c in _CYCLIC:  # (50c) R_a x R_b - s R_c = 0, component k
        for k in range(3):
            k1, k2 = (k + 1) % 3, (k + 2) % 3
            add(idx(k1, a), idx(k2, b), 1.0, con)
            add(idx(k2, a), idx(k1, b), -1.0, con)
            add(s, idx(k, c), -1.0, con)
            con += 1
    return np.array(P), np.array(Qi), np.array(V), np.array(Ci)


_PATTERN = _one_rotation_pattern()


def so3_constraint_matrices(rotation_offsets: np.ndarray, d: int, s_index: int) -> ConstraintSet:
    """Build :class:`ConstraintSet` for rotations whose ``vec(R)`` starts at ``rotation_offsets``.

    Column-major ``vec``: ``R[i, c] = z[o + 3 c + i]``. 21 constraints per rotation (one of them
    linearly dependent on the others, harmless) plus ``s^2 = 1`` last. The entries of one
    rotation's constraints are built once and shifted to every offset.
    """
    offsets = np.asarray(rotation_offsets, dtype=int).reshape(-1)
    P, Qi, V, Ci = _PATTERN
    n = offsets.size
    gp = np.where(P[None, :] == 9, s_index, offsets[:, None] + P[None, :])
    gq = np.where(Qi[None, :] == 9, s_index, offsets[:, None] + Qi[None, :])
    rows = (gp * d + gq).ravel()
    cols = (21 * np.arange(n)[:, None] + Ci[None, :]).ravel()
    vals = np.tile(V, n)
    rows = np.concatenate([rows, [s_index * d + s_index]])  # s^2 = 1, last
    cols = np.concatenate([cols, [21 * n]])
    vals = np.concatenate([vals, [1.0]])
    C = sp.csc_matrix((vals, (rows, cols)), shape=(d * d, 21 * n + 1))
    C.sum_duplicates()
    return ConstraintSet(C=C, d=d, s_index=s_index, n_rotations=n)


@functools.lru_cache(maxsize=8)
def frame_constraints(n_frames: int) -> ConstraintSet:
    """:func:`so3_constraint_matrices` of ``n_frames`` rotations at offsets ``0, 9, ..`` of
    ``z = [vec R_1; ..; vec R_n; s]`` (``d = 9 n + 1``, ``s`` last): the constraint set of the
    reduced problem, which depends on the frame count only, so it is built once per count and
    shared (its arrays are read-only). The same matrix as a fresh build, entry for entry."""
    n = int(n_frames)
    d = 9 * n + 1
    cons = so3_constraint_matrices(np.arange(n) * 9, d, d - 1)
    for a in (cons.C.data, cons.C.indices, cons.C.indptr):
        a.flags.writeable = False
    return cons


@dataclass
class SdpOptions:
    """Options of the dual SDP solve.

    Attributes
    ----------
    clarabel : dict
        Settings passed to Clarabel through cvxpy (e.g. ``tol_gap_abs``, ``tol_gap_rel``,
        ``tol_feas``, ``max_iter``, ``chordal_decomposition_*``). Defaults are Clarabel's 1e-8
        tolerances, which on the scaled problem (optimum ~1) resolve ``rho_hat`` to ~1e-8, and
        iterative refinement of the KKT solves off: on the paper's 24-frame problem it cost a
        quarter of the time (reduced form, 54 s -> 40 s) without changing the certificate (rho_hat
        ~1e-12 either way); the certificate is checked independently of Clarabel's accuracy.
    form : str
        ``"reduced"`` (``Q'`` on the rotations), ``"full"`` (``Q`` with the translations kept;
        sparse, for Clarabel's chordal decomposition), ``"arrow"`` (``Q'`` with one small cone
        per target, :func:`solve_dual_sdp_arrow`) or ``"auto"`` (the cheapest by the cost
        model of :func:`rwhec_ros.core.certify.sparsity.estimate_form_costs`). Same optimum and
        multipliers. Used by the ``cvxpy`` backend; the structured one always solves the
        reduced form.
    backend : str
        ``"structured"`` (the interior-point method of
        :mod:`rwhec_ros.core.certify.sdp_ipm` on the frame blocks of the reduced form),
        ``"cvxpy"`` (cvxpy + Clarabel on ``form``) or ``"auto"`` (default: the structured method
        unless Clarabel's chordal decomposition is estimated cheaper,
        :func:`rwhec_ros.core.certify.sdp_ipm.structured_is_cheaper`).
    ipm : dict
        Options of the structured method (:class:`rwhec_ros.core.certify.sdp_ipm.IpmOptions`
        keywords).
    verbose : bool
    """

    form: str = "auto"
    backend: str = "auto"
    ipm: dict = field(default_factory=dict)
    clarabel: dict = field(
        default_factory=lambda: {
            "tol_gap_abs": 1e-8,
            "tol_gap_rel": 1e-8,
            "tol_feas": 1e-8,
            "max_iter": 200,
            "iterative_refinement_enable": False,
        }
    )
    verbose: bool = False

    def __post_init__(self) -> None:
        if self.form not in SDP_FORMS:
            raise ValueError(f"form: expected one of {SDP_FORMS}, got {self.form!r}")
        if self.backend not in SDP_BACKENDS:
            raise ValueError(f"backend: expected one of {SDP_BACKENDS}, got {self.backend!r}")


@dataclass
class DualSolution:
    """Solution of Problem 7 on scaled data: multipliers ``lam`` (m,) with ``lam[-1] =
    lambda_s``, the solver status string, compile/solve times in seconds, and the solver's
    warnings in words (never printed: the caller puts them in the result's notes)."""

    lam: np.ndarray
    status: str
    compile_s: float
    solve_s: float
    iterations: int
    total_s: float = 0.0
    warnings: list[str] = field(default_factory=list)

    @property
    def lambda_s(self) -> float:
        return float(self.lam[-1])


def evaluate_Z(Q: np.ndarray, constraints: ConstraintSet, lam: np.ndarray) -> np.ndarray:
    """``Z(lambda) = Q - lambda_s E_ss - sum lambda_c A_c`` (dense, symmetrised), eq. (51)."""
    Z = np.asarray(Q.toarray() if sp.issparse(Q) else Q, float) - constraints.apply(lam)
    return 0.5 * (Z + Z.T)


def solve_dual_sdp(
    Q: np.ndarray | sp.spmatrix, constraints: ConstraintSet, options: SdpOptions | None = None
) -> DualSolution:
    """Solve Problem 7 (``max lambda_s s.t. Z(lambda) >= 0``) with cvxpy + Clarabel.

    ``Q`` (d, d) should already be scaled (e.g. divided by an upper bound on the optimum).
    """
    import cvxpy as cp

    options = options or SdpOptions()
    d = constraints.d
    Qs = sp.csc_matrix(Q) if not sp.issparse(Q) else Q.tocsc()
    Qs = 0.5 * (Qs + Qs.T)
    t0 = time.perf_counter()
    lam = cp.Variable(constraints.m)
    Zexpr = Qs - cp.reshape(constraints.C @ lam, (d, d), order="F")
    # Z is symmetric by construction; the PSD cone reads its lower triangle.
    prob = cp.Problem(cp.Maximize(lam[constraints.m - 1]), [cp.PSD(Zexpr)])
    return _run(prob, lam, constraints.m, options, t0)


def _block(Q: np.ndarray, C: sp.csr_matrix, lam, rows: np.ndarray, cols: np.ndarray):
    """cvxpy expression of the block ``Z(lambda)[rows][:, cols]`` (affine in ``lam``); ``C`` is
    :attr:`ConstraintSet.C` in CSR form (row slicing)."""
    import cvxpy as cp

    d = Q.shape[0]
    vec = (rows[:, None] + d * cols[None, :]).ravel(order="F")  # column-major vec of the block
    return Q[np.ix_(rows, cols)] - cp.reshape(C[vec] @ lam, (rows.size, cols.size), order="F")


def solve_dual_sdp_arrow(
    Q: np.ndarray, constraints: ConstraintSet, split: ArrowSplit,
    options: SdpOptions | None = None,
) -> DualSolution:
    """Solve Problem 7 on the reduced ``Q'`` with the hub/leaf cones of ``split``.

    ``Z(lambda) >= 0`` is imposed as (see :mod:`rwhec_ros.core.certify.sparsity` for the proof)::

        [[Z_LjLj, Z_LjH Pi_j], [Pi_j^T Z_HLj, S_j]] >= 0   for every leaf j,
        Z_HH - sum_j Pi_j S_j Pi_j^T >= 0,

        with auxiliary symmetric S_j of size k_j + 1 <= 10.

    Same multipliers ``lambda`` and optimum as :func:`solve_dual_sdp`; the certificate is still
    evaluated on the whole ``Z(lambda)``.

    Parameters
    ----------
    Q : (d, d)
        Scaled ``Q'``, ``s`` last.
    constraints : ConstraintSet
        From :func:`so3_constraint_matrices` on the same ``z``.
    split : ArrowSplit
        From :func:`rwhec_ros.core.certify.sparsity.arrow_split` on ``Q``.
    """
    import cvxpy as cp

    options = options or SdpOptions()
    Qd = np.asarray(Q.toarray() if sp.issparse(Q) else Q, float)
    Qd = 0.5 * (Qd + Qd.T)
    C = constraints.C.tocsr()
    t0 = time.perf_counter()
    lam = cp.Variable(constraints.m)
    H = split.hub
    cones = []
    hub = _block(Qd, C, lam, H, H)
    for L, Pi in zip(split.leaves, split.bases, strict=True):
        k = Pi.shape[1]
        S = cp.Variable((k, k), symmetric=True)
        D = _block(Qd, C, lam, L, L)
        B = _block(Qd, C, lam, L, H) @ Pi
        cones.append(cp.PSD(cp.bmat([[D, B], [B.T, S]])))
        hub = hub - Pi @ S @ Pi.T
    cones.append(cp.PSD(hub))
    prob = cp.Problem(cp.Maximize(lam[constraints.m - 1]), cones)
    return _run(prob, lam, constraints.m, options, t0, ARROW_CLARABEL_DEFAULTS)


#: Clarabel settings of the arrow form unless :attr:`SdpOptions.clarabel` sets them: without
#: Ruiz equilibration it needed 16 instead of 20-21 iterations on the paper's real data (about
#: 6.5 s instead of 7.5-8.7 s on one core) and the same or fewer on most random graphs, all
#: certified (``benchmarks/sdp_forms.md``); the reduced form was slower without it.
ARROW_CLARABEL_DEFAULTS = {"equilibrate_enable": False}


def _run(prob, lam, m: int, options: SdpOptions, t0: float,
         defaults: dict | None = None) -> DualSolution:
    """Solve ``prob`` with Clarabel (``defaults`` overridden by ``options.clarabel``) and
    collect the multipliers, status and times."""
    import cvxpy as cp

    settings = {**(defaults or {}), **options.clarabel}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        prob.solve(solver=cp.CLARABEL, verbose=options.verbose, **settings)
    total = time.perf_counter() - t0
    solve_s = float(getattr(prob.solver_stats, "solve_time", None) or 0.0)
    compile_s = float(getattr(prob, "compilation_time", None) or max(total - solve_s, 0.0))
    value = lam.value
    status = str(prob.status)
    iters = int(getattr(prob.solver_stats, "num_iters", 0) or 0)
    if value is None:
        value = np.full(m, np.nan)
    notes = [_WARNING_WORDS.get(str(w.message).split(".")[0], str(w.message)) for w in caught]
    return DualSolution(lam=np.asarray(value, float), status=status, compile_s=compile_s,
                        solve_s=solve_s, iterations=iters, total_s=total,
                        warnings=list(dict.fromkeys(notes)))


#: cvxpy warnings in words for a user (the key is the warning's first sentence).
_WARNING_WORDS = {
    "Solution may be inaccurate": "the SDP solver (Clarabel) reached its iteration limit or "
    "reduced accuracy; its multipliers are used only if the certificate proves the bound",
}
