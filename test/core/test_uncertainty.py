"""Per-frame uncertainty (issue 11): the information matrix against finite differences and two
independent implementations, the covariance against Monte-Carlo, the frame conventions, the
unobservable directions and the a-posteriori variance factor."""

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from rwhec_ros.core.analysis.information import information_from_cost_matrix, information_matrix
from rwhec_ros.core.analysis.uncertainty import UncertaintyOptions, frame_uncertainty
from rwhec_ros.core.identifiability import numeric_check
from rwhec_ros.core.lie import invert_transform, make_transform, so3_exp, so3_log
from rwhec_ros.core.model.cost import build_cost_matrices, direct_cost
from rwhec_ros.core.model.gauge import GaugeOptions, TranslationPrior
from rwhec_ros.core.problem import Edge, Problem
from rwhec_ros.core.solve import solve
from rwhec_ros.simulation.synthetic import (
    perturb_measurements,
    planar_instance,
    random_instance,
    random_transforms,
)


def _instance(seed, unknown_scale=False, sigma=0.05, kappa=10.0):
    rng = np.random.default_rng(seed)
    return random_instance(rng, 2, 2, n_per_edge=10, sigma=sigma, kappa=kappa,
                           unknown_scale=unknown_scale, alpha=0.7 if unknown_scale else 1.0)


@pytest.mark.parametrize("unknown_scale", [False, True])
@pytest.mark.parametrize("offset", [0.0, 0.05])
def test_information_is_the_hessian_of_the_direct_cost(unknown_scale, offset):
    """Central second differences of eq. (33) evaluated directly, at the optimum and away from
    it (so the second-order residual terms are exercised)."""
    problem, _ = _instance(3, unknown_scale)
    res = solve(problem)
    T0 = np.concatenate([res.X, res.Y])
    T0[:, :3, 3] += offset
    a = res.scale
    info = information_matrix(problem, T0[:2], T0[2:], a)
    lay = info.layout
    n, F = lay.size, 4

    def f(xi):
        t = T0[:, :3, 3] + xi[: 3 * F].reshape(F, 3)
        al = a + (xi[3 * F] if unknown_scale else 0.0)
        T = make_transform(T0[:, :3, :3] @ so3_exp(xi[lay.r0:].reshape(F, 3)), t)
        return direct_cost(problem, T[:2], T[2:], al)

    h = 1e-4
    E = np.eye(n) * h
    H = np.array([[(f(E[i] + E[j]) - f(E[i] - E[j]) - f(E[j] - E[i]) + f(-E[i] - E[j]))
                   / (4 * h * h) for j in range(n)] for i in range(n)])
    # truncation O(h^2 f'''') and rounding O(u f / h^2) are both ~1e-8 of the largest entry
    assert np.abs(H - info.H).max() <= 1e-6 * np.abs(info.H).max()
    assert info.chi2 == pytest.approx(2.0 * direct_cost(problem, T0[:2], T0[2:], a), rel=1e-12)


@pytest.mark.parametrize("unknown_scale", [False, True])
def test_information_from_the_cost_matrix_agrees(unknown_scale):
    """Pair-by-pair assembly against 2 J^T Q J + curvature on the assembled Q of eq. (42)."""
    problem, _ = _instance(4, unknown_scale)
    res = solve(problem)
    a = information_matrix(problem, res.X, res.Y, res.scale)
    b = information_from_cost_matrix(problem, build_cost_matrices(problem)[0], res.X, res.Y,
                                     res.scale)
    # both exact; differences are rounding of sums of ~100 terms
    assert np.abs(a.H - b.H).max() <= 1e-12 * np.abs(a.H).max()
    assert np.abs(a.Q_ee - b.Q_ee).max() <= 1e-12 * np.abs(a.Q_ee).max()
    assert b.chi2 == pytest.approx(a.chi2, rel=1e-9)


