"""The exact forms of the SDP: the hub/leaf (arrow) split and its proof obligations, the clique
cost model, and agreement of the reduced, full and arrow forms on the same problems."""

import numpy as np
import pytest

from rwhec_ros.core.certify.relaxation import SdpOptions, evaluate_Z, so3_constraint_matrices
from rwhec_ros.core.certify.sparsity import (
    arrow_split,
    clique_weights,
    cone_cost,
    estimate_form_costs,
)
from rwhec_ros.core.lie import rotation_distance
from rwhec_ros.core.pipeline.dense import _form_costs
from rwhec_ros.core.pipeline.dense import prepare_dense as _prepare
from rwhec_ros.core.solve import SolveOptions, solve
from rwhec_ros.simulation.synthetic import random_instance

# every target seen by every camera: the leaves' couplings are wider than 9 (the SVD basis)
DENSE_4X3 = (4, 3, [(j, k) for j in range(4) for k in range(3)])


def _prepared(M, P, edges=None, unknown_scale=False, seed=0):
    rng = np.random.default_rng(seed)
    problem, gt = random_instance(rng, M, P, edges, n_per_edge=10, sigma=0.01, kappa=100.0,
                                  unknown_scale=unknown_scale, alpha=0.8 if unknown_scale else 1.0)
    return problem, gt, _prepare(problem, SolveOptions(mode="sdp"))


@pytest.mark.parametrize("unknown_scale", [False, True])
def test_targets_are_the_leaves_and_bases_span_the_coupling(unknown_scale):
    problem, _, prep = _prepared(*DENSE_4X3, unknown_scale=unknown_scale)
    n, d = problem.n_frames, 9 * problem.n_frames + 1
    split = arrow_split(prep.Qs, n)
    # X frames (targets) never couple to each other in Q' (eq. (48)); the cameras are the hub
    assert list(split.leaf_frames) == list(range(problem.M))
    assert list(split.hub) == list(range(9 * problem.M, d))
    cons = so3_constraint_matrices(np.arange(n) * 9, d, d - 1)
    lam = np.random.default_rng(1).normal(size=cons.m)
    Z = evaluate_Z(prep.Qs, cons, lam)  # any multipliers: the span must hold for all of them
    for L, Pi in zip(split.leaves, split.bases, strict=True):
        assert Pi.shape == (len(split.hub), 10)  # 3 cameras x 9 > 9: rank-9 basis + s
        np.testing.assert_allclose(Pi.T @ Pi, np.eye(10), atol=1e-12)
        B = Z[np.ix_(L, split.hub)]
        # B = B Pi Pi^T: the rows of the leaf-hub block lie in span(Pi) (round-off only)
        np.testing.assert_allclose(B @ Pi @ Pi.T, B, atol=1e-10 * np.abs(B).max())
        # no leaf-leaf coupling at all (exact zeros, the premise of the split)
        others = np.setdiff1d(np.arange(9 * problem.M), L)
        assert not np.any(Z[np.ix_(L, others)])
    assert split.cone_sizes == [19] * problem.M + [9 * problem.P + 1]


def test_arrow_decomposition_of_a_psd_matrix():
    """The lemma behind the arrow form, on a PSD matrix with the arrow pattern: the pieces
    S_j = Pi^T B^T D^-1 B Pi leave a PSD hub remainder, and the embedded pieces sum to Z."""
    problem, _, prep = _prepared(*DENSE_4X3)
    n, d = problem.n_frames, 9 * problem.n_frames + 1
    split = arrow_split(prep.Qs, n)
    cons = so3_constraint_matrices(np.arange(n) * 9, d, d - 1)
    lam = np.zeros(cons.m)
    lam[-1] = -1.0  # Z = Q' + E_ss: positive definite (Q' is PSD as a sum of squares)
    Z = evaluate_Z(prep.Qs, cons, lam)
    assert np.linalg.eigvalsh(Z)[0] > 0
    H = split.hub
    hub = Z[np.ix_(H, H)].copy()
    rebuilt = np.zeros_like(Z)
    for L, Pi in zip(split.leaves, split.bases, strict=True):
        D, B = Z[np.ix_(L, L)], Z[np.ix_(L, H)] @ Pi
        S = B.T @ np.linalg.solve(D, B)
        piece = np.block([[D, B], [B.T, S]])
        assert np.linalg.eigvalsh(piece)[0] > -1e-9 * np.abs(piece).max()
        hub -= Pi @ S @ Pi.T
        rebuilt[np.ix_(L, L)] += D
        rebuilt[np.ix_(L, H)] += B @ Pi.T
        rebuilt[np.ix_(H, L)] += Pi @ B.T
        rebuilt[np.ix_(H, H)] += Pi @ S @ Pi.T
    assert np.linalg.eigvalsh(hub)[0] > 0  # the Schur complement of Z over the leaves
    rebuilt[np.ix_(H, H)] += hub
    np.testing.assert_allclose(rebuilt, Z, atol=1e-9 * np.abs(Z).max())


