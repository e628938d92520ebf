"""The structured SDP path: its block operators against the generic constraint matrices, the
interior-point method against cvxpy + Clarabel, KKT residuals, failures that map to the existing
statuses (never a certificate), and the paper's 16 x 8 data."""

from pathlib import Path

import numpy as np
import pytest

from rwhec_ros.core.certify.dense import certify
from rwhec_ros.core.certify.relaxation import SdpOptions, frame_constraints, solve_dual_sdp
from rwhec_ros.core.certify.sdp_ipm import (
    IpmOptions,
    initial_point,
    solve_dual_sdp_structured,
    structured_is_cheaper,
)
from rwhec_ros.core.certify.sdp_structure import frame_blocks
from rwhec_ros.core.pipeline.dense import prepare_dense
from rwhec_ros.core.result import Status
from rwhec_ros.core.solve import SolveOptions, solve
from rwhec_ros.simulation.synthetic import random_instance

SHARED = Path(__file__).resolve().parents[2] / ".." / "shared"


def _sdp(backend: str, **kw) -> SolveOptions:
    return SolveOptions(mode="sdp", sdp=SdpOptions(backend=backend, **kw))


def _explicit(fb):
    """The constraint matrices one by one, from the generic construction."""
    cons = frame_constraints(fb.n)
    return [cons.apply(fb.full_multipliers(e)) for e in np.eye(fb.m)]


@pytest.mark.parametrize("n", [1, 2, 4])
def test_block_operators_match_the_generic_constraint_matrices(n):
    rng = np.random.default_rng(n)
    fb = frame_blocks(n)
    A = _explicit(fb)
    y = rng.standard_normal(fb.m)
    G = rng.standard_normal((fb.d, fb.d))
    X = G @ G.T
    z = rng.standard_normal(fb.d)
    # adjoint = K(lambda) of the certificate, with the left-out constraint's multiplier 0
    assert np.array_equal(fb.full_multipliers(y)[11::21], np.zeros(n))
    np.testing.assert_allclose(fb.adjoint(y), sum(c * a for c, a in zip(y, A, strict=True)),
                               rtol=0, atol=1e-13)
    np.testing.assert_allclose(fb.apply(X), [np.vdot(a, X) for a in A], rtol=1e-13, atol=1e-12)
    M = np.array([[np.trace(ai @ X @ aj @ X) for aj in A] for ai in A])
    np.testing.assert_allclose(fb.schur(X), M, rtol=1e-12, atol=1e-12 * np.abs(M).max())
    np.testing.assert_allclose(fb.jacobian(z), np.stack([a @ z for a in A], axis=1), atol=1e-13)
    # the kept constraints are independent (the interior-point method needs it)
    assert np.linalg.matrix_rank(np.stack([a.ravel() for a in A])) == fb.m


def test_initial_point_is_strictly_feasible():
    rng = np.random.default_rng(3)
    fb = frame_blocks(3)
    G = rng.standard_normal((fb.d, fb.d))
    C = G @ G.T
    X, y, S = initial_point(C, fb, tau=1.0)
    np.testing.assert_allclose(fb.apply(X), fb.b(), atol=1e-15)
    np.testing.assert_allclose(S, C + np.eye(fb.d), atol=1e-12)
    assert np.linalg.eigvalsh(X).min() > 0 and np.linalg.eigvalsh(S).min() > 0


CASES = {  # (M, P, edges, sigma, unknown scale)
    "1X1Y": (1, 1, None, 0.01, False),
    "4X1Y": (4, 1, None, 0.01, False),
    "3X5Y": (3, 5, [(0, 0), (0, 1), (1, 1), (1, 2), (2, 2), (2, 3), (0, 4), (2, 4)], 0.01,
             False),
    "6X4Y unknown scale": (6, 4, None, 0.02, True),
}


@pytest.mark.parametrize("case", list(CASES))
def test_structured_and_cvxpy_reach_the_same_optimum_and_certificate(case):
    M, P, edges, sigma, unk = CASES[case]
    rng = np.random.default_rng(7)
    problem, _ = random_instance(rng, M, P, edges, n_per_edge=20, sigma=sigma, kappa=100.0,
                                 unknown_scale=unk, alpha=0.8 if unk else 1.0)
    new = solve(problem, _sdp("structured"))
    old = solve(problem, _sdp("cvxpy"))
    assert "SDP backend: structured" in new.notes and "SDP backend: cvxpy" in old.notes
    assert new.certificate.status is old.certificate.status is Status.CERTIFIED_OPTIMAL
    # p: the same estimate up to the solvers' accuracy (gap tolerances 1e-8 of the scaled cost)
    p_new, p_old = new.certificate.primal_cost, old.certificate.primal_cost
    assert abs(p_new - p_old) <= 1e-7 * p_old
    # the dual bounds agree within the tolerances (1e-8 relative each, 1e-7 allowed)
    assert abs(new.certificate.dual_bound - old.certificate.dual_bound) <= \
        1e-7 * old.certificate.dual_bound
    assert new.certificate.suboptimality_bound <= new.certificate.tolerance