@pytest.mark.parametrize("unknown_scale", [False, True])
@pytest.mark.parametrize("offset", [0.0, 0.05])
def test_information_from_the_edge_blocks_agrees(unknown_scale, offset):
    """Edge-block assembly (the live path) against the pair-by-pair one, at the optimum and away
    from it (the curvature terms of a non-zero gradient), with precomputed blocks too."""
    from rwhec_ros.core.analysis.information import information_from_edge_blocks
    from rwhec_ros.core.model.edge_cache import EdgeBlockCache

    problem, _ = _instance(5, unknown_scale)
    res = solve(problem)
    T = np.concatenate([res.X, res.Y])
    T[:, :3, 3] += offset
    a = information_matrix(problem, T[:2], T[2:], res.scale)
    b = information_from_edge_blocks(problem, T[:2], T[2:], res.scale)
    problem.precomputed_blocks = EdgeBlockCache().blocks(problem)
    c = information_from_edge_blocks(problem, T[:2], T[2:], res.scale)
    for got in (b, c):
        # both exact; differences are rounding of sums of ~100 terms
        assert np.abs(a.H - got.H).max() <= 1e-12 * np.abs(a.H).max()
        assert np.abs(a.Q_ee - got.Q_ee).max() <= 1e-12 * np.abs(a.Q_ee).max()
        # chi2 from x^T Q x: rounding u |x|^T |Q| |x|, here ~1e-12 of chi2
        assert got.chi2 == pytest.approx(a.chi2, rel=1e-9)
        np.testing.assert_allclose(got.edge_chi2, a.edge_chi2, rtol=1e-9)
        assert got.n_pairs == a.n_pairs and got.names == a.names


def test_edge_block_uncertainty_is_the_pair_uncertainty_with_a_gauge():
    """frame_uncertainty with information="edge_blocks" against the default on a planar problem
    (an unobservable direction: the gauge analysis and NaN axes must come out the same)."""
    rng = np.random.default_rng(2)
    problem, _ = planar_instance(rng, 2, 2, n_per_edge=15, sigma=0.02, kappa=100.0)
    res = solve(problem)
    a = frame_uncertainty(problem, res)
    b = frame_uncertainty(problem, res, UncertaintyOptions(information="edge_blocks"))
    # the words end with the std of the null direction's eigenvalue, rounding noise (~1e5 m,
    # or "no information" when it rounds to <= 0): compare the directions named
    assert [w.rsplit(" (", 1)[0] for w in a.unobservable] == \
        [w.rsplit(" (", 1)[0] for w in b.unobservable]
    assert a.unobservable and a.rank == b.rank and a.dof == b.dof
    for fa, fb in zip(a.frames, b.frames, strict=True):
        np.testing.assert_array_equal(np.isnan(fa.covariance), np.isnan(fb.covariance))
        # the same matrices to rounding, through a 2-4 digit condition number
        np.testing.assert_allclose(fb.covariance, fa.covariance, rtol=1e-8, atol=1e-14)
    assert b.variance_factor == pytest.approx(a.variance_factor, rel=1e-9)
    with pytest.raises(ValueError, match="information"):
        UncertaintyOptions(information="pair")


def test_worst_direction_matches_the_numeric_identifiability_check():
    """numeric_check inverts its own Hessian (state coordinates, other code): its worst-direction
    stds are the largest eigenvalues of our per-frame blocks."""
    problem, _ = _instance(5)
    res = solve(problem)
    unc = frame_uncertainty(problem, res)
    nc = numeric_check(problem, solution=(res.X, res.Y, res.scale))
    for f in unc.frames:
        t = np.sqrt(np.linalg.eigvalsh(f.covariance[:3, :3])[-1])
        r = np.degrees(np.sqrt(np.linalg.eigvalsh(f.covariance[3:, 3:])[-1]))
        assert t == pytest.approx(nc.translation_std_m[f.name], rel=1e-6)
        assert r == pytest.approx(nc.rotation_std_deg[f.name], rel=1e-6)


def _errors(res, X, Y):
    """Per frame [dt, phi] with t = t_true + dt, R = exp(phi^) R_true (the reported convention)."""
    T_hat = np.concatenate([res.X, res.Y])
    T = np.concatenate([X, Y])
    dt = T_hat[:, :3, 3] - T[:, :3, 3]
    phi = so3_log(T_hat[:, :3, :3] @ np.swapaxes(T[:, :3, :3], 1, 2))
    return np.concatenate([dt, phi], axis=1)


