"""The offsets' profile Newton step (rwhec_ros.core.analysis.time_offset) on synthetic streams:
its gradient against finite differences of the cost, the planted offsets recovered, at-rest
cameras not determined, and the std against the scatter of repeated draws."""

from __future__ import annotations

import numpy as np
import pytest

from rwhec_ros.core.analysis.information import information_matrix
from rwhec_ros.core.analysis.time_offset import MIN_CLUSTERS, offset_step, offset_terms
from rwhec_ros.core.lie import invert_transform, make_transform, so3_exp
from rwhec_ros.core.outliers.pairs import pair_residuals
from rwhec_ros.core.problem import Edge, Problem
from rwhec_ros.core.solve import SolveOptions, solve
from rwhec_ros.sync.interpolation import se3_log

SIGMA, KAPPA = 0.002, 2000.0


def stream(t: float) -> np.ndarray:
    """``A(t) = T_rig_world`` of a smooth motion (about 0.5 m/s, 50 deg/s)."""
    T = make_transform(so3_exp(np.array([0.3 * np.sin(t), 0.5 * np.cos(0.7 * t), 0.8 * t])),
                       np.array([0.5 * np.sin(1.3 * t), 0.4 * np.cos(t), 0.2 * np.sin(2 * t)]))
    return invert_transform(T)


def rate(t: float, h: float = 1e-5) -> np.ndarray:
    """The twist rate of :func:`stream` (``dA/dt = xi^ A``), by a fine central difference."""
    return se3_log(stream(t + h) @ invert_transform(stream(t - h))) / (2 * h)


def planted(rng, delta, *, noise: bool = True, n: int = 30, at_rest=()):
    """A problem whose camera ``k``'s pairs are taken at true times ``t`` and paired with the
    stream at ``t - delta[k]``; returns the problem, its pairs' stamps (true times minus the
    offset) per edge in problem order, the rates there, and the truth."""
    X = [make_transform(so3_exp(rng.normal(size=3)), rng.normal(size=3)) for _ in range(3)]
    Y = [make_transform(so3_exp(rng.normal(size=3)), 0.2 * rng.normal(size=3))
         for _ in delta]
    edges, stamps, rates = [], [], []
    for j in range(len(X)):
        for k in range(len(Y)):
            ts = np.sort(rng.uniform(0, 30, n))
            As, Bs, rs = [], [], []
            for t in ts:
                B = invert_transform(Y[k]) @ stream(t) @ X[j]
                if noise:
                    B = make_transform(B[:3, :3] @ so3_exp(rng.normal(size=3) / np.sqrt(2 * KAPPA)),
                                       B[:3, 3] + SIGMA * rng.normal(size=3))
                s = t - delta[k]
                As.append(stream(s))
                Bs.append(B)
                rs.append(np.zeros(6) if k in at_rest else rate(s))
            edges.append(Edge.build(f"x{j}", f"y{k}", np.array(As), np.array(Bs), sigma=SIGMA,
                                    kappa=KAPPA))
            stamps.append(ts - delta[k])
            rates.append(np.array(rs))
    problem = Problem([f"x{j}" for j in range(len(X))], [f"y{k}" for k in range(len(Y))], edges)
    return problem, stamps, np.concatenate(rates), (np.array(X), np.array(Y))


def shifted(problem: Problem, stamps, delta) -> Problem:
    """``problem`` with each pair's ``A`` the stream at its stamp + its camera's offset."""
    edges = [Edge.build(e.x, e.y, np.array([stream(s + delta[k]) for s in st]), e.B,
                        sigma=e.sigma, kappa=e.kappa)
             for e, st, k in zip(problem.edges, stamps, problem.edge_y, strict=True)]
    return problem.with_edges(edges)


