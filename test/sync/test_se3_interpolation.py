"""SE(3) exp/log and Lie-algebraic interpolation (Barfoot ch. 8, paper Section 9.1)."""

import numpy as np
import pytest
import scipy.linalg

from rwhec_ros.core.lie import (
    hat,
    invert_transform,
    make_transform,
    so3_exp,
    so3_log,
)
from rwhec_ros.simulation.synthetic import random_transforms
from rwhec_ros.sync.interpolation import (
    interpolate_se3,
    se3_exp,
    se3_log,
    so3_left_jacobian,
    so3_left_jacobian_inverse,
)


def wedge(xi):
    """4x4 matrix of the twist ``[rho, phi]`` (independent path via scipy.linalg.expm)."""
    M = np.zeros((4, 4))
    M[:3, :3] = hat(xi[3:])
    M[:3, 3] = xi[:3]
    return M


def random_twists(rng, angles):
    xi = rng.standard_normal((len(angles), 6))
    xi[:, 3:] *= (np.asarray(angles) / np.linalg.norm(xi[:, 3:], axis=1))[:, None]
    return xi


ANGLES = [0.0, 1e-12, 1e-7, 0.99e-4, 1e-4, 1.01e-4, 1e-3, 0.3, 1.0, 2.0, 3.0, np.pi - 1e-6]


def test_se3_exp_matches_matrix_exponential():
    rng = np.random.default_rng(0)
    xi = random_twists(rng, ANGLES)
    T = se3_exp(xi)  # vectorised path
    for i in range(len(ANGLES)):
        # 1e-12: entries are O(1); expm (Pade) and the closed form agree to a few ulps.
        np.testing.assert_allclose(T[i], scipy.linalg.expm(wedge(xi[i])), rtol=0, atol=1e-12)
        np.testing.assert_allclose(se3_exp(xi[i]), T[i], rtol=0, atol=0)


def test_se3_log_inverts_exp_on_principal_branch():
    rng = np.random.default_rng(1)
    xi = random_twists(rng, ANGLES)
    # 1e-9: log near pi divides by sin(theta/2)-type terms; ~1e6 ulps margin, errors are ~1e-15.
    np.testing.assert_allclose(se3_log(se3_exp(xi)), xi, rtol=0, atol=1e-9)


def test_jacobian_series_and_closed_form_agree_at_switch():
    axis = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    below, above = axis * (1e-4 * (1 - 1e-12)), axis * (1e-4 * (1 + 1e-12))
    # 1e-14: the two branches differ by the O(theta^6) series remainder and closed-form rounding.
    np.testing.assert_allclose(so3_left_jacobian(below), so3_left_jacobian(above), atol=1e-14)
    np.testing.assert_allclose(
        so3_left_jacobian_inverse(below), so3_left_jacobian_inverse(above), atol=1e-14
    )
    rng = np.random.default_rng(2)
    phi = random_twists(rng, ANGLES[:-1])[:, 3:]
    # 1e-12: J J^-1 = I with O(1) entries (away from 2 pi, where J^-1 is singular).
    eye = so3_left_jacobian(phi) @ so3_left_jacobian_inverse(phi)
    np.testing.assert_allclose(eye, np.broadcast_to(np.eye(3), eye.shape), atol=1e-12)


def test_interpolation_exact_on_constant_twist_motion():
    rng = np.random.default_rng(3)
    xi = np.array([0.8, -0.3, 0.5, 0.4, -0.9, 0.6])  # [m/s, rad/s]: |omega| = 1.15 rad/s
    T_start = random_transforms(rng, 1)[0]
    s0, s1 = 0.37, 2.1  # rotation between samples: 2.0 rad < pi

    def trajectory(s):
        return se3_exp(s * xi) @ T_start

    T0, T1 = trajectory(s0), trajectory(s1)
    u = np.linspace(0.0, 1.0, 11)
    out = interpolate_se3(T0, T1, u)
    expected = np.stack([trajectory(s0 + ui * (s1 - s0)) for ui in u])
    # 1e-9: a handful of float64 exp/log/products on O(1) entries; roundoff is ~1e-15, while a
    # method error (e.g. interpolating R and t separately, checked below) is ~1e-1 here.
    np.testing.assert_allclose(out, expected, rtol=0, atol=1e-9)
    # Scalar u gives a single (4, 4).
    np.testing.assert_allclose(interpolate_se3(T0, T1, 0.5), expected[5], rtol=0, atol=1e-9)

    # The SO(3) x R^3 split is NOT exact on this motion: the test above can fail.
    R_split = so3_exp(0.5 * so3_log(T1[:3, :3] @ T0[:3, :3].T)) @ T0[:3, :3]
    t_split = 0.5 * (T0[:3, 3] + T1[:3, 3])
    split = make_transform(R_split, t_split)
    assert np.abs(split - expected[5]).max() > 1e-2


def test_interpolation_endpoints_body_form_and_inverse():
    rng = np.random.default_rng(4)
    T0, T1 = random_transforms(rng, 2)
    # 1e-12: endpoints reproduce the samples up to exp(log(.)) rounding on O(1) entries.
    np.testing.assert_allclose(interpolate_se3(T0, T1, 0.0), T0, atol=1e-12)
    np.testing.assert_allclose(interpolate_se3(T0, T1, 1.0), T1, atol=1e-12)
    for u in (0.1, 0.5, 0.83):
        body = T0 @ se3_exp(u * se3_log(invert_transform(T0) @ T1))
        # 1e-10: equal in exact arithmetic (adjoint identity); rotations here may be near pi.
        np.testing.assert_allclose(interpolate_se3(T0, T1, u), body, atol=1e-10)
        # Interpolating the inverses gives the inverse of the interpolation (same identity).
        inv = interpolate_se3(invert_transform(T0), invert_transform(T1), u)
        np.testing.assert_allclose(inv, invert_transform(interpolate_se3(T0, T1, u)), atol=1e-10)
        # The result is a rigid transform (1e-12: orthonormality up to rounding).
        T = interpolate_se3(T0, T1, u)
        np.testing.assert_allclose(T[:3, :3].T @ T[:3, :3], np.eye(3), atol=1e-12)
        np.testing.assert_allclose(T[3], [0, 0, 0, 1], atol=0)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"T0": np.eye(3), "T1": np.eye(4), "u": 0.5}, "T0"),
        ({"T0": np.eye(4), "T1": np.eye(4)[None], "u": 0.5}, "T1"),
        ({"T0": np.eye(4), "T1": np.eye(4), "u": np.nan}, "u"),
        ({"T0": np.eye(4), "T1": np.eye(4), "u": np.zeros((2, 2))}, "u"),
    ],
)
def test_interpolation_rejects_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        interpolate_se3(**kwargs)


def test_se3_maps_reject_bad_shapes():
    with pytest.raises(ValueError, match="xi"):
        se3_exp(np.zeros(5))
    with pytest.raises(ValueError, match="T"):
        se3_log(np.eye(3))
