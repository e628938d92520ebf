"""pinv_solve (rwhec_ros.core.numerics.pinv) and frame_of_coordinate against direct forms."""

from __future__ import annotations

import numpy as np

from rwhec_ros.core.analysis.information import TangentLayout, frame_of_coordinate
from rwhec_ros.core.numerics.pinv import pinv_solve
from rwhec_ros.core.problem import Edge, Problem


def test_pinv_solve_is_the_inverse_or_the_scaled_pseudo_inverse():
    """Full rank (badly scaled): the inverse. A null direction: for a right-hand side in the
    range, a solution of ``H x = B``, and the pseudo-inverse of the Jacobi-scaled matrix
    (``D^-1 (D^-1 H D^-1)^+ D^-1 B``, the gauge it fixes: no step along the scaled null
    direction)."""
    rng = np.random.default_rng(0)
    G = rng.normal(size=(6, 6))
    D = np.diag([1e-3, 1.0, 1e3, 1.0, 10.0, 0.1])
    H = D @ (G @ G.T + np.eye(6)) @ D
    B = rng.normal(size=(6, 2))
    np.testing.assert_allclose(pinv_solve(H, B), np.linalg.solve(H, B), rtol=1e-8)
    U = np.linalg.qr(rng.normal(size=(6, 6)))[0]
    Hs = D @ U @ np.diag([0.0, 1.0, 2.0, 3.0, 4.0, 5.0]) @ U.T @ D
    b = Hs @ rng.normal(size=6)
    x = pinv_solve(Hs, b)
    np.testing.assert_allclose(Hs @ x, b, rtol=1e-7, atol=1e-9 * np.abs(b).max())
    d = np.sqrt(np.diag(Hs))
    expected = np.linalg.pinv(Hs / np.outer(d, d), rcond=1e-9) @ (b / d) / d
    np.testing.assert_allclose(x, expected, rtol=1e-6)


def test_frame_of_coordinate_follows_the_tangent_layout():
    A = np.tile(np.eye(4), (3, 1, 1))
    problem = Problem(["t0", "t1"], ["c0"], [Edge.build("t0", "c0", A, A, sigma=1.0, kappa=1.0),
                                              Edge.build("t1", "c0", A, A, sigma=1.0, kappa=1.0)],
                      unknown_scale=True)
    layout = TangentLayout(2, 1, True)
    for f, name in enumerate(["t0", "t1", "c0"]):
        for i in layout.frame_indices(f):
            assert frame_of_coordinate(problem, int(i)) == name
    assert frame_of_coordinate(problem, layout.alpha) == "the scale"
