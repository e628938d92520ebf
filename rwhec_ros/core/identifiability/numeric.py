"""Whole-problem identifiability from the assembled MLE cost (paper Theorems 1 and 3).

The Hessian on the manifold at a minimiser of ``x^T Q x`` (eq. (42)) reveals, through its null
space and inverse, what the per-edge test of :mod:`.edge` cannot (e.g. several single-axis edges
that together fix a frame, Theorem 1's general case), and predicts every frame's uncertainty from
the stated noise levels. Cost: 55-90 ms on the paper's real data (24 frames, 3230 pairs) with
single-threaded BLAS (measured on a loaded 2-core machine; multi-threaded OpenBLAS took 0.2 s to
seconds there, from thread oversubscription on small matrices: ``OPENBLAS_NUM_THREADS=1``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ..lie import hat, project_to_so3, so3_exp, unvec, vec
from ..model.cost import StateLayout, build_cost_matrix
from ..model.reduction import reduce_cost
from ..problem import Problem, check_transforms
from .status import IdentifiabilityStatus, IdentifiabilityThresholds, worst_status

__all__ = ["NumericCheck", "numeric_check"]


# ----------------------------------------------------------------------------------------------
# Whole-problem numeric check
# ----------------------------------------------------------------------------------------------
@dataclass
class NumericCheck:
    """Hessian of the MLE cost on the manifold at a minimiser (noise-aware, Theorems 1 and 3).

    Tangent coordinates: translations (``alpha t`` for unknown scale) of all frames, ``alpha``
    (unknown scale only), right-perturbation rotation vectors of all frames. The Hessian is exact
    (Gauss-Newton term plus the curvature term of the retraction), so at a minimiser the flat
    directions of exact symmetries of noisy data have zero eigenvalues, unlike ``J^T Q J`` alone.

    Attributes
    ----------
    status : IdentifiabilityStatus
    reasons : list of str
    null_dim : int
        Number of eigenvalues of the Jacobi-normalised Hessian below ``null_tol``.
    smallest_eigenvalues : list of float
        The smallest few eigenvalues of the normalised Hessian (unit diagonal).
    undetermined_frames : list of str
        Frames taking part in a null direction.
    scale_undetermined : bool
    frame_status : dict of str to IdentifiabilityStatus
    rotation_std_deg, translation_std_m : dict of str to float
        Predicted worst-direction standard deviation per frame (``inf`` if undetermined);
        translations metric (delta method through ``t = t_alpha / alpha``).
    scale_rel_std : float or None
        Predicted ``std(alpha) / alpha`` (unknown scale only).
    reduced_eigenvalues : list of float
        Smallest eigenvalues of the reduced cost of eq. (48) over its largest (the rotation-only
        view of Corollaries 2/4: one near-zero then a clear gap for a unique unconstrained
        minimiser; known scale includes ``s``).
    cost : float
        ``x^T Q x`` at the linearisation point.
    gradient_norm : float
        Riemannian gradient norm at the linearisation point.
    iterations : int
        Newton iterations used to polish the starting point.
    from_solution : bool
        The linearisation point came from a given solution (else from the reduced null vector).
    """

    status: IdentifiabilityStatus
    reasons: list[str]
    null_dim: int
    smallest_eigenvalues: list[float]
    undetermined_frames: list[str]
    scale_undetermined: bool
    frame_status: dict[str, IdentifiabilityStatus]
    rotation_std_deg: dict[str, float]
    translation_std_m: dict[str, float]
    scale_rel_std: float | None
    reduced_eigenvalues: list[float]
    cost: float
    gradient_norm: float
    iterations: int
    from_solution: bool

    def to_dict(self) -> dict:
        return {
            "status": self.status.value,
            "reasons": list(self.reasons),
            "null_dim": int(self.null_dim),
            "smallest_eigenvalues": [float(v) for v in self.smallest_eigenvalues],
            "undetermined_frames": list(self.undetermined_frames),
            "scale_undetermined": bool(self.scale_undetermined),
            "frame_status": {k: v.value for k, v in self.frame_status.items()},
            "rotation_std_deg": {k: float(v) for k, v in self.rotation_std_deg.items()},
            "translation_std_m": {k: float(v) for k, v in self.translation_std_m.items()},
            "scale_rel_std": None if self.scale_rel_std is None else float(self.scale_rel_std),
            "reduced_eigenvalues": [float(v) for v in self.reduced_eigenvalues],
            "cost": float(self.cost),
            "gradient_norm": float(self.gradient_norm),
            "iterations": int(self.iterations),
            "from_solution": bool(self.from_solution),
        }


class _ManifoldCost:
    """``f = x^T Q x`` pulled back to (translations, [alpha], SO(3)^F) with right perturbations."""

    def __init__(self, Q: sp.spmatrix, layout: StateLayout, unknown_scale: bool):
        self.Q = sp.csr_matrix(Q)
        self.layout = layout
        self.unknown = unknown_scale
        F = layout.n_frames
        self.F = F
        self.n_tan = 6 * F + (1 if unknown_scale else 0)
        self.c_rot = 3 * F + (1 if unknown_scale else 0)

    def state(self, R: np.ndarray, t_abs: np.ndarray, alpha: float) -> np.ndarray:
        lay = self.layout
        x = np.empty(lay.size)
        x[: lay.n_t] = t_abs.ravel()
        x[lay.alpha] = alpha
        x[lay.r0 :] = vec(R).ravel()
        return x

    def tangent_map(self, R: np.ndarray) -> sp.csr_matrix:
        """Sparse ``J = dx / d xi`` (state size x tangent size)."""
        lay, F = self.layout, self.F
        rows = [np.arange(3 * F)]
        cols = [np.arange(3 * F)]
        vals = [np.ones(3 * F)]
        if self.unknown:
            rows.append(np.array([lay.alpha]))
            cols.append(np.array([3 * F]))
            vals.append(np.ones(1))
        E = hat(np.eye(3))  # E[k] = hat(e_k)
        basis = vec(np.einsum("fab,kbc->fkac", R, E))  # (F, 3, 9): vec(R_f hat(e_k))
        rr = lay.r0 + 9 * np.arange(F)[:, None, None] + np.arange(9)[None, None, :]
        cc = self.c_rot + 3 * np.arange(F)[:, None, None] + np.arange(3)[None, :, None]
        rows.append(np.broadcast_to(rr, (F, 3, 9)).ravel())
        cols.append(np.broadcast_to(cc, (F, 3, 9)).ravel())
        vals.append(basis.ravel())
        return sp.csr_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
            shape=(lay.size, self.n_tan),
        )

    def evaluate(self, R, t_abs, alpha):
        """Cost, Riemannian gradient, exact Hessian of the pullback and the scaling ``d``.

        ``d = sqrt(diag(2 J^T Q J))`` (Gauss-Newton part, never negative, floored at 1e-12 of
        its maximum) is the Jacobi scaling used to normalise the Hessian.
        """
        x = self.state(R, t_abs, alpha)
        Qx = self.Q @ x
        f = float(x @ Qx)
        g_state = 2.0 * Qx
        J = self.tangent_map(R)
        grad = J.T @ g_state
        H = 2.0 * (J.T @ (self.Q @ J)).toarray()
        dgn = np.abs(np.diag(H))
        d = np.sqrt(np.maximum(dgn, 1e-12 * max(float(dgn.max(initial=0.0)), 1e-300)))
        G = unvec(g_state[self.layout.r0 :].reshape(self.F, 9))
        GtR = np.swapaxes(G, 1, 2) @ R
        curv = 0.5 * (GtR + np.swapaxes(GtR, 1, 2))
        curv -= np.trace(GtR, axis1=1, axis2=2)[:, None, None] * np.eye(3)
        for f_idx in range(self.F):
            sl = slice(self.c_rot + 3 * f_idx, self.c_rot + 3 * f_idx + 3)
            H[sl, sl] += curv[f_idx]
        return f, grad, 0.5 * (H + H.T), d

    def retract(self, R, t_abs, alpha, step):
        F = self.F
        t_new = t_abs + step[: 3 * F].reshape(F, 3)
        a_new = alpha + (float(step[3 * F]) if self.unknown else 0.0)
        R_new = R @ so3_exp(step[self.c_rot :].reshape(F, 3))
        return R_new, t_new, a_new


def _initial_point(problem: Problem, Q, layout: StateLayout):
    """Rotations from the reduced cost's smallest eigenvector, optimal translations (eq. (47))."""
    F = layout.n_frames
    nr = 9 * F
    red = reduce_cost(Q, layout, problem.unknown_scale)
    Qr = red.Qr[:nr, :nr] if problem.unknown_scale else red.Qr
    w, V = np.linalg.eigh(0.5 * (Qr + Qr.T))
    top = max(abs(float(w[-1])), 1e-300)
    reduced_eigs = [float(v) / top for v in w[: min(4, w.size)]]
    blocks = unvec(V[:nr, 0].reshape(F, 9))
    eta = float(np.mean(np.cbrt(np.linalg.det(blocks))))
    R = project_to_so3(blocks / (eta if abs(eta) > 1e-300 else 1.0))
    z = np.concatenate([vec(R).ravel(), [1.0]])
    ta = red.recover @ z
    alpha = float(ta[-1]) if problem.unknown_scale else 1.0
    if problem.unknown_scale and not alpha > 0:
        alpha = 1.0
    return R, ta[:-1].reshape(F, 3), alpha, reduced_eigs


