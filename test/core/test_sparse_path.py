"""The large-problem path of ``fast``: sparse LDL^T and its error bound, the unreduced cost with
the gauge penalty tree, agreement with the dense path, and the soundness of the sparse
certificate (issue 14, with the rules of issue 10)."""

import numpy as np
import pytest
import scipy.sparse as sp
from test_gauge import _planar_rig

from rwhec_ros.core.certify.sparse import (
    CertificatePattern,
    first_order_multipliers,
    sparse_dual_bound,
)
from rwhec_ros.core.certify.sparsity import elimination_front
from rwhec_ros.core.initial.closed_form import estimate_from_rotations
from rwhec_ros.core.local.sparse import refine_rotations_sparse
from rwhec_ros.core.model import gauge as gauge_module
from rwhec_ros.core.model.cost import DENSE_MAX_SIZE, StateLayout, build_cost_matrices
from rwhec_ros.core.model.gauge import (
    GaugeOptions,
    TranslationPrior,
    build_gauge_fix,
    find_unobservable_directions,
)
from rwhec_ros.core.model.reduction import reduce_cost
from rwhec_ros.core.model.sparse_cost import build_full_form
from rwhec_ros.core.numerics.sparse_ldl import FactorizationError, SparseLDL, upper_with_diagonal
from rwhec_ros.core.pipeline.sparse import prepare_sparse, use_sparse
from rwhec_ros.core.problem import Problem
from rwhec_ros.core.result import Status
from rwhec_ros.core.solve import SolveOptions, solve
from rwhec_ros.simulation.synthetic import (
    random_camera_tag_graph,
    random_instance,
    random_rotations,
)


def _hub_spd(rng, n, hub=3):
    """A random sparse SPD matrix whose first ``hub`` rows are dense (a target every camera
    sees) -- long rows of L after AMD puts them last."""
    A = sp.random(n, n, density=3.0 / n, random_state=np.random.RandomState(1))
    A = sp.lil_matrix(A + A.T)
    A[:hub, :] = rng.standard_normal((hub, n))
    A[:, :hub] = A[:hub, :].T
    A = sp.triu(sp.csr_matrix(A), format="csr")
    A = A + sp.triu(A, 1).T  # exactly symmetric
    return (A + sp.diags(np.asarray(abs(A).sum(axis=1)).ravel() + 1.0)).tocsr()


def test_ldl_backward_error_bound_holds():
    """|A - P (I + L) D (I + L)^T P^T| (evaluated in extended precision) is within the row
    weights of backward_error_rows for matrices with and without hub rows."""
    rng = np.random.default_rng(0)
    for n, hub in ((60, 0), (120, 3)):
        A = _hub_spd(rng, n, hub) if hub else _hub_spd(rng, n, 0)
        f = SparseLDL(upper_with_diagonal(A))
        assert f.positive_definite
        Lf = (np.eye(n) + f.L.toarray()).astype(np.longdouble)
        LDLt = (Lf * f.D.astype(np.longdouble)) @ Lf.T
        back = np.empty((n, n), dtype=np.longdouble)
        back[np.ix_(f.perm, f.perm)] = LDLt
        dA = np.abs(back - A.toarray().astype(np.longdouble)).sum(axis=1)
        c = f.backward_error_rows()
        assert np.all(dA <= c)
        assert np.all(c < 1e-12 * np.abs(A).sum(axis=1).A1)  # and not vacuous


def test_ldl_inertia_refactor_and_breakdown():
    rng = np.random.default_rng(1)
    A = _hub_spd(rng, 80, 2)
    f = SparseLDL(upper_with_diagonal(A))
    b = rng.standard_normal(80)
    assert np.allclose(A @ f.solve(b), b, atol=1e-10)
    shift = 0.5 * (np.linalg.eigvalsh(A.toarray())[2] + np.linalg.eigvalsh(A.toarray())[3])
    f.refactor(upper_with_diagonal(A - shift * sp.eye(80)).data)
    assert f.n_negative == 3 and not f.positive_definite  # Sylvester's law of inertia
    with pytest.raises(FactorizationError):
        SparseLDL(upper_with_diagonal(sp.csr_matrix((3, 3))))  # zero pivots
    with pytest.raises(FactorizationError):
        f.refactor(np.full(upper_with_diagonal(A).nnz, np.nan))


