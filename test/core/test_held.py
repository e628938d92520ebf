"""Frames held at known values by pseudo-measurements (rwhec_ros.core.model.held)."""

from __future__ import annotations

import numpy as np
import pytest

from rwhec_ros.core.lie import make_transform, rotation_distance, so3_exp
from rwhec_ros.core.model.held import ANCHOR_X, ANCHOR_Y, hold_frames, without_anchors
from rwhec_ros.core.solve import solve
from rwhec_ros.simulation.synthetic import random_instance


def _instance(seed: int = 0):
    return random_instance(np.random.default_rng(seed), 3, 3, n_per_edge=15, sigma=0.005,
                           kappa=400.0)


def test_the_anchor_pairs_fix_both_anchors_at_the_identity():
    """Only X = Y = I satisfy G X = Y G for I and the quarter turns (module docstring): a
    perturbed candidate leaves a residual on some pair."""
    problem, _ = _instance()
    hp = hold_frames(problem, {})
    anchor = hp.problem.edges[len(problem.edges)]
    assert (anchor.x, anchor.y) == (ANCHOR_X, ANCHOR_Y)
    for delta in (make_transform(np.eye(3), [0.0, 0.0, 0.01]),
                  make_transform(so3_exp(np.array([0.01, 0.0, 0.0])), np.zeros(3))):
        # X = Y = delta (so that G = I fits) still violates some quarter turn
        residual = [np.abs(A @ delta - delta @ B).max() for A, B in zip(anchor.A, anchor.B,
                                                                         strict=True)]
        assert max(residual) > 1e-3


def test_held_frames_stay_at_their_values_and_the_solve_is_certified():
    problem, gt = _instance(1)
    # hold the targets and one camera at values 5 mm / 0.3 deg off the truth: the data pull
    # them, the pseudo-measurements (1e4 times all the data's precision) keep them
    off = make_transform(so3_exp(np.array([0.0, 0.0, np.radians(0.3)])), [0.005, 0.0, 0.0])
    held = {n: gt.X[i] @ off for i, n in enumerate(problem.x_names)}
    held["y0"] = gt.Y[0] @ off
    hp = hold_frames(problem, held)
    res = solve(hp.problem)
    assert res.certified, res.certificate.message
    out = without_anchors(res)
    assert out.x_names == problem.x_names and out.y_names == problem.y_names
    for name, T in held.items():
        est = out.transform(name)
        # the pull of the data on a held frame is ~1/strength (1e-4) of the offset: 0.5 um
        # (0.4-0.8 um measured over seeds 0-3; bound 4x) and ~1e-6 deg (bound 1e-3 deg)
        assert np.linalg.norm(est[:3, 3] - T[:3, 3]) < 2e-6
        assert np.degrees(rotation_distance(est[:3, :3], T[:3, :3])) < 1e-3
    # the free cameras follow the data given the (wrong) held frames: not at the truth
    assert "held" not in hp.describe() or "pseudo-measurements holding" in hp.describe()
    assert "x0, x1, x2, y0" in hp.describe()


def test_hold_frames_refuses_bad_input():
    problem, gt = _instance()
    with pytest.raises(ValueError, match="not a frame of the data"):
        hold_frames(problem, {"cam9": np.eye(4)})
    with pytest.raises(ValueError, match="held frame x0"):
        hold_frames(problem, {"x0": np.ones((4, 4))})
    with pytest.raises(ValueError, match="strength"):
        hold_frames(problem, {}, strength=0.0)


def test_without_anchors_leaves_other_results_alone():
    problem, _ = _instance()
    res = solve(problem)
    assert without_anchors(res) is res
