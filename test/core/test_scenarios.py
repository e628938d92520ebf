"""Section 8 scenario generators and the Langevin sampler they rely on."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate, stats

from rwhec_ros.core.baselines import run_baseline
from rwhec_ros.core.lie import invert_transform, rotation_angle, so3_log
from rwhec_ros.simulation.scenarios import (
    PAPER_NOISE_LEVELS,
    FixedCameraDesign,
    fixed_cameras_hand_target,
    hand_camera_sphere,
    noisy_measurements,
    sphere_camera_poses,
    sphere_spiral_directions,
    target_visibility,
)
from rwhec_ros.simulation.synthetic import sample_langevin

#: Exact data built by composing float64 transforms: residuals are round-off (~1e-15); 1e-9
#: leaves margin for the ~1 m lever arms.
EXACT_TOL = 1e-9


def _langevin_angle_cdf(kappa: float):
    """Numerically integrated CDF of p(theta) ∝ exp(2 kappa cos theta) (1 - cos theta) on
    [0, pi] (trapezoid rule on 2e5 intervals: CDF error ~1e-9, far below KS resolution)."""
    th = np.linspace(0.0, np.pi, 200_001)
    pdf = np.exp(2.0 * kappa * (np.cos(th) - 1.0)) * (1.0 - np.cos(th))
    cdf = integrate.cumulative_trapezoid(pdf, th, initial=0.0)
    cdf /= cdf[-1]
    return lambda x: np.interp(x, th, cdf)


@pytest.mark.parametrize("kappa", [0.5, 12.0, 125.0])
def test_langevin_angle_matches_analytic_density_ks(kappa):
    theta = rotation_angle(sample_langevin(np.random.default_rng(0), kappa, 20_000))
    cdf = _langevin_angle_cdf(kappa)
    # Fixed seed, so deterministic; a correct sampler fails at this level 0.1 % of seeds.
    assert stats.kstest(theta, cdf).pvalue > 1e-3
    # Power check on the same sample size: a 10 % wrong concentration and a von Mises angle
    # (a common mistake, rotation-vector variance 1/(3 kappa) instead of 1/(2 kappa)) are caught.
    assert stats.kstest(theta, _langevin_angle_cdf(1.1 * kappa)).pvalue < 1e-6
    vm = np.abs(np.random.default_rng(1).vonmises(0.0, kappa, 20_000))
    assert stats.kstest(vm, cdf).pvalue < 1e-6


def test_langevin_axis_is_isotropic():
    phi = so3_log(sample_langevin(np.random.default_rng(2), 12.0, 20_000))
    axis_z = phi[:, 2] / np.linalg.norm(phi, axis=1)
    # The z-component of a uniform unit axis is uniform on [-1, 1] (Archimedes).
    assert stats.kstest(axis_z, stats.uniform(loc=-1.0, scale=2.0).cdf).pvalue > 1e-3


def _residual(problem, gt, alpha=1.0):
    worst = 0.0
    for e, j, k in zip(problem.edges, problem.edge_x, problem.edge_y, strict=True):
        B = e.B.copy()
        B[:, :3, 3] /= alpha
        worst = max(worst, np.abs(e.A @ gt.X[j] - gt.Y[k] @ B).max())
    return worst


def test_hand_camera_sphere_geometry_and_exact_data():
    problem, gt = hand_camera_sphere(np.random.default_rng(3))
    assert (problem.M, problem.P, len(problem.edges)) == (1, 1, 1)
    assert problem.edges[0].n == 100 and not problem.unknown_scale
    assert _residual(problem, gt) < EXACT_TOL
    B = problem.edges[0].B  # T_target_cam
    t = B[:, :3, 3]
    x, y, z = B[:, :3, 0], B[:, :3, 1], B[:, :3, 2]
    np.testing.assert_allclose(np.linalg.norm(t, axis=1), 1.0, atol=EXACT_TOL)  # on the sphere
    np.testing.assert_allclose(z, -t, atol=EXACT_TOL)  # optical axis at the target origin
    assert np.all(y[:, 2] < 0)  # y towards the south pole (-z of the target) ...
    np.testing.assert_allclose(x[:, 2], 0.0, atol=EXACT_TOL)  # ... in the meridian plane
    polar = np.degrees(np.arccos(t[:, 2]))
    assert polar.min() == pytest.approx(45.0) and polar.max() == pytest.approx(135.0)


def test_hand_camera_sphere_monocular_two_spheres():
    problem, gt = hand_camera_sphere(np.random.default_rng(4), monocular=True)
    assert problem.unknown_scale and gt.alpha == 0.5
    e = problem.edges[0]
    assert e.n == 100
    radii = np.linalg.norm(e.B[:, :3, 3], axis=1) / gt.alpha
    np.testing.assert_allclose(np.sort(radii)[:50], 0.3, atol=EXACT_TOL)
    np.testing.assert_allclose(np.sort(radii)[50:], 1.0, atol=EXACT_TOL)
    assert _residual(problem, gt, gt.alpha) < EXACT_TOL


def _scale_design_singular_values(problem):
    """Singular values of the monocular translation system [R_A, -I, t_A] (true rotations)."""
    e = problem.edges[0]
    K = np.zeros((e.n, 3, 7))
    K[:, :, :3] = e.A[:, :3, :3]
    K[:, :, 3:6] = -np.eye(3)
    K[:, :, 6] = e.A[:, :3, 3]
    return np.linalg.svd(K.reshape(-1, 7), compute_uv=False)


def test_single_sphere_monocular_is_unidentifiable_two_spheres_are_not():
    # Paper Section 8.1: with the optical axis always through the sphere centre, moving the
    # camera along its axis is indistinguishable from a change of scale on one sphere.
    one, _ = hand_camera_sphere(np.random.default_rng(5), monocular=True, n_poses=100,
                                radii=(1.0,))
    two, _ = hand_camera_sphere(np.random.default_rng(5), monocular=True)
    s1, s2 = _scale_design_singular_values(one), _scale_design_singular_values(two)
    # Relative smallest singular value: round-off (~1e-16) vs order 0.1 for a full-rank design.
    assert s1[-1] / s1[0] < 1e-10
    assert s2[-1] / s2[0] > 1e-3


def test_wang_recovers_monocular_two_sphere_ground_truth():
    problem, gt = hand_camera_sphere(np.random.default_rng(6), monocular=True)
    X, Y, alpha = run_baseline("wang", problem)
    assert np.abs(X - gt.X).max() < 1e-7  # exact data; closed form, round-off only
    assert np.abs(Y - gt.Y).max() < 1e-7
    assert alpha == pytest.approx(0.5, abs=1e-9)


def test_noise_order_of_the_monocular_scaling():
    rng = np.random.default_rng(7)
    B = sphere_camera_poses(sphere_spiral_directions(20_000), 1.0)
    after = noisy_measurements(rng, B, 0.05, np.inf, 0.5, scale_after_noise=True)
    before = noisy_measurements(rng, B, 0.05, np.inf, 0.5, scale_after_noise=False)
    # Sample std of 60 000 Gaussian draws: relative standard error 0.3 %; 3 % is 10 sigma.
    assert np.std(after[:, :3, 3] - 0.5 * B[:, :3, 3]) == pytest.approx(0.025, rel=0.03)
    assert np.std(before[:, :3, 3] - 0.5 * B[:, :3, 3]) == pytest.approx(0.05, rel=0.03)
    np.testing.assert_array_equal(after[:, :3, :3], B[:, :3, :3])  # kappa = inf: exact rotations


def test_fixed_cameras_geometry_visibility_and_exact_data():
    problem, gt = fixed_cameras_hand_target(np.random.default_rng(8))
    assert (problem.M, problem.P, len(problem.edges)) == (4, 1, 4)
    assert problem.x_names == ("cam0", "cam1", "cam2", "cam3")
    assert all(e.n == 108 for e in problem.edges)
    A0 = problem.edges[0].A
    for e in problem.edges[1:]:
        np.testing.assert_array_equal(e.A, A0)  # one arm pose per time step, seen by all
    assert _residual(problem, gt) < EXACT_TOL
    # Recover T_base_target(i) = A_i^-1 Y and check every camera sees the target.
    T_base_target = invert_transform(A0) @ gt.Y[0]
    d = FixedCameraDesign()
    vis = target_visibility(gt.X, T_base_target, fov_half_angle_deg=d.fov_half_angle_deg,
                            min_depth=d.min_depth)
    assert vis.shape == (108, 4) and vis.all()
    for j, e in enumerate(problem.edges):
        # B = T_target_cam_j: the target origin in camera j is -R_B^T t_B, in front of it.
        p_cam = -np.einsum("nji,nj->ni", e.B[:, :3, :3], e.B[:, :3, 3])
        assert np.all(p_cam[:, 2] >= d.min_depth), j
        off_axis = np.degrees(np.arccos(p_cam[:, 2] / np.linalg.norm(p_cam, axis=1)))
        assert off_axis.max() <= d.fov_half_angle_deg + 1e-9
    # Rotational excitation about several axes (Corollary 4): relative hand rotations span 3D.
    rel = np.einsum("ji,njk->nik", A0[0, :3, :3], A0[:, :3, :3])
    axes = np.array([np.linalg.svd(R - np.eye(3))[2][-1] for R in rel[1:]])
    assert np.linalg.matrix_rank(axes, tol=0.1) == 3


def test_fixed_cameras_facing_design_respects_incidence():
    d = FixedCameraDesign(target_rotation="facing", max_incidence_deg=60.0,
                          fov_half_angle_deg=35.0)
    problem, gt = fixed_cameras_hand_target(np.random.default_rng(9), design=d, monocular=True)
    assert problem.unknown_scale and _residual(problem, gt, 0.5) < EXACT_TOL
    T_base_target = invert_transform(problem.edges[0].A) @ gt.Y[0]
    assert target_visibility(gt.X, T_base_target, fov_half_angle_deg=35.0,
                             max_incidence_deg=60.0).all()
    X, Y, alpha = run_baseline("wang", problem)
    assert np.abs(X - gt.X).max() < 1e-7  # exact data: the design is identifiable
    assert alpha == pytest.approx(0.5, abs=1e-9)


def test_scenarios_are_seeded_and_noise_is_applied():
    lv = PAPER_NOISE_LEVELS[3]
    p1, g1 = fixed_cameras_hand_target(np.random.default_rng(10), lv.sigma, lv.kappa)
    p2, g2 = fixed_cameras_hand_target(np.random.default_rng(10), lv.sigma, lv.kappa)
    p3, _ = fixed_cameras_hand_target(np.random.default_rng(11), lv.sigma, lv.kappa)
    np.testing.assert_array_equal(p1.edges[2].B, p2.edges[2].B)
    np.testing.assert_array_equal(g1.X, g2.X)
    assert not np.array_equal(p1.edges[2].B, p3.edges[2].B)
    assert _residual(p1, g1) > 0.01  # 5 cm / kappa 12 noise is really there
    assert p1.edges[0].sigma[0] == lv.sigma and p1.edges[0].kappa[0] == lv.kappa
    assert [(lv.kappa, lv.sigma) for lv in PAPER_NOISE_LEVELS] == [
        (125.0, 0.01), (125.0, 0.05), (12.0, 0.01), (12.0, 0.05)
    ]


def test_monocular_default_weights_follow_the_scaled_noise():
    problem, _ = hand_camera_sphere(np.random.default_rng(12), 0.01, 125.0, monocular=True)
    assert problem.edges[0].sigma[0] == pytest.approx(0.005)  # alpha sigma
    problem, _ = hand_camera_sphere(np.random.default_rng(12), 0.01, 125.0, monocular=True,
                                    scale_after_noise=False)
    assert problem.edges[0].sigma[0] == pytest.approx(0.01)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"sigma": -0.1}, "sigma"),
        ({"kappa": 0.0}, "kappa"),
        ({"n_poses": 0}, "n"),
        ({"radii": ()}, "radii"),
        ({"radii": (1.0, -0.3)}, "radius"),
        ({"polar_range_deg": (0.0, 90.0)}, "polar_range_deg"),
    ],
)
def test_bad_arguments_raise(kwargs, match):
    with pytest.raises(ValueError, match=match):
        hand_camera_sphere(np.random.default_rng(13), **kwargs)


def test_unreachable_visibility_raises():
    d = FixedCameraDesign(fov_half_angle_deg=0.01)
    with pytest.raises(ValueError, match="visible to all cameras"):
        fixed_cameras_hand_target(np.random.default_rng(14), design=d, n_poses=5)
