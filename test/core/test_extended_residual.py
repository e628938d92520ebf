"""The extended-precision residual bound of the Schur reduction and the certificate retry that
uses it (rwhec_ros.core.numerics.extended_residual, cost.reduce_cost(residual="extended"),
solve._certify).

The data set ``fixtures/precise_rig.npz`` is a 3-camera, 6-tag part (252 pairs) of the camera-rate
benchmark's bag (benchmarks/camera_rate_load.py: rendered 1280x1024 images, sigma 5 mm, kappa
400 as configured, the detections far more precise than that): there the Cholesky backward-error
bound on the recovery's residual alone exceeds the certificate's tolerance (rho_hat 1.25e-6 >
1e-6), and the session fell back to a 17 s SDP on the whole rig.
"""

from __future__ import annotations

from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

import rwhec_ros.core.pipeline.dense as dense_path
from rwhec_ros.core.model.cost import StateLayout, build_cost_matrices
from rwhec_ros.core.model.reduction import reduce_cost
from rwhec_ros.core.numerics.extended_residual import extended_dtype, residual_bound
from rwhec_ros.core.problem import Edge, Problem
from rwhec_ros.core.result import Certificate, Status
from rwhec_ros.core.solve import SolveOptions, solve
from rwhec_ros.simulation.synthetic import random_instance, random_rotations

FIXTURE = Path(__file__).parent / "fixtures" / "precise_rig.npz"


def _precise_rig() -> Problem:
    f = np.load(FIXTURE)
    edges, start = [], 0
    bottom = np.array([0.0, 0.0, 0.0, 1.0])
    for x, y, n, sigma, kappa in zip(f["x"], f["y"], f["n"], f["sigma"], f["kappa"], strict=True):
        A = np.concatenate([f["A"][start:start + n], np.broadcast_to(bottom, (n, 1, 4))], axis=1)
        B = np.concatenate([f["B"][start:start + n], np.broadcast_to(bottom, (n, 1, 4))], axis=1)
        edges.append(Edge.build(str(x), str(y), A, B, sigma=float(sigma), kappa=float(kappa)))
        start += n
    return Problem(sorted({e.x for e in edges}), sorted({e.y for e in edges}), edges)


def _exact(M: np.ndarray) -> list[list[Fraction]]:
    return [[Fraction(float(v)) for v in row] for row in np.asarray(M, dtype=float)]


def _exact_residual(Qee, G, Qey) -> np.ndarray:
    """|Q_ee G + Q_ey| in exact rational arithmetic, rounded to double at the end."""
    A, X, C = _exact(Qee), _exact(G), _exact(Qey)
    m, k = len(X), len(X[0])
    return np.array([[abs(float(sum(A[i][t] * X[t][j] for t in range(m)) + C[i][j]))
                      for j in range(k)] for i in range(len(A))])


@pytest.mark.parametrize("seed", range(4))
def test_residual_bound_covers_the_exact_residual(seed):
    """Random and ill-conditioned blocks (condition up to 1e12), G from a double solve and G
    perturbed far from it: the bound is above the exact residual everywhere."""
    rng = np.random.default_rng(seed)
    m, k = 6, 5
    U, _ = np.linalg.qr(rng.standard_normal((m, m)))
    Qee = U @ np.diag(np.logspace(0, 12 * seed / 3, m)) @ U.T
    Qee = 0.5 * (Qee + Qee.T)
    Qey = rng.standard_normal((m, k)) * 10.0 ** rng.integers(-3, 4)
    G = -np.linalg.solve(Qee, Qey)
    for Gu in (G, G * (1 + 1e-9 * rng.standard_normal(G.shape))):
        bound = residual_bound(Qee, Gu, Qey)
        exact = _exact_residual(Qee, Gu, Qey)
        assert np.all(bound >= exact)
        assert np.all(np.isfinite(bound))