def test_offset_gradient_matches_finite_differences_of_the_cost():
    """``g_d`` (closed form from the twist rates) against the central difference of the cost of
    eq. (33) with every pair of a camera re-evaluated on the stream at shifted stamps, X and Y
    fixed; h = 1 us: truncation O(h^2 f''') ~1e-9 relative, rounding ~1e-16 f / h ~1e-9."""
    rng = np.random.default_rng(0)
    delta = np.array([0.01, -0.02])
    problem, stamps, rates, (X, Y) = planted(rng, delta)
    terms = offset_terms(problem, X, Y, 1.0, rates)

    def cost(d):
        res = pair_residuals(shifted(problem, stamps, d), X, Y)
        return 0.5 * sum(float(r.normalised.sum()) for r in res.values())

    assert cost(np.zeros(2)) == pytest.approx(terms.cost, rel=1e-12)
    h = 1e-6
    for k in range(2):
        e = np.zeros(2)
        e[k] = h
        fd = (cost(e) - cost(-e)) / (2 * h)
        assert terms.g_d[k] == pytest.approx(fd, rel=1e-5)
        # and the diagonal of H_dd against the second difference of the cost along that
        # offset (Gauss-Newton: equal up to the residuals' curvature, small here)
        fd2 = (cost(100 * e) - 2 * cost(np.zeros(2)) + cost(-100 * e)) / (100 * h) ** 2
        assert terms.H_dd[k, k] == pytest.approx(fd2, rel=0.05)


def test_newton_steps_recover_planted_offsets_exactly_without_noise():
    """Noise-free pairs: the joint optimum is the planted offsets and the certified solve's
    extrinsics; a few profile Newton steps (each followed by a solve) reach them to 1 us."""
    rng = np.random.default_rng(1)
    delta = np.array([0.035, -0.05])
    problem, stamps, _, truth = planted(rng, delta, noise=False)
    d = np.zeros(2)
    current = problem
    for _ in range(4):
        res = solve(current, SolveOptions())
        assert res.certified
        rates = np.concatenate([[rate(s + d[k]) for s in st]
                                for st, k in zip(stamps, problem.edge_y, strict=True)])
        step = offset_step(offset_terms(current, res.X, res.Y, res.scale, rates),
                           information_matrix(current, res.X, res.Y, res.scale).H)
        assert step.determined.all()
        d = d + step.step_s
        current = shifted(problem, stamps, d)
    np.testing.assert_allclose(d, delta, atol=1e-6)
    res = solve(current, SolveOptions())
    np.testing.assert_allclose(res.Y[:, :3, 3], truth[1][:, :3, 3], atol=1e-6)


def test_a_camera_at_rest_is_not_determined():
    """Pairs without a rate (the stream at rest) carry no information on their camera's
    offset: not determined, no step, NaN std; the moving camera's offset is still found."""
    rng = np.random.default_rng(2)
    delta = np.array([0.02, 0.0])
    problem, _, rates, _ = planted(rng, delta, at_rest=(1,))
    res = solve(problem, SolveOptions())
    step = offset_step(offset_terms(problem, res.X, res.Y, res.scale, rates),
                       information_matrix(problem, res.X, res.Y, res.scale).H)
    assert step.determined.tolist() == [True, False]
    assert step.step_s[1] == 0.0 and np.isnan(step.std_s[1])
    assert abs(step.step_s[0] - 0.02) < 3 * step.std_s[0] + 1e-3


def test_bad_rates_are_refused():
    rng = np.random.default_rng(3)
    problem, _, rates, (X, Y) = planted(rng, np.zeros(2), n=5)
    with pytest.raises(ValueError, match=r"rates: expected shape \(30, 6\)"):
        offset_terms(problem, X, Y, 1.0, rates[:-1])
    with pytest.raises(ValueError, match="X, Y: expected shapes"):
        offset_terms(problem, X[:1], Y, 1.0, rates)