def test_elimination_front():
    star_x = np.zeros(50, int)
    assert elimination_front(1, 50, star_x, np.arange(50)) == (1, 50 * 4 + 1)
    jj, kk = np.meshgrid(np.arange(3), np.arange(7), indexing="ij")  # complete bipartite 3x7
    front, _ = elimination_front(3, 7, jj.ravel(), kk.ravel())
    assert front == 3
    e = np.array(random_camera_tag_graph(np.random.default_rng(0), 100, 100, 5))
    front, work = elimination_front(100, 100, e[:, 0], e[:, 1])
    assert front > 30 and work > 0.01 * 200**3  # a random graph fills in
    front2, work2 = elimination_front(100, 100, e[:, 0], e[:, 1], max_work=1e3)
    assert work2 > 1e3 and front2 <= front  # stopped early


def test_automatic_choice():
    rng = np.random.default_rng(2)
    star, _ = random_instance(rng, 1, 60, n_per_edge=3, sigma=0.01, kappa=100)
    small, _ = random_instance(rng, 1, 20, n_per_edge=3, sigma=0.01, kappa=100)
    dense_graph, _ = random_instance(rng, 10, 45, n_per_edge=3, sigma=0.01, kappa=100)
    assert use_sparse(star, "auto") and not use_sparse(small, "auto")
    # complete 10 x 45: work 0.035 n^3 (dense faster, cf. 4 x 30: 38 ms dense, 64 ms sparse)
    assert not use_sparse(dense_graph, "auto")
    assert use_sparse(small, "sparse") and not use_sparse(star, "dense")
    with pytest.raises(ValueError, match="fast_form"):
        SolveOptions(fast_form="banded")


@pytest.mark.parametrize("unknown_scale", [False, True])
def test_full_form_reproduces_the_reduced_cost_with_the_penalty_tree(unknown_scale):
    """Translations, scale and cost for arbitrary rotations: the sparse recovery equals eq. (47)
    of the dense path, the gauge penalty as a spring tree included (planar motion)."""
    problem, _, _ = _planar_rig(np.random.default_rng(3), M=2, P=7, jitter=1e-7)
    problem = Problem(problem.x_names, problem.y_names, problem.edges,
                      unknown_scale=unknown_scale)
    layout = StateLayout(problem.M, problem.P)
    Q, _ = build_cost_matrices(problem)
    fix = build_gauge_fix(problem, *find_unobservable_directions(Q, layout, problem))
    assert not fix.empty
    red = reduce_cost(Q + fix.penalty_matrix(layout).toarray(), layout, unknown_scale)
    form = build_full_form(problem, fix)
    assert form.n_aux > 0
    R = random_rotations(np.random.default_rng(4), problem.n_frames)
    dense, sparse = estimate_from_rotations(problem, red, R), form.estimate(R)
    assert sparse.cost == pytest.approx(dense.cost, rel=1e-12)  # rounding only
    assert np.allclose(sparse.t, dense.t, atol=1e-9) and sparse.alpha == pytest.approx(
        dense.alpha, rel=1e-12)


@pytest.mark.parametrize("case", ["star", "star_sparse_build", "unknown_scale", "graph"])
def test_sparse_and_dense_paths_agree(case):
    """Same optimum, both certified, p the direct cost on both (mid-size problems).
    ``star_sparse_build``: 61 frames, so the cost matrices are built sparse (above
    DENSE_MAX_SIZE) while the dense path's closed form still takes its dense eigensolver (the
    rotation block is below 1000): a sparse matrix there once crashed the dense path."""
    rng = np.random.default_rng(5)
    if case == "star":
        problem, _ = random_instance(rng, 1, 45, n_per_edge=10, sigma=0.02, kappa=100)
    elif case == "star_sparse_build":
        problem, _ = random_instance(rng, 1, 60, n_per_edge=10, sigma=0.02, kappa=100)
        layout = StateLayout(problem.M, problem.P)
        assert layout.size > DENSE_MAX_SIZE and 200 < layout.size - layout.r0 <= 1000
    elif case == "unknown_scale":
        problem, _ = random_instance(rng, 2, 20, n_per_edge=10, sigma=0.02, kappa=100,
                                     unknown_scale=True, alpha=0.8)
    else:
        edges = random_camera_tag_graph(rng, 10, 40, 3)
        problem, _ = random_instance(rng, 10, 40, edges=edges, n_per_edge=10, sigma=0.02,
                                     kappa=100)
    dense = solve(problem, SolveOptions(fast_form="dense", fallback_to_sdp=False))
    sparse = solve(problem, SolveOptions(fast_form="sparse", fallback_to_sdp=False))
    assert dense.certified and sparse.certified
    assert "sparse unreduced path" in sparse.notes[0]
    # same critical point: both local solvers stop at gradient 1e-10 relative
    for a, b in ((dense.X, sparse.X), (dense.Y, sparse.Y)):
        assert np.abs(a - b).max() < 1e-7
    assert sparse.scale == pytest.approx(dense.scale, rel=1e-9)
    assert sparse.certificate.primal_cost == pytest.approx(dense.certificate.primal_cost,
                                                           rel=1e-12)
    # both bounds below the common cost and within the tolerance of it
    for res in (dense, sparse):
        c = res.certificate
        assert c.dual_bound <= c.primal_cost and c.suboptimality_bound <= 1e-6


