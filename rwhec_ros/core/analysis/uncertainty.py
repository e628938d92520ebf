"""Uncertainty of every estimated frame: the covariance of the MLE from its information matrix.

The cost ``f = x^T Q x`` of eq. (42) is the negative log-likelihood of the data under the paper's
noise model (Section 4.2, per-pair ``sigma_i`` and ``kappa_i``), so at the (certified) optimum the
covariance of the estimate is, to first order, the inverse of the Hessian of ``f`` on the manifold
(:mod:`rwhec_ros.core.analysis.information`, exact including the curvature terms). Two versions:

* **predicted**: from the stated noise alone (``sigma``, ``kappa`` as given with the data);
* **a posteriori**: the predicted covariance times the variance factor
  ``s0^2 = sum_i J_i / dof`` of the residuals at the optimum (``sum_i J_i`` is chi-square with
  ``dof = 6 N - rank(H)`` degrees of freedom when the stated noise is right; ``rank(H) =
  6 (M + P) [+ 1 for unknown scale]`` when every direction is determined). ``s0^2 > 1``: the
  data are noisier than stated.

Convention (:data:`CONVENTION`): each frame ``T = (R, t)`` is expressed in its parent (carrier:
X frames in the tag carrier, Y frames in the camera carrier). The perturbation is
``t = t_hat + dt`` and ``R = exp(phi^) R_hat`` -- translation added and rotation applied *on the
left*, i.e. about the axes of the parent -- and the 6x6 ``covariance`` is that of
``[dt_x, dt_y, dt_z, phi_x, phi_y, phi_z]`` in metres and radians (the order and units of ROS
``geometry_msgs/PoseWithCovariance``). ``std_translation_m`` and ``std_rotation_deg`` are the
square roots of its diagonal (rotations in degrees). Internally the Hessian uses right
perturbations ``R_hat exp(w^)``; ``phi = R_hat w``.

Unobservable directions are never reported as huge numbers. Translation directions the data do
not determine are found exactly as :func:`~rwhec_ros.core.solve.solve` finds them
(:mod:`rwhec_ros.core.model.gauge`, same :class:`~rwhec_ros.core.model.gauge.GaugeOptions`), and any
further null direction of the (Jacobi-normalised) information matrix, e.g. a rotation the data do
not fix, is found by its eigenvalues. The covariance is computed on the complement of those
directions; every axis of a frame (and the scale) that takes part in one is *unobservable*: its
entries are NaN (``None`` in :meth:`FrameUncertainty.to_dict`) and it is named in words. When
user priors pin every such direction (the :class:`~rwhec_ros.core.model.gauge.TranslationPrior` s
given to the solve), the covariance is instead the one *given the priors* (the priors exact) and
no axis is unobservable.

Cost: a few milliseconds on the paper's real data (3,230 pairs, 24 frames; see
``benchmarks/uncertainty.md``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg

from ..model.gauge import (
    GaugeOptions,
    axis_words,
    build_gauge_fix,
    unobservable_directions_of_block,
)
from ..model.recentre import recentred_analysis
from ..numerics.blas import blas_threads
from ..problem import Problem
from .information import (
    Information,
    check_result_frames,
    information_from_edge_blocks,
    information_matrix,
)
from .worst_direction import block_variances

__all__ = [
    "CONVENTION",
    "UncertaintyOptions",
    "FrameUncertainty",
    "Uncertainty",
    "Covariance",
    "frame_uncertainty",
    "covariance_of",
    "frame_covariances",
    "uncertainty_from_information",
]

#: The perturbation convention of every reported covariance (module docstring), in words.
CONVENTION = (
    "frame T = (R, t) in its parent; t = t_hat + dt, R = exp(phi^) R_hat (rotation about the "
    "parent's axes); covariance of [dt_x, dt_y, dt_z, phi_x, phi_y, phi_z] in m and rad (ROS "
    "PoseWithCovariance order)"
)

_AXES = ("x", "y", "z")

#: Values of :attr:`UncertaintyOptions.information`.
INFORMATION_FORMS = ("pairs", "edge_blocks")


@dataclass
class UncertaintyOptions:
    """Options of :func:`frame_uncertainty`.

    Attributes
    ----------
    gauge : GaugeOptions
        When a translation direction is unobservable, and the priors that fix such directions:
        pass the ``SolveOptions.gauge`` of the solve so that both agree.
    null_tol : float
        Eigenvalues of the Jacobi-normalised information matrix (unit diagonal) below this span
        further null directions (1e-8; exact symmetries give ~1e-12, cf.
        :class:`~rwhec_ros.core.identifiability.IdentifiabilityThresholds`).
    axis_tol : float
        An axis of a frame is unobservable when the unit null directions have a component of at
        least this along it (1e-3, the threshold of the gauge's frame components).
    blas_threads : int or None
        BLAS threads while computing (1, as :attr:`~rwhec_ros.core.solve.SolveOptions.
        blas_threads`: a 145x145 Cholesky took 0.4 s with multi-threaded OpenBLAS on the busy
        2-core machine, against 1 ms single-threaded); ``None`` leaves the library's setting.
    information : str
        How the information matrix is assembled: ``"pairs"`` (default,
        :func:`~rwhec_ros.core.analysis.information.information_matrix`: summed over the pairs,
        ``chi2`` from the residuals) or ``"edge_blocks"``
        (:func:`~rwhec_ros.core.analysis.information.information_from_edge_blocks`: from the cost's
        edge blocks, the problem's ``precomputed_blocks`` when set; the same matrix to rounding,
        ``chi2`` from the quadratic form; the live re-solve's, several times faster).
    """

    gauge: GaugeOptions = field(default_factory=GaugeOptions)
    null_tol: float = 1e-8
    axis_tol: float = 1e-3
    blas_threads: int | None = 1
    information: str = "pairs"

    def __post_init__(self) -> None:
        if self.information not in INFORMATION_FORMS:
            raise ValueError(f"information: expected one of {INFORMATION_FORMS}, got "
                             f"{self.information!r}")
        for name in ("null_tol", "axis_tol"):
            v = getattr(self, name)
            if not (np.isfinite(v) and 0 < v < 1):
                raise ValueError(f"{name}: must be in (0, 1), got {v!r}")


def _nan_list(a: np.ndarray):
    """Nested lists of floats with NaN as ``None`` (YAML-friendly)."""
    a = np.asarray(a, float)
    if a.ndim == 0:
        return None if np.isnan(a) else float(a)
    return [_nan_list(v) for v in a]


@dataclass
class FrameUncertainty:
    """Uncertainty of one frame (conventions: module docstring and :data:`CONVENTION`).

    Attributes
    ----------
    name : str
    role : str
        ``"X"`` (tag) or ``"Y"`` (camera).
    covariance : ndarray, shape (6, 6)
        Predicted covariance of ``[dt (m), phi (rad)]`` in the parent; NaN in the rows and
        columns of unobservable axes.
    variance_factor : float
        ``s0^2`` of the solve (:attr:`Uncertainty.variance_factor`).
    unobservable_translation, unobservable_rotation : ndarray of bool, shape (3,)
        Axes (of the parent) along which the translation / about which the rotation is not
        determined by the data.
    """

    name: str
    role: str
    covariance: np.ndarray
    variance_factor: float
    unobservable_translation: np.ndarray
    unobservable_rotation: np.ndarray

    @property
    def std_translation_m(self) -> np.ndarray:
        """Predicted standard deviation (3,) [m] along the parent's x, y, z (NaN: unobservable)."""
        return np.sqrt(np.maximum(np.diag(self.covariance)[:3], 0.0))

    @property
    def std_rotation_deg(self) -> np.ndarray:
        """Predicted standard deviation (3,) [deg] about the parent's x, y, z (NaN:
        unobservable)."""
        return np.degrees(np.sqrt(np.maximum(np.diag(self.covariance)[3:], 0.0)))

    @property
    def covariance_a_posteriori(self) -> np.ndarray:
        """The covariance rescaled by the variance factor (NaN when it is undefined)."""
        return self.variance_factor * self.covariance

    @property
    def std_translation_m_a_posteriori(self) -> np.ndarray:
        return np.sqrt(np.maximum(self.variance_factor, 0.0)) * self.std_translation_m

    @property
    def std_rotation_deg_a_posteriori(self) -> np.ndarray:
        return np.sqrt(np.maximum(self.variance_factor, 0.0)) * self.std_rotation_deg

    def worst_std(self) -> tuple[float, float]:
        """Predicted std in the worst direction: ``(translation [m], rotation [deg])``, the
        square roots of the largest eigenvalues of the 3x3 translation and rotation blocks of
        :attr:`covariance` (at least the largest per-axis std); ``inf`` for a block with an
        unobservable axis (not determined)."""
        lam = block_variances(self.covariance, missing=np.inf)
        out = []
        for v, bad, unit in ((lam[0], self.unobservable_translation, 1.0),
                             (lam[1], self.unobservable_rotation, np.degrees(1.0))):
            out.append(float("inf") if np.asarray(bad).any()
                       else float(unit * np.sqrt(max(v, 0.0))))
        return out[0], out[1]

    @property
    def observable(self) -> bool:
        """No axis of this frame is unobservable."""
        return not (self.unobservable_translation.any() or self.unobservable_rotation.any())

    def to_dict(self) -> dict:
        """The result-YAML keys: predicted ``std_translation_m``, ``std_rotation_deg`` and
        ``covariance`` (``None`` for unobservable entries), the same ``a_posteriori``, and the
        unobservable axes by name."""
        return {
            "std_translation_m": _nan_list(self.std_translation_m),
            "std_rotation_deg": _nan_list(self.std_rotation_deg),
            "covariance": _nan_list(self.covariance),
            "a_posteriori": {
                "std_translation_m": _nan_list(self.std_translation_m_a_posteriori),
                "std_rotation_deg": _nan_list(self.std_rotation_deg_a_posteriori),
                "covariance": _nan_list(self.covariance_a_posteriori),
            },
            "unobservable": {
                "translation": [a for a, u in zip(_AXES, self.unobservable_translation,
                                                  strict=True) if u],
                "rotation": [a for a, u in zip(_AXES, self.unobservable_rotation,
                                               strict=True) if u],
            },
        }


@dataclass
class Covariance:
    """The covariance in the tangent coordinates of :mod:`rwhec_ros.core.analysis.information`.

    Attributes
    ----------
    sigma : ndarray, shape (n, n)
        Covariance of ``xi`` on the complement of the null directions (the gauge of the module
        docstring); meaningful only for functionals orthogonal to ``null``.
    null : ndarray, shape (n, k)
        Unit null (unobservable) directions in ``xi`` (empty when the priors pin the gauge).
    rank : int
        Number of determined directions, ``n - k`` (``n`` with pinning priors).
    words : list of str
        The unobservable directions in words.
    pinned : bool
        User priors pin every translation direction the data do not determine (``sigma`` is
        then conditional on them).
    n_gauge : int
        Number of translation directions found unobservable by the gauge analysis.
    negative_curvature : float
        Most negative normalised eigenvalue (0 at a minimum).
    """

    sigma: np.ndarray
    null: np.ndarray
    rank: int
    words: list[str]
    pinned: bool
    n_gauge: int
    negative_curvature: float = 0.0

    def frame_blocks(self, info: Information) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per-frame covariances (F, 6, 6) in the reporting convention (no NaN masking) and the
        parts of the null directions along each frame's translation axes (F, 3, k) and rotation
        axes (F, 3, k), both in the parent."""
        lay = info.layout
        idx = lay.frame_indices(np.arange(lay.n_frames))  # (F, 6)
        C = self.sigma[idx[:, :, None], idx[:, None, :]]
        Tm = np.zeros((lay.n_frames, 6, 6))
        Tm[:, :3, :3] = np.eye(3)
        Tm[:, 3:, 3:] = info.R  # phi = R w
        C = Tm @ C @ np.swapaxes(Tm, 1, 2)
        Vt = self.null[idx[:, :3]]  # (F, 3, k)
        Vr = info.R @ self.null[idx[:, 3:]]  # rotation parts in the parent
        return C, Vt, Vr


def _metric_directions(info: Information, V_w: np.ndarray) -> np.ndarray:
    """Directions (n, k) in ``xi`` of the gauge's unobservable directions ``V_w`` (m, k), which
    are in the state coordinates ``[alpha t, alpha]``: ``dt = (d(alpha t) - t d alpha) / alpha``."""
    lay = info.layout
    F = lay.n_frames
    out = np.zeros((lay.size, V_w.shape[1]))
    if lay.unknown_scale:
        da = V_w[3 * F]
        out[: 3 * F] = (V_w[: 3 * F] - info.t.reshape(-1, 1) * da) / info.alpha
        out[3 * F] = da
    else:
        out[: 3 * F] = V_w[: 3 * F]
    return np.linalg.qr(out)[0]


def _complement(C: np.ndarray, n: int) -> np.ndarray:
    """Orthonormal basis (n, n - rank C) of the null space of the rows ``C`` (k, n)."""
    Qf, Rf = np.linalg.qr(C.T, mode="complete")
    rank = int(np.sum(np.abs(np.diag(Rf)) > 1e-12 * max(float(np.abs(Rf).max(initial=0)), 1e-300)))
    return Qf[:, rank:]


def _null_words(info: Information, v: np.ndarray) -> str:
    """Words for a null direction ``v`` (n,) of the information matrix."""
    lay = info.layout
    parts = []
    for f, name in enumerate(info.names):
        i = lay.frame_indices(f)
        vt, vr = v[i[:3]], info.R[f] @ v[i[3:]]
        what = []
        if np.linalg.norm(vt) >= 0.1 * np.abs(v).max():
            what.append(f"translation along {axis_words(vt)}")
        if np.linalg.norm(vr) >= 0.1 * np.abs(v).max():
            what.append(f"rotation about {axis_words(vr)}")
        if what:
            parts.append(f"{name} ({' and '.join(what)})")
    if lay.alpha is not None and abs(v[lay.alpha]) >= 0.1 * np.abs(v).max():
        parts.append("the scale")
    return (", ".join(parts) + " together not determined by the data (a null direction of the "
            "information matrix; axes in the frames' parents)")


def _inverse_from_cholesky(A: np.ndarray) -> np.ndarray:
    """``A^-1`` of a symmetric positive definite ``A`` from its Cholesky factor (LAPACK
    ``potrf`` + ``potri``: a third of the work of solving for the identity's columns), exactly
    symmetric (the upper triangle ``potri`` computes, mirrored); ``LinAlgError`` when ``A`` is
    not positive definite."""
    A = np.asarray(A, dtype=float)
    if A.ndim != 2 or A.shape[0] != A.shape[1] or not A.size:
        raise ValueError(f"expected a non-empty square matrix, got shape {A.shape}")
    # potrf as scipy.linalg.cho_factor(A, check_finite=False) calls it (upper factor), without
    # its look-ups
    factor, info = scipy.linalg.lapack.dpotrf(A, lower=False, clean=False)
    if info != 0:
        raise np.linalg.LinAlgError(f"potrf: info {info} (not positive definite)")
    inv, info = scipy.linalg.lapack.dpotri(factor, lower=False)
    if info != 0:
        raise np.linalg.LinAlgError(f"potri: info {info}")
    n = inv.shape[0]
    upper = np.arange(n)[:, None] <= np.arange(n)  # the triangle potri wrote
    return np.where(upper, inv, inv.T)


def _clearly_above(Cn: np.ndarray, tol: float) -> bool:
    """Every eigenvalue of the symmetric positive definite ``Hn = Cn^-1`` is at least ``2 tol``:
    ``lambda_max(Cn) <= |Cn|_inf`` (largest absolute row sum) ``<= 1 / (2 tol)``. A sufficient
    test (no factorisation): ``False`` says nothing."""
    return bool(np.abs(Cn).sum(axis=1).max(initial=0.0) <= 0.5 / tol)


def covariance_of(info: Information, problem: Problem,
                  options: UncertaintyOptions | None = None) -> Covariance:
    """The covariance of the estimate from ``info`` (module docstring): the gauge analysis of
    ``info.Q_ee`` (as the solve does), then the normalised information matrix on the complement,
    its Cholesky factor (usual case) or eigen-decomposition (further null directions)."""
    opts = options or UncertaintyOptions()
    lay = info.layout
    n = lay.size
    V_w, w_w, directions, w_max = unobservable_directions_of_block(info.Q_ee, problem, opts.gauge)
    k = V_w.shape[1]
    words: list[str] = []
    pinned = False
    null = np.zeros((n, 0))
    basis = None
    if k:
        V = _metric_directions(info, V_w)
        fix = build_gauge_fix(problem, V_w, w_w, directions, w_max, opts.gauge.priors)
        pinned = bool(opts.gauge.priors) and fix.pinned
        if pinned:  # G dt = 0 (metric t; for unknown scale G (alpha t) = b alpha <=> G t = b)
            C = np.zeros((fix.G.shape[0], n))
            C[:, : 3 * lay.n_frames] = fix.G
        else:
            C = V.T
            null = V
            words = [d.describe(x_names=problem.x_names) for d in directions]
        basis = _complement(C, n)
    Hc = info.H if basis is None else basis.T @ info.H @ basis
    dg = np.abs(np.diag(Hc))
    d = np.sqrt(np.maximum(dg, 1e-12 * max(float(dg.max(initial=0.0)), 1e-300)))
    dd = np.outer(d, d)
    Hn = Hc / dd
    Hn += Hn.T
    Hn *= 0.5
    negative = 0.0
    try:  # usual case: every normalised eigenvalue above null_tol
        Cn = _inverse_from_cholesky(Hn)
        # Hn - null_tol I positive definite: proven by the bound on Cn (no factorisation), or
        # else by its own Cholesky factorisation (raises when not)
        if not _clearly_above(Cn, opts.null_tol):
            scipy.linalg.cholesky(Hn - opts.null_tol * np.eye(Hn.shape[0]), check_finite=False)
        extra = np.zeros((Hn.shape[0], 0))
        exact_sym = True  # Cn and dd exactly symmetric, so is Cn / dd
    except (np.linalg.LinAlgError, ValueError):
        lam, U = np.linalg.eigh(Hn)
        negative = float(min(lam[0], 0.0)) if lam[0] < -opts.null_tol else 0.0
        keep = np.abs(lam) >= opts.null_tol
        Cn = (U[:, keep] / np.abs(lam[keep])) @ U[:, keep].T
        extra = U[:, ~keep] / d[:, None]
        exact_sym = False
    Cc = np.divide(Cn, dd, out=Cn) if exact_sym else Cn / dd
    sigma = Cc if basis is None else basis @ Cc @ basis.T
    if extra.shape[1]:
        ext = extra if basis is None else basis @ extra
        ext, _ = np.linalg.qr(ext)
        words += [_null_words(info, ext[:, i]) for i in range(ext.shape[1])]
        null = np.concatenate([null, ext], axis=1)
    rank = n - k - extra.shape[1]  # the data's rank (priors add none)
    if basis is not None or not exact_sym:  # (exactly symmetric already: the same bits)
        sigma = 0.5 * (sigma + sigma.T)
    return Covariance(sigma=sigma, null=null, rank=rank, words=words,
                      pinned=pinned, n_gauge=k, negative_curvature=negative)


@dataclass
class Uncertainty:
    """Uncertainty of every estimated frame (module docstring).

    Attributes
    ----------
    frames : list of FrameUncertainty
        In problem order (X frames, then Y frames).
    scale_std : float or None
        Predicted standard deviation of ``alpha`` (unknown scale; NaN when unobservable),
        ``None`` for known scale.
    variance_factor : float
        ``s0^2 = chi2 / dof`` (NaN when ``dof <= 0``): multiply predicted variances by it for the
        a-posteriori ones.
    chi2 : float
        ``sum_i J_i`` (eq. (33)) at the estimate.
    dof : int
        ``6 N - rank``.
    rank : int
        Number of determined directions of the ``6 (M + P) [+1]`` tangent coordinates.
    unobservable : list of str
        The undetermined directions in words (empty when none, or when the priors pin them).
    conditioned_on_priors : bool
        User priors pin the directions the data do not determine; the stds are given them.
    notes : list of str
    timing_s : float
        Seconds to compute it.
    """

    frames: list[FrameUncertainty]
    scale_std: float | None
    variance_factor: float
    chi2: float
    dof: int
    rank: int
    unobservable: list[str] = field(default_factory=list)
    conditioned_on_priors: bool = False
    notes: list[str] = field(default_factory=list)
    timing_s: float = 0.0

    def frame(self, name: str) -> FrameUncertainty:
        for f in self.frames:
            if f.name == name:
                return f
        raise KeyError(f"no frame named {name!r}; have {[f.name for f in self.frames]}")

    @property
    def observable(self) -> bool:
        """Every axis of every frame (and the scale) is determined."""
        return all(f.observable for f in self.frames) and not (
            self.scale_std is not None and np.isnan(self.scale_std))

    def max_std(self, *, a_posteriori: bool = False) -> tuple[float, float]:
        """Largest ``(translation std [m], rotation std [deg])`` over the observable axes of all
        frames (predicted, or rescaled with ``a_posteriori``); NaN where nothing is observable."""
        t = [f.std_translation_m_a_posteriori if a_posteriori else f.std_translation_m
             for f in self.frames]
        r = [f.std_rotation_deg_a_posteriori if a_posteriori else f.std_rotation_deg
             for f in self.frames]
        tt, rr = np.concatenate(t), np.concatenate(r)
        return (float(np.nanmax(tt)) if np.isfinite(tt).any() else float("nan"),
                float(np.nanmax(rr)) if np.isfinite(rr).any() else float("nan"))

    def converged(self, max_std_translation_m: float, max_std_rotation_deg: float, *,
                  a_posteriori: bool = False) -> bool:
        """Every frame observable and every std at or below the given limits."""
        if not self.observable:
            return False
        t, r = self.max_std(a_posteriori=a_posteriori)
        return bool(t <= max_std_translation_m and r <= max_std_rotation_deg)

    def to_dict(self) -> dict:
        """Plain-Python mapping for the result YAML (``None`` for unobservable entries)."""
        return {
            "convention": CONVENTION,
            "predicted_from": "the stated per-pair noise (sigma, kappa)",
            "a_posteriori": "predicted times variance_factor = chi2 / dof of the residuals",
            "variance_factor": _nan_list(self.variance_factor),
            "chi2": float(self.chi2),
            "dof": int(self.dof),
            "frames": {f.name: f.to_dict() for f in self.frames},
            "scale_std": None if self.scale_std is None else _nan_list(self.scale_std),
            "unobservable": list(self.unobservable),
            "conditioned_on_priors": bool(self.conditioned_on_priors),
            "notes": list(self.notes),
        }


def frame_covariances(cov: Covariance, info: Information, axis_tol: float = 1e-3
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray, bool]:
    """Per-frame covariances (F, 6, 6) in the reporting convention with NaN rows and columns on
    unobservable axes, the unobservable translation (F, 3) and rotation (F, 3) axes, and whether
    the scale is unobservable (see :class:`UncertaintyOptions` for ``axis_tol``)."""
    C, Vt, Vr = cov.frame_blocks(info)
    if not cov.null.shape[1]:  # no null direction (the usual case): no axis unobservable
        ut = ur = np.zeros(Vt.shape[:2], dtype=bool)
        return C, ut, ur.copy(), False
    ut = np.linalg.norm(Vt, axis=2) >= axis_tol
    ur = np.linalg.norm(Vr, axis=2) >= axis_tol
    bad = np.concatenate([ut, ur], axis=1)  # (F, 6)
    C = np.where(bad[:, :, None] | bad[:, None, :], np.nan, C)
    a = info.layout.alpha
    scale_null = bool(a is not None and cov.null.shape[1]
                      and np.abs(cov.null[a]).max() >= axis_tol)
    return C, ut, ur, scale_null


def uncertainty_from_information(info: Information, problem: Problem,
                                 options: UncertaintyOptions | None = None) -> Uncertainty:
    """:class:`Uncertainty` from an information matrix (see :func:`frame_uncertainty`)."""
    opts = options or UncertaintyOptions()
    t0 = time.perf_counter()
    with blas_threads(opts.blas_threads):
        return _uncertainty_from_information(info, problem, opts, t0)


def _uncertainty_from_information(info: Information, problem: Problem,
                                  opts: UncertaintyOptions, t0: float) -> Uncertainty:
    """:func:`uncertainty_from_information` inside the caller's BLAS thread limit (started at
    ``t0``)."""
    cov = covariance_of(info, problem, opts)
    C, ut, ur, scale_null = frame_covariances(cov, info, opts.axis_tol)
    lay = info.layout
    dof = 6 * info.n_pairs - cov.rank
    # chi2 is a sum of squares; on exact data its evaluation can come out a hair below zero
    s0 = max(info.chi2, 0.0) / dof if dof > 0 else float("nan")
    frames = [FrameUncertainty(name, "X" if f < lay.M else "Y", C[f], s0, ut[f], ur[f])
              for f, name in enumerate(info.names)]
    scale_std = None
    if lay.alpha is not None:
        scale_std = float("nan") if scale_null else float(
            np.sqrt(max(cov.sigma[lay.alpha, lay.alpha], 0.0)))
    notes = []
    if cov.negative_curvature < 0:
        notes.append(f"negative curvature {cov.negative_curvature:.2e}: the estimate is not a "
                     "local minimum of the data's cost; the stds are rough")
    if cov.pinned:
        notes.append("the translation directions the data do not determine are fixed by the "
                     "given priors; the stds are given those priors (taken as exact)")
    if dof <= 0:
        notes.append(f"no redundancy ({info.n_pairs} pairs for {cov.rank} determined "
                     "directions): no a-posteriori variance factor")
    return Uncertainty(frames=frames, scale_std=scale_std, variance_factor=s0, chi2=info.chi2,
                       dof=dof, rank=cov.rank, unobservable=cov.words,
                       conditioned_on_priors=cov.pinned, notes=notes,
                       timing_s=time.perf_counter() - t0)


def frame_uncertainty(problem: Problem, result, options: UncertaintyOptions | None = None
                      ) -> Uncertainty:
    """Covariance of every frame (and the scale) of ``result`` for ``problem``'s data.

    Parameters
    ----------
    problem : Problem
        The data the result was solved from (after any outlier removal).
    result : CalibrationResult
        From :func:`~rwhec_ros.core.solve.solve`: ``X``, ``Y`` (metric), ``scale`` and
        ``unobservable``; ideally certified (the covariance describes the global optimum).
    options : UncertaintyOptions, optional
        Pass ``UncertaintyOptions(gauge=solve_options.gauge)`` to use the solve's priors.

    Returns
    -------
    Uncertainty
        Per frame the predicted and a-posteriori stds and 6x6 covariances in the frame's parent
        (:data:`CONVENTION`), unobservable axes as such, the variance factor.
    """
    t0 = time.perf_counter()
    check_result_frames(problem, result)
    opts = options or UncertaintyOptions()
    # far from the pose stream's origin: the same information about a nearby point (exact)
    problem, result = recentred_analysis(problem, result, priors=bool(opts.gauge.priors))
    assemble = (information_from_edge_blocks if opts.information == "edge_blocks"
                else information_matrix)
    with blas_threads(opts.blas_threads):
        info = assemble(problem, result.X, result.Y, result.scale)
        unc = _uncertainty_from_information(info, problem, opts, t0)
    n_res = len(getattr(result, "unobservable", []) or [])
    n_gauge = sum(1 for w in unc.unobservable if w.startswith("translation"))
    if not unc.conditioned_on_priors and n_res != n_gauge:
        unc.notes.append(f"the solve reported {n_res} unobservable translation direction(s), "
                         f"this analysis {n_gauge}: pass the solve's GaugeOptions")
    unc.timing_s = time.perf_counter() - t0
    return unc