def _two_steps(problem: Problem, stamps, clusters=None, redo=lambda p: p):
    """Two profile Newton steps from zero offsets, each followed by a solve of the pairs
    re-interpolated at the shifted stamps (``redo`` applied to them); ``(offsets, last step)``."""
    d, current = np.zeros(problem.P), problem
    for _ in range(2):
        res = solve(current, SolveOptions())
        rates = np.concatenate([[rate(s + d[k]) for s in st]
                                for st, k in zip(stamps, problem.edge_y, strict=True)])
        step = offset_step(offset_terms(current, res.X, res.Y, res.scale, rates),
                           information_matrix(current, res.X, res.Y, res.scale).H, clusters)
        d = d + step.step_s
        current = redo(shifted(problem, stamps, d))
    return d, step


@pytest.mark.slow
def test_std_matches_the_scatter_of_repeated_estimates():
    """40 draws of the noise around one planted offset: the scatter of the estimates (two
    Newton steps each) agrees with the reported std. The ratio of a 40-sample std to the truth
    lies within [0.75, 1.3] with 95 % probability (chi-square, 39 dof); the reported std
    varies little between draws (the same geometry)."""
    delta = np.array([0.015, -0.025])
    est, std = [], []
    exact, stamps, _, _ = planted(np.random.default_rng(7), delta, noise=False, n=12)
    for seed in range(40):
        rng = np.random.default_rng(100 + seed)
        problem = exact
        # the same geometry and stamps every time; fresh noise on B
        edges = []
        for e in problem.edges:
            B = np.array([make_transform(b[:3, :3] @ so3_exp(rng.normal(size=3)
                                                             / np.sqrt(2 * KAPPA)),
                                         b[:3, 3] + SIGMA * rng.normal(size=3)) for b in e.B])
            edges.append(Edge.build(e.x, e.y, e.A, B, sigma=SIGMA, kappa=KAPPA))
        problem = problem.with_edges(edges)
        d, step = _two_steps(problem, stamps)
        est.append(d)
        std.append(step.std_s)
    est, std = np.array(est), np.array(std)
    scatter = est.std(axis=0, ddof=1)
    ratio = scatter / std.mean(axis=0)
    assert ((ratio > 0.75) & (ratio < 1.3)).all(), (scatter, std.mean(axis=0))
    assert (np.abs(est.mean(axis=0) - delta) < 3 * scatter / np.sqrt(40)).all()



def _same_stamps(rng, delta, n: int):
    """Noise-free pairs whose camera ``k`` sees every target at the same true times (one image,
    three tags), stamped ``t - delta[k]``; returns the problem and its stamps per edge."""
    X = [make_transform(so3_exp(rng.normal(size=3)), rng.normal(size=3)) for _ in range(3)]
    Y = [make_transform(so3_exp(rng.normal(size=3)), 0.2 * rng.normal(size=3))
         for _ in delta]
    times = [np.sort(rng.uniform(0, 30, n)) for _ in delta]
    edges, stamps = [], []
    for j in range(len(X)):
        for k in range(len(Y)):
            A = np.array([stream(t - delta[k]) for t in times[k]])
            B = np.array([invert_transform(Y[k]) @ stream(t) @ X[j] for t in times[k]])
            edges.append(Edge.build(f"x{j}", f"y{k}", A, B, sigma=SIGMA, kappa=KAPPA))
            stamps.append(times[k] - delta[k])
    problem = Problem([f"x{j}" for j in range(len(X))], [f"y{k}" for k in range(len(Y))], edges)
    return problem, stamps


def _stream_error(rng, problem: Problem) -> list[np.ndarray]:
    """Per edge, an error of the stream per pair, the same for every pair of one image (one
    camera, one stamp): (n, 4, 4) transforms to left-multiply ``A`` with."""
    shared: dict[tuple[int, int], np.ndarray] = {}
    out = []
    for e, k in zip(problem.edges, problem.edge_y, strict=True):
        for i in range(e.n):
            if (k, i) not in shared:
                shared[k, i] = make_transform(so3_exp(2e-3 * rng.normal(size=3)),
                                              4e-3 * rng.normal(size=3))
        out.append(np.array([shared[k, i] for i in range(e.n)]))
    return out


