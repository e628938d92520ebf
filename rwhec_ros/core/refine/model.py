"""The corner-level measurement model: the reprojection of every corner through the chain.

For a view (:mod:`.views`) of target ``X_j`` by camera ``Y_k`` with pose-stream transform ``A``
and corner ``p`` (target frame, nominal), the predicted pixel is::

    u = pi_k( Y_k^-1  E_g A  X_j  p / alpha )      (camera moves: "y")
    u = pi_k( Y_k^-1  A E_g  X_j  p / alpha )      (target moves: "x")

``pi_k`` the camera's projection with its distortion, ``alpha`` the scale (1 for a known scale,
:class:`~rwhec_ros.core.result.CalibrationResult`'s ``scale``), and ``E_g = (exp(phi) , rho)``
the error of the pose sample of the view's pose group ``g``: a rigid motion of the *moving*
carrier in its own frame (a robot's or a motion-capture pose error moves the carrier it
measures), shared by every view of that sample. The error of a corner is ``u - u_detected``,
Gaussian with std ``sigma_k`` [px] per axis (per camera); ``rho`` and ``phi`` are Gaussian with
stds ``sigma_t`` [m] and ``sigma_r`` [rad] per axis (:mod:`.solver` estimates all of them from
the residuals). Without ``E_g`` (``sigma_t = sigma_r = 0``) this is the plain reprojection-error
fit of the issue; with it, the many corners of one image are not counted as independent
evidence about a pose that was measured once.

Parameters of a frame are perturbed as the package reports covariances
(:data:`rwhec_ros.core.analysis.uncertainty.CONVENTION`): ``t = t_hat + dt``,
``R = exp(phi^) R_hat``; the tangent vector is ``[dt, phi]`` per frame, X frames then Y frames,
then ``d alpha`` for an unknown scale. ``E_g`` is perturbed the same way.

Extension point (not built): a per-camera time offset ``delta_k`` would replace ``A`` by the
pose stream's pose at ``t_image + delta_k`` (``A(t + delta) ~ exp(delta xi) A`` with the
stream's twist ``xi`` at the stamp); it is one more global column per view (the view's local
block :attr:`Linearization.index` grows from 12/13 to 13/14 columns), the solver is unchanged.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from ..lie import hat, so3_exp, so3_log
from .views import CornerViews

__all__ = ["State", "Linearization", "linearize", "retract", "frame_difference",
           "predict_pixels", "SIDES"]

#: Which carrier the pose group's error moves: "y" the camera carrier (``E A``), "x" the target
#: carrier (``A E``).
SIDES = ("y", "x")


@dataclass(frozen=True)
class State:
    """A point of the refinement: the frames, the scale and the pose-group errors.

    Attributes
    ----------
    X : ndarray, shape (M, 4, 4)
    Y : ndarray, shape (P, 4, 4)
    alpha : float
    E : ndarray, shape (G, 4, 4)
        The pose errors of the groups (identity at the start).
    """

    X: np.ndarray
    Y: np.ndarray
    alpha: float
    E: np.ndarray

    @staticmethod
    def start(X: np.ndarray, Y: np.ndarray, alpha: float, n_groups: int) -> State:
        return State(np.array(X, float), np.array(Y, float), float(alpha),
                     np.tile(np.eye(4), (n_groups, 1, 1)))

    def without_pose_errors(self) -> State:
        """The same frames with every ``E_g`` the identity (what a user's overlay shows)."""
        return replace(self, E=np.tile(np.eye(4), (self.E.shape[0], 1, 1)))

    def pose_error_vectors(self) -> np.ndarray:
        """``[rho, log R]`` of every ``E_g``, shape (G, 6)."""
        if not self.E.shape[0]:
            return np.zeros((0, 6))
        return np.concatenate([self.E[:, :3, 3], so3_log(self.E[:, :3, :3])], axis=1)


@dataclass
class Linearization:
    """Residuals and Jacobians at a :class:`State` (module docstring).

    Attributes
    ----------
    residual : ndarray, shape (N, 2)
        ``(u - u_detected) / sigma_k`` (whitened).
    J_global : ndarray, shape (N, 2, L)
        Whitened derivatives with respect to the view's global columns ``index[view]``.
    J_group : ndarray, shape (N, 2, 6)
        Whitened derivatives with respect to the perturbation of the view's ``E_g``.
    index : ndarray of int, shape (V, L)
        Global tangent columns of each view: its X frame's six, its Y frame's six (and the
        scale's one).
    depth : ndarray, shape (N,)
        ``z`` of each corner in the camera frame (> 0 in front of it).
    """

    residual: np.ndarray
    J_global: np.ndarray
    J_group: np.ndarray
    index: np.ndarray
    depth: np.ndarray


def _gather(views: CornerViews, state: State, side: str):
    """Per-corner rotation/translation stacks of the chain and its intermediate points."""
    v = views.corner_view
    X, Y, E = state.X[views.view_x][v], state.Y[views.view_y][v], \
        state.E[views.view_group][v]
    A = views.A[v]
    q0 = views.points / state.alpha
    Rq0 = np.einsum("nij,nj->ni", X[:, :3, :3], q0)
    q1 = Rq0 + X[:, :3, 3]
    if side == "x":
        q1 = np.einsum("nij,nj->ni", E[:, :3, :3], q1) + E[:, :3, 3]
    q2 = np.einsum("nij,nj->ni", A[:, :3, :3], q1) + A[:, :3, 3]
    if side == "y":
        q2 = np.einsum("nij,nj->ni", E[:, :3, :3], q2) + E[:, :3, 3]
    d = q2 - Y[:, :3, 3]
    RYt = np.transpose(Y[:, :3, :3], (0, 2, 1))
    q3 = np.einsum("nij,nj->ni", RYt, d)
    return X, Y, E, A, q0, Rq0, q1, q2, d, RYt, q3


def _project(views: CornerViews, cameras: Mapping, q3: np.ndarray, jacobian: bool):
    cam = views.view_y[views.corner_view]
    uv = np.zeros((q3.shape[0], 2))
    Jp = np.zeros((q3.shape[0], 2, 3)) if jacobian else None
    for k in np.unique(cam):
        m = cam == k
        u, J = cameras[views.y_names[k]].project_with_jacobian(q3[m])
        uv[m] = u
        if jacobian:
            Jp[m] = J
    return uv, Jp


def predict_pixels(views: CornerViews, cameras: Mapping, state: State, side: str
                   ) -> tuple[np.ndarray, np.ndarray]:
    """Predicted pixels (N, 2) of every corner and their depths (N,) at ``state``."""
    q3 = _gather(views, state, side)[-1]
    return _project(views, cameras, q3, False)[0], q3[:, 2]


def global_index(views: CornerViews, unknown_scale: bool) -> np.ndarray:
    """:attr:`Linearization.index` of every view."""
    M = len(views.x_names)
    cols = [6 * views.view_x[:, None] + np.arange(6),
            6 * (M + views.view_y[:, None]) + np.arange(6)]
    if unknown_scale:
        n = 6 * (M + len(views.y_names))
        cols.append(np.full((views.n_views, 1), n))
    return np.concatenate(cols, axis=1).astype(np.intp)


def linearize(views: CornerViews, cameras: Mapping, state: State, sigma_px: np.ndarray,
              side: str, unknown_scale: bool) -> Linearization:
    """Whitened residuals and Jacobians at ``state`` (``sigma_px``: per camera, (P,))."""
    X, Y, E, A, q0, Rq0, q1, q2, d, RYt, q3 = _gather(views, state, side)
    uv, Jp = _project(views, cameras, q3, True)
    w = 1.0 / sigma_px[views.view_y[views.corner_view]]
    n = q3.shape[0]
    # d q3 / d q2 (after E on the camera side) and d q3 / d q1 (before A)
    M3 = RYt
    T1 = M3 @ A[:, :3, :3]
    if side == "y":
        T1 = M3 @ E[:, :3, :3] @ A[:, :3, :3]
        G_rho, G_phi = M3, -M3 @ hat(q2 - E[:, :3, 3])
    else:
        G_rho = T1
        G_phi = -T1 @ hat(q1 - E[:, :3, 3])
        T1 = T1 @ E[:, :3, :3]
    cols = [T1, -T1 @ hat(Rq0), -M3, M3 @ hat(d)]
    if unknown_scale:
        cols.append(-(T1 @ Rq0[:, :, None]) / state.alpha)
    Jq = np.concatenate(cols, axis=2)  # (N, 3, L)
    Jg = np.concatenate([G_rho, G_phi], axis=2)  # (N, 3, 6)
    Jpw = Jp * w[:, None, None]
    return Linearization(
        residual=(uv - views.pixels) * w[:, None],
        J_global=Jpw @ Jq, J_group=Jpw @ Jg,
        index=global_index(views, unknown_scale), depth=q3[:, 2].reshape(n))


def frame_difference(T: np.ndarray, T_ref: np.ndarray) -> np.ndarray:
    """``[t - t_ref, log(R R_ref^T)]`` of frames ``T`` (..., 4, 4) about ``T_ref`` (same shape):
    the tangent of the covariances (module docstring; what :func:`retract` adds), shape
    (..., 6)."""
    T, T_ref = np.asarray(T, float), np.asarray(T_ref, float)
    return np.concatenate([T[..., :3, 3] - T_ref[..., :3, 3],
                           so3_log(T[..., :3, :3] @ np.swapaxes(T_ref[..., :3, :3], -1, -2))],
                          axis=-1)


def retract(state: State, d_global: np.ndarray, d_group: np.ndarray, unknown_scale: bool
            ) -> State:
    """``state`` moved by the tangent steps ``d_global`` (6 per frame, X then Y, [+1 scale]) and
    ``d_group`` (G, 6) (module docstring)."""
    M, P = state.X.shape[0], state.Y.shape[0]
    d = np.asarray(d_global, float)
    frames = d[:6 * (M + P)].reshape(M + P, 6)

    def move(T: np.ndarray, dv: np.ndarray) -> np.ndarray:
        out = np.array(T, float)
        out[:, :3, 3] += dv[:, :3]
        out[:, :3, :3] = so3_exp(dv[:, 3:]) @ T[:, :3, :3]
        return out

    alpha = state.alpha + (float(d[6 * (M + P)]) if unknown_scale else 0.0)
    E = move(state.E, np.asarray(d_group, float)) if state.E.shape[0] else state.E
    return State(move(state.X, frames[:M]) if M else state.X,
                 move(state.Y, frames[M:]), alpha, E)