def _prep(seed=5, M=3, P=2, sigma=0.02):
    rng = np.random.default_rng(seed)
    problem, _ = random_instance(rng, M, P, n_per_edge=20, sigma=sigma, kappa=100.0)
    return prepare_dense(problem, SolveOptions(mode="sdp")), problem.n_frames


def test_kkt_residuals_of_the_interior_point_run_without_polishing():
    prep, n = _prep()
    fb = frame_blocks(n)
    opts = IpmOptions(polish_gap=0.0)
    trace = []
    sol = solve_dual_sdp_structured(prep.Qs, n, opts, trace=trace)
    t = trace[0]
    assert sol.status == "optimal" and not t.polished
    lam_s = sol.lambda_s
    # the returned multipliers are exactly the iterate's: S = Q' - A^T(y) positive definite
    Z = prep.Qs - frame_constraints(n).apply(sol.lam)
    assert np.linalg.eigvalsh(0.5 * (Z + Z.T)).min() > 0
    assert lam_s == t.dobj
    # primal feasibility, positive semidefinite X, and the gap within the tolerances
    assert np.abs(fb.apply(t.X) - fb.b()).max() <= opts.tol_feas
    assert np.linalg.eigvalsh(t.X).min() > 0
    assert t.pobj - t.dobj <= max(opts.tol_gap_abs, opts.tol_gap_rel * abs(t.pobj))
    assert 0 < t.gap <= max(opts.tol_gap_abs, opts.tol_gap_rel * abs(t.dobj))


def test_polished_pair_is_primal_dual_optimal_at_the_rounded_estimate():
    prep, n = _prep()
    fb = frame_blocks(n)
    trace = []
    sol = solve_dual_sdp_structured(prep.Qs, n, trace=trace)
    t = trace[0]
    assert sol.status == "optimal" and t.polished
    Z = prep.Qs - frame_constraints(n).apply(sol.lam)
    Z = 0.5 * (Z + Z.T)
    w, V = np.linalg.eigh(Z)
    z = V[:, 0] / V[-1, 0]  # the null vector, s = 1: a feasible point z z^T ...
    np.testing.assert_allclose(fb.apply(np.outer(z, z)), fb.b(), atol=1e-10)
    # ... whose cost is lambda_s (complementarity: Z z = 0) and Z >= 0 up to rounding
    assert abs(z @ prep.Qs @ z - sol.lambda_s) <= 1e-10 * abs(sol.lambda_s)
    assert np.linalg.norm(Z @ z) <= 1e-10 * np.linalg.norm(z)
    assert w[0] >= -1e-12 * np.abs(Z).max() and w[1] >= IpmOptions().polish_min_eig


def test_not_tight_data_run_to_the_tolerances_and_agree_with_cvxpy():
    """A random positive semidefinite cost on SO(3)^2 (no measurements behind it): the relaxation
    is not tight, polishing cannot close the gap and the method must converge by itself."""
    rng = np.random.default_rng(11)
    fb = frame_blocks(2)
    G = rng.standard_normal((fb.d, 4))
    C = G @ G.T / 4.0
    trace = []
    sol = solve_dual_sdp_structured(C, 2, trace=trace)
    assert not trace[0].polished
    ref = solve_dual_sdp(C, frame_constraints(2))
    assert sol.status == "optimal" and ref.status == "optimal"
    # both within 1e-8 of the optimum (relative gap tolerances of both solvers)
    assert abs(sol.lambda_s - ref.lambda_s) <= 3e-8 * max(1.0, abs(ref.lambda_s))
    assert np.linalg.matrix_rank(trace[0].X, tol=1e-6 * np.abs(trace[0].X).max()) > 1


def test_non_finite_data_fail_without_multipliers():
    fb = frame_blocks(2)
    C = np.eye(fb.d)
    C[3, 4] = C[4, 3] = np.nan
    sol = solve_dual_sdp_structured(C, 2)
    assert sol.status == "solver_error" and np.all(np.isnan(sol.lam))
    with pytest.raises(ValueError, match="Q: expected shape"):
        solve_dual_sdp_structured(np.eye(5), 2)


def test_unfactorisable_data_fail_without_multipliers():
    fb = frame_blocks(1)
    C = np.full((fb.d, fb.d), 1e308)  # overflows in every factorisation
    sol = solve_dual_sdp_structured(C, 1)
    assert sol.status == "solver_error" and not np.any(np.isfinite(sol.lam))