def test_residual_bound_is_tight_in_extended_precision():
    """Where numpy's longdouble is IEEE extended or quad, the bound on a solve's residual is far
    below the double-precision backward-error bound (it is what makes the fix worth it)."""
    dtype, u = extended_dtype()
    if dtype is np.float64:
        pytest.skip("numpy's longdouble is not an IEEE extended format here")
    assert u < 1e-18
    rng = np.random.default_rng(3)
    m, k = 30, 40
    S = rng.standard_normal((m, m))
    Qee = S @ S.T + m * np.eye(m)
    Qey = rng.standard_normal((m, k))
    G = -np.linalg.solve(Qee, Qey)
    a_priori = 3 * m * np.finfo(float).eps / 2 * (np.abs(Qee) @ np.abs(G))
    assert residual_bound(Qee, G, Qey).sum() < 0.1 * a_priori.sum()


def test_residual_bound_non_finite_input_is_infinite():
    Qee = np.eye(2)
    G = np.array([[np.nan, 1.0], [0.0, 1.0]])
    bound = residual_bound(Qee, G, np.zeros((2, 2)))
    assert np.isinf(bound[0, 0])


def _small_problem(seed: int, unknown_scale: bool = False
                   ) -> tuple[Problem, StateLayout, np.ndarray]:
    rng = np.random.default_rng(seed)
    problem, _ = random_instance(rng, 1, 1, n_per_edge=8, sigma=0.002, kappa=2000.0,
                                 unknown_scale=unknown_scale, alpha=0.7 if unknown_scale else 1.0)
    layout = StateLayout(problem.M, problem.P)
    Q, _ = build_cost_matrices(problem)
    Q = Q.toarray() if hasattr(Q, "toarray") else np.asarray(Q)
    return problem, layout, Q


@pytest.mark.parametrize(("seed", "unknown_scale"), [(0, False), (1, False), (2, False),
                                                     (3, True), (4, True)])
def test_extended_reduction_same_matrices_and_a_valid_bound(seed, unknown_scale):
    """``residual="extended"`` changes only the bounds: Qr and the recovery are bit for bit those
    of the default; and its err_rows bound |Qr - S_G| (S_G, the exact reduced cost for the G
    used, in rational arithmetic) row by row; known scale (s kept) and unknown scale (alpha
    eliminated with the translations, Qr's s row and column zero)."""
    problem, layout, Q = _small_problem(seed, unknown_scale)
    base = reduce_cost(Q, layout, problem.unknown_scale)
    tight = reduce_cost(Q, layout, problem.unknown_scale, residual="extended")
    assert tight.verified and base.verified
    assert np.array_equal(tight.Qr, base.Qr) and np.array_equal(tight.recover, base.recover)
    assert tight.block_lower == base.block_lower
    nt = layout.n_t
    if unknown_scale:
        keep = np.arange(layout.r0, layout.size)
        elim = np.arange(nt + 1)
        G = tight.recover[:, :-1]
    else:
        keep = np.concatenate([np.arange(layout.r0, layout.size), [layout.alpha]])
        elim = np.arange(nt)
        G = tight.recover[:nt, :]
    nt = len(elim)
    Qe, Qk = _exact(Q[np.ix_(elim, elim)]), _exact(Q[np.ix_(elim, keep)])
    Qkk, Gx = _exact(Q[np.ix_(keep, keep)]), _exact(G)
    k = len(keep)
    # S_G = Q_kk + G^T Q_ee G + G^T Q_ek + Q_ek^T G
    QeG = [[sum(Qe[i][t] * Gx[t][j] for t in range(nt)) for j in range(k)] for i in range(nt)]
    S = [[Qkk[a][b] + sum(Gx[t][a] * (QeG[t][b] + Qk[t][b]) + Qk[t][a] * Gx[t][b]
                          for t in range(nt)) for b in range(k)] for a in range(k)]
    diff_rows = np.array([sum(abs(Fraction(float(tight.Qr[a, b])) - S[a][b]) for b in range(k))
                          for a in range(k)], dtype=float)
    assert np.all(diff_rows <= tight.err_rows[:k])
    assert np.all(diff_rows <= base.err_rows[:k])
    if unknown_scale:  # the s row of Qr is zero, exactly
        assert not tight.Qr[-1].any() and tight.err_rows[-1] == 0.0
    assert tight.residual_norm <= base.residual_norm


def test_reduce_cost_rejects_an_unknown_residual_option():
    problem, layout, Q = _small_problem(0)
    with pytest.raises(ValueError, match="residual: expected 'cholesky' or 'extended'"):
        reduce_cost(Q, layout, problem.unknown_scale, residual="exact")


