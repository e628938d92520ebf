"""Baselines: exact on noise-free data, the OpenCV frame mapping, and cross-checks on noisy data."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from rwhec_ros.core.baselines import (
    BASELINES,
    baseline_names,
    dornaika1998,
    dornaika_cost,
    opencv_robot_world_hand_eye,
    run_baseline,
    wang2022,
)
from rwhec_ros.core.baselines.dornaika import _dornaika_residuals
from rwhec_ros.core.lie import invert_transform, rotation_distance
from rwhec_ros.simulation.synthetic import random_instance, random_transforms

#: Noise-free data: every method is exact up to round-off in its linear algebra (SVDs, OpenCV's
#: internal conversions, a converged Gauss-Newton); 1e-6 leaves ample margin above ~1e-12.
EXACT_TOL = 1e-6

SINGLE_EDGE = [n for n in baseline_names() if n != "lom"]


def _max_err(X, Y, gt):
    return max(np.abs(X - gt.X).max(), np.abs(Y - gt.Y).max())


@pytest.mark.parametrize("name", SINGLE_EDGE)
def test_exact_on_noise_free_1x1y(name):
    problem, gt = random_instance(np.random.default_rng(0), 1, 1, n_per_edge=12)
    X, Y, alpha = run_baseline(name, problem)
    assert X.shape == (1, 4, 4) and Y.shape == (1, 4, 4)
    assert _max_err(X, Y, gt) < EXACT_TOL
    assert alpha == 1.0


@pytest.mark.parametrize("name", ["wang", "dornaika"])
@pytest.mark.parametrize(
    "M, P, edges",
    [(4, 1, None), (2, 3, [(0, 0), (0, 1), (1, 1), (1, 2)])],
    ids=["4X1Y", "2X3Y-path"],
)
def test_exact_on_noise_free_graphs(name, M, P, edges):
    problem, gt = random_instance(np.random.default_rng(1), M, P, edges, n_per_edge=8)
    X, Y, _ = run_baseline(name, problem)
    assert X.shape == (M, 4, 4) and Y.shape == (P, 4, 4)
    assert _max_err(X, Y, gt) < EXACT_TOL


def test_wang_unknown_scale_recovers_alpha():
    problem, gt = random_instance(
        np.random.default_rng(2), 2, 3, [(0, 0), (0, 1), (1, 1), (1, 2)], n_per_edge=8,
        unknown_scale=True, alpha=0.5,
    )
    X, Y, alpha = run_baseline("wang", problem)
    assert _max_err(X, Y, gt) < EXACT_TOL
    assert alpha == pytest.approx(0.5, abs=EXACT_TOL)


@pytest.mark.parametrize("name", [n for n, i in BASELINES.items() if i.single_edge_only])
def test_opencv_methods_reject_multi_edge_naming_the_method(name):
    problem, _ = random_instance(np.random.default_rng(3), 2, 1, n_per_edge=5)
    with pytest.raises(ValueError, match=r"OpenCV calibrate\w+ \((shah|li|tsai|park|horaud|"
                       r"andreff|daniilidis)\).*one X and one Y"):
        run_baseline(name, problem)


def test_known_scale_methods_reject_unknown_scale():
    problem, _ = random_instance(np.random.default_rng(4), 1, 1, n_per_edge=5, unknown_scale=True)
    with pytest.raises(ValueError, match="shah.*unknown_scale"):
        run_baseline("shah", problem)
    with pytest.raises(ValueError, match="dornaika.*unknown_scale"):
        run_baseline("dornaika", problem)


def test_too_few_pairs_and_bad_names_raise():
    problem, _ = random_instance(np.random.default_rng(5), 1, 1, n_per_edge=2)
    with pytest.raises(ValueError, match="at least 3 measurement pairs, got 2"):
        run_baseline("tsai", problem)
    with pytest.raises(ValueError, match="unknown baseline 'nope'"):
        run_baseline("nope", problem)
    with pytest.raises(ValueError, match="mapping"):
        opencv_robot_world_hand_eye(problem, "shah", mapping="sideways")


def test_opencv_frame_mapping_differs_only_in_noise():
    # Both mappings are exact without noise (above); with noise the documented-frames mapping
    # puts the translation residual in the camera frame, so it differs from the direct one.
    problem, gt = random_instance(
        np.random.default_rng(6), 1, 1, n_per_edge=40, sigma=0.01, kappa=125.0
    )
    Xf, Yf, _ = run_baseline("shah", problem)
    Xd, Yd, _ = run_baseline("shah_direct", problem)
    # Same rotation stage up to the orthogonal factor (R_B^T (x) I): identical null vector.
    assert rotation_distance(Xf[0, :3, :3], Xd[0, :3, :3]) < 1e-9
    assert np.linalg.norm(Xf[0, :3, 3] - Xd[0, :3, 3]) > 1e-4


def test_opencv_shah_direct_equals_our_wang_on_noisy_data():
    # Independent implementations of the same linear estimator (paper Table 2: Shah == Wang).
    problem, _ = random_instance(
        np.random.default_rng(7), 1, 1, n_per_edge=60, sigma=0.05, kappa=12.0
    )
    Xs, Ys, _ = run_baseline("shah_direct", problem)
    Xw, Yw, _ = run_baseline("wang", problem)
    # Tolerance: both are SVD-based closed forms in float64; 1e-8 is far above round-off and far
    # below the ~1e-2 differences between genuinely different estimators on this data.
    assert np.abs(Xs - Xw).max() < 1e-8
    assert np.abs(Ys - Yw).max() < 1e-8


def test_dornaika_is_a_stationary_point_that_improves_on_wang():
    problem, _ = random_instance(
        np.random.default_rng(8), 2, 2, n_per_edge=30, sigma=0.02, kappa=50.0
    )
    Xw, Yw, _ = wang2022(problem)
    X, Y, _ = dornaika1998(problem, Xw, Yw)
    assert dornaika_cost(problem, X, Y) < dornaika_cost(problem, Xw, Yw)
    r, J = _dornaika_residuals(problem, X, Y, 1.0, 1.0, with_jacobian=True)
    # Gradient J^T r relative to |J| |r|: Gauss-Newton converged to round-off (~1e-12);
    # 1e-7 tolerates the stopping rule.
    assert np.linalg.norm(J.T @ r) < 1e-7 * np.linalg.norm(J) * np.linalg.norm(r)
    for T in np.concatenate([X, Y]):
        R = T[:3, :3]
        assert np.abs(R.T @ R - np.eye(3)).max() < 1e-12
        assert np.linalg.det(R) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("name", ["shah_direct", "park", "wang", "dornaika"])
def test_equivariant_under_change_of_base_and_hand_frames(name):
    # A -> G A H^-1 with X -> H X, Y -> G Y: the estimates must transform the same way. This is
    # why the scenarios' ground-truth distributions do not change the error statistics. (Not
    # true of OpenCV's RWHE methods with the documented-frames mapping: there the noisy R_B^T
    # multiplies the translation of the base change.)
    rng = np.random.default_rng(9)
    problem, _ = random_instance(rng, 1, 1, n_per_edge=30, sigma=0.02, kappa=50.0)
    G, H = random_transforms(rng, 2, 1.0)
    e = problem.edges[0]
    moved = problem.with_edges([type(e).build(e.x, e.y, G @ e.A @ invert_transform(H), e.B,
                                              sigma=e.sigma, kappa=e.kappa)])
    X, Y, _ = run_baseline(name, problem)
    X2, Y2, _ = run_baseline(name, moved)
    # Round-off through different but equivalent linear systems; 1e-7 is far above it.
    assert np.abs(X2[0] - H @ X[0]).max() < 1e-7
    assert np.abs(Y2[0] - G @ Y[0]).max() < 1e-7


def test_registry_is_read_only_and_labelled():
    assert "wang" in BASELINES and "shah" in BASELINES
    for info in BASELINES.values():
        assert info.label and info.reference
    with pytest.raises(TypeError):
        BASELINES["x"] = BASELINES["wang"]  # type: ignore[index]


@pytest.mark.skipif(
    importlib.util.find_spec("rwhec_ros.core.baselines.lom_solver") is None,
    reason="rwhec_ros.core.baselines.lom_solver missing",
)
def test_lom_exact_on_noise_free_graph():
    problem, gt = random_instance(np.random.default_rng(10), 2, 2, n_per_edge=8)
    X, Y, alpha = run_baseline("lom", problem)
    assert _max_err(X, Y, gt) < EXACT_TOL
    assert alpha == pytest.approx(1.0, abs=EXACT_TOL)
