"""Pairs with few corners weighted by their camera's pooled corner noise
(:mod:`rwhec_ros.session.pooled_noise`), boards with many keep their own, and the session's solve
uses it where the pairs' noise comes from the reprojection."""

from __future__ import annotations

import numpy as np

from rwhec_ros.core.lie import invert_transform, make_transform, so3_exp
from rwhec_ros.core.noise import NoiseOptions
from rwhec_ros.core.problem import Edge, Problem
from rwhec_ros.session.accuracy import AccuracyOptions
from rwhec_ros.session.pooled_noise import pooled_corner_noise
from rwhec_ros.session.solving import solve_and_assess
from rwhec_ros.vision.detection import tag_object_points
from rwhec_ros.vision.intrinsics import CameraIntrinsics
from rwhec_ros.vision.reprojection import CornerObservation

CAM = CameraIntrinsics.pinhole(640, 480, 500.0)
SIZE = 0.1
BOARD = np.array([[0.03 * i, 0.03 * j, 0.0] for j in range(3) for i in range(4)])  # 12 corners


def _scene(seed=0, n=12):
    """A camera on a moving rig, one single tag and one 12-corner board fixed in the world;
    per pair a corner noise drawn between 0.05 and 1 px, ``sigma``/``kappa`` proportional to
    the noise its own corners show, as the detector's precision model gives."""
    rng = np.random.default_rng(seed)
    Y = make_transform(np.eye(3), [0.0, 0.0, 0.0])
    X = {"tag_0": make_transform(np.eye(3), [0.0, 0.0, 1.0]),
         "board": make_transform(np.eye(3), [-0.05, -0.03, 1.2])}
    edges, obs = [], []
    for name, X_j in X.items():
        pts = tag_object_points(SIZE) if name == "tag_0" else BOARD
        A, B, sig, kap = [], [], [], []
        for _ in range(n):
            A_i = invert_transform(make_transform(so3_exp(rng.normal(0, 0.1, 3)),
                                                  rng.normal(0, 0.03, 3)))
            B_i = invert_transform(Y) @ A_i @ X_j
            px = float(np.exp(rng.uniform(np.log(0.05), np.log(1.0))))
            c = CAM.project_points(pts, B_i) + rng.normal(0, px, (len(pts), 2))
            N = len(pts)
            rms = float(np.sqrt(np.mean(np.sum((CAM.project_points(pts, B_i) - c) ** 2, 1))))
            s_px = max(0.1, rms * np.sqrt(N / (2 * N - 6)))  # the detector's own estimate
            A.append(A_i)
            B.append(B_i)
            sig.append(2e-3 * s_px)  # this scene's geometry: the same factor for every pair
            kap.append(1.0 / (2e-3 * s_px) ** 2)
            obs.append(CornerObservation(name, "cam0", A_i, c,
                                         tag_size_m=SIZE if name == "tag_0" else None,
                                         object_points=None if name == "tag_0" else BOARD))
        edges.append(Edge._of(name, "cam0", np.array(A), np.array(B), np.array(sig),
                              np.array(kap)))
    return Problem(tuple(X), ("cam0",), edges), (obs, {"cam0": CAM})


def _rms(o, B):
    pts = tag_object_points(SIZE) if o.object_points is None else o.object_points
    return float(np.sqrt(np.mean(np.sum((CAM.project_points(pts, B) - o.corners_px) ** 2,
                                        axis=1))))


def test_a_single_tag_pair_takes_the_pooled_noise_a_board_keeps_its_own():
    problem, corners = _scene()
    out = pooled_corner_noise(problem, corners)
    tag, board = (e for e in problem.edges)
    new_tag, new_board = (e for e in out.edges)
    # boards: 12 corners, 18 degrees of freedom >= 10: untouched
    np.testing.assert_array_equal(new_board.sigma, board.sigma)
    np.testing.assert_array_equal(new_board.kappa, board.kappa)
    # tags: 2 degrees of freedom each; s_i = sqrt(2) rms_i, pooled s^2 = sum 4 rms^2 / sum 2
    tag_obs = [o for o in corners[0] if o.x == "tag_0"]
    rms = np.array([_rms(o, B) for o, B in zip(tag_obs, tag.B, strict=True)])
    s_i = np.maximum(0.1, np.sqrt(2.0) * rms)
    pooled = max(0.1, float(np.sqrt(np.sum(4 * rms**2) / (2 * len(rms)))))
    np.testing.assert_allclose(new_tag.sigma / tag.sigma, pooled / s_i, rtol=1e-9)
    np.testing.assert_allclose(new_tag.kappa * new_tag.sigma**2, tag.kappa * tag.sigma**2,
                               rtol=1e-9)
    # the weights' spread was the 2-dof noise estimates' (here > 5x); now it is the
    # geometry's, which this scene makes the same for every pair
    assert np.ptp(np.log(tag.sigma)) > np.log(5)
    np.testing.assert_allclose(new_tag.sigma, 2e-3 * pooled, rtol=1e-9)


def test_the_solve_weights_single_tags_by_the_pooled_noise_with_reprojection_noise_only():
    problem, corners = _scene(1)
    acc = AccuracyOptions(folds=0, guidance=False)
    pooled = solve_and_assess(problem, corners=corners, accuracy=acc, refine=False,
                              noise=NoiseOptions(given="reprojection"))
    stated = solve_and_assess(problem, corners=corners, accuracy=acc, refine=False,
                              noise=NoiseOptions(given="stated"))
    expected = pooled_corner_noise(problem, corners)
    edge = next(e for e in pooled.problem.edges if e.x == "tag_0")
    want = next(e for e in expected.edges if e.x == "tag_0")
    # the solved pairs carry the pooled weights' shape (the noise estimate rescales the level)
    ratio = edge.sigma / want.sigma
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-6)
    edge = next(e for e in stated.problem.edges if e.x == "tag_0")
    ratio = edge.sigma / next(e for e in problem.edges if e.x == "tag_0").sigma
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-6)  # stated noise: as given