def _polish(cost: _ManifoldCost, R, t_abs, alpha, max_iterations: int, step_tol: float,
            null_tol: float):
    """Damped (saddle-free) Riemannian Newton on ``x^T Q x`` to a critical point.

    Steps use the eigen-decomposition of the Jacobi-normalised Hessian, dropping directions with
    ``|eigenvalue| < null_tol`` (so exactly flat directions do not drift) and damping the others
    by ``|eigenvalue| + mu``. Stops when the step is below ``step_tol`` (rad, translation units):
    the flatness of exact symmetries in the final Hessian is accurate to about the distance from
    the critical point. Decreases at the rounding level of the cost,
    ``1e-14 |x|^T |Q| |x|``, count as accepted (exact data reach ``f ~ 0`` only up to rounding).
    """
    f, grad, H, d = cost.evaluate(R, t_abs, alpha)
    xa = np.abs(cost.state(R, t_abs, alpha))
    floor = 1e-14 * float(xa @ (abs(cost.Q) @ xa))
    mu = 1e-10
    it = 0
    for it in range(1, max_iterations + 1):
        lam, U = np.linalg.eigh(H / np.outer(d, d))
        keep = np.abs(lam) >= null_tol
        Uk, lk = U[:, keep], np.abs(lam[keep])
        gk = Uk.T @ (grad / d)
        accepted = False
        for _ in range(40):
            step = -(Uk @ (gk / (lk + mu))) / d
            if float(np.max(np.abs(step), initial=0.0)) <= step_tol:
                return R, t_abs, alpha, f, grad, H, d, it - 1
            predicted = -(grad @ step + 0.5 * step @ H @ step)
            cand = cost.retract(R, t_abs, alpha, step)
            f_new, g_new, H_new, d_new = cost.evaluate(*cand)
            actual = f - f_new
            if actual >= 0.25 * predicted or abs(actual) <= floor:
                (R, t_abs, alpha), f, grad, H, d = cand, f_new, g_new, H_new, d_new
                mu = max(mu / 10.0, 1e-14)
                accepted = True
                break
            mu = max(mu * 10.0, 1e-8)
        if not accepted:
            break
    return R, t_abs, alpha, f, grad, H, d, it


