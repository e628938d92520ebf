"""Unobservable translations (motion about one axis), priors, the scale floor, solver failures:
the statuses of issue 10, checked against an independent least-squares solver."""

import time

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from rwhec_ros.core.certify.relaxation import SdpOptions
from rwhec_ros.core.lie import invert_transform, make_transform
from rwhec_ros.core.model.cost import direct_cost
from rwhec_ros.core.model.gauge import GaugeOptions, TranslationPrior, axis_words
from rwhec_ros.core.pipeline import dense as dense_path
from rwhec_ros.core.problem import Edge, Problem
from rwhec_ros.core.result import Status
from rwhec_ros.core.solve import SolveOptions, solve
from rwhec_ros.simulation.synthetic import (
    planar_instance,
    random_instance,
    random_transforms,
)


def _planar_rig(rng, M=2, P=2, n=20, sigma=0.01, kappa=125.0, jitter=0.0):
    """A ground robot (:func:`planar_instance`): the rig yaws (+ ``jitter`` rad of tilt)."""
    problem, truth = planar_instance(rng, M, P, n, sigma, kappa, tilt=jitter)
    return problem, truth.X, truth.Y


def _independent_min(problem, rng, starts=20, penalty=None):
    """Smallest cost found by scipy least_squares on the residuals of eq. (33) (own code: rotation
    vectors, metric translations) from random starts, plus an optional linear prior residual
    ``sqrt(rho) (G t - b)``. Returns the best cost (1/2 sum J, as the product's)."""
    n = problem.n_frames
    M = problem.M
    st = problem.stacked()
    wt = np.sqrt(0.5) / st["sigma"]
    wr = np.sqrt(0.5 * st["kappa"])

    def residuals(x):
        R = Rotation.from_rotvec(x[: 3 * n].reshape(n, 3)).as_matrix()
        t = x[3 * n:].reshape(n, 3)
        RX, tX = R[st["xi"]], t[st["xi"]]
        RY, tY = R[M + st["yi"]], t[M + st["yi"]]
        RA, tA = st["A"][:, :3, :3], st["A"][:, :3, 3]
        RB, tB = st["B"][:, :3, :3], st["B"][:, :3, 3]
        rt = np.einsum("nij,nj->ni", RA, tX) + tA - tY - np.einsum("nij,nj->ni", RY, tB)
        rR = RA @ RX - RY @ RB
        out = [(wt[:, None] * rt).ravel(), (wr[:, None, None] * rR).ravel()]
        if penalty is not None:
            G, b, rho = penalty
            out.append(np.sqrt(rho) * (G @ t.ravel() - b))
        return np.concatenate(out)

    best = np.inf
    for _ in range(starts):
        x0 = np.concatenate([Rotation.random(n, random_state=rng).as_rotvec().ravel(),
                             rng.normal(0, 1.0, 3 * n)])
        sol = least_squares(residuals, x0, method="lm", xtol=1e-14, ftol=1e-14, gtol=1e-14,
                            max_nfev=4000)
        best = min(best, 2.0 * float(sol.cost))  # least_squares: 1/2 sum r^2; ours: sum r^2
    return best


@pytest.mark.parametrize("jitter", [0.0, 1e-6, 1e-4])
def test_single_axis_motion_is_not_identifiable_and_named(jitter):
    rng = np.random.default_rng(1)
    problem, X, Y = _planar_rig(rng, jitter=jitter)
    res = solve(problem)
    c = res.certificate
    assert c.status is Status.NOT_IDENTIFIABLE, c.message
    assert len(res.unobservable) == 1
    d = res.unobservable[0]
    assert set(d.frames()) == {"tag_0", "tag_1", "cam0", "cam1"}
    assert all(axis_words(v) == "z" for v in d.components.values())
    assert "z of" in c.message and "cam0" in c.message and "give a prior" in c.message
    # the underlying certificate was certified: the message quotes it, not a failure
    assert c.message.endswith(f"With that, the rest is certified optimal "
                              f"(rho_hat={c.suboptimality_bound:.3g}).")
    assert d.fixed_by == "default"
    # the default: the cameras' heights are zero on average
    assert abs(res.Y[:, 2, 3].mean()) < 1e-4  # held by a penalty of weight w_max: ~1e-5 m
    # the primal cost is the cost of the returned estimate
    assert c.primal_cost == pytest.approx(direct_cost(problem, res.X, res.Y), rel=1e-9)
    # the relative heights are observable and right (noise 1 cm, 80 pairs)
    rel_true = X[:, 2, 3] - Y[0, 2, 3]
    rel_est = res.X[:, 2, 3] - res.Y[0, 2, 3]
    np.testing.assert_allclose(rel_est, rel_true, atol=0.02)