def test_iteration_limit_is_inaccurate_and_never_certified():
    rng = np.random.default_rng(2)
    problem, _ = random_instance(rng, 2, 2, n_per_edge=20, sigma=0.01, kappa=100.0)
    res = solve(problem, _sdp("structured", ipm={"max_iter": 2, "polish_gap": 0.0}))
    assert res.solver_status == "optimal_inaccurate"
    assert res.certificate.status is Status.SOLVER_INACCURATE
    assert not res.certified
    assert any("stopped before its tolerances" in n for n in res.notes)


def test_no_multipliers_become_solver_failed(monkeypatch):
    import rwhec_ros.core.pipeline.dense as solve_mod

    rng = np.random.default_rng(2)
    problem, _ = random_instance(rng, 2, 2, n_per_edge=20, sigma=0.01, kappa=100.0)
    fb = frame_blocks(problem.n_frames)
    real = solve_mod.solve_dual_sdp_structured

    def nan_data(Q, n, options=None, **kw):
        return real(np.full_like(Q, np.nan), n, options, **kw)

    monkeypatch.setattr(solve_mod, "solve_dual_sdp_structured", nan_data)
    res = solve(problem, _sdp("structured"))
    assert res.certificate.status is Status.SOLVER_FAILED and not res.certified

    def broken(Q, n, options=None, **kw):
        raise np.linalg.LinAlgError("broken on purpose")

    monkeypatch.setattr(solve_mod, "solve_dual_sdp_structured", broken)
    res = solve(problem, _sdp("structured"))
    assert res.certificate.status is Status.SOLVER_FAILED
    assert "structured IPM" in res.certificate.message
    assert fb.m == 20 * problem.n_frames + 1


def test_certificate_of_the_iterate_is_as_rigorous_as_of_any_multipliers():
    """Multipliers of an early iterate (far from optimal) give a valid, weak bound: the
    certificate does not take the solver's word for anything."""
    prep, n = _prep()
    sol = solve_dual_sdp_structured(prep.Qs, n, IpmOptions(max_iter=3, polish_gap=0.0))
    assert sol.status == "optimal_inaccurate"
    from rwhec_ros.core.initial.closed_form import primal_cost

    est_cost = primal_cost(prep.problem, _estimate_of(prep), prep.gauge)
    cert = certify(prep.reduced, prep.scale, prep.Qs, prep.cons(), sol.lam, est_cost)
    assert cert.status is Status.NOT_TIGHT
    assert cert.dual_bound <= est_cost
    assert not cert.suboptimality_bound <= cert.tolerance  # nan when the bound is <= 0


def _estimate_of(prep):
    from rwhec_ros.core.initial.closed_form import estimate_from_rotations

    return estimate_from_rotations(prep.problem, prep.reduced, prep.init_R)


def test_backend_choice():
    with pytest.raises(ValueError, match="backend"):
        SdpOptions(backend="mosek")
    with pytest.raises(ValueError, match="polish_min_eig"):
        IpmOptions(polish_min_eig=-1.0)
    rng = np.random.default_rng(4)
    problem, _ = random_instance(rng, 4, 1, n_per_edge=20, sigma=0.01, kappa=100.0)
    assert "SDP backend: structured" in solve(problem, _sdp("auto")).notes
    # a form is a cvxpy setting: asking for one takes cvxpy
    assert "SDP backend: cvxpy" in solve(problem, _sdp("auto", form="full")).notes
    # Clarabel's chordal decomposition wins for many leaves around a small hub, and loses for
    # one dense block (costs in the units of rwhec_ros.core.sparsity.cone_cost)
    assert not structured_is_cheaper(51, 3.4e8)      # 50 cameras as X x 1 target
    assert structured_is_cheaper(24, 2.0e10)         # the paper's 16 x 8


@pytest.mark.skipif(not (SHARED / "data" / "paper_real_world").is_dir(),
                    reason="the paper's data (../shared) are not available")
def test_paper_real_data_certified_by_the_structured_path():
    from rwhec_ros.data.paper_csv import read_paper_csv

    problem = read_paper_csv(SHARED / "data" / "paper_real_world", sigma=0.1, kappa=125.0,
                             min_pairs=3)
    res = solve(problem, _sdp("auto"))
    fast = solve(problem, SolveOptions(mode="fast"))
    assert "SDP backend: structured" in res.notes
    assert res.certificate.status is Status.CERTIFIED_OPTIMAL
    assert res.certificate.suboptimality_bound <= 1e-6
    # the same optimum as the fast path (the costs of the two estimates agree to 1e-9)
    assert abs(res.certificate.primal_cost - fast.certificate.primal_cost) <= \
        1e-9 * fast.certificate.primal_cost
    R = np.concatenate([res.X, res.Y])[:, :3, :3]
    np.testing.assert_allclose(np.swapaxes(R, 1, 2) @ R, np.broadcast_to(np.eye(3), R.shape),
                               atol=1e-12)