def _null_axis(M: np.ndarray) -> str:
    """Words for the main direction of the columns of ``M`` (3, k): ``"z"`` or ``[...]``."""
    from ..model.gauge import axis_words

    u, sv, _ = np.linalg.svd(M)
    v = u[:, 0]
    if v[int(np.argmax(np.abs(v)))] < 0:
        v = -v
    words = axis_words(v)
    if sv.size > 1 and sv[1] > 0.3 * sv[0]:
        words += " and other directions"
    return words


def numeric_check(
    problem: Problem,
    *,
    thresholds: IdentifiabilityThresholds | None = None,
    solution: tuple[np.ndarray, np.ndarray, float] | None = None,
    max_iterations: int = 50,
    step_tol: float = 1e-11,
) -> NumericCheck:
    """Noise-aware identifiability of the whole problem from the assembled cost.

    Builds ``Q`` (:func:`~rwhec_ros.core.model.cost.build_cost_matrix`), starts from ``solution``
    ``(X (M,4,4), Y (P,4,4), alpha)`` (metric) if given, else from the smallest eigenvector of the
    reduced cost (:func:`~rwhec_ros.core.model.reduction.reduce_cost`, eq. (48)) with optimal
    translations (eq. (47)); polishes to a critical point with a damped Riemannian Newton method;
    and analyses the exact Hessian there. ``x^T Q x`` is the negative log-likelihood, so the inverse
    Hessian predicts the covariance of the estimate. Null directions (normalised eigenvalue below
    ``null_tol``) are structural: insufficient; predicted standard deviations above the
    ``full_*`` thresholds: weak.
    """
    thr = thresholds or IdentifiabilityThresholds()
    layout = StateLayout(problem.M, problem.P)
    F = layout.n_frames
    names = problem.frame_names
    unknown = problem.unknown_scale
    Q = build_cost_matrix(problem)
    R, t_abs, alpha, reduced_eigs = _initial_point(problem, Q, layout)
    if solution is not None:
        X, Y, a = solution
        T = np.concatenate([check_transforms(X, what="solution X"),
                            check_transforms(Y, what="solution Y")])
        if T.shape[0] != F:
            raise ValueError(f"solution: expected {problem.M} X and {problem.P} Y transforms, "
                             f"got {len(X)} and {len(Y)}")
        alpha = float(a) if unknown else 1.0
        if not np.isfinite(alpha) or alpha <= 0:
            raise ValueError(f"solution alpha must be finite and > 0, got {a!r}")
        R, t_abs = T[:, :3, :3], alpha * T[:, :3, 3]
    mc = _ManifoldCost(Q, layout, unknown)
    R, t_abs, alpha, f, grad, H, d, iters = _polish(mc, R, t_abs, alpha, max_iterations,
                                                    step_tol, thr.null_tol)
    Hn = H / np.outer(d, d)
    lam, U = np.linalg.eigh(0.5 * (Hn + Hn.T))
    null = lam < thr.null_tol
    Pnull = (U[:, null] ** 2).sum(axis=1)  # participation of each tangent coordinate
    keep = ~null
    C = (U[:, keep] / lam[keep]) @ U[:, keep].T / np.outer(d, d)
    c_rot = mc.c_rot
    reasons: list[str] = []
    if lam[0] < -thr.null_tol:
        reasons.append(f"negative curvature {lam[0]:.2e}: the linearisation point is not a local "
                       "minimum (predictions are rough)")
    rot_std: dict[str, float] = {}
    trans_std: dict[str, float] = {}
    frame_status: dict[str, IdentifiabilityStatus] = {}
    undetermined: list[str] = []
    part_tol = 1e-4  # share of a unit null vector (normalised coordinates) marking a frame
    a_idx = 3 * F
    scale_null = bool(unknown and Pnull[a_idx] > part_tol)
    for f_idx, name in enumerate(names):
        ts = slice(3 * f_idx, 3 * f_idx + 3)
        rs = slice(c_rot + 3 * f_idx, c_rot + 3 * f_idx + 3)
        rot_null = Pnull[rs].sum() > part_tol
        trans_null = Pnull[ts].sum() > part_tol
        if rot_null or trans_null:
            undetermined.append(name)
            what = []
            if trans_null:  # translation coordinates are in the frame's carrier
                what.append("translation along " + _null_axis(U[ts][:, null] / d[ts, None]))
            if rot_null:  # right perturbation R exp(w^): the axis in the carrier is R w
                what.append("rotation about " + _null_axis(R[f_idx] @ (U[rs][:, null]
                                                                       / d[rs, None])))
            reasons.append(f"{name}: {' and '.join(what)} (in its carrier) not determined "
                           "(null direction of the Hessian)")
            frame_status[name] = IdentifiabilityStatus.INSUFFICIENT
            rot_std[name] = float("inf") if rot_null else float(
                np.degrees(np.sqrt(np.linalg.eigvalsh(C[rs, rs])[-1])))
            trans_std[name] = float("inf")
            continue
        rot_std[name] = float(np.degrees(np.sqrt(max(np.linalg.eigvalsh(C[rs, rs])[-1], 0.0))))
        if unknown:
            if scale_null:
                trans_std[name] = float("inf")
            else:
                idx = np.r_[np.arange(3 * f_idx, 3 * f_idx + 3), a_idx]
                Jd = np.hstack([np.eye(3) / alpha, -t_abs[f_idx][:, None] / alpha**2])
                cov_t = Jd @ C[np.ix_(idx, idx)] @ Jd.T
                trans_std[name] = float(np.sqrt(max(np.linalg.eigvalsh(cov_t)[-1], 0.0)))
        else:
            trans_std[name] = float(np.sqrt(max(np.linalg.eigvalsh(C[ts, ts])[-1], 0.0)))
        weak = []
        if rot_std[name] > thr.full_rotation_std_deg:
            weak.append(f"rotation +-{rot_std[name]:.2f} deg (comfortable <= "
                        f"{thr.full_rotation_std_deg:g})")
        if trans_std[name] > thr.full_translation_std_m:
            weak.append(f"translation +-{1e3 * trans_std[name]:.1f} mm (comfortable <= "
                        f"{1e3 * thr.full_translation_std_m:g})")
        if weak:
            reasons.append(f"{name}: predicted " + ", ".join(weak))
            frame_status[name] = IdentifiabilityStatus.WEAK
        else:
            frame_status[name] = IdentifiabilityStatus.IDENTIFIABLE
    scale_std = None
    if unknown:
        if scale_null:
            scale_std = float("inf")
            reasons.append("scale not determined (null direction of the Hessian)")
        else:
            scale_std = float(np.sqrt(max(C[a_idx, a_idx], 0.0)) / abs(alpha))
            if scale_std > thr.full_scale_rel_std:
                reasons.append(f"scale: predicted +-{100 * scale_std:.2g}% (comfortable <= "
                               f"{100 * thr.full_scale_rel_std:g}%)")
    status = worst_status(frame_status.values())
    if scale_null:
        status = IdentifiabilityStatus.INSUFFICIENT
    elif scale_std is not None and scale_std > thr.full_scale_rel_std:
        status = worst_status([status, IdentifiabilityStatus.WEAK])
    return NumericCheck(
        status=status,
        reasons=reasons,
        null_dim=int(null.sum()),
        smallest_eigenvalues=[float(v) for v in lam[: min(6, lam.size)]],
        undetermined_frames=undetermined,
        scale_undetermined=scale_null,
        frame_status=frame_status,
        rotation_std_deg=rot_std,
        translation_std_m=trans_std,
        scale_rel_std=scale_std,
        reduced_eigenvalues=reduced_eigs,
        cost=float(f),
        gradient_norm=float(np.linalg.norm(grad)),
        iterations=int(iters),
        from_solution=solution is not None,
    )