def test_prior_pins_the_height_and_the_certificate_holds():
    """With cam0's height known the problem is determined: certified, the prior met, and no
    independent random-start solve of the same problem (data + the prior's term) beats the dual
    bound."""
    rng = np.random.default_rng(2)
    problem, X, Y = _planar_rig(rng, jitter=1e-6)
    prior = TranslationPrior("cam0", "z", float(Y[0, 2, 3]))
    res = solve(problem, SolveOptions(gauge=GaugeOptions(priors=(prior,))))
    c = res.certificate
    assert c.status is Status.CERTIFIED_OPTIMAL, c.message
    assert res.Y[0, 2, 3] == pytest.approx(Y[0, 2, 3], abs=1e-6)
    assert res.unobservable and res.unobservable[0].fixed_by == "prior"
    np.testing.assert_allclose(res.X[:, 2, 3], X[:, 2, 3], atol=0.02)
    fix = dense_path.prepare_dense(problem, SolveOptions(gauge=GaugeOptions(priors=(prior,)))).gauge
    best = _independent_min(problem, rng, starts=10, penalty=(fix.G, fix.b, fix.rho))
    # false certificate = a feasible point below the bound (beyond evaluation noise 1e-9 rel.)
    assert best >= c.dual_bound * (1 - 1e-9)
    assert c.primal_cost <= best * (1 + 1e-6)


def test_prior_on_an_unknown_frame_is_refused():
    rng = np.random.default_rng(3)
    problem, _, _ = _planar_rig(rng)
    with pytest.raises(ValueError, match="unknown frame 'cam9'"):
        solve(problem, SolveOptions(gauge=GaugeOptions(priors=(TranslationPrior("cam9", "z",
                                                                                  0.3),))))


@pytest.mark.parametrize("axis", ["w", 3, [0, 0, 0], [np.nan, 0, 1]])
def test_bad_prior_axis_is_refused(axis):
    with pytest.raises(ValueError, match="axis"):
        TranslationPrior("cam0", axis, 0.3)


def test_well_posed_data_have_no_unobservable_direction():
    rng = np.random.default_rng(4)
    problem, _ = random_instance(rng, 2, 2, n_per_edge=20, sigma=0.01, kappa=125)
    res = solve(problem)
    assert res.certified and not res.unobservable


@pytest.mark.parametrize("seed", [0, 4, 14])
def test_non_positive_unknown_scale_is_never_certified(seed):
    """Noise far above the translations: the unknown-scale optimum has alpha <= 0."""
    rng = np.random.default_rng(seed)
    problem, _ = random_instance(rng, 1, 1, n_per_edge=3, sigma=0.5, kappa=2,
                                 unknown_scale=True, alpha=0.5)
    res = solve(problem)
    assert res.scale <= 0.01
    assert res.certificate.status is Status.NOT_IDENTIFIABLE
    assert "scale" in res.certificate.message


def test_scale_floor_option():
    rng = np.random.default_rng(5)
    problem, _ = random_instance(rng, 1, 2, n_per_edge=20, sigma=0.01, kappa=125,
                                 unknown_scale=True, alpha=0.5)
    assert solve(problem).certified
    res = solve(problem, SolveOptions(min_scale=0.6))
    assert res.certificate.status is Status.NOT_IDENTIFIABLE
    with pytest.raises(ValueError, match="min_scale"):
        SolveOptions(min_scale=0.0)


def test_sdp_solver_exception_becomes_solver_failed(monkeypatch):
    import cvxpy

    def boom(*args, **kwargs):
        raise cvxpy.error.SolverError("Solver 'CLARABEL' failed. Try another solver")

    monkeypatch.setattr(dense_path, "solve_dual_sdp", boom)
    monkeypatch.setattr(dense_path, "solve_dual_sdp_arrow", boom)
    rng = np.random.default_rng(6)
    problem, _ = random_instance(rng, 1, 1, n_per_edge=10, sigma=0.01, kappa=125)
    # the cvxpy + Clarabel backend (the structured one: test/core/test_sdp_ipm.py)
    res = solve(problem, SolveOptions(mode="sdp", sdp=SdpOptions(backend="cvxpy")))
    assert res.certificate.status is Status.SOLVER_FAILED
    # what ran, in words; not cvxpy's advice to its own users (issue 32)
    assert "the SDP solver (Clarabel) stopped with an error" in res.certificate.message
    assert "Try another solver" not in res.certificate.message
    assert np.all(np.isfinite(res.X)) and np.all(np.isfinite(res.Y))
    _assert_failed_result(res)


