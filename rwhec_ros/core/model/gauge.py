"""Translations (and scale) the data do not determine, and the prior that fixes them.

The translations enter the MLE cost (eq. (33)) through the block ``Q_ee`` of ``Q`` (eq. (42))
that the Schur reduction (eq. (47)-(48)) inverts: ``e`` = the translations ``t`` of every frame,
and ``alpha`` too for unknown scale. Its eigenvectors are the directions of the translations
and their eigenvalues ``w`` the information the data carry about them: the negative
log-likelihood is ``x^T Q x``, its Hessian ``2 Q``, so the predicted standard deviation of the
translations along an eigenvector is ``1 / sqrt(2 w)`` metres. The block depends on the pose
stream's rotations ``R_A`` and on ``sigma`` only, not on the measurements ``B``.

A direction is **unobservable** when its predicted standard deviation exceeds
``max_std_m`` (the data do not determine it usefully) or its eigenvalue is below
``w_max / max_condition`` (the Schur reduction could not be computed reliably in floating point).
The classic case is motion about one axis (paper Section 6): a ground robot that only yaws, or an
arm turning one joint. Then ``R_A a = a`` for the axis ``a`` and moving every translation by the
same amount along ``a`` leaves each residual ``R_A t_X + t_A - t_Y - R_Y t_B`` unchanged: the
heights of the cameras relative to the tags are not observable.

Such directions are fixed by a **prior** and the certificate then applies to the problem with
the prior (a MAP problem, cf. paper Section 9.2): for the unobservable coordinates
``omega = V_w^T t`` the value that best satisfies the user's :class:`TranslationPrior` s (known
components of a frame's translation, e.g. a camera's height), in least squares given the
observable part ``P_obs t``, or -- for what no user prior pins -- the documented default: the
camera (Y) frames' translations along the direction are zero on average (then the tag (X)
frames'). This rule is linear, ``omega = K (c - P^T P_obs t)``, so the constraint
``(V_w^T + K P^T P_obs) t = K c`` is imposed as the quadratic penalty
``rho |G t - b h|^2`` (``h`` the homogenising variable: ``s = 1`` for known scale, ``alpha``
for unknown scale, whose translations are ``alpha t``), with ``rho`` the largest eigenvalue of
``Q_ee``. The penalty vanishes for every observable configuration once ``omega`` follows the
rule, so it does not bias the observable part beyond what the tiny information along the
unobservable direction would.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from ..problem import Problem
from .cost import StateLayout

__all__ = [
    "TranslationPrior",
    "GaugeOptions",
    "UnobservableDirection",
    "GaugeFix",
    "find_unobservable_directions",
    "unobservable_directions_of_block",
    "build_gauge_fix",
    "axis_words",
]

_AXIS_NAMES = ("x", "y", "z")


@dataclass(frozen=True)
class TranslationPrior:
    """A known component of a frame's translation: ``axis . t_frame = value_m``.

    Attributes
    ----------
    frame : str
        Name of an X or Y frame of the problem.
    axis : ndarray, shape (3,)
        Unit vector in the frame's parent (its carrier: X frames in the tag carrier, Y frames in
        the camera carrier); ``0, 1, 2`` (or ``"x"``, ``"y"``, ``"z"``) for a coordinate axis.
    value_m : float
        The component in metres.
    """

    frame: str
    axis: np.ndarray
    value_m: float

    def __post_init__(self) -> None:
        ax = self.axis
        if isinstance(ax, str):
            if ax not in _AXIS_NAMES:
                raise ValueError(f"prior {self.frame}: axis must be x, y or z, got {ax!r}")
            ax = _AXIS_NAMES.index(ax)
        if isinstance(ax, (int, np.integer)):
            if not 0 <= int(ax) <= 2:
                raise ValueError(f"prior {self.frame}: axis index must be 0, 1 or 2, got {ax}")
            vec = np.zeros(3)
            vec[int(ax)] = 1.0
        else:
            vec = np.asarray(ax, dtype=float).reshape(-1)
            if vec.shape != (3,) or not np.all(np.isfinite(vec)) or np.linalg.norm(vec) < 1e-9:
                raise ValueError(f"prior {self.frame}: axis must be a non-zero 3-vector, got "
                                 f"{np.asarray(ax).tolist()}")
            vec = vec / np.linalg.norm(vec)
        if not np.isfinite(self.value_m):
            raise ValueError(f"prior {self.frame}: value_m must be finite, got {self.value_m!r}")
        object.__setattr__(self, "axis", vec)
        object.__setattr__(self, "value_m", float(self.value_m))


@dataclass
class GaugeOptions:
    """When a translation direction counts as unobservable.

    Attributes
    ----------
    max_std_m : float
        Largest predicted standard deviation [m] of the translations along a direction (from the
        stated noise) for it to count as determined by the data (1.0 m).
    max_condition : float
        Largest ratio ``w_max / w`` of the translation block's eigenvalues that the Schur reduction
        and its error bound handle in double precision (1e8); weaker directions are treated as
        unobservable whatever ``max_std_m`` says.
    priors : tuple of TranslationPrior
        Known translation components used to fix unobservable directions.
    """

    max_std_m: float = 1.0
    max_condition: float = 1e8
    priors: tuple[TranslationPrior, ...] = ()

    def __post_init__(self) -> None:
        if not (np.isfinite(self.max_std_m) and self.max_std_m > 0):
            raise ValueError(f"max_std_m: must be finite and > 0, got {self.max_std_m!r}")
        if not (np.isfinite(self.max_condition) and self.max_condition > 1):
            raise ValueError(f"max_condition: must be finite and > 1, got {self.max_condition!r}")
        self.priors = tuple(self.priors)
        for i, p in enumerate(self.priors):
            if not isinstance(p, TranslationPrior):
                raise ValueError(f"priors[{i}]: expected TranslationPrior, got {type(p).__name__}")


@dataclass
class UnobservableDirection:
    """A direction of the translations (and scale) that the data do not determine.

    Attributes
    ----------
    components : dict of str to ndarray (3,)
        Per frame, its part of the unit direction (in the frame's parent); frames whose part is
        negligible (< 1e-3) are left out.
    std_m : float
        Predicted standard deviation along the direction from the data alone (``inf`` when the
        data carry no information at all).
    involves_scale : bool
        The unknown scale ``alpha`` is part of the direction (unknown scale only): the scale is
        not determined either.
    fixed_by : str
        ``"prior"`` when the user's priors pin it, else ``"default"``.
    value_m : float
        After the solve: the component ``V^T t`` of the returned translations along the direction.
    """

    components: dict[str, np.ndarray]
    std_m: float
    involves_scale: bool = False
    fixed_by: str = "default"
    value_m: float = float("nan")

    def frames(self) -> list[str]:
        return list(self.components)

    def component_of(self, translations: dict[str, np.ndarray]) -> float:
        """The component along this direction (its translation part, normalised) of the frames'
        translations ``{name: t (3,)}``, in metres."""
        norm2 = sum(float(v @ v) for v in self.components.values())
        if norm2 <= 0.0:
            return float("nan")
        return float(sum(v @ np.asarray(translations[n], float)
                         for n, v in self.components.items() if n in translations)
                     / np.sqrt(norm2))

    def describe(self, x_parent: str = "the tag carrier", y_parent: str = "the camera carrier",
                 x_names: tuple[str, ...] = (), parents: dict[str, str] | None = None) -> str:
        """One sentence in words, e.g. ``translation along rig z of cam0, cam1 and along world z
        of tag_0 not determined by the data (predicted std 3.1e+03 m)``. ``parents`` (frame ->
        name of its carrier) overrides ``x_parent``/``y_parent``."""
        groups: dict[tuple[str, str], list[str]] = {}
        # cameras (Y) first, then tags (X), each in problem order
        ordered = sorted(self.components.items(), key=lambda kv: kv[0] in x_names)
        for name, vec in ordered:
            parent = x_parent if name in x_names else y_parent
            if parents and name in parents:
                parent = parents[name]
            groups.setdefault((parent, axis_words(vec)), []).append(name)
        parts = [f"along {parent} {axis} of {', '.join(names)}"
                 for (parent, axis), names in groups.items()]
        std = "no information" if not np.isfinite(self.std_m) else \
            f"predicted std {self.std_m:.3g} m"
        text = "translation " + " and ".join(parts) + f" not determined by the data ({std})"
        if self.involves_scale:
            text += "; the scale is not determined either"
        return text

    def to_dict(self) -> dict:
        return {
            "frames": {k: [float(x) for x in v] for k, v in self.components.items()},
            "std_m": float(self.std_m) if np.isfinite(self.std_m) else None,
            "involves_scale": bool(self.involves_scale),
            "fixed_by": self.fixed_by,
            "value_m": float(self.value_m),
        }


def axis_words(vec: np.ndarray) -> str:
    """``"z"``, ``"-x"`` for a vector within 2 deg of a coordinate axis, else the rounded vector."""
    v = np.asarray(vec, float)
    v = v / max(np.linalg.norm(v), 1e-300)
    i = int(np.argmax(np.abs(v)))
    if abs(v[i]) >= np.cos(np.deg2rad(2.0)):
        return ("-" if v[i] < 0 else "") + _AXIS_NAMES[i]
    # + 0.0 turns -0.0 into 0.0, and a component that rounds to zero prints without a sign
    return "[" + ", ".join("+0.00" if round(x, 2) == 0 else f"{x + 0.0:+.2f}" for x in v) + "]"


def _eliminated(layout: StateLayout, unknown_scale: bool) -> np.ndarray:
    """Indices of the block the Schur reduction eliminates: ``t`` (and ``alpha``)."""
    n_t = layout.n_t
    return np.arange(n_t + 1) if unknown_scale else np.arange(n_t)


def _block(Q, idx: np.ndarray):
    """``Q[idx][:, idx]``, symmetrised: dense, or sparse CSR for a sparse ``Q`` above
    :data:`SPARSE_MIN_SIZE` entries."""
    if sp.issparse(Q):
        E = sp.csr_matrix(Q)[idx][:, idx]
        if idx.size <= SPARSE_MIN_SIZE:
            E = E.toarray()
    else:
        E = np.asarray(Q, float)[np.ix_(idx, idx)]
    return 0.5 * (E + E.T)


#: Translation blocks with more entries than this (and a sparse ``Q``) are analysed with a sparse
#: ``L D L^T`` factorisation and shift-invert Lanczos instead of a dense Cholesky factorisation and
#: eigendecomposition (1,000 cameras: 3,003 entries; a dense ``eigh`` would take seconds and
#: ``eigh`` of 9,003 entries (3,000 cameras) minutes).
SPARSE_MIN_SIZE = 1500


def _positive_definite(E, tau: float) -> bool:
    """Whether ``E - tau I`` has a (floating-point) Cholesky / ``L D L^T`` factorisation with
    positive pivots."""
    if sp.issparse(E):
        from ..numerics.sparse_ldl import FactorizationError, SparseLDL, upper_with_diagonal

        try:
            return SparseLDL(upper_with_diagonal(E - tau * sp.eye(E.shape[0]))).positive_definite
        except FactorizationError:
            return False
    if not E.size:
        return True
    # LAPACK potrf as scipy.linalg.cholesky calls it, without its look-ups: info 0 = factored
    _, info = scipy.linalg.lapack.dpotrf(E - tau * np.eye(E.shape[0]), lower=False,
                                         overwrite_a=True)
    return info == 0


def _weak_eigenpairs(E, opts: GaugeOptions, info_floor: float
                     ) -> tuple[np.ndarray, np.ndarray, float]:
    """Eigenpairs of ``E`` below the thresholds of :class:`GaugeOptions`, and ``w_max``. Dense:
    ``eigh``; sparse: the largest eigenvalue by Lanczos and the smallest by shift-invert Lanczos
    around ``-thr`` (``E + thr I`` factored), asking for more until one above the threshold shows
    (so none is missed)."""
    if not sp.issparse(E):
        w, V = np.linalg.eigh(E)
        w_max = float(max(w[-1], 0.0)) if w.size else 0.0
        weak = (w <= w_max / opts.max_condition) | (w < info_floor)
        return w[weak], V[:, weak].copy(), w_max
    import scipy.sparse.linalg as spla

    from ..numerics.sparse_ldl import SparseLDL, upper_with_diagonal
    from ..numerics.verified import lanczos_start

    m = E.shape[0]
    w_top = spla.eigsh(E, k=1, which="LA", tol=1e-8, return_eigenvectors=False,
                       v0=lanczos_start(m))
    w_max = float(max(w_top[0], 0.0))
    thr = max(w_max / opts.max_condition, info_floor)
    factor = SparseLDL(upper_with_diagonal(E + thr * sp.eye(m)))
    op = spla.LinearOperator((m, m), matvec=factor.solve, dtype=float)
    k = min(6, m - 1)
    while True:
        w, V = spla.eigsh(E, k=k, sigma=-thr, which="LM", OPinv=op, v0=lanczos_start(m))
        order = np.argsort(w)
        w, V = w[order], V[:, order]
        weak = (w <= w_max / opts.max_condition) | (w < info_floor)
        if not weak.all() or k >= min(m - 1, 48):
            return w[weak], V[:, weak].copy(), w_max
        k = min(2 * k, m - 1, 48)


def find_unobservable_directions(
    Q, layout: StateLayout, problem: Problem, options: GaugeOptions | None = None
) -> tuple[np.ndarray, np.ndarray, list[UnobservableDirection], float]:
    """Eigen-analysis of the translation block ``Q_ee`` of the unscaled ``Q`` (eq. (42)).

    Returns ``(V_w, w_w, directions, w_max)``: the unobservable unit directions (m, k) over the
    eliminated variables (``m = 3 (M + P)``, ``+ 1`` with unknown scale: ``alpha`` last), their
    eigenvalues (k,), their descriptions, and the largest eigenvalue of ``Q_ee`` (an upper
    bound on it when no direction is weak: the eigendecomposition is skipped when a Cholesky
    factorisation shows every eigenvalue above both thresholds). Above
    :data:`SPARSE_MIN_SIZE` entries (sparse ``Q``) the same is done with sparse factorisations and
    Lanczos (large rigs).
    """
    idx = _eliminated(layout, problem.unknown_scale)
    return unobservable_directions_of_block(_block(Q, idx), problem, options)


def unobservable_directions_of_block(
    E, problem: Problem, options: GaugeOptions | None = None
) -> tuple[np.ndarray, np.ndarray, list[UnobservableDirection], float]:
    """:func:`find_unobservable_directions` on the translation block ``E = Q_ee`` itself
    (m, m), dense or (above :data:`SPARSE_MIN_SIZE` entries) sparse: ``m = 3 (M + P)``
    translations (``alpha t`` for unknown scale) and then ``alpha`` (unknown scale only), as the
    Schur reduction eliminates them."""
    opts = options or GaugeOptions()
    E = sp.csr_matrix(E) if sp.issparse(E) else np.asarray(E, float)
    E = 0.5 * (E + E.T)
    info_floor = 1.0 / (2.0 * opts.max_std_m**2)
    # quick exit (the usual case): E - tau I positive definite with tau above both thresholds,
    # using an upper bound on w_max (largest absolute row sum), so no eigenvalue can be weak
    w_max_ub = float(np.asarray(abs(E).sum(axis=1)).max(initial=0.0))
    tau = max(info_floor, w_max_ub / opts.max_condition)
    if _positive_definite(E, tau):
        return np.zeros((E.shape[0], 0)), np.zeros(0), [], w_max_ub
    w_w, V_w, w_max = _weak_eigenpairs(E, opts, info_floor)
    names = problem.frame_names
    directions = []
    for i in range(V_w.shape[1]):
        v = V_w[:, i]
        # canonical sign: the largest-magnitude translation entry positive
        big = int(np.argmax(np.abs(v[: 3 * len(names)])))
        if v[big] < 0:
            v = -v
            V_w[:, i] = v
        comps = {}
        for f, name in enumerate(names):
            part = v[3 * f: 3 * f + 3]
            if np.linalg.norm(part) >= 1e-3:
                comps[name] = part.copy()
        std = 1.0 / np.sqrt(2.0 * w_w[i]) if w_w[i] > 0 else float("inf")
        involves_scale = bool(problem.unknown_scale and abs(v[-1]) > 0.1)
        directions.append(UnobservableDirection(comps, float(std), involves_scale))
    return V_w, w_w, directions, w_max


@dataclass
class GaugeFix:
    """The penalty ``rho |G t - b h|^2`` that fixes the unobservable directions (module docstring).

    Attributes
    ----------
    directions : list of UnobservableDirection
    G : ndarray, shape (k, 3 (M + P))
        Rows of the linear rule on the (metric, or ``alpha``-scaled) translations.
    b : ndarray, shape (k,)
        Its right-hand side (metres).
    rho : float
        Weight of the penalty.
    V_w : ndarray, shape (3 (M + P), k)
        The unobservable directions (translation part, orthonormal).
    pinned : bool
        Every direction is pinned by user priors (not only by the default rule).
    prior_rows : list of (TranslationPrior, ndarray (3 (M + P),))
        The user priors as linear functionals on ``t``.
    notes : list of str
        What was fixed and how, in words.
    """

    directions: list[UnobservableDirection]
    G: np.ndarray
    b: np.ndarray
    rho: float
    V_w: np.ndarray
    pinned: bool
    prior_rows: list = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def empty(self) -> bool:
        return not self.directions

    @property
    def has_penalty(self) -> bool:
        return self.G.shape[0] > 0

    def penalty_matrix(self, layout: StateLayout) -> sp.csr_matrix:
        """The penalty as a quadratic form on the state ``x`` of eq. (44) (sparse, size of Q)."""
        n_t, h = layout.n_t, layout.alpha
        k = self.G.shape[0]
        Gx = np.zeros((k, n_t + 1))
        Gx[:, :n_t] = self.G
        Gx[:, n_t] = -self.b  # h sits right after the translations (index alpha = n_t)
        blk = self.rho * (Gx.T @ Gx)
        idx = np.r_[np.arange(n_t), h]
        rows = np.repeat(idx, idx.size)
        cols = np.tile(idx, idx.size)
        return sp.csr_matrix((blk.ravel(), (rows, cols)), shape=(layout.size, layout.size))

    def penalty_value(self, t: np.ndarray, h: float = 1.0) -> float:
        """``rho |G (h t) - b h|^2`` for metric translations ``t`` (n, 3) and homogeniser ``h``
        (``alpha`` for unknown scale, whose state holds ``alpha t``)."""
        r = h * (self.G @ np.asarray(t, float).reshape(-1) - self.b)
        return float(self.rho * r @ r)

    def penalty_error(self, t: np.ndarray, h: float = 1.0) -> float:
        """A proven bound on the rounding of :meth:`penalty_value` (same arguments): entry ``i``
        of ``r`` is off by at most ``gamma_{m+2} |h| (|G| |t| + |b|)_i`` (``m`` columns of
        ``G``), so the value is within ``rho (2 |r| e + e^2)`` of the exact one plus
        ``gamma_{m+3}`` of itself; the bound's own rounding is covered by ``1 + 1e-6``."""
        from ..numerics.verified import gamma

        tv = np.asarray(t, float).reshape(-1)
        r = h * (self.G @ tv - self.b)
        m = self.G.shape[1]
        e = float(np.linalg.norm(gamma(m + 2) * abs(h) * (np.abs(self.G) @ np.abs(tv)
                                                          + np.abs(self.b))))
        value = float(self.rho * r @ r)
        err = (abs(self.rho) * e * (2.0 * float(np.linalg.norm(r)) + e)
               + gamma(m + 3) * abs(value)) * (1.0 + 1e-6)
        return err if np.isfinite(err) else float("inf")


def build_gauge_fix(
    problem: Problem,
    V_w: np.ndarray,
    w_w: np.ndarray,
    directions: list[UnobservableDirection],
    w_max: float,
    priors: tuple[TranslationPrior, ...] = (),
) -> GaugeFix:
    """The penalty fixing ``directions`` by the user's ``priors`` and the default rule.

    Raises ``ValueError`` for a prior on a frame the problem does not have.
    """
    n = problem.n_frames
    n_t = 3 * n
    names = problem.frame_names
    index = {name: i for i, name in enumerate(names)}
    # the translation parts of the directions (the alpha part dropped for unknown scale) and an
    # orthonormal basis of their span: with unknown scale there can be more directions than
    # translation dimensions, and a direction of the scale alone has no translation part
    T_parts = V_w[:n_t]
    if T_parts.shape[1]:
        U, sv, _ = np.linalg.svd(T_parts, full_matrices=False)
        Vt = U[:, sv > 1e-6 * max(float(sv.max(initial=0.0)), 1e-300)]
    else:
        Vt = np.zeros((n_t, 0))
    k = Vt.shape[1]
    rows, vals = [], []
    prior_rows = []
    for i, p in enumerate(priors):
        if p.frame not in index:
            raise ValueError(f"priors[{i}]: unknown frame {p.frame!r}; frames: {list(names)}")
        row = np.zeros(n_t)
        f = index[p.frame]
        row[3 * f: 3 * f + 3] = p.axis
        rows.append(row)
        vals.append(p.value_m)
        prior_rows.append((p, row))
    n_user = len(rows)
    if k == 0:
        return GaugeFix(list(directions), np.zeros((0, n_t)), np.zeros(0), 0.0, Vt,
                        not directions, prior_rows)
    # The rule's rows P: the user's priors (weight 1), then the default rule -- camera (Y)
    # frames' translations zero on average along the direction, then the tag (X) frames' (a far
    # smaller weight, so it only decides what the cameras cannot): one identity row per
    # coordinate, kept implicit (P_d = I, A_d = P_d V = V) so that nothing of size n_t^2 is formed.
    P_u = np.array(rows).reshape(n_user, n_t)
    c_u = np.array(vals)
    A_u = P_u @ Vt  # (n_user, k)
    pinned = False
    if n_user:
        s = np.linalg.svd(A_u, compute_uv=False)
        pinned = bool(s.size >= k and s[k - 1] >= 1e-3)
    Mk = A_u.T @ A_u
    W_d = np.zeros(n_t)
    if not pinned:  # otherwise the user's priors alone decide (no pull towards the default)
        W_d = np.repeat(np.where(np.arange(n) >= problem.M, 1e-6, 1e-12), 3)
        Mk = Mk + Vt.T @ (W_d[:, None] * Vt)
    K_u = np.linalg.solve(Mk, A_u.T)  # (k, n_user)
    K_d = np.linalg.solve(Mk, (Vt * W_d[:, None]).T)  # (k, n_t)
    # G = V^T + K P P_obs with P_obs = I - V V^T: K P - (K A) V^T, without forming P_obs
    KP = K_u @ P_u + K_d
    KA = K_u @ A_u + K_d @ Vt
    G = Vt.T + KP - KA @ Vt.T
    b = K_u @ c_u
    notes = []
    for i, d in enumerate(directions):
        t_part = T_parts[:, i] / max(float(np.linalg.norm(T_parts[:, i])), 1e-300)
        by_user = n_user and np.linalg.norm(P_u @ t_part) >= 1e-3
        d.fixed_by = "prior" if pinned or by_user else "default"
    rho = float(max(w_max, 1.0))
    return GaugeFix(directions, G, b, rho, Vt, pinned, prior_rows, notes)