def _certificate_data(problem):
    prep = prepare_sparse(problem, SolveOptions())
    loc = refine_rotations_sparse(prep.form, prep.Qs, prep.init_R)
    pattern = CertificatePattern(prep.form, prep.Qs)
    Gamma, lam_s, z = first_order_multipliers(prep.form, prep.Qs, loc.R)
    data, err = pattern.matrix_data(Gamma, lam_s)
    return prep, pattern, data, err, lam_s, z


def _dense_Z(pattern, data):
    U = sp.csc_matrix((data, pattern.U.indices, pattern.U.indptr), shape=pattern.U.shape)
    U = U.toarray()
    return np.triu(U) + np.triu(U, 1).T


def test_crafted_indefinite_Z_is_rejected():
    """A certificate matrix made indefinite (a) along a rotation entry, (b) along a translation:
    the proven eigenvalue bound stays below the true smallest eigenvalue of the reduced matrix,
    and a translation direction of negative curvature yields no bound at all."""
    problem, _ = random_instance(np.random.default_rng(6), 1, 12, n_per_edge=10, sigma=0.02,
                                 kappa=100)
    prep, pattern, data, err, lam_s, z = _certificate_data(problem)
    nf = prep.form.n_free
    base = sparse_dual_bound(pattern, data, err, lam_s, 1e-14, z)
    assert np.isfinite(base.bound.value) and base.bound.value <= lam_s
    for eta in (1e-10, 1e-6, 1e-2):
        bad = data.copy()
        bad[pattern.diag[nf + 4]] -= eta  # one rotation entry
        Z = _dense_Z(pattern, bad)
        Zr = Z[nf:, nf:] - Z[nf:, :nf] @ np.linalg.solve(Z[:nf, :nf], Z[:nf, nf:])
        lam_min = np.linalg.eigvalsh(Zr)[0]
        assert lam_min < -0.5 * eta * z[nf + 4] ** 2 / (z[nf:] @ z[nf:])
        sb = sparse_dual_bound(pattern, bad, err, lam_s, 1e-14, z)
        assert sb.bound.lambda_min_lower <= lam_min
        assert sb.bound.value <= lam_s - (9 * 13 + 1) * 0.5 * abs(lam_min)
    bad = data.copy()
    bad[pattern.diag[5]] -= 2.0 * np.linalg.eigvalsh(_dense_Z(pattern, data)[:nf, :nf])[-1]
    sb = sparse_dual_bound(pattern, bad, err, lam_s, 1e-14, z)
    assert not np.isfinite(sb.bound.value) and "no shifted factorisation" in sb.bound.reason


@pytest.mark.parametrize("sparse_analysis", [False, True])
def test_near_single_axis_motion_on_the_sparse_path(monkeypatch, sparse_analysis):
    """Planar motion: the height is named as unobservable (not_identifiable), and with a prior
    the result is certified -- with the dense or the sparse (Lanczos) analysis of the
    translation block."""
    if sparse_analysis:  # exercise the large-rig analysis on a small problem
        monkeypatch.setattr(gauge_module, "SPARSE_MIN_SIZE", 10)
    problem, _, Y = _planar_rig(np.random.default_rng(7), M=2, P=8, n=10, jitter=1e-6)
    opts = dict(fast_form="sparse", sdp_fallback_max_frames=0)
    res = solve(problem, SolveOptions(**opts))
    assert res.certificate.status is Status.NOT_IDENTIFIABLE
    assert "translation along" in res.certificate.message and "cam0" in res.certificate.message
    prior = TranslationPrior("cam0", "z", float(Y[0, 2, 3]))
    res_p = solve(problem, SolveOptions(gauge=GaugeOptions(priors=(prior,)), **opts))
    # certified by the sparse path itself (no dense fallback), the prior honoured: the penalty
    # pins the height to ~1e-9 m (rho = the largest eigenvalue of the translation block)
    assert res_p.certified, res_p.certificate.message
    assert abs(res_p.Y[0, 2, 3] - Y[0, 2, 3]) < 1e-6
    assert "strengthened" in " ".join(res_p.notes)  # planar motion needs the handedness step
    # the dense analysis finds the same direction
    layout = StateLayout(problem.M, problem.P)
    Q, _ = build_cost_matrices(problem)
    monkeypatch.setattr(gauge_module, "SPARSE_MIN_SIZE", 10**9)
    V_dense, w_dense, _, _ = find_unobservable_directions(Q, layout, problem)
    monkeypatch.setattr(gauge_module, "SPARSE_MIN_SIZE", 10)
    V_sparse, w_sparse, _, _ = find_unobservable_directions(sp.csr_matrix(Q), layout, problem)
    assert V_dense.shape[1] == V_sparse.shape[1] == 1
    assert abs(V_dense[:, 0] @ V_sparse[:, 0]) > 1 - 1e-9
    assert w_sparse[0] == pytest.approx(w_dense[0], abs=1e-9 * np.abs(Q).max())


