"""Fits of the corner model: robust Gauss-Newton at a given noise, the noise from the residuals,
and the covariance of each fit.

* :meth:`CornerFit.gauss_newton`: steps of :mod:`.normal` on the robust cost of :mod:`.model`
  (Huber on each corner's whitened distance, the Gaussian prior on the pose-group errors),
  each halved until the cost decreases, until a step moves no unknown by more than 1e-2 of its
  conditional std (the Huber weights make IRLS converge linearly, not quadratically).
* :meth:`CornerFit.estimate_noise`: alternates those steps with Foerstner's
  variance-component update -- each component's weighted square sum over its redundancy
  ``n_c - tr(N^-1 H_c)`` (:func:`.normal.traces`): per camera the corner noise ``sigma_k``
  [px per axis], and the pose stream's noise ``sigma_t`` [m] and ``sigma_r`` [rad] per axis of
  the moving carrier -- until no estimate changes by more than the tolerance.
* Covariances, in the tangent coordinates of :mod:`.model` (the package's convention): of the fit
  with the pose errors (``S^-1``: the corner-level ``(J^T W J)^-1`` with the pose errors
  marginalised), and of the *plain* fit that holds them at zero (corners independent, the
  reprojection-error fit of other tools), whose spread under the same noise is the sandwich
  ``H^-1 (H + sum_g B_g Sigma_A B_g^T) H^-1``: the corners of one pose sample share its error.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .model import State, global_index, linearize, predict_pixels, retract
from .normal import Groups, huber, inverse, normal_equations, solve_step, traces
from .views import CornerViews

__all__ = ["Noise", "CornerFit", "RefinementFailed"]

_FLOOR_PX, _FLOOR_M, _FLOOR_RAD = 1e-4, 1e-7, 1e-8
#: ``sigma`` of the pose-group errors of the plain fit (held at zero).
_HELD = 1e-12


class RefinementFailed(ValueError):
    """The data do not allow the refinement (the message says why)."""


_SINGULAR = "the corners do not determine every direction of the frames (singular normal matrix)"


@dataclass(frozen=True)
class Noise:
    """The noise of the corner model: ``sigma_px`` (P,) per camera [px per axis], the pose
    errors' ``sigma_m`` and ``sigma_rad`` per axis (``plain``: held at zero)."""

    sigma_px: np.ndarray
    sigma_m: float
    sigma_rad: float
    plain: bool = False

    def prior_weights(self) -> np.ndarray:
        """``1 / sigma^2`` of the six pose-group coordinates."""
        if self.plain:
            return np.full(6, 1.0 / _HELD ** 2)
        return np.repeat([1.0 / self.sigma_m ** 2, 1.0 / self.sigma_rad ** 2], 3)

    def as_plain(self) -> Noise:
        return Noise(self.sigma_px, self.sigma_m, self.sigma_rad, plain=True)


