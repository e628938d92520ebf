"""Has a frame changed since a reference calibration? A test per frame, with its error rates.

In: the data (a :class:`~rwhec_ros.core.problem.Problem`), an estimate of its frames solved with
some frames *held* (conditioned on: the gauge) and the others *free*, and the reference value of
each frame to test (with its covariance when the reference has one). Out: per frame the change
``delta`` and its covariance, the chi-square (F) statistic of "no change", a confidence region
of the change and a decision against a tolerance: ``consistent``, ``moved`` or ``undecided``.

**The change.** For a frame ``T = (R, t)`` in its parent (the convention of
:mod:`rwhec_ros.core.analysis.uncertainty`): ``delta = [t_hat - t_ref, log(R_hat R_ref^T)]``
(m, rad: translation and rotation about the parent's axes), so ``T_hat = exp(delta) T_ref``.

**Its covariance.** The information of the data (:func:`~rwhec_ros.core.analysis.information.
information_matrix`, the exact Hessian of the negative log-likelihood) restricted to the free
frames' coordinates (and the unknown scale) is inverted: the covariance of the free frames
*given* the held ones (held = fixed variables). The noise is the noise the data show
(``noise="data"``): per camera, a variance factor for the translation and one for the rotation
residuals, ``s^2 = sum J / (3 n_k rho)`` with ``n_k`` the camera's pairs and
``rho = 1 - p / (6 N)`` the share of redundant residuals (``p`` free coordinates), scale the
camera's ``sigma^2`` and ``1 / kappa`` before the information is computed; ``noise="stated"``
keeps the stated noise. Directions the data do not determine (null directions of the
Jacobi-normalised information, as in :mod:`~rwhec_ros.core.analysis.uncertainty`) leave the axes
they touch untested. The reference's own covariance (per frame; correlations between reference
frames are not stored) is added: ``Sigma = C_new + C_ref``.

**The test.** On the ``r`` tested axes, ``W = delta^T Sigma^-1 delta``; under "no change"
``W / r`` is ``F(r, nu)``-distributed (``nu`` the camera's redundant residuals when the noise is
estimated, ``nu = inf``, chi-square, with the stated noise) to first order. The confidence
region ``{d : (d - delta)^T Sigma^-1 (d - delta) <= c}``, ``c = r F^-1(1 - a; r, nu)``, holds the
true change with probability ``1 - a``; its projections give bounds on the size of the change,
``|d_t|`` in ``[lo_t, hi_t]`` and ``|d_phi|`` in ``[lo_r, hi_r]`` (exact extremes of the norm over
an ellipsoid, :func:`norm_bounds`).

**The decision** against a tolerance ``(tol_t, tol_r)``:

* ``moved`` when ``lo_t > tol_t`` or ``lo_r > tol_r``: the whole region is beyond the tolerance;
* ``consistent`` when ``hi_t <= tol_t`` and ``hi_r <= tol_r``: the whole region is within it;
* ``undecided`` otherwise (not enough data yet: the region straddles the tolerance).

Both wrong decisions ("moved" for a change within the tolerance, "consistent" for one beyond it)
need the true change outside the region: each has probability at most ``a``. With ``tol = 0``
"moved" implies the level-``a`` test of "no change" rejects (``W > c``: the region excludes 0),
not conversely (the projections are coarser than the region). ``a`` is the family's rate
``alpha`` split by Bonferroni over the frames tested together and, for repeated looks at growing
data, spent over the looks (:func:`look_level`): the probability of any wrong decision, over all
frames and looks, is at most ``alpha`` (to the first order the test is exact to).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy import stats

from ..lie import so3_log
from ..problem import Edge, Problem
from .information import information_matrix, pair_residuals

__all__ = [
    "DECISIONS",
    "ChangeTolerance",
    "ChangeOptions",
    "FrameChange",
    "ChangeTest",
    "look_level",
    "norm_bounds",
    "decide",
    "noise_reweighted",
    "frame_changes",
]

#: The decisions of :func:`decide`.
DECISIONS = ("consistent", "moved", "undecided")
_NOISE = ("data", "stated")


@dataclass(frozen=True)
class ChangeTolerance:
    """The change a user accepts: translation [m] and rotation [deg] (defaults 2 mm, 0.2 deg)."""

    translation_m: float = 0.002
    rotation_deg: float = 0.2

    def __post_init__(self) -> None:
        for name in ("translation_m", "rotation_deg"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"tolerance {name}: must be finite and >= 0, got {v!r}")


@dataclass(frozen=True)
class ChangeOptions:
    """Options of :func:`frame_changes`.

    Attributes
    ----------
    tolerance : ChangeTolerance
    noise : str
        ``"data"`` (per camera translation and rotation variance factors from the residuals) or
        ``"stated"`` (the problem's ``sigma``, ``kappa`` as given).
    null_tol : float
        Eigenvalues of the Jacobi-normalised conditional information below this are directions
        the data do not determine (1e-8, as :class:`~rwhec_ros.core.analysis.uncertainty.
        UncertaintyOptions`).
    axis_tol : float
        An axis with a null direction's component of at least this is not tested (1e-3).
    min_variance_factor : float
        Floor of an estimated variance factor (1e-4): noise-free data would otherwise give a zero
        covariance.
    """

    tolerance: ChangeTolerance = field(default_factory=ChangeTolerance)
    noise: str = "data"
    null_tol: float = 1e-8
    axis_tol: float = 1e-3
    min_variance_factor: float = 1e-4

    def __post_init__(self) -> None:
        if self.noise not in _NOISE:
            raise ValueError(f"noise: expected one of {_NOISE}, got {self.noise!r}")
        for name in ("null_tol", "axis_tol", "min_variance_factor"):
            v = getattr(self, name)
            if not (np.isfinite(v) and 0 < v < 1):
                raise ValueError(f"{name}: must be in (0, 1), got {v!r}")


@dataclass
class FrameChange:
    """The change of one frame against its reference (module docstring).

    Attributes
    ----------
    name, role : str
        Frame name; ``"X"`` (target) or ``"Y"`` (camera).
    delta : ndarray, shape (6,)
        ``[dt (m), dphi (rad)]`` in the parent.
    covariance : ndarray, shape (6, 6)
        ``C_new + C_ref`` (NaN rows/columns on untested axes).
    tested : ndarray of bool, shape (6,)
        The axes the test uses (the data determine them and the reference has them).
    statistic : float
        ``W`` (NaN when no axis is tested).
    dof : int
        ``r``, the number of tested axes.
    residual_dof : float
        ``nu`` of the F distribution (``inf``: chi-square).
    p_value : float
        Of "no change".
    level : float
        ``a``: the error rate of this frame's decision (after Bonferroni and the looks).
    translation_m, rotation_deg : float
        ``|dt|`` and ``|dphi|`` (deg).
    translation_std_m, rotation_std_deg : float
        Their standard deviations (first order).
    translation_bounds_m, rotation_bounds_deg : (float, float)
        ``(lo, hi)`` of the confidence region (``hi = inf`` with an untested axis).
    decision : str
        ``consistent``, ``moved`` or ``undecided``.
    n_pairs : int
        Pairs of the data on this frame's edges.
    """

    name: str
    role: str
    delta: np.ndarray
    covariance: np.ndarray
    tested: np.ndarray
    statistic: float
    dof: int
    residual_dof: float
    p_value: float
    level: float
    translation_m: float
    rotation_deg: float
    translation_std_m: float
    rotation_std_deg: float
    translation_bounds_m: tuple[float, float]
    rotation_bounds_deg: tuple[float, float]
    decision: str
    n_pairs: int = 0

    def to_dict(self) -> dict:
        def num(v):
            v = float(v)
            return v if np.isfinite(v) else None

        return {
            "name": self.name, "role": self.role, "decision": self.decision,
            "translation_mm": num(1e3 * self.translation_m),
            "translation_std_mm": num(1e3 * self.translation_std_m),
            "rotation_deg": num(self.rotation_deg),
            "rotation_std_deg": num(self.rotation_std_deg),
            "translation_bounds_mm": [num(1e3 * v) for v in self.translation_bounds_m],
            "rotation_bounds_deg": [num(v) for v in self.rotation_bounds_deg],
            "delta": [num(v) for v in self.delta],
            "covariance": [[num(v) for v in row] for row in self.covariance],
            "tested_axes": [a for a, t in zip(("x", "y", "z", "rx", "ry", "rz"), self.tested,
                                              strict=True) if t],
            "statistic": num(self.statistic), "dof": int(self.dof),
            "residual_dof": num(self.residual_dof), "p_value": num(self.p_value),
            "level": float(self.level), "n_pairs": int(self.n_pairs),
        }


@dataclass
class ChangeTest:
    """:func:`frame_changes`' answer: per tested frame a :class:`FrameChange`, and the variance
    factors used (camera -> ``(translation, rotation)``; empty with the stated noise)."""

    frames: dict[str, FrameChange]
    variance_factors: dict[str, tuple[float, float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def look_level(alpha: float, look: int, *, sequential: bool = True) -> float:
    """The error rate spent at look ``look`` (1, 2, ...) of a family of rate ``alpha``:
    ``6 alpha / (pi^2 look^2)`` (the rates of all looks sum to ``alpha``: a union bound holds
    whatever the data and whenever one looks), or ``alpha`` for a single look
    (``sequential=False``)."""
    if not (np.isfinite(alpha) and 0 < alpha < 1):
        raise ValueError(f"false-alarm rate: must be in (0, 1), got {alpha!r}")
    if int(look) < 1:
        raise ValueError(f"look: must be >= 1, got {look!r}")
    return float(alpha) if not sequential else 6.0 * float(alpha) / (np.pi ** 2 * int(look) ** 2)


def norm_bounds(m: np.ndarray, S: np.ndarray, c: float) -> tuple[float, float]:
    """Smallest and largest ``|x|`` over the ellipsoid ``(x - m)^T S^-1 (x - m) <= c``.

    ``m`` (n,), ``S`` (n, n) symmetric positive definite, ``c >= 0``. With the eigenvalues ``s_i``
    of ``S`` and ``m`` in its eigenvectors, a stationary point of ``|x|^2`` on the boundary is
    ``x_i = m_i lam / (lam - s_i)`` with ``g(lam) = sum m_i^2 s_i / (lam - s_i)^2 = c``: the
    minimum (when ``m`` lies outside: ``m^T S^-1 m > c``; else 0) at the root ``lam < 0``, the
    maximum at the root ``lam > max s_i`` (both found by bisection on a monotone ``g``); when
    ``m`` has no component along the largest eigenvector the maximum is bounded by
    ``|m| + sqrt(c max s)`` instead (never smaller than the exact value).
    """
    m = np.asarray(m, float)
    s, U = np.linalg.eigh(0.5 * (S + S.T))
    s = np.maximum(s, 1e-300)
    mu = U.T @ m
    c = max(float(c), 0.0)

    def g(lam: float) -> float:
        return float(np.sum(mu ** 2 * s / (lam - s) ** 2))

    def x_norm(lam: float) -> float:
        return float(np.linalg.norm(mu * lam / (lam - s)))

    def bisect(a: float, b: float) -> float:  # g(a) > c > g(b) (decreasing) or increasing
        ga = g(a) - c
        for _ in range(200):
            mid = 0.5 * (a + b)
            if (g(mid) - c) * ga > 0:
                a = mid
            else:
                b = mid
        return 0.5 * (a + b)

    norm_m = float(np.linalg.norm(m))
    if float(np.sum(mu ** 2 / s)) <= c:
        lo = 0.0
    else:  # g increases from 0 (lam -> -inf) to m^T S^-1 m > c (lam = 0) on (-inf, 0]
        left = -1.0 * max(s.max(), 1e-300)
        while g(left) > c:
            left *= 2.0
        lo = x_norm(bisect(left, 0.0))
    top = s.max()
    along_top = float(np.sum(mu[s >= top * (1.0 - 1e-12)] ** 2))
    if along_top * top <= 1e-24 * max(norm_m ** 2 * top, 1e-300):
        return lo, norm_m + float(np.sqrt(c * top))
    right = top + max(top, 1e-300)
    while g(right) > c:
        right = top + 2.0 * (right - top)
    hi = x_norm(bisect(top * (1.0 + 1e-15) + 1e-300, right))
    return lo, max(hi, norm_m)


def decide(translation_bounds_m: tuple[float, float], rotation_bounds_deg: tuple[float, float],
           tolerance: ChangeTolerance) -> str:
    """``moved``, ``consistent`` or ``undecided`` (module docstring) from the bounds."""
    (lo_t, hi_t), (lo_r, hi_r) = translation_bounds_m, rotation_bounds_deg
    if lo_t > tolerance.translation_m or lo_r > tolerance.rotation_deg:
        return "moved"
    if hi_t <= tolerance.translation_m and hi_r <= tolerance.rotation_deg:
        return "consistent"
    return "undecided"


def _camera_pairs(problem: Problem) -> dict[str, np.ndarray]:
    """Per Y frame (camera), the indices of its pairs in ``problem.stacked()`` order."""
    counts = [e.n for e in problem.edges]
    starts = np.r_[0, np.cumsum(counts)[:-1]]
    out: dict[str, list[np.ndarray]] = {}
    for e, s in zip(problem.edges, starts, strict=True):
        out.setdefault(e.y, []).append(np.arange(s, s + e.n))
    return {k: np.concatenate(v) for k, v in out.items()}


def noise_reweighted(problem: Problem, X: np.ndarray, Y: np.ndarray, alpha: float,
                     n_free: int, *, floor: float = 1e-4
                     ) -> tuple[Problem, dict[str, tuple[float, float]]]:
    """``problem`` with each camera's ``sigma`` times ``s_t`` and ``kappa`` over ``s_r^2``: the
    per-camera translation and rotation variance factors of the residuals at the estimate
    ``(X, Y, alpha)`` (module docstring; ``n_free`` free coordinates, each factor floored at
    ``floor``). Returns the problem and camera -> ``(s_t^2, s_r^2)``."""
    st = problem.stacked()
    T = np.concatenate([np.asarray(X, float), np.asarray(Y, float)])
    a = float(alpha) if problem.unknown_scale else 1.0
    r_t, _ = pair_residuals(st["A"], st["B"], T[st["xi"]], T[problem.M + st["yi"]], a)
    RA, RB = st["A"][:, :3, :3], st["B"][:, :3, :3]
    RX, RY = T[st["xi"]][:, :3, :3], T[problem.M + st["yi"]][:, :3, :3]
    D = np.swapaxes(RA @ RX, 1, 2) @ RY @ RB
    chi_r = 2.0 * st["kappa"] * (3.0 - np.trace(D, axis1=1, axis2=2))
    chi_t = np.einsum("ni,ni->n", r_t, r_t) * a * a / st["sigma"] ** 2
    N = problem.n_measurements
    rho = max(1.0 - n_free / (6.0 * N), 1.0 / (6.0 * N))
    factors: dict[str, tuple[float, float]] = {}
    for cam, idx in _camera_pairs(problem).items():
        denom = 3.0 * idx.size * rho
        factors[cam] = (max(float(chi_t[idx].sum()) / denom, floor),
                        max(float(chi_r[idx].sum()) / denom, floor))
    edges = [Edge._of(e.x, e.y, e.A, e.B, e.sigma * np.sqrt(factors[e.y][0]),
                      e.kappa / factors[e.y][1]) for e in problem.edges]
    return Problem(problem.x_names, problem.y_names, edges,
                   unknown_scale=problem.unknown_scale), factors


def _conditional_covariance(H: np.ndarray, free_idx: np.ndarray, null_tol: float
                            ) -> tuple[np.ndarray, np.ndarray]:
    """Covariance (n, n) on the coordinates ``free_idx`` of ``H`` (the rest held) and the unit
    null directions (n, k) of the Jacobi-normalised block (their span is left out)."""
    Hf = H[np.ix_(free_idx, free_idx)]
    dg = np.abs(np.diag(Hf))
    d = np.sqrt(np.maximum(dg, 1e-12 * max(float(dg.max(initial=0.0)), 1e-300)))
    Hn = Hf / np.outer(d, d)
    lam, U = np.linalg.eigh(0.5 * (Hn + Hn.T))
    keep = lam >= null_tol
    Cn = (U[:, keep] / lam[keep]) @ U[:, keep].T
    null = U[:, ~keep] / d[:, None]
    if null.shape[1]:
        null = null / np.linalg.norm(null, axis=0)
    return Cn / np.outer(d, d), null


def _size(v: np.ndarray, C: np.ndarray) -> tuple[float, float]:
    """``|v|`` and its first-order std for covariance ``C`` of ``v``."""
    n = float(np.linalg.norm(v))
    if not v.size:
        return float("nan"), float("nan")
    if n > 0:
        u = v / n
        return n, float(np.sqrt(max(u @ C @ u, 0.0)))
    return n, float(np.sqrt(max(np.trace(C) / v.size, 0.0)))


def frame_changes(
    problem: Problem,
    X: np.ndarray,
    Y: np.ndarray,
    alpha: float,
    *,
    free: Sequence[str],
    reference: Mapping[str, np.ndarray],
    level: float,
    reference_covariance: Mapping[str, np.ndarray] | None = None,
    options: ChangeOptions | None = None,
) -> ChangeTest:
    """Test every frame of ``reference`` that is in ``free`` (module docstring).

    Parameters
    ----------
    problem : Problem
        The data alone (no pseudo-measurements).
    X, Y : ndarray, shapes (M, 4, 4), (P, 4, 4)
        The estimate, in ``problem``'s frame order (held frames at their held values).
    alpha : float
        Its scale (1 for known scale).
    free : sequence of str
        The frames estimated from the data; every other frame of ``problem`` is held.
    reference : mapping of str to ndarray (4, 4)
        Reference value of each frame to test (frames of ``free``; others are ignored).
    level : float
        ``a``: the error rate of each frame's decision (already split over frames and looks).
    reference_covariance : mapping of str to ndarray (6, 6), optional
        The reference's covariance per frame in the convention of the module docstring (NaN
        entries: that axis is not tested).
    options : ChangeOptions, optional
    """
    opts = options or ChangeOptions()
    if not (np.isfinite(level) and 0 < level < 1):
        raise ValueError(f"level: must be in (0, 1), got {level!r}")
    unknown = [n for n in free if n not in problem.frame_names]
    if unknown:
        raise ValueError(f"free frames {unknown} are not frames of the problem "
                         f"{list(problem.frame_names)}")
    names = problem.frame_names
    fidx = [names.index(n) for n in free]
    n_free = 6 * len(fidx) + (1 if problem.unknown_scale else 0)
    notes: list[str] = []
    factors: dict[str, tuple[float, float]] = {}
    weighted = problem
    if opts.noise == "data":
        weighted, factors = noise_reweighted(problem, X, Y, alpha, n_free,
                                             floor=opts.min_variance_factor)
    info = information_matrix(weighted, X, Y, alpha)
    lay = info.layout
    coords = [lay.frame_indices(f) for f in fidx]
    free_idx = np.concatenate(coords + ([np.array([lay.alpha])] if lay.alpha is not None
                                        else [])) if coords else np.zeros(0, int)
    C, null = _conditional_covariance(info.H, free_idx, opts.null_tol)
    N = problem.n_measurements
    rho = max(1.0 - n_free / (6.0 * N), 1.0 / (6.0 * N))
    per_cam = _camera_pairs(problem)
    edge_pairs: dict[str, int] = {}
    for e in problem.edges:
        edge_pairs[e.x] = edge_pairs.get(e.x, 0) + e.n
        edge_pairs[e.y] = edge_pairs.get(e.y, 0) + e.n
    T = np.concatenate([np.asarray(X, float), np.asarray(Y, float)])
    ref_cov = dict(reference_covariance or {})
    out: dict[str, FrameChange] = {}
    for pos, f in enumerate(fidx):
        name = names[f]
        if name not in reference:
            continue
        loc = np.arange(6 * pos, 6 * pos + 6)
        Jl = np.eye(6)
        Jl[3:, 3:] = T[f, :3, :3]  # right perturbation w -> left phi = R_hat w
        Cf = Jl @ C[np.ix_(loc, loc)] @ Jl.T
        undetermined = np.zeros(6, bool)
        if null.shape[1]:
            undetermined = np.linalg.norm(null[loc], axis=1) >= opts.axis_tol
        Cr = np.asarray(ref_cov.get(name, np.zeros((6, 6))), float)
        if Cr.shape != (6, 6):
            raise ValueError(f"reference covariance of {name}: expected shape (6, 6), got "
                             f"{Cr.shape}")
        no_ref = ~np.isfinite(np.diag(Cr))
        tested = ~undetermined & ~no_ref
        Sigma = Cf + np.where(np.isfinite(Cr), Cr, 0.0)
        Sigma[~tested, :] = np.nan
        Sigma[:, ~tested] = np.nan
        Tref = np.asarray(reference[name], float)
        delta = np.r_[T[f, :3, 3] - Tref[:3, 3], so3_log(T[f, :3, :3] @ Tref[:3, :3].T)]
        cams = [name] if name in per_cam else [e.y for e in problem.edges if e.x == name]
        n_k = sum(per_cam[c].size for c in dict.fromkeys(cams))
        nu = float("inf") if opts.noise == "stated" else 3.0 * n_k * rho
        out[name] = _one_frame(name, "X" if f < problem.M else "Y", delta, Sigma, tested, nu,
                               level, opts.tolerance, edge_pairs.get(name, 0))
        if undetermined.any():
            notes.append(f"{name}: axes {_axes(undetermined)} not determined by these data "
                         "(not tested)")
    return ChangeTest(out, factors, notes)


def _axes(mask: np.ndarray) -> str:
    return ", ".join(a for a, m in zip(("x", "y", "z", "rx", "ry", "rz"), mask, strict=True)
                     if m)


def _one_frame(name: str, role: str, delta: np.ndarray, Sigma: np.ndarray, tested: np.ndarray,
               nu: float, level: float, tol: ChangeTolerance, n_pairs: int) -> FrameChange:
    """The test and the decision of one frame (module docstring)."""
    r = int(tested.sum())
    nan = float("nan")
    if r == 0:
        return FrameChange(name, role, delta, Sigma, tested, nan, 0, nu, nan, level,
                           float(np.linalg.norm(delta[:3])),
                           float(np.degrees(np.linalg.norm(delta[3:]))), nan, nan,
                           (0.0, float("inf")), (0.0, float("inf")), "undecided", n_pairs)
    a = np.flatnonzero(tested)
    S = Sigma[np.ix_(a, a)]
    d = delta[a]
    W = float(d @ np.linalg.solve(S, d))
    if np.isfinite(nu):
        p = float(stats.f.sf(W / r, r, nu))
        c = r * float(stats.f.isf(level, r, nu))
    else:
        p = float(stats.chi2.sf(W, r))
        c = float(stats.chi2.isf(level, r))
    bounds = []
    sizes = []
    for block, scale in ((np.arange(3), 1.0), (np.arange(3, 6), float(np.degrees(1.0)))):
        sel = np.flatnonzero(tested[block])
        full = sel.size == 3
        v = delta[block]
        if sel.size:
            pos = np.searchsorted(a, block[sel])
            lo, hi = norm_bounds(d[pos], S[np.ix_(pos, pos)], c)
            size, std = _size(v[sel], S[np.ix_(pos, pos)])
        else:
            lo, hi, size, std = 0.0, float("inf"), float(np.linalg.norm(v)), nan
        if not full:
            hi = float("inf")
            size = float(np.linalg.norm(v))
        bounds.append((scale * lo, scale * hi))
        sizes.append((scale * size, scale * std))
    decision = decide(bounds[0], bounds[1], tol)
    return FrameChange(name, role, delta, Sigma, tested, W, r, nu, p, level, sizes[0][0],
                       sizes[1][0], sizes[0][1], sizes[1][1], bounds[0], bounds[1], decision,
                       n_pairs)