def _assert_failed_result(res, wall=60.0):
    """A failed solve: no eigenvalues, the -1 null-space flag, the configured tolerance, the
    closed-form estimate not rounded from a null vector, and sane step timings (seconds)."""
    c = res.certificate
    assert c.eigenvalues.size == 0 and c.null_space_dim == -1
    assert c.tolerance == SolveOptions().certificate.rho_tol
    assert res.rounding_displacement == 0.0
    assert all(0.0 <= t < wall for t in res.timing_s.values()), res.timing_s


def test_local_solver_exception_falls_back_or_fails(monkeypatch):
    def boom(*args, **kwargs):
        raise np.linalg.LinAlgError("singular matrix")

    monkeypatch.setattr(dense_path, "refine_rotations", boom)
    rng = np.random.default_rng(7)
    problem, _ = random_instance(rng, 1, 1, n_per_edge=10, sigma=0.01, kappa=125)
    res = solve(problem)
    assert res.certified and any("local solver failed" in n for n in res.notes)
    assert any("SDP form" in n for n in res.notes)  # the SDP took over
    t0 = time.perf_counter()
    res = solve(problem, SolveOptions(fallback_to_sdp=False))
    wall = time.perf_counter() - t0
    assert res.certificate.status is Status.SOLVER_FAILED
    assert res.certificate.message == "the local solver failed: singular matrix"
    assert res.notes == ["local solver failed (LinAlgError: singular matrix)"]
    assert res.solver_status == "failed" and res.mode == "fast"
    assert np.all(np.isfinite(res.X)) and np.all(np.isfinite(res.Y))
    _assert_failed_result(res, wall)


def test_nan_sdp_multipliers_become_solver_failed(monkeypatch):
    from rwhec_ros.core.certify.relaxation import DualSolution

    def nan_dual(Q, cons, options=None, *a):
        return DualSolution(np.full(cons.m, np.nan), "infeasible", 0.0, 0.0, 3)

    monkeypatch.setattr(dense_path, "solve_dual_sdp", nan_dual)
    rng = np.random.default_rng(8)
    problem, _ = random_instance(rng, 1, 1, n_per_edge=10, sigma=0.01, kappa=125)
    res = solve(problem, SolveOptions(mode="sdp", sdp=SdpOptions(backend="cvxpy")))
    assert res.certificate.status is Status.SOLVER_FAILED
    assert "no solution" in res.certificate.message
    _assert_failed_result(res)
    assert "extract" in res.timing_s and "constraints" in res.timing_s


def test_eigendecomposition_failure_of_the_sdp_z_becomes_solver_failed(monkeypatch):
    def bad_z(*a, **k):
        raise np.linalg.LinAlgError("Eigenvalues did not converge")

    monkeypatch.setattr(dense_path, "certificate_matrix", bad_z)
    rng = np.random.default_rng(8)
    problem, _ = random_instance(rng, 1, 1, n_per_edge=10, sigma=0.01, kappa=125)
    res = solve(problem, SolveOptions(mode="sdp"))
    assert res.certificate.status is Status.SOLVER_FAILED
    assert "eigendecomposition of Z failed" in res.certificate.message
    _assert_failed_result(res)


class _FormTaken(Exception):
    pass


@pytest.mark.parametrize("form", ["auto", "arrow", "full", "reduced"])
def test_the_sdp_form_asked_for_is_the_form_solved(monkeypatch, form):
    """Which SDP builder runs (spies that stop the solve), and the note naming the form: an
    explicit form is honoured; ``auto`` on 4 targets x 3 cameras picks ``arrow`` (its cost
    model, see benchmarks/sdp_forms.md). Forms are a setting of the cvxpy backend."""
    called = []

    def spy(name):
        def f(*a, **k):
            called.append(name)
            raise _FormTaken(name)
        return f

    monkeypatch.setattr(dense_path, "solve_dual_sdp_arrow", spy("arrow"))
    monkeypatch.setattr(dense_path, "solve_dual_sdp", spy("dense"))
    rng = np.random.default_rng(0)
    problem, _ = random_instance(rng, 4, 3, [(j, k) for j in range(4) for k in range(3)],
                                 n_per_edge=10, sigma=0.01, kappa=100.0)
    res = solve(problem, SolveOptions(mode="sdp", sdp=SdpOptions(form=form, backend="cvxpy")))
    solved = "arrow" if form == "auto" else form
    assert f"SDP form: {solved}" in res.notes
    assert called == ["arrow" if solved == "arrow" else "dense"]
    assert res.certificate.status is Status.SOLVER_FAILED