# a chain: targets seen by one or two cameras (coordinate-selection bases of size 9 and the
# SVD basis of an 18-wide coupling)
CHAIN_3X5 = (3, 5, [(0, 0), (0, 1), (1, 1), (1, 2), (2, 2), (2, 3), (0, 4), (2, 4)])


@pytest.mark.slow
@pytest.mark.parametrize(("graph", "unknown_scale"),
                         [(DENSE_4X3, False), (DENSE_4X3, True), (CHAIN_3X5, False)])
def test_forms_agree(graph, unknown_scale):
    """reduced, full and arrow are exact forms of Problem 7: same lambda_s, same certified
    optimum (to the solvers' 1e-8 tolerance, far inside the 1e-6 of the issue)."""
    problem, _, _ = _prepared(*graph, unknown_scale=unknown_scale, seed=3)
    results = {f: solve(problem, SolveOptions(mode="sdp", sdp=SdpOptions(form=f)))
               for f in ("reduced", "full", "arrow")}
    ref = results["reduced"]
    for form, res in results.items():
        assert res.certified, (form, res.certificate.message)
        assert f"SDP form: {form}" in res.notes
        assert res.certificate.dual_bound == pytest.approx(ref.certificate.dual_bound, rel=1e-6)
        assert rotation_distance(res.Y[:, :3, :3], ref.Y[:, :3, :3]).max() < 1e-6
        assert rotation_distance(res.X[:, :3, :3], ref.X[:, :3, :3]).max() < 1e-6
        assert np.abs(res.X[:, :3, 3] - ref.X[:, :3, 3]).max() < 1e-6


def test_arrow_noise_free_exact_recovery():
    rng = np.random.default_rng(4)
    problem, gt = random_instance(rng, *DENSE_4X3, n_per_edge=8)
    res = solve(problem, SolveOptions(mode="sdp", sdp=SdpOptions(form="arrow")))
    e = res.errors_to(gt.X, gt.Y)
    assert res.certified
    # 1e-6 m / rad: the bound for exact data
    assert max(e["t_x"].max(), e["t_y"].max(), e["r_x"].max(), e["r_y"].max()) <= 1e-6


def test_clique_weights_small_graphs():
    path = np.zeros((3, 3), bool)
    path[0, 1] = path[1, 2] = True
    assert sorted(clique_weights(path, [1, 2, 3])) == [3, 5]
    cycle = np.zeros((4, 4), bool)
    cycle[0, 1] = cycle[1, 2] = cycle[2, 3] = cycle[3, 0] = True
    assert clique_weights(cycle, [1, 1, 1, 1]) == [3, 3]  # one chord: two triangles
    assert clique_weights(np.ones((5, 5), bool), [2] * 5) == [10]
    star = np.zeros((5, 5), bool)
    star[0, 1:] = True
    assert sorted(clique_weights(star, [9, 1, 1, 1, 1])) == [10] * 4
    assert cone_cost(1) == 1.0 and cone_cost(3) == 216.0


def test_auto_picks_the_cheapest_form_by_structure():
    # many targets each seen by several cameras: arrow; one target seen by many cameras: full
    _, _, prep = _prepared(6, 4, [(j, k) for j in range(6) for k in range(4)])
    assert _form_costs(prep)[0] == "arrow"
    _, _, prep = _prepared(1, 10)
    assert _form_costs(prep)[0] == "full"
    _, _, prep = _prepared(1, 1)
    assert _form_costs(prep)[0] == "reduced"


def test_estimate_form_costs_reduced_only_and_validation():
    problem, _, prep = _prepared(*DENSE_4X3)
    costs = estimate_form_costs(prep.Qs, problem.n_frames)
    # 4 leaves of 9 + 27 + 1 = 37 and the 28-hub, dense: a chordal decomposition into 4 cliques
    assert costs == {"reduced": pytest.approx(4 * cone_cost(37))}
    with pytest.raises(ValueError, match="Q: expected shape"):
        arrow_split(prep.Qs[:-1, :-1], problem.n_frames)
    assert arrow_split(np.zeros((10, 10)), 1) is None


def test_sdp_form_validation():
    with pytest.raises(ValueError, match="form: expected one of"):
        SdpOptions(form="sparse")
