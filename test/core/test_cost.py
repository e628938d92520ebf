"""The quadratic form of Problem 5 against the direct sum of eq. (33), and the Schur reduction."""

import numpy as np
import pytest

from rwhec_ros.core.model.cost import StateLayout, build_cost_matrix, direct_cost, pack_state
from rwhec_ros.core.model.reduction import reduce_cost
from rwhec_ros.simulation.synthetic import random_instance, random_transforms


@pytest.mark.parametrize("unknown_scale", [False, True])
def test_quadratic_form_equals_direct_cost(unknown_scale):
    rng = np.random.default_rng(3)
    edges = [(0, 0), (0, 1), (1, 1), (2, 0), (2, 2)]
    problem, _ = random_instance(rng, 3, 3, edges, n_per_edge=9, sigma=0.05, kappa=20,
                                 unknown_scale=unknown_scale, alpha=0.7)
    # heterogeneous per-pair precisions (footnote 7)
    from rwhec_ros.core.problem import Edge, Problem

    het = [Edge.build(e.x, e.y, e.A, e.B, sigma=rng.uniform(0.01, 0.1, e.n),
                      kappa=rng.uniform(5, 200, e.n)) for e in problem.edges]
    problem = Problem(problem.x_names, problem.y_names, het, unknown_scale=unknown_scale)
    Q = build_cost_matrix(problem)
    layout = StateLayout(problem.M, problem.P)
    assert Q.shape == (layout.size, layout.size)
    assert abs(Q - Q.T).max() == 0.0
    for _ in range(5):
        X = random_transforms(rng, problem.M)
        Y = random_transforms(rng, problem.P)
        alpha = float(rng.uniform(0.3, 3.0)) if unknown_scale else 1.0
        x = pack_state(layout, X, Y, alpha)
        direct = direct_cost(problem, X, Y, alpha)
        # relative 1e-12: both are sums of O(1e5) positive terms in double precision
        assert x @ (Q @ x) == pytest.approx(direct, rel=1e-12)


def test_cost_matrix_is_linear_in_data_and_psd():
    rng = np.random.default_rng(4)
    problem, _ = random_instance(rng, 2, 2, n_per_edge=15, sigma=0.02, kappa=50)
    Q = build_cost_matrix(problem).toarray()
    # a sum of Gram matrices: PSD up to round-off
    assert np.linalg.eigvalsh(Q).min() > -1e-9 * np.abs(Q).max()


@pytest.mark.parametrize("unknown_scale", [False, True])
def test_schur_reduction_and_recovery(unknown_scale):
    rng = np.random.default_rng(5)
    problem, gt = random_instance(rng, 2, 3, n_per_edge=12, sigma=0.03, kappa=40,
                                  unknown_scale=unknown_scale, alpha=0.6 if unknown_scale else 1.0)
    layout = StateLayout(problem.M, problem.P)
    Q = build_cost_matrix(problem)
    red = reduce_cost(Q, layout, unknown_scale)
    # For fixed rotations, eq. (47) gives the minimising translations (and scale): the reduced
    # cost equals the full cost at the recovered translations and is below it elsewhere.
    X = random_transforms(rng, problem.M)
    Y = random_transforms(rng, problem.P)
    R = np.concatenate([X, Y])[:, :3, :3]
    z = np.concatenate([np.swapaxes(R, 1, 2).reshape(-1), [1.0]])
    ta = red.recover @ z
    alpha = ta[-1] if unknown_scale else 1.0
    T = np.concatenate([X, Y]).copy()
    T[:, :3, 3] = ta[:-1].reshape(-1, 3) / alpha
    full = direct_cost(problem, T[: problem.M], T[problem.M:], alpha)
    assert z @ red.Qr @ z == pytest.approx(full, rel=1e-9)  # pinv round-off on a small system
    perturbed = T.copy()
    perturbed[:, :3, 3] += 0.01 * rng.standard_normal((problem.n_frames, 3))
    assert direct_cost(problem, perturbed[: problem.M], perturbed[problem.M:], alpha) > full
    if unknown_scale:
        assert np.allclose(red.Qr[-1], 0.0) and np.allclose(red.Qr[:, -1], 0.0)


def test_cost_matrix_is_additive_over_pairs():
    """Q is a sum over pairs (eq. (29)): building it from all 50 pairs at once equals the sum of
    the matrices of two halves, i.e. the vectorised per-edge reduction drops nothing."""
    rng = np.random.default_rng(6)
    problem, _ = random_instance(rng, 1, 1, n_per_edge=50, sigma=0.02, kappa=50)
    from rwhec_ros.core.problem import Edge, Problem

    e = problem.edges[0]
    halves = [Problem(["x0"], ["y0"],
                      [Edge.build("x0", "y0", e.A[s], e.B[s], e.sigma[s], e.kappa[s])])
              for s in (slice(0, 25), slice(25, 50))]
    Qsum = build_cost_matrix(halves[0]) + build_cost_matrix(halves[1])
    assert abs(build_cost_matrix(problem) - Qsum).max() < 1e-9