def test_covariance_matches_monte_carlo():
    """One design (A and the truth fixed), 200 noise draws: the predicted stds match the spread
    of the estimates and the 95 % ellipsoid covers about 95 % of them."""
    rng = np.random.default_rng(11)
    X, Y = random_transforms(rng, 1), random_transforms(rng, 1)
    A = random_transforms(rng, 30)
    B0 = invert_transform(Y[0]) @ A @ X[0]
    sigma, kappa = 0.01, 200.0
    err, covs = [], []
    for _ in range(200):
        B = perturb_measurements(rng, B0, sigma, kappa)
        problem = Problem(["tag"], ["cam"], [Edge.build("tag", "cam", A, B, sigma, kappa)])
        res = solve(problem)
        unc = frame_uncertainty(problem, res)
        err.append(_errors(res, X, Y))
        covs.append(np.stack([f.covariance for f in unc.frames]))
    err, covs = np.array(err), np.array(covs)  # (runs, 2, 6), (runs, 2, 6, 6)
    emp = err.std(axis=0)
    pred = np.sqrt(np.diagonal(covs.mean(axis=0), axis1=1, axis2=2))
    # the std of a sample std over 200 runs is ~5 %; 25 % is > 4 of those
    np.testing.assert_array_less(np.abs(emp / pred - 1.0), 0.25)
    d2 = np.einsum("rfi,rfij,rfj->rf", err, np.linalg.inv(covs), err)
    coverage = np.mean(d2 <= 12.592)  # chi2(6) 95 % quantile
    # binomial std of the coverage over 400 frame-runs ~1.1 %: 0.90..0.99 is > 4 of those
    assert 0.90 <= coverage <= 0.99


def _rotated_parent(problem, side, C):
    """The same data with the camera carrier (side "y": A <- C A) or the tag carrier (side "x":
    A <- A C^-1) moved by the rigid transform ``C``."""
    edges = []
    for e in problem.edges:
        A = C @ e.A if side == "y" else e.A @ invert_transform(C)
        edges.append(Edge.build(e.x, e.y, A, e.B, e.sigma, e.kappa))
    return Problem(problem.x_names, problem.y_names, edges, unknown_scale=problem.unknown_scale)


@pytest.mark.parametrize("side", ["x", "y"])
def test_rotating_the_parent_rotates_the_reported_axes(side):
    """The MLE is equivariant: Y' = C Y (or X' = C X); the reported covariance of the moved
    frames turns with the parent, R_C cov R_C^T in both blocks, the others stay."""
    problem, _ = _instance(6, sigma=0.02, kappa=100.0)
    C = make_transform(Rotation.from_rotvec([0.3, -1.1, 0.7]).as_matrix(), [0.5, -0.2, 1.0])
    moved = _rotated_parent(problem, side, C)
    u0 = frame_uncertainty(problem, solve(problem))
    u1 = frame_uncertainty(moved, solve(moved))
    Rc = np.kron(np.eye(2), C[:3, :3])
    for f0, f1 in zip(u0.frames, u1.frames, strict=True):
        expect = Rc @ f0.covariance @ Rc.T if f0.role == side.upper() else f0.covariance
        # the optima agree to ~1e-9 relative; the covariances follow
        np.testing.assert_allclose(f1.covariance, expect, rtol=0, atol=1e-7 * np.abs(
            expect).max())
    # and the axes do change: a non-trivial rotation moves the diagonal
    moved_frames = [f for f in u0.frames if f.role == side.upper()]
    assert not np.allclose(u1.frame(moved_frames[0].name).std_translation_m,
                           moved_frames[0].std_translation_m, rtol=1e-3)


def _planar(seed=1):
    """A ground robot that only yaws: camera and tag heights unobservable."""
    return planar_instance(np.random.default_rng(seed))[0]


def test_unobservable_heights_are_reported_as_such():
    problem = _planar()
    res = solve(problem)
    unc = frame_uncertainty(problem, res)
    assert not unc.observable and len(unc.unobservable) == 1
    assert "z" in unc.unobservable[0]
    for f in unc.frames:
        assert f.unobservable_translation.tolist() == [False, False, True]
        assert not f.unobservable_rotation.any()
        assert np.isnan(f.std_translation_m[2]) and np.isnan(f.covariance[2]).all()
        # the determined axes keep honest, finite numbers (centimetres here, not 1e4 m)
        assert np.all(f.std_translation_m[:2] < 0.05) and np.all(f.std_rotation_deg < 2.0)
        d = f.to_dict()
        assert d["std_translation_m"][2] is None and d["unobservable"]["translation"] == ["z"]
    yaml.safe_dump(unc.to_dict())
    assert unc.max_std()[0] < 0.05
    assert not unc.converged(1.0, 10.0)  # never converged with an unobservable axis
    assert not unc.notes  # the solve reported the same direction