def test_inaccurate_sdp_status_is_not_certified(monkeypatch):
    """Clarabel stopping at max_iterations with finite multipliers: the numbers are reported but
    the status is solver_inaccurate, even if the bound would close."""
    real = dense_path.solve_dual_sdp

    def capped(Q, cons, options=None):
        sol = real(Q, cons, options)
        sol.status = "user_limit"
        return sol

    monkeypatch.setattr(dense_path, "solve_dual_sdp", capped)
    rng = np.random.default_rng(9)
    problem, _ = random_instance(rng, 1, 1, n_per_edge=10, sigma=0.01, kappa=125)
    res = solve(problem, SolveOptions(mode="sdp", sdp=SdpOptions(backend="cvxpy")))
    assert res.certificate.status is Status.SOLVER_INACCURATE
    assert np.isfinite(res.certificate.dual_bound)


@pytest.mark.parametrize("mode", ["fast", "sdp"])
@pytest.mark.parametrize("unknown_scale", [False, True])
def test_certified_primal_cost_is_the_direct_cost(mode, unknown_scale):
    rng = np.random.default_rng(10)
    problem, _ = random_instance(rng, 2, 2, n_per_edge=15, sigma=0.02, kappa=100,
                                 unknown_scale=unknown_scale, alpha=0.7 if unknown_scale else 1)
    t0 = time.perf_counter()
    res = solve(problem, SolveOptions(mode=mode))
    wall = time.perf_counter() - t0
    assert res.certified, res.certificate.message
    p = direct_cost(problem, res.X, res.Y, res.scale)
    assert res.certificate.primal_cost == pytest.approx(p, rel=1e-12)
    assert res.certificate.dual_bound <= p
    # each step's time is a duration within the call (not a clock reading)
    assert all(0.0 <= t <= wall for t in res.timing_s.values()), res.timing_s
    if mode == "fast":  # the local solver's rotations are exact: nothing was rounded
        assert res.rounding_displacement == 0.0
        local = solve(problem, SolveOptions(mode="local"))
        assert local.rounding_displacement == 0.0 and local.certificate.status is Status.LOCAL_ONLY


def test_unknown_scale_fast_certified_without_sdp_fallback():
    """The homogeneous (trivial e_s) branch certifies unknown-scale solves in the fast path: the
    SDP never runs (no SDP notes, no solve/compile times)."""
    rng = np.random.default_rng(11)
    problem, _ = random_instance(rng, 2, 1, n_per_edge=20, sigma=0.01, kappa=125,
                                 unknown_scale=True, alpha=0.5)
    res = solve(problem)
    assert res.certified, res.certificate.message
    assert "sign of s" in res.certificate.message
    assert not any("SDP" in n for n in res.notes)
    assert "solve" not in res.timing_s and "compile" not in res.timing_s


def test_certified_fast_solve_does_not_run_the_sdp():
    rng = np.random.default_rng(12)
    problem, _ = random_instance(rng, 3, 2, n_per_edge=15, sigma=0.01, kappa=125)
    res = solve(problem)
    assert res.certified and res.mode == "fast"
    assert "solve" not in res.timing_s and not any("SDP" in n for n in res.notes)


@pytest.mark.parametrize("fast_form", ["auto", "sparse"])
def test_exact_single_axis_rotation_only_problem_names_the_rotation(fast_form):
    """No translation and rotations about one axis: the yaw of the frames is a free gauge (the
    optimum is not unique): not_identifiable, with the rotation named, never certified -- also by
    the large-rig sparse path on its own (its Hessian analysis, no dense fallback)."""
    rng = np.random.default_rng(13)
    X = random_transforms(rng, 1)
    Y = random_transforms(rng, 1)
    yaw = rng.uniform(-np.pi, np.pi, 12)
    A = make_transform(Rotation.from_rotvec(np.outer(yaw, [0, 0, 1])).as_matrix(),
                       np.zeros((12, 3)))
    B = invert_transform(Y[0]) @ A @ X[0]
    problem = Problem(["tag_0"], ["cam0"], [Edge.build("tag_0", "cam0", A, B, 0.01, 125)])
    res = solve(problem, SolveOptions(fast_form=fast_form, sdp_fallback_max_frames=0))
    assert any("sparse unreduced path" in n for n in res.notes) == (fast_form == "sparse")
    assert not res.certified
    assert res.certificate.status is Status.NOT_IDENTIFIABLE, res.certificate.message
    assert "rotation of tag_0, cam0 about z" in res.certificate.message


def test_axis_words_prints_no_negative_zero():
    """A component that rounds to zero (e.g. after an axis sign flip) prints as +0.00."""
    words = axis_words(np.array([0.6, -0.001, -0.8]))
    assert words == "[+0.60, +0.00, -0.80]"
    assert axis_words(np.array([-0.0, 0.7, 0.7])) == "[+0.00, +0.71, +0.71]"