class CornerFit:
    """One set of views and cameras, fitted at a given :class:`Noise` (module docstring)."""

    def __init__(self, views: CornerViews, cameras: Mapping, unknown_scale: bool, side: str,
                 huber_c: float) -> None:
        self.views, self.cameras, self.side, self.c = views, cameras, side, huber_c
        self.unknown_scale = unknown_scale
        M, P = len(views.x_names), len(views.y_names)
        self.p = 6 * (M + P) + (1 if unknown_scale else 0)
        self.groups = Groups.build(views, global_index(views, unknown_scale), self.p)
        self.camera_of_corner = views.view_y[views.corner_view]

    # ------------------------------------------------------------------ pieces
    def cost(self, state: State, noise: Noise) -> float:
        """The robust cost (``inf`` with a corner at or behind its camera)."""
        uv, depth = predict_pixels(self.views, self.cameras, state, self.side)
        if not np.all(depth > 0):
            return np.inf
        s = np.linalg.norm((uv - self.views.pixels)
                           / noise.sigma_px[self.camera_of_corner][:, None], axis=1)
        return float(huber(s, self.c)[0].sum()
                     + np.sum(noise.prior_weights() * state.pose_error_vectors() ** 2))

    def normal(self, state: State, noise: Noise):
        """``(linearization, whitened distances, Huber weights, normal equations)``."""
        lin = linearize(self.views, self.cameras, state, noise.sigma_px, self.side,
                        self.unknown_scale)
        s = np.linalg.norm(lin.residual, axis=1)
        w = huber(s, self.c)[1]
        return lin, s, w, normal_equations(self.views, lin, self.groups, w,
                                           noise.prior_weights(), state.pose_error_vectors())

    def rms(self, state: State) -> dict[str, float]:
        """Per camera the RMS corner distance [px] with the pose errors zero (an overlay)."""
        uv, _ = predict_pixels(self.views, self.cameras, state.without_pose_errors(), self.side)
        d2 = np.sum((uv - self.views.pixels) ** 2, axis=1)
        cam = self.camera_of_corner
        return {self.views.y_names[k]: float(np.sqrt(np.mean(d2[cam == k])))
                for k in np.unique(cam)}

    # ------------------------------------------------------------------ fits
    def gauss_newton(self, state: State, noise: Noise, max_steps: int = 20,
                     frames_fixed: bool = False, tol: float = 1e-2) -> State:
        """Steps at fixed ``noise`` until one moves no unknown by more than ``tol`` of its
        conditional std (module docstring); ``frames_fixed``: only the pose-group errors move
        (the cost of given frames with the pose errors re-fitted)."""
        f0 = self.cost(state, noise)
        for _ in range(max_steps):
            normal = self.normal(state, noise)[3]
            step = solve_step(normal, self.groups)
            if step is None:
                raise RefinementFailed(_SINGULAR)
            dtheta, dg = step
            if frames_fixed:
                dtheta = np.zeros_like(dtheta)
                dg = -np.einsum("gij,gj->gi", normal.Dinv, normal.ga)
            size = max(float(np.max(np.abs(dtheta) * np.sqrt(np.diag(normal.S)))),
                       float(np.max(np.abs(dg) * np.sqrt(np.einsum(
                           "gii->gi", np.linalg.inv(normal.Dinv))), initial=0.0)))
            for _ in range(12):
                new = retract(state, dtheta, dg, self.unknown_scale)
                f1 = self.cost(new, noise)
                if f1 <= f0:
                    break
                dtheta, dg = 0.5 * dtheta, 0.5 * dg
            else:
                return state
            state, f0 = new, f1
            if size < tol:
                break
        return state

    def estimate_noise(self, state: State, noise: Noise, max_rounds: int, tolerance: float
                       ) -> tuple[State, Noise, int, bool, float]:
        """Gauss-Newton and variance-component rounds (module docstring) from ``noise``:
        ``(state, noise, rounds, converged, last relative change)``."""
        counts = np.bincount(self.camera_of_corner, minlength=len(self.views.y_names))
        G = self.views.n_groups
        change, rounds = np.inf, 0
        for rounds in range(1, max_rounds + 1):
            state = self.gauss_newton(state, noise)
            lin, s, w, normal = self.normal(state, noise)
            Sinv = inverse(normal.S)
            if Sinv is None:
                raise RefinementFailed(_SINGULAR)
            prior_w = noise.prior_weights()
            tr_cam, tr_rho, tr_phi = traces(self.views, lin, self.groups, normal, Sinv, prior_w)
            omega = np.bincount(self.camera_of_corner, weights=w * s * s,
                                minlength=counts.size)
            red = 2.0 * counts - tr_cam
            sig = noise.sigma_px
            new_px = np.where(red > 0.5, sig * np.sqrt(omega / np.maximum(red, 0.5)), sig)
            new_px = np.maximum(new_px, _FLOOR_PX)
            pose = np.array([noise.sigma_m, noise.sigma_rad])
            new_pose = pose.copy()
            if not noise.plain and G:
                vec = state.pose_error_vectors()
                for i, (tr, floor) in enumerate(((tr_rho, _FLOOR_M), (tr_phi, _FLOOR_RAD))):
                    r_i = 3.0 * G - tr
                    if r_i > 0.5:
                        om = float(np.sum(vec[:, 3 * i:3 * i + 3] ** 2)) / pose[i] ** 2
                        new_pose[i] = max(pose[i] * np.sqrt(om / r_i), floor)
            change = float(max(np.max(np.abs(new_px / sig - 1.0)),
                               np.max(np.abs(new_pose / pose - 1.0))))
            noise = Noise(new_px, float(new_pose[0]), float(new_pose[1]), noise.plain)
            if change < tolerance:
                return self.gauss_newton(state, noise), noise, rounds, True, change
        return self.gauss_newton(state, noise), noise, rounds, False, change

    # ------------------------------------------------------------------ covariances
    def covariance(self, state: State, noise: Noise) -> tuple[np.ndarray, int]:
        """``(covariance (p, p), corners beyond the Huber threshold)`` of the estimate at
        ``state``: ``S^-1`` of the fit with pose errors; for ``noise.plain`` the sandwich of the
        plain fit under the pose noise of ``noise`` (module docstring)."""
        lin, s, w, normal = self.normal(state, Noise(noise.sigma_px, noise.sigma_m,
                                                    noise.sigma_rad))
        n_down = int(np.sum(w < 1.0))
        if not noise.plain:
            out = inverse(normal.S)
            if out is None:
                raise RefinementFailed(_SINGULAR)
            return out, n_down
        Hinv = inverse(normal.H)
        if Hinv is None:
            raise RefinementFailed(_SINGULAR)
        sigma_a = np.repeat([noise.sigma_m ** 2, noise.sigma_rad ** 2], 3)
        middle = np.array(normal.H, copy=True)
        p = self.p
        for blk in self.groups.blocks():
            sup = self.groups.support[blk]
            width = sup.shape[1]
            part = (normal.B[blk] * sigma_a) @ np.transpose(normal.B[blk], (0, 2, 1))
            rows = np.repeat(sup, width, axis=1).ravel()
            cols = np.tile(sup, (1, width)).ravel()
            keep = (rows < p) & (cols < p)
            np.add.at(middle, (rows[keep], cols[keep]), part.ravel()[keep])
        out = Hinv @ middle @ Hinv
        return 0.5 * (out + out.T), n_down
