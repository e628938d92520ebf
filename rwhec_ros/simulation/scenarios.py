"""The paper's simulation scenarios (Section 8), seeded and returning ``(Problem, GroundTruth)``.

Two systems, each with a known-scale and a monocular (unknown scale) variant:

* :func:`hand_camera_sphere` (Section 8.1, Tables 2 and 3): a hand-mounted camera observes a
  static target from poses on a sphere around it. ``X = T_hand_cam``, ``Y = T_base_target``,
  ``A_i = T_base_hand(i)``, ``B_i = T_target_cam(i)`` (eq. (6)), one edge.
* :func:`fixed_cameras_hand_target` (Section 8.2, Tables 4 and 5): four fixed cameras observe a
  hand-mounted target. ``X_j = T_base_cam_j``, ``Y = T_hand_target``, ``A_i = T_hand_base(i)``,
  ``B_ij = T_target_cam_j(i)``; the chain ``T_hand_base T_base_cam_j = T_hand_target
  T_target_cam_j`` (both ``T_hand_cam_j``) is ``A_i X_j = Y B_ij``. Four edges sharing ``A``.

As in the paper, the trajectory fixes the exact ``B`` (and the ground truth), the exact ``A``
follows from ``A = Y B X^-1``, and only ``B`` is perturbed (Section 4.2 assumptions):
``t_B <- t_B + N(0, sigma^2 I)``, ``R_B <- R_B R_eps`` with ``R_eps ~ Lang(I, kappa)``
(:func:`~rwhec_ros.simulation.synthetic.perturb_measurements`).

Monocular noise (Section 8: "we scale the translation component of the noisy B measurements by
alpha"): by default the noise is added first and the noisy translation is then scaled,
``t_B <- alpha (t_B + eps)``, so the noise in the scaled units has standard deviation
``alpha sigma``. Eq. (20) and ``perturb_measurements(..., alpha)`` instead add the noise after
scaling, ``alpha t_B + eps``; ``scale_after_noise=False`` selects that reading. The two differ by
the factor ``alpha`` on the noise (0.5 in the paper), i.e. a factor 2 in metric noise.

Ground truth and design choices the paper does not state (documented here; the MLE, Wang,
Dornaika and the hand-eye baselines are equivariant under ``X -> H X`` and ``Y -> G Y`` -- a
change of hand and base frame -- so their error statistics do not depend on the ground-truth
distributions, only on the trajectory of ``B``; OpenCV's robot-world methods with the
documented-frames mapping are the exception, see :mod:`~rwhec_ros.core.baselines`):

* 8.1: ``X``: uniform rotation, translation ``N(0, (0.1 m)^2 I)``; ``Y``: uniform rotation,
  translation ``N(0, (1 m)^2 I)``. The trajectory is a spiral on the sphere of radius ``r`` about
  the target origin: polar angle (from the target's ``+z``, the north pole) linear from 45 to
  135 degrees (latitudes +45 to -45) while the azimuth makes one full turn from a random start;
  optical axis ``z`` at the target origin, ``y`` towards the south pole, ``x = y x z``. The
  paper's monocular variant uses 50 poses on each of two spheres (1 m and 0.3 m). Of the
  readings we tried (whole sphere, polar caps, this band; ``benchmarks/paper_tables.md``), only
  an equatorial band reproduces the paper's pattern ``t_y`` well below ``t_x`` in Table 2.
* 8.2: see :func:`fixed_cameras_hand_target`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..core.lie import invert_transform, make_transform, so3_exp
from ..core.problem import Edge, Problem
from .synthetic import GroundTruth, perturb_measurements, random_rotations, random_transforms

__all__ = [
    "NoiseLevel",
    "PAPER_NOISE_LEVELS",
    "look_at_rotation",
    "sphere_spiral_directions",
    "sphere_camera_poses",
    "noisy_measurements",
    "hand_camera_sphere",
    "FixedCameraDesign",
    "target_visibility",
    "fixed_cameras_hand_target",
]


@dataclass(frozen=True)
class NoiseLevel:
    """One noise level of Section 8: Langevin concentration ``kappa``, translation std ``sigma``
    [m]."""

    kappa: float
    sigma: float

    @property
    def label(self) -> str:
        return f"kappa = {self.kappa:g}, sigma = {100 * self.sigma:g} cm"


#: The four noise levels of Tables 2-5, in the paper's row order.
PAPER_NOISE_LEVELS: tuple[NoiseLevel, ...] = (
    NoiseLevel(125.0, 0.01),
    NoiseLevel(125.0, 0.05),
    NoiseLevel(12.0, 0.01),
    NoiseLevel(12.0, 0.05),
)

_EZ = np.array([0.0, 0.0, 1.0])


def look_at_rotation(forward: np.ndarray, down: np.ndarray) -> np.ndarray:
    """Rotation(s) (..., 3, 3) whose columns are a camera's ``x, y, z`` axes: ``z`` along
    ``forward``, ``y`` along the part of ``down`` orthogonal to ``z``, ``x = y x z``.

    ``forward`` and ``down`` have shape (..., 3); ``down`` must not be parallel to ``forward``
    (``ValueError`` names the first offending index).
    """
    f = np.asarray(forward, float)
    d = np.broadcast_to(np.asarray(down, float), f.shape)
    z = f / np.linalg.norm(f, axis=-1, keepdims=True)
    y = d - np.sum(d * z, axis=-1, keepdims=True) * z
    ny = np.linalg.norm(y, axis=-1, keepdims=True)
    bad = (ny[..., 0] < 1e-9).reshape(-1)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"down[{i}] is parallel to forward[{i}]: {f.reshape(-1, 3)[i].tolist()}")
    y = y / ny
    x = np.cross(y, z)
    return np.stack([x, y, z], axis=-1)


def sphere_spiral_directions(
    n: int,
    *,
    polar_range_deg: tuple[float, float] = (45.0, 135.0),
    turns: float = 1.0,
    azimuth0: float = 0.0,
) -> np.ndarray:
    """Unit vectors (n, 3) along a spiral: polar angle (from ``+z``) linear over
    ``polar_range_deg`` while the azimuth advances ``turns`` full turns from ``azimuth0`` [rad]."""
    if n < 1:
        raise ValueError(f"n: need at least one pose, got {n}")
    lo, hi = polar_range_deg
    if not (0.0 < lo <= hi < 180.0):
        raise ValueError(f"polar_range_deg: need 0 < lo <= hi < 180, got {polar_range_deg}")
    theta = np.radians(np.linspace(lo, hi, n))
    phi = azimuth0 + 2.0 * np.pi * turns * np.arange(n) / n
    return np.stack(
        [np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], axis=1
    )


def sphere_camera_poses(directions: np.ndarray, radius: float) -> np.ndarray:
    """``T_target_cam`` (n, 4, 4) for cameras at ``radius * directions`` (target frame) whose
    optical axis ``z`` points at the target origin and whose ``y`` points towards the south pole
    (``-z`` of the target), Section 8.1."""
    if not np.isfinite(radius) or radius <= 0:
        raise ValueError(f"radius: must be finite and > 0, got {radius!r}")
    u = np.asarray(directions, float)
    u = u / np.linalg.norm(u, axis=1, keepdims=True)
    R = look_at_rotation(-u, -_EZ)
    return make_transform(R, radius * u)


def noisy_measurements(
    rng: np.random.Generator,
    B: np.ndarray,
    sigma: float,
    kappa: float,
    alpha: float = 1.0,
    *,
    scale_after_noise: bool = True,
) -> np.ndarray:
    """The paper's noise on exact ``B`` (N, 4, 4), with the monocular scaling of Section 8.

    ``scale_after_noise=True``: ``t <- alpha (t + eps)``; ``False``: ``t <- alpha t + eps``
    (eq. (20)); ``eps ~ N(0, sigma^2 I)``. Rotations: ``R <- R R_eps``, ``R_eps ~ Lang(I,
    kappa)``. ``sigma = 0`` and ``kappa = inf`` give exact data.
    """
    if scale_after_noise:
        out = perturb_measurements(rng, B, sigma, kappa, 1.0)
        out[:, :3, 3] *= alpha
        return out
    return perturb_measurements(rng, B, sigma, kappa, alpha)


def _weights(sigma: float, kappa: float, alpha: float, scale_after_noise: bool, ws, wk):
    """Default weights: the true noise of the data handed to the solver (floored for exact
    data): ``alpha sigma`` when the noise was scaled with the translations."""
    s_true = alpha * sigma if scale_after_noise else sigma
    ws = max(s_true, 1e-3) if ws is None else ws
    wk = min(kappa, 1e4) if wk is None else wk
    return ws, wk


def _check_level(sigma: float, kappa: float, alpha: float) -> None:
    if not np.isfinite(sigma) or sigma < 0:
        raise ValueError(f"sigma: must be finite and >= 0, got {sigma!r}")
    if np.isnan(kappa) or kappa <= 0:
        raise ValueError(f"kappa: must be > 0 (inf for no rotation noise), got {kappa!r}")
    if not np.isfinite(alpha) or alpha <= 0:
        raise ValueError(f"alpha: must be finite and > 0, got {alpha!r}")


def hand_camera_sphere(
    rng: np.random.Generator,
    sigma: float = 0.0,
    kappa: float = np.inf,
    *,
    monocular: bool = False,
    n_poses: int | None = None,
    radii: Sequence[float] | None = None,
    alpha: float = 0.5,
    polar_range_deg: tuple[float, float] = (45.0, 135.0),
    turns: float = 1.0,
    scale_after_noise: bool = True,
    weight_sigma: float | None = None,
    weight_kappa: float | None = None,
) -> tuple[Problem, GroundTruth]:
    """Section 8.1: hand-mounted camera, poses on sphere(s) around a static target.

    Parameters
    ----------
    rng : numpy.random.Generator
    sigma : float
        Translation noise standard deviation [m] (0: exact).
    kappa : float
        Langevin concentration of the rotation noise (``inf``: exact).
    monocular : bool
        Unknown scale (Table 3): ``n_poses`` per sphere over ``radii`` (default 50 on each of
        1 m and 0.3 m), ``B`` translations scaled by ``alpha``. Otherwise (Table 2) 100 poses on
        one sphere of radius 1 m and ``alpha = 1``.
    n_poses : int, optional
        Poses per sphere (default 100, or 50 for ``monocular``).
    radii : sequence of float, optional
        Sphere radii [m] (default ``(1.0,)``, or ``(1.0, 0.3)`` for ``monocular``).
    alpha : float
        True scale of the monocular measurements (ignored unless ``monocular``).
    polar_range_deg, turns : see :func:`sphere_spiral_directions`.
    scale_after_noise : bool
        Monocular noise order (module docstring).
    weight_sigma, weight_kappa : float, optional
        Precisions stored in the problem; default the true noise of the data (``alpha sigma``
        for scaled noise), floored at 1 mm / capped at 1e4 for exact data.

    Returns
    -------
    problem : Problem
        ``x_names = ("camera",)``, ``y_names = ("target",)``, one edge.
    truth : GroundTruth
        ``X = T_hand_cam`` (1, 4, 4), ``Y = T_base_target`` (1, 4, 4), ``alpha``.
    """
    _check_level(sigma, kappa, alpha)
    n = (50 if monocular else 100) if n_poses is None else int(n_poses)
    radii = tuple((1.0, 0.3) if monocular else (1.0,)) if radii is None else tuple(radii)
    if not radii:
        raise ValueError("radii: need at least one sphere radius, got ()")
    a = float(alpha) if monocular else 1.0
    X = random_transforms(rng, 1, 0.1)
    Y = random_transforms(rng, 1, 1.0)
    B = np.concatenate(
        [
            sphere_camera_poses(
                sphere_spiral_directions(
                    n,
                    polar_range_deg=polar_range_deg,
                    turns=turns,
                    azimuth0=rng.uniform(0.0, 2.0 * np.pi),
                ),
                r,
            )
            for r in radii
        ]
    )
    A = Y[0] @ B @ invert_transform(X[0])
    B_noisy = noisy_measurements(rng, B, sigma, kappa, a, scale_after_noise=scale_after_noise)
    ws, wk = _weights(sigma, kappa, a, scale_after_noise, weight_sigma, weight_kappa)
    edge = Edge.build("camera", "target", A, B_noisy, sigma=ws, kappa=wk)
    problem = Problem(["camera"], ["target"], [edge], unknown_scale=monocular)
    return problem, GroundTruth(X=X, Y=Y, alpha=a)


@dataclass(frozen=True)
class FixedCameraDesign:
    """Geometry of the Section 8.2 simulation (base frame ``z`` up, metres and degrees).

    Attributes
    ----------
    workspace_center : tuple of float
        Centre of the hand-target workspace in the base frame.
    workspace_half_extent : tuple of float
        Target positions are uniform in ``center +- half_extent``.
    camera_distance : float
        Distance of the cameras from the workspace centre.
    camera_azimuths_deg, camera_elevations_deg : tuple of float
        Camera directions seen from the workspace centre (azimuth about base ``z`` from ``+x``,
        elevation above the horizontal), one entry per camera.
    camera_position_jitter, camera_aim_jitter : float
        Per-run Gaussian jitter [m] of the camera positions and of their look-at points.
    target_rotation : {"uniform", "facing"}
        ``uniform``: target orientations uniform on SO(3) (strong excitation about all axes);
        ``facing``: the target normal (``+z``) is tilted from the mean camera direction by a
        uniform angle in ``[0, max_tilt_deg]`` about a uniform axis and rolled about the normal
        by up to ``+-max_roll_deg`` (a planar target facing the cameras).
    max_tilt_deg, max_roll_deg : float
        See ``target_rotation="facing"``.
    fov_half_angle_deg : float
        The target origin must lie within this angle of every optical axis, in front of it.
    max_incidence_deg : float or None
        If set, the angle between the target normal and the direction to every camera must not
        exceed it (the face of a planar target is seen by all cameras); ``None``: not checked.
    min_depth : float
        Minimum depth of the target origin in front of every camera [m].
    """

    workspace_center: tuple[float, float, float] = (0.6, 0.0, 0.4)
    workspace_half_extent: tuple[float, float, float] = (0.4, 0.4, 0.3)
    camera_distance: float = 1.5
    camera_azimuths_deg: tuple[float, ...] = (-30.0, 30.0, -30.0, 30.0)
    camera_elevations_deg: tuple[float, ...] = (5.0, 5.0, 35.0, 35.0)
    camera_position_jitter: float = 0.05
    camera_aim_jitter: float = 0.05
    target_rotation: str = "uniform"
    max_tilt_deg: float = 30.0
    max_roll_deg: float = 90.0
    fov_half_angle_deg: float = 60.0
    max_incidence_deg: float | None = None
    min_depth: float = 0.3


def target_visibility(
    T_base_cam: np.ndarray,
    T_base_target: np.ndarray,
    *,
    fov_half_angle_deg: float = 60.0,
    max_incidence_deg: float | None = None,
    min_depth: float = 0.3,
) -> np.ndarray:
    """Whether each target pose is visible to each camera, shape (N, C) bool.

    ``T_base_cam`` (C, 4, 4), ``T_base_target`` (N, 4, 4). Visible means: target origin at depth
    ``>= min_depth`` in front of the camera and within ``fov_half_angle_deg`` of the optical
    axis, and (if ``max_incidence_deg`` is set) the target normal (its ``+z``) within
    ``max_incidence_deg`` of the direction from the target to the camera.
    """
    Tc = np.asarray(T_base_cam, float)
    Tt = np.asarray(T_base_target, float)
    p_cam = np.einsum(
        "cji,ncj->nci", Tc[:, :3, :3], Tt[:, None, :3, 3] - Tc[None, :, :3, 3]
    )  # target origin in each camera frame, (N, C, 3)
    depth = p_cam[..., 2]
    dist = np.linalg.norm(p_cam, axis=-1)
    off_axis = np.degrees(np.arccos(np.clip(depth / np.maximum(dist, 1e-12), -1.0, 1.0)))
    visible = (depth >= min_depth) & (off_axis <= fov_half_angle_deg)
    if max_incidence_deg is not None:
        to_cam = Tc[None, :, :3, 3] - Tt[:, None, :3, 3]
        to_cam /= np.linalg.norm(to_cam, axis=-1, keepdims=True)
        normal = Tt[:, None, :3, 2]
        incidence = np.degrees(np.arccos(np.clip(np.sum(to_cam * normal, -1), -1.0, 1.0)))
        visible &= incidence <= max_incidence_deg
    return visible


def _fixed_cameras(rng: np.random.Generator, d: FixedCameraDesign) -> np.ndarray:
    az = np.radians(np.asarray(d.camera_azimuths_deg, float))
    el = np.radians(np.asarray(d.camera_elevations_deg, float))
    if az.shape != el.shape or az.size < 1:
        raise ValueError(
            f"design: camera_azimuths_deg and camera_elevations_deg must have the same non-zero "
            f"length, got {az.size} and {el.size}"
        )
    c = np.asarray(d.workspace_center, float)
    dirs = np.stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)], axis=1)
    pos = c + d.camera_distance * dirs + d.camera_position_jitter * rng.standard_normal(dirs.shape)
    aim = c + d.camera_aim_jitter * rng.standard_normal(dirs.shape)
    R = look_at_rotation(aim - pos, -_EZ)
    return make_transform(R, pos)


def _target_poses(
    rng: np.random.Generator,
    d: FixedCameraDesign,
    T_base_cam: np.ndarray,
    n: int,
    max_batches: int = 1000,
) -> np.ndarray:
    c = np.asarray(d.workspace_center, float)
    h = np.asarray(d.workspace_half_extent, float)
    n0 = np.mean(T_base_cam[:, :3, 3], axis=0) - c
    n0 /= np.linalg.norm(n0)
    R0 = look_at_rotation(n0, -_EZ)  # columns: target x, y, z (= n0)
    if d.target_rotation not in ("uniform", "facing"):
        raise ValueError(
            f"design.target_rotation: expected 'uniform' or 'facing', got {d.target_rotation!r}"
        )
    out: list[np.ndarray] = []
    for _ in range(max_batches):
        m = 4 * n
        if d.target_rotation == "uniform":
            R = random_rotations(rng, m)
        else:
            tilt_axis = rng.standard_normal((m, 2))
            tilt_axis /= np.linalg.norm(tilt_axis, axis=1, keepdims=True)
            tilt = np.radians(d.max_tilt_deg) * rng.random(m)
            roll = np.radians(d.max_roll_deg) * rng.uniform(-1.0, 1.0, m)
            phi = np.zeros((m, 3))
            phi[:, :2] = tilt_axis * tilt[:, None]
            R = R0 @ so3_exp(phi) @ so3_exp(roll[:, None] * _EZ)
        p = c + h * rng.uniform(-1.0, 1.0, (m, 3))
        T = make_transform(R, p)
        vis = target_visibility(
            T_base_cam,
            T,
            fov_half_angle_deg=d.fov_half_angle_deg,
            max_incidence_deg=d.max_incidence_deg,
            min_depth=d.min_depth,
        ).all(axis=1)
        out.extend(T[vis])
        if len(out) >= n:
            return np.stack(out[:n])
    raise ValueError(
        f"design: found only {len(out)} of {n} target poses visible to all cameras; widen "
        "fov_half_angle_deg / max_incidence_deg or move the cameras"
    )


def fixed_cameras_hand_target(
    rng: np.random.Generator,
    sigma: float = 0.0,
    kappa: float = np.inf,
    *,
    monocular: bool = False,
    n_poses: int = 108,
    alpha: float = 0.5,
    design: FixedCameraDesign | None = None,
    scale_after_noise: bool = True,
    weight_sigma: float | None = None,
    weight_kappa: float | None = None,
) -> tuple[Problem, GroundTruth]:
    """Section 8.2: four fixed cameras observe a hand-mounted target through ``n_poses`` arm
    poses, the target visible to every camera in every pose.

    Design (:class:`FixedCameraDesign`, redrawn every run): the cameras sit 1.5 m from the
    workspace centre ``(0.6, 0, 0.4)`` at azimuths +-30 deg and elevations 5 and 35 deg (+5 cm
    jitter), looking at the centre (+5 cm jitter) with ``y`` towards the floor. Target poses are
    rejection-sampled: position uniform in an 80 x 80 x 60 cm box, orientation uniform on SO(3)
    (rotations about all axes, Corollary 4), kept only if :func:`target_visibility` holds for
    every camera (at least 0.3 m in front and within 60 deg of each optical axis). The paper
    only says the target is "always visible to every fixed camera"; a planar target that must
    also face all four cameras (``target_rotation="facing"``, ``max_incidence_deg=60``) limits
    the excitation and gives clearly larger errors. Hand poses follow from
    ``T_base_hand = T_base_target Y^-1``.

    Ground truth: ``X_j = T_base_cam_j`` from the design; ``Y = T_hand_target`` with uniform
    rotation and translation ``N(0, (0.1 m)^2 I)``.

    Parameters
    ----------
    rng : numpy.random.Generator
    sigma, kappa : float
        Noise of ``B`` (0 / ``inf``: exact).
    monocular : bool
        Unknown scale (Table 5): ``B`` translations scaled by ``alpha``.
    n_poses : int
        Arm poses (108 in the paper).
    alpha : float
        True monocular scale.
    design : FixedCameraDesign, optional
    scale_after_noise : bool
        Monocular noise order (module docstring).
    weight_sigma, weight_kappa : float, optional
        As in :func:`hand_camera_sphere`.

    Returns
    -------
    problem : Problem
        ``x_names = ("cam0", .., "cam3")``, ``y_names = ("target",)``, edges ``(cam_j,
        target)`` each with ``n_poses`` pairs sharing the same ``A``.
    truth : GroundTruth
        ``X`` (4, 4, 4), ``Y`` (1, 4, 4), ``alpha``.
    """
    _check_level(sigma, kappa, alpha)
    if n_poses < 1:
        raise ValueError(f"n_poses: need at least one pose, got {n_poses}")
    d = FixedCameraDesign() if design is None else design
    a = float(alpha) if monocular else 1.0
    X = _fixed_cameras(rng, d)  # T_base_cam_j
    Y = make_transform(random_rotations(rng, 1), 0.1 * rng.standard_normal((1, 3)))
    T_base_target = _target_poses(rng, d, X, int(n_poses))
    A = invert_transform(T_base_target @ invert_transform(Y[0]))  # T_hand_base
    T_target_base = invert_transform(T_base_target)
    ws, wk = _weights(sigma, kappa, a, scale_after_noise, weight_sigma, weight_kappa)
    names = [f"cam{j}" for j in range(X.shape[0])]
    edges = []
    for j, name in enumerate(names):
        B = T_target_base @ X[j]  # T_target_cam_j
        B_noisy = noisy_measurements(rng, B, sigma, kappa, a, scale_after_noise=scale_after_noise)
        edges.append(Edge.build(name, "target", A, B_noisy, sigma=ws, kappa=wk))
    problem = Problem(names, ["target"], edges, unknown_scale=monocular)
    return problem, GroundTruth(X=X, Y=Y, alpha=a)