def test_large_rig_certified_on_the_sparse_path():
    """300 cameras and one target, chosen automatically: certified, p the direct cost, and a
    random start converges to the same optimum."""
    rng = np.random.default_rng(8)
    problem, gt = random_instance(rng, 1, 300, n_per_edge=6, sigma=0.02, kappa=100)
    res = solve(problem)
    assert res.certified and "sparse unreduced path" in res.notes[0]
    assert np.abs(res.Y[:, :3, 3] - gt.Y[:, :3, 3]).max() < 0.1  # 2 cm noise, 6 pairs



@pytest.mark.parametrize("t", [0.0, 0.37, -0.37])
def test_sparse_certificate_matrix_and_its_rounding_rows(t):
    """``matrix_data`` against dense matrices built entry by entry from the module docstring:
    ``Z = Q_s - K(Gamma, lambda_s) - t D`` (K holds Gamma_l[a, b] at (3a+i, 3b+i) of block l and
    ``lambda_s - sum tr Gamma_l`` at (s, s); D the handedness matrix) and the row sums of ``E``:
    ``gamma_2 (|Q_s| + |K|) 1``, plus ``gamma_{3n+1} (|lambda_s| + sum |diag Gamma_l|)`` on the s
    row, plus with ``t``: ``gamma_{n+8} h + gamma_2 (|Q_s| + |K| + h) 1`` with ``h`` the row sums
    of ``|t|`` times the bound on |D|'s terms. Relative agreement 1e-12 (the sums run in another
    order); every factor of the bound changes it by far more."""
    from rwhec_ros.core.certify.sparse import handedness_entries
    from rwhec_ros.core.numerics.verified import gamma

    problem, _ = random_instance(np.random.default_rng(4), 1, 5, n_per_edge=8, sigma=0.02,
                                 kappa=100)
    prep = prepare_sparse(problem, SolveOptions())
    loc = refine_rotations_sparse(prep.form, prep.Qs, prep.init_R)
    pattern = CertificatePattern(prep.form, prep.Qs)
    Gamma, lam_s, _ = first_order_multipliers(prep.form, prep.Qs, loc.R)
    Gamma = Gamma + 1e-3 * np.random.default_rng(1).standard_normal(Gamma.shape)  # not optimal:
    Gamma = 0.5 * (Gamma + np.swapaxes(Gamma, 1, 2))  # every term of the bound is non-zero
    hand = handedness_entries(loc.R) if t else None
    data, err = pattern.matrix_data(Gamma, lam_s, t, hand)
    n, nf, size = pattern.n, pattern.nf, pattern.size
    Qd = prep.Qs.toarray()
    K = np.zeros((size, size))
    for ell in range(n):
        for a in range(3):
            for b in range(3):
                for i in range(3):
                    K[nf + 9 * ell + 3 * a + i, nf + 9 * ell + 3 * b + i] = Gamma[ell, a, b]
    K[-1, -1] = lam_s - sum(np.trace(G) for G in Gamma)
    D = np.zeros((size, size))
    Dabs = np.zeros((size, size))
    if t:
        pp, qq = np.triu_indices(10)
        vals, absv = hand
        for ell in range(n):
            glob = [nf + 9 * ell + k for k in range(9)] + [size - 1]
            for k, (p, q) in enumerate(zip(pp, qq, strict=True)):
                for M, v in ((D, vals[ell, k]), (Dabs, absv[ell, k])):
                    M[glob[p], glob[q]] += v
                    if p != q:
                        M[glob[q], glob[p]] += v
    Z = Qd - K - t * D
    got = _dense_Z(pattern, data)
    np.testing.assert_allclose(got[np.abs(Z) > 0], Z[np.abs(Z) > 0], rtol=1e-12, atol=1e-14)
    base = np.abs(Qd).sum(axis=1) + np.abs(K).sum(axis=1)
    E = gamma(2) * base
    E[-1] += gamma(3 * n + 1) * (abs(lam_s) + sum(np.abs(np.diag(G)).sum() for G in Gamma))
    if t:
        h = abs(t) * Dabs.sum(axis=1)
        E += gamma(n + 8) * h + gamma(2) * (base + h)
    np.testing.assert_allclose(err, E, rtol=1e-12)