def _with_errors(problem: Problem, errors, rng=None) -> Problem:
    """``problem`` with the stream errors on ``A`` (and, given ``rng``, a little noise on B)."""
    edges = []
    for e, err in zip(problem.edges, errors, strict=True):
        B = e.B if rng is None else np.array(
            [make_transform(b[:3, :3] @ so3_exp(2e-4 * rng.normal(size=3)),
                            b[:3, 3] + 2e-4 * rng.normal(size=3)) for b in e.B])
        edges.append(Edge.build(e.x, e.y, err @ e.A, B, sigma=SIGMA, kappa=KAPPA))
    return problem.with_edges(edges)


@pytest.mark.slow
def test_cluster_robust_std_holds_when_pairs_share_the_stream_error():
    """Every target of a camera seen at the same stamps and the stream's error shared by the
    pairs of one stamp (one image, three tags): the model-based std takes the pairs as
    independent and is too small (2.0-2.3x here); the cluster-robust std, one cluster per
    image, matches the scatter of 40 draws (ratio within [0.75, 1.3]: chi-square, 39 dof, 95 %)
    and the model-based one does not (ratio above 1.3)."""
    delta = np.array([0.015, -0.025])
    exact, stamps = _same_stamps(np.random.default_rng(11), delta, 40)
    clusters = np.concatenate([k * 10_000 + np.arange(e.n)
                               for e, k in zip(exact.edges, exact.edge_y, strict=True)])
    est, robust, model = [], [], []
    for seed in range(40):
        rng = np.random.default_rng(300 + seed)
        errors = _stream_error(rng, exact)
        problem = _with_errors(exact, errors, rng)
        # re-interpolated at the shifted stamps, the same stream error on each pair
        d, step = _two_steps(problem, stamps, clusters,
                             lambda p, errors=errors: _with_errors(p, errors))
        assert step.clusters == 80
        est.append(d)
        robust.append(step.std_s)
        model.append(np.sqrt(np.diag(step.covariance_model)))
    scatter = np.array(est).std(axis=0, ddof=1)
    ratio_robust = scatter / np.array(robust).mean(axis=0)
    ratio_model = scatter / np.array(model).mean(axis=0)
    assert ((ratio_robust > 0.75) & (ratio_robust < 1.3)).all(), (scatter, ratio_robust)
    assert (ratio_model > 1.3).all(), ratio_model
    assert (np.abs(np.array(est).mean(axis=0) - delta) < 3 * scatter / np.sqrt(40)).all()


def test_clusters_of_one_pair_each_give_the_residual_based_std():
    """Clusters must be one label per pair; with fewer than MIN_CLUSTERS labels the model-based
    covariance is kept, with more the robust one is never below it."""
    rng = np.random.default_rng(4)
    problem, _, rates, _ = planted(rng, np.array([0.01, -0.01]), n=8)
    res = solve(problem, SolveOptions())
    terms = offset_terms(problem, res.X, res.Y, res.scale, rates)
    H = information_matrix(problem, res.X, res.Y, res.scale).H
    with pytest.raises(ValueError, match=r"clusters: expected shape \(48,\)"):
        offset_step(terms, H, np.zeros(5))
    few = offset_step(terms, H, np.arange(48) % (MIN_CLUSTERS - 1))
    assert few.clusters == MIN_CLUSTERS - 1
    np.testing.assert_array_equal(few.covariance, few.covariance_model)
    each = offset_step(terms, H, np.arange(48))
    assert each.clusters == 48
    assert (np.diag(each.covariance) >= np.diag(each.covariance_model) * (1 - 1e-12)).all()
    np.testing.assert_allclose(each.step_s, few.step_s)
