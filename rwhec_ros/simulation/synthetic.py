"""Seeded generators of synthetic RWHEC data and the paper's noise model (Section 4.2).

Randomness only through a passed-in :class:`numpy.random.Generator`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from ..core.lie import invert_transform, make_transform, so3_exp
from ..core.problem import Edge, Problem

__all__ = [
    "sample_langevin",
    "random_rotations",
    "random_transforms",
    "perturb_measurements",
    "GroundTruth",
    "random_instance",
    "random_camera_tag_graph",
    "planar_instance",
]


def sample_langevin(rng: np.random.Generator, kappa: float, size: int) -> np.ndarray:
    """Exact samples of the isotropic Langevin distribution ``Lang(I, kappa)`` on SO(3).

    The density w.r.t. the Haar measure is proportional to ``exp(kappa tr R)``; the rotation angle
    ``theta`` then has density proportional to ``exp(2 kappa cos theta) (1 - cos theta)`` on
    ``[0, pi]`` and the axis is uniform. ``theta`` is drawn by rejection from a Maxwell (chi with 3
    degrees of freedom) proposal of scale ``pi / sqrt(8 kappa)``, which dominates the target because
    ``1 - cos theta <= theta^2 / 2`` and ``1 - cos theta >= 2 theta^2 / pi^2`` on ``[0, pi]``.
    ``kappa <= 0`` gives uniform rotations.

    Returns shape (size, 3, 3).
    """
    if size <= 0:
        return np.zeros((0, 3, 3))
    if not np.isfinite(kappa):
        raise ValueError(f"kappa must be finite, got {kappa!r}")
    if kappa <= 0:
        return Rotation.random(size, random_state=rng).as_matrix()
    s = np.pi / np.sqrt(8.0 * kappa)
    theta = np.empty(0)
    while theta.size < size:
        m = 2 * (size - theta.size) + 16
        cand = s * np.linalg.norm(rng.standard_normal((m, 3)), axis=1)
        cand = cand[cand <= np.pi]
        log_target = 2.0 * kappa * (np.cos(cand) - 1.0) + np.log(1.0 - np.cos(cand) + 1e-300)
        log_prop = np.log(0.5 * cand**2 + 1e-300) - 4.0 * kappa * cand**2 / np.pi**2
        accept = np.log(rng.random(cand.size)) < (log_target - log_prop)
        theta = np.concatenate([theta, cand[accept]])
    theta = theta[:size]
    axis = rng.standard_normal((size, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    return so3_exp(axis * theta[:, None])


def random_rotations(rng: np.random.Generator, size: int) -> np.ndarray:
    """Uniform random rotations, shape (size, 3, 3)."""
    return Rotation.random(size, random_state=rng).as_matrix()


def random_transforms(
    rng: np.random.Generator, size: int, translation_scale: float = 1.0
) -> np.ndarray:
    """Random rigid transforms (size, 4, 4): uniform rotation, Gaussian translation."""
    return make_transform(
        random_rotations(rng, size), translation_scale * rng.standard_normal((size, 3))
    )


def perturb_measurements(
    rng: np.random.Generator, B: np.ndarray, sigma: float, kappa: float, alpha: float = 1.0
) -> np.ndarray:
    """Apply the paper's noise model (Section 4.2, eq. (20)) to exact ``B`` (N, 4, 4).

    ``t_B <- alpha t_B + N(0, sigma^2 I)`` and ``R_B <- R_B R_eps`` with
    ``R_eps ~ Lang(I, kappa)``. ``sigma = 0`` and ``kappa = inf`` give no noise.
    """
    B = np.array(B, dtype=float)
    N = B.shape[0]
    out = B.copy()
    out[:, :3, 3] = alpha * B[:, :3, 3]
    if sigma > 0:
        out[:, :3, 3] += sigma * rng.standard_normal((N, 3))
    if np.isfinite(kappa):
        out[:, :3, :3] = B[:, :3, :3] @ sample_langevin(rng, kappa, N)
    return out


@dataclass(frozen=True)
class GroundTruth:
    """True extrinsics: ``X`` (M, 4, 4), ``Y`` (P, 4, 4) in problem order, and ``alpha``."""

    X: np.ndarray
    Y: np.ndarray
    alpha: float = 1.0


def random_instance(
    rng: np.random.Generator,
    M: int,
    P: int,
    edges: Sequence[tuple[int, int]] | None = None,
    n_per_edge: int = 20,
    sigma: float = 0.0,
    kappa: float = np.inf,
    *,
    unknown_scale: bool = False,
    alpha: float = 1.0,
    weight_sigma: float | None = None,
    weight_kappa: float | None = None,
) -> tuple[Problem, GroundTruth]:
    """A random generalized RWHEC instance with exact or noisy ``B`` and its ground truth.

    ``A`` are uniformly random poses (so every edge is identifiable); ``B = Y^-1 A X`` then
    perturbed with :func:`perturb_measurements`. ``edges`` defaults to the complete bipartite
    graph. Weights default to the noise levels (``sigma`` floored at 1 mm, ``kappa`` capped at
    1e4 for exact data). Frame names are ``x<j>`` and ``y<k>``.
    """
    if edges is None:
        edges = [(j, k) for j in range(M) for k in range(P)]
    X = random_transforms(rng, M)
    Y = random_transforms(rng, P)
    ws = weight_sigma if weight_sigma is not None else max(sigma, 1e-3)
    wk = weight_kappa if weight_kappa is not None else (min(kappa, 1e4))
    out_edges = []
    for j, k in edges:
        A = random_transforms(rng, n_per_edge)
        B = invert_transform(Y[k]) @ A @ X[j]
        B = perturb_measurements(rng, B, sigma, kappa, alpha)
        out_edges.append(Edge.build(f"x{j}", f"y{k}", A, B, sigma=ws, kappa=wk))
    problem = Problem(
        [f"x{j}" for j in range(M)], [f"y{k}" for k in range(P)], out_edges,
        unknown_scale=unknown_scale,
    )
    return problem, GroundTruth(X=X, Y=Y, alpha=alpha)


def random_camera_tag_graph(rng: np.random.Generator, M: int, P: int, per_camera: int
                            ) -> list[tuple[int, int]]:
    """Edges ``(j, k)`` of a random sparse camera-tag graph for :func:`random_instance`: every
    camera (Y frame ``k``) sees ``per_camera`` distinct random tags (X frames); a tag no camera
    sees is given to a random camera (so that every frame has an edge)."""
    if not 1 <= per_camera <= M:
        raise ValueError(f"per_camera: must be in 1..{M}, got {per_camera}")
    edges = set()
    for k in range(P):
        for j in rng.choice(M, per_camera, replace=False):
            edges.add((int(j), k))
    seen = {j for j, _ in edges}
    edges |= {(j, int(rng.integers(P))) for j in range(M) if j not in seen}
    return sorted(edges)


def planar_instance(
    rng: np.random.Generator,
    M: int = 2,
    P: int = 2,
    n_per_edge: int = 20,
    sigma: float = 0.01,
    kappa: float = 125.0,
    *,
    tilt: float = 0.0,
) -> tuple[Problem, GroundTruth]:
    """A ground robot: the rig (camera carrier) yaws about the world ``z`` axis and drives in the
    world ``xy`` plane among tags fixed in the world (``A = T_rig_world``), with Gaussian roll and
    pitch of ``tilt`` rad. With ``tilt = 0`` the heights of the cameras relative to the tags are
    not observable (motion about one axis, paper Section 6). Complete graph, frame names
    ``tag_<j>`` and ``cam<k>``, weights equal to the noise; ``B`` perturbed with
    :func:`perturb_measurements`."""
    X = random_transforms(rng, M)
    Y = random_transforms(rng, P)
    edges = []
    for j in range(M):
        for k in range(P):
            yaw = rng.uniform(-np.pi, np.pi, n_per_edge)
            rotvec = np.column_stack([tilt * rng.standard_normal((n_per_edge, 2)), yaw])
            T_world_rig = make_transform(Rotation.from_rotvec(rotvec).as_matrix(),
                                         np.column_stack([rng.uniform(-2, 2, (n_per_edge, 2)),
                                                          np.zeros(n_per_edge)]))
            A = invert_transform(T_world_rig)
            B = perturb_measurements(rng, invert_transform(Y[k]) @ A @ X[j], sigma, kappa)
            edges.append(Edge.build(f"tag_{j}", f"cam{k}", A, B, sigma=sigma, kappa=kappa))
    problem = Problem([f"tag_{j}" for j in range(M)], [f"cam{k}" for k in range(P)], edges)
    return problem, GroundTruth(X=X, Y=Y)