@pytest.fixture(scope="module")
def precise_rig() -> Problem:
    if not FIXTURE.is_file():
        pytest.skip("fixture missing")
    return _precise_rig()


def test_precise_rig_certified_only_with_the_extended_bound(precise_rig, monkeypatch):
    """The case the retry exists for: with the Cholesky bound alone the fast certificate fails
    on its bound (NOT_TIGHT, rho_hat > 1e-6, one-dimensional null space); with the retry the
    same estimate (bit for bit: the retry changes no matrix the solvers use) is certified."""
    opts = SolveOptions(mode="fast", fallback_to_sdp=False)
    certified = solve(precise_rig, opts)
    monkeypatch.setattr(dense_path, "_tighten_reduction", lambda prep: False)
    plain = solve(precise_rig, opts)
    assert plain.certificate.status is Status.NOT_TIGHT
    assert plain.certificate.null_space_dim == 1
    assert plain.certificate.suboptimality_bound > 1e-6
    assert certified.certificate.status is Status.CERTIFIED_OPTIMAL
    assert certified.certificate.suboptimality_bound < 0.5 * 1e-6
    assert "tighten" in certified.timing_s
    assert np.array_equal(certified.X, plain.X) and np.array_equal(certified.Y, plain.Y)
    assert certified.certificate.primal_cost == plain.certificate.primal_cost
    # the tighter bound lowered only the reduction's rounding term
    m0, m1 = plain.certificate.margins, certified.certificate.margins
    assert m1["rounding"] < 0.1 * m0["rounding"]
    assert m1["eigenvalue"] == m0["eigenvalue"]


def test_precise_rig_certified_estimate_beats_random_starts(precise_rig):
    """Independent check of the certified claim: no local solve from random rotations finds a
    lower cost than the certified estimate (up to its proven bound plus rounding of the cost)."""
    from rwhec_ros.core.local.dense import refine_rotations
    res = solve(precise_rig, SolveOptions(mode="fast", fallback_to_sdp=False))
    assert res.certificate.certified
    p = res.certificate.primal_cost
    rng = np.random.default_rng(0)
    prep = dense_path.prepare_dense(precise_rig, SolveOptions(mode="fast"))
    n = precise_rig.M + precise_rig.P
    for _ in range(8):
        R0 = random_rotations(rng, n)
        loc = refine_rotations(prep.Qs, R0, SolveOptions().local)
        _, cost = dense_path._estimate(prep, loc.R)
        assert cost >= p * (1 - res.certificate.suboptimality_bound) - 1e-9 * p


def _cert(status=Status.NOT_TIGHT, null_dim=1, rounding=1e-3, schur=0.0, dual=10.0):
    return Certificate(status, dual * 1.00001, dual, 1e-5, 0.0, np.zeros(2), null_dim, 1e-6,
                       "", margins={"eigenvalue": 0.0, "rounding": rounding, "schur": schur})


@pytest.mark.parametrize(("kwargs", "expected"), [
    ({}, True),
    ({"status": Status.CERTIFIED_OPTIMAL}, False),
    ({"status": Status.SOLVER_INACCURATE}, False),
    ({"null_dim": 2}, False),
    ({"rounding": 0.0, "schur": 0.0}, False),
    ({"rounding": 0.09e-6 * 10.0}, False),  # under a tenth of the allowed gap rho_tol * d
    ({"rounding": 0.11e-6 * 10.0}, True),
    ({"rounding": 0.0, "schur": 0.11e-6 * 10.0}, True),
])
def test_retry_only_when_the_reduction_bound_can_decide(kwargs, expected):
    assert dense_path._residual_bound_decides(_cert(**kwargs), SolveOptions()) is expected


def test_retry_allowance_uses_the_cost_floor():
    """The gap allowed is rho_tol times the bound's denominator: the cost floor when it is larger
    than the dual bound (precise data), so small reduction terms do not trigger the retry."""
    cert = _cert(rounding=0.11e-6 * 10.0, dual=10.0)
    assert dense_path._residual_bound_decides(cert, SolveOptions(), 0.0)
    assert not dense_path._residual_bound_decides(cert, SolveOptions(), 1000.0)