def test_priors_that_pin_the_heights_give_stds_given_the_priors():
    problem = _planar()
    gauge = GaugeOptions(priors=(TranslationPrior("cam0", "z", 0.3),))
    from rwhec_ros.core.solve import SolveOptions

    res = solve(problem, SolveOptions(gauge=gauge))
    unc = frame_uncertainty(problem, res, UncertaintyOptions(gauge=gauge))
    assert unc.conditioned_on_priors and unc.observable and not unc.unobservable
    cam0, cam1 = unc.frame("cam0"), unc.frame("cam1")
    # cam0's height is the prior itself; the others' are relative to it, hence finite
    assert cam0.std_translation_m[2] < 1e-6
    assert 1e-4 < cam1.std_translation_m[2] < 0.05
    # the determined axes do not depend on how the undetermined one is fixed
    free = frame_uncertainty(problem, solve(problem))
    np.testing.assert_allclose(cam1.std_translation_m[:2],
                               free.frame("cam1").std_translation_m[:2], rtol=1e-5)


def test_unobservable_rotation_from_the_information_matrix():
    """No translation and rotations about one axis: the common yaw of both frames is a null
    direction of the information matrix (not a translation gauge)."""
    rng = np.random.default_rng(13)
    X, Y = random_transforms(rng, 1), random_transforms(rng, 1)
    yaw = rng.uniform(-np.pi, np.pi, 12)
    A = make_transform(Rotation.from_rotvec(np.outer(yaw, [0, 0, 1])).as_matrix(),
                       np.zeros((12, 3)))
    B = invert_transform(Y[0]) @ A @ X[0]
    problem = Problem(["tag_0"], ["cam0"], [Edge.build("tag_0", "cam0", A, B, 0.01, 125)])
    unc = frame_uncertainty(problem, solve(problem))
    assert any("rotation about" in w for w in unc.unobservable)
    for f in unc.frames:
        assert f.unobservable_rotation.any()
        assert np.all(np.isnan(f.std_rotation_deg[f.unobservable_rotation]))
        finite = f.std_rotation_deg[~f.unobservable_rotation]
        # per-pair rotation noise 1/sqrt(2 kappa) = 3.6 deg, over 12 pairs ~1 deg
        assert np.all(np.isfinite(finite)) and np.all(finite < 2.0)


def test_variance_factor_detects_understated_noise():
    """Data twice as noisy as stated (sigma x 2, kappa / 4): s0^2 ~ 4, and the a-posteriori stds
    are 2x the predicted ones; with the noise as stated s0^2 ~ 1."""
    rng = np.random.default_rng(21)
    X, Y = random_transforms(rng, 2), random_transforms(rng, 2)
    out = {}
    for factor in (1.0, 2.0):
        edges = []
        for j in range(2):
            for k in range(2):
                A = random_transforms(rng, 60)
                B = perturb_measurements(rng, invert_transform(Y[k]) @ A @ X[j], 0.01 * factor,
                                         200.0 / factor**2)
                edges.append(Edge.build(f"t{j}", f"c{k}", A, B, 0.01, 200.0))
        problem = Problem(["t0", "t1"], ["c0", "c1"], edges)
        unc = frame_uncertainty(problem, solve(problem))
        assert unc.dof == 6 * 240 - 24
        out[factor] = unc
        f = unc.frames[0]
        np.testing.assert_allclose(f.std_translation_m_a_posteriori,
                                   np.sqrt(unc.variance_factor) * f.std_translation_m)
    # chi2 / dof has std sqrt(2 / 1416) ~ 4 %; 15 % margins
    assert out[1.0].variance_factor == pytest.approx(1.0, abs=0.15)
    assert out[2.0].variance_factor == pytest.approx(4.0, rel=0.15)


def test_mismatched_result_is_refused():
    problem, _ = _instance(7)
    other, _ = random_instance(np.random.default_rng(1), 1, 1, n_per_edge=5)
    with pytest.raises(ValueError, match="do not match"):
        frame_uncertainty(problem, solve(other))
    with pytest.raises(ValueError, match="null_tol"):
        UncertaintyOptions(null_tol=0.0)


def test_inverse_from_cholesky_is_the_inverse():
    """potri's inverse (both triangles filled) against solving for the identity's columns."""
    import scipy.linalg

    from rwhec_ros.core.analysis.uncertainty import _inverse_from_cholesky

    rng = np.random.default_rng(4)
    G = rng.normal(size=(40, 80))
    A = G @ G.T / 80 + 0.1 * np.eye(40)
    inv = _inverse_from_cholesky(A)
    ref = scipy.linalg.cho_solve(scipy.linalg.cho_factor(A), np.eye(40))
    np.testing.assert_array_equal(inv, inv.T)
    # both backward stable; condition number ~30: agreement to ~1e-14 of the largest entry
    assert np.abs(inv - ref).max() <= 1e-12 * np.abs(ref).max()
    with pytest.raises(np.linalg.LinAlgError):
        _inverse_from_cholesky(-A)
