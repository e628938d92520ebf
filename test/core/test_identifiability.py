"""Tests of the identifiability analysis (paper Section 6, Section 8.1, Figure 10)."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from rwhec_ros.core.identifiability import (
    EdgeStatistics,
    IdentifiabilityStatus,
    IdentifiabilityThresholds,
    IdentifiabilityTracker,
    analyze,
    analyze_edge,
)
from rwhec_ros.core.lie import invert_transform, make_transform, so3_exp
from rwhec_ros.core.problem import Edge, Problem
from rwhec_ros.simulation.synthetic import perturb_measurements, random_instance, random_transforms

S = IdentifiabilityStatus
SHARED = Path(__file__).resolve().parents[2] / ".." / "shared"


# ----------------------------------------------------------------------------------------------
# data generators
# ----------------------------------------------------------------------------------------------
def _edge(rng, X, Y, A, x, y, sigma=0.0, kappa=np.inf, alpha=1.0):
    """Edge with ``B = Y^-1 A X`` (then noise); weights floored like random_instance."""
    B = perturb_measurements(rng, invert_transform(Y) @ A @ X, sigma, kappa, alpha)
    return Edge.build(x, y, A, B, sigma=max(sigma, 1e-3), kappa=min(kappa, 1e4))


def _single_axis_A(rng, n, axis, fixed_line=False, max_angle=np.pi):
    th = rng.uniform(-max_angle, max_angle, n)
    R = so3_exp(np.asarray(axis, float)[None] * th[:, None])
    if fixed_line:  # pure rotation about a fixed line (turntable)
        c = np.array([0.3, -0.2, 0.5])
        t = c - np.einsum("nij,j->ni", R, c)
    else:  # planar motion: rotation about one axis direction, arbitrary translations
        t = rng.standard_normal((n, 3))
    return make_transform(R, t)


def _sphere_problem(rng, radii, unknown_scale, sigma=0.0, kappa=np.inf, n=100, alpha=0.5):
    """Paper Section 8.1: a hand camera on a sphere cap (or two) around the target, optical axis
    towards the centre. ``X = T_base_tag``, ``Y = T_hand_cam``, ``B = T_cam_tag``,
    ``A = T_hand_base = Y B X^-1``."""
    X = random_transforms(rng, 1)[0]
    Y = random_transforms(rng, 1)[0]
    r = np.asarray(radii, float)[rng.integers(0, len(radii), n)]
    polar = np.deg2rad(rng.uniform(5.0, 50.0, n))
    az = rng.uniform(0.0, 2.0 * np.pi, n)
    d = np.stack([np.sin(polar) * np.cos(az), np.sin(polar) * np.sin(az), np.cos(polar)], 1)
    z = -d  # optical axis towards the centre
    up = np.array([0.0, -1.0, 0.0])
    yv = up - (z @ up)[:, None] * z
    yv /= np.linalg.norm(yv, axis=1, keepdims=True)
    T_tag_cam = make_transform(np.stack([np.cross(yv, z), yv, z], axis=2), r[:, None] * d)
    B = invert_transform(T_tag_cam)
    A = Y @ B @ invert_transform(X)
    Bn = perturb_measurements(rng, B, sigma, kappa, alpha if unknown_scale else 1.0)
    e = Edge.build("tag", "cam", A, Bn, sigma=max(sigma, 1e-3), kappa=min(kappa, 1e4))
    return Problem(["tag"], ["cam"], [e], unknown_scale=unknown_scale)


# ----------------------------------------------------------------------------------------------
# per-edge quantities against independent computations
# ----------------------------------------------------------------------------------------------
def test_random_poses_are_identifiable():
    rng = np.random.default_rng(0)
    problem, _ = random_instance(rng, 3, 2, n_per_edge=20)
    rep = analyze(problem)
    assert all(e.status is S.IDENTIFIABLE for e in rep.edges), [e.reasons for e in rep.edges]
    assert len(rep.components) == 1 and rep.components[0].status is S.IDENTIFIABLE
    assert rep.numeric.null_dim == 0 and rep.numeric.status is S.IDENTIFIABLE
    assert rep.identifiable and rep.verdict.startswith("identifiable")


def test_spreads_of_a_single_axis_pair_have_closed_form():
    # two pairs, R_A = I and Rz(40 deg): S = I + Rz, sigma_min = 2 cos(20 deg) -> spread 20 deg,
    # and z is preserved exactly -> second-axis spread 0
    A = make_transform(so3_exp(np.array([[0, 0, 0], [0, 0, np.deg2rad(40.0)]])), np.zeros((2, 3)))
    st = EdgeStatistics.from_pairs("x", "y", A, A)
    rep = analyze_edge(st)
    assert rep.rotation_spread_deg == pytest.approx(20.0, abs=1e-9)
    assert rep.second_axis_spread_deg == pytest.approx(0.0, abs=1e-5)  # arccos near 1: sqrt(eps)
    np.testing.assert_allclose(rep.dominant_axis, [0.0, 0.0, 1.0], atol=1e-9)
    assert rep.status is S.INSUFFICIENT


def test_rotation_system_singular_values_match_direct_svd():
    rng = np.random.default_rng(1)
    problem, _ = random_instance(rng, 1, 1, n_per_edge=12, sigma=0.01, kappa=50.0)
    e = problem.edges[0]
    rep = analyze_edge(EdgeStatistics.from_edge(e))
    # eq. (60) stacked explicitly: rows vec(R_A R_X) - vec(R_Y R_B)
    I3 = np.eye(3)
    rows = [np.hstack([np.kron(I3, a[:3, :3]), -np.kron(b[:3, :3].T, I3)]) for a, b in
            zip(e.A, e.B)]
    sv = np.linalg.svd(np.vstack(rows), compute_uv=False)
    # Gram route takes sqrt(N - s_k): ~1e-8 relative accuracy on the smallest values
    assert rep.rotation_sv_ratio == pytest.approx(sv[-2] / sv[0], rel=1e-6)
    assert rep.rotation_residual_ratio == pytest.approx(sv[-1] / sv[0], rel=1e-6)


def test_rotation_std_matches_explicit_information_matrix():
    rng = np.random.default_rng(2)
    A = random_transforms(rng, 7)
    kappa = rng.uniform(20.0, 200.0, 7)
    rep = analyze_edge(EdgeStatistics.from_pairs("x", "y", A, A, sigma=0.01, kappa=kappa))
    info = sum(2.0 * k * np.block([[np.eye(3), -a[:3, :3].T], [-a[:3, :3], np.eye(3)]])
               for a, k in zip(A, kappa))
    lam = np.linalg.eigvalsh(info)[0]
    assert rep.rotation_std_deg == pytest.approx(np.degrees(1.0 / np.sqrt(lam)), rel=1e-9)


def test_translation_excitation_matches_least_squares():
    rng = np.random.default_rng(3)
    A = random_transforms(rng, 9)
    rep = analyze_edge(EdgeStatistics.from_pairs("x", "y", A, A))
    # min_{u,v} sum |t_A - (R_A u - v)|^2 by lstsq on the stacked 3N x 6 system
    M = np.vstack([np.hstack([a[:3, :3], -np.eye(3)]) for a in A])
    t = A[:, :3, 3].ravel()
    res = t - M @ np.linalg.lstsq(M, t, rcond=None)[0]
    assert rep.translation_excitation_m == pytest.approx(np.sqrt(res @ res / 9), rel=1e-9)


# ----------------------------------------------------------------------------------------------
# graded verdicts with reasons
# ----------------------------------------------------------------------------------------------
def test_insufficient_edges_say_why():
    rng = np.random.default_rng(4)
    X, Y = random_transforms(rng, 1)[0], random_transforms(rng, 1)[0]
    two = _edge(rng, X, Y, random_transforms(rng, 2), "x", "y")
    pure_t = _edge(rng, X, Y, make_transform(np.broadcast_to(np.eye(3), (10, 3, 3)),
                                             rng.standard_normal((10, 3))), "x", "y")
    one_axis = _edge(rng, X, Y, _single_axis_A(rng, 30, [1.0, 0.0, 0.0]), "x", "y")
    r_two = analyze_edge(EdgeStatistics.from_edge(two))
    r_pure = analyze_edge(EdgeStatistics.from_edge(pure_t))
    r_axis = analyze_edge(EdgeStatistics.from_edge(one_axis))
    assert r_two.status is S.INSUFFICIENT and "fewer than 3 pairs" in r_two.reasons[0]
    assert r_pure.status is S.INSUFFICIENT and "no rotation" in r_pure.reasons[0]
    assert r_axis.status is S.INSUFFICIENT and "only about one axis" in r_axis.reasons[0]
    assert abs(r_axis.dominant_axis[0]) == pytest.approx(1.0, abs=1e-9)


def test_small_second_axis_rotation_is_weak():
    rng = np.random.default_rng(5)
    X, Y = random_transforms(rng, 1)[0], random_transforms(rng, 1)[0]
    A = _single_axis_A(rng, 40, [0.0, 0.0, 1.0])
    # wobble of +-4 deg about x on top of the z rotations: above the 1 deg hard threshold,
    # below the 5 deg comfortable one
    A[:, :3, :3] = A[:, :3, :3] @ so3_exp(np.outer(rng.uniform(-1, 1, 40) * np.deg2rad(4.0),
                                                   [1.0, 0.0, 0.0]))
    rep = analyze_edge(EdgeStatistics.from_edge(_edge(rng, X, Y, A, "x", "y")))
    assert 1.0 < rep.second_axis_spread_deg < 5.0
    assert rep.status is S.WEAK and "second axis" in rep.reasons[0]
    strict = IdentifiabilityThresholds(good_second_axis_deg=0.5)
    assert analyze_edge(EdgeStatistics.from_edge(_edge(rng, X, Y, A, "x", "y")),
                        thresholds=strict).status is S.IDENTIFIABLE


@pytest.mark.parametrize("sigma, kappa", [(0.0, np.inf), (0.01, 125.0)])
def test_single_sphere_monocular_is_not_identifiable(sigma, kappa):
    rng = np.random.default_rng(6)
    rep = analyze(_sphere_problem(rng, [1.0], True, sigma, kappa))
    e = rep.edges[0]
    # it has two rotation axes (Corollary 4 holds), but the scale is not identifiable (Sec. 8.1)
    assert e.second_axis_spread_deg > 10.0
    assert e.status is S.INSUFFICIENT and "scale is not identifiable" in e.reasons[0]
    assert e.rigid_status is S.IDENTIFIABLE
    assert rep.numeric.scale_undetermined and rep.numeric.null_dim == 1
    assert not rep.identifiable and rep.verdict.startswith("NOT identifiable")


@pytest.mark.parametrize("sigma, kappa", [(0.0, np.inf), (0.01, 125.0)])
def test_two_sphere_monocular_is_identifiable(sigma, kappa):
    rng = np.random.default_rng(7)
    rep = analyze(_sphere_problem(rng, [1.0, 0.3], True, sigma, kappa))
    assert rep.edges[0].status is S.IDENTIFIABLE, rep.edges[0].reasons
    assert rep.edges[0].translation_excitation_m > 0.1  # radii differ by 0.7 m
    assert rep.numeric.null_dim == 0 and not rep.numeric.scale_undetermined
    # 100 pairs, 1 cm noise, ~0.35 m excitation: predicted scale std well below 1 %
    assert rep.numeric.scale_rel_std < 0.01
    assert rep.identifiable


def test_single_sphere_known_scale_is_unique_but_flags_eq63():
    rng = np.random.default_rng(8)
    rep = analyze(_sphere_problem(rng, [1.0], False))
    e = rep.edges[0]
    assert e.status is S.WEAK and "eq. (63)" in e.reasons[0]
    assert rep.numeric.null_dim == 0
    # the reduced cost (unconstrained view, s included) has a second null direction
    assert rep.numeric.reduced_eigenvalues[1] < 1e-9
    assert rep.identifiable


# ----------------------------------------------------------------------------------------------
# whole problem: propagation and the numeric check
# ----------------------------------------------------------------------------------------------
@pytest.mark.parametrize("sigma, kappa", [(0.0, np.inf), (0.01, 125.0)])
def test_numeric_check_finds_what_single_edges_cannot(sigma, kappa):
    """Theorem 1's general case: two single-axis edges sharing X fix everything together."""
    rng = np.random.default_rng(9)
    X, Y = random_transforms(rng, 1)[0], random_transforms(rng, 2)
    e1 = _edge(rng, X, Y[0], _single_axis_A(rng, 40, [0, 0, 1]), "x0", "y0", sigma, kappa)
    e2 = _edge(rng, X, Y[1], _single_axis_A(rng, 40, [1, 0, 0]), "x0", "y1", sigma, kappa)
    rep = analyze(Problem(["x0"], ["y0", "y1"], [e1, e2]))
    assert [e.status for e in rep.edges] == [S.INSUFFICIENT, S.INSUFFICIENT]
    comp = rep.components[0]
    assert comp.propagation_status is S.INSUFFICIENT and comp.identifiable_edges == []
    assert rep.numeric.null_dim == 0 and comp.status is not S.INSUFFICIENT
    assert any("together determine" in r for r in comp.reasons)
    assert rep.identifiable
    # without the numeric check only propagation speaks
    assert not analyze(Problem(["x0"], ["y0", "y1"], [e1, e2]), full=False).identifiable


@pytest.mark.parametrize("sigma, kappa", [(0.0, np.inf), (0.01, 125.0)])
def test_numeric_check_null_directions_of_single_axis_motions(sigma, kappa):
    rng = np.random.default_rng(10)
    X, Y = random_transforms(rng, 1)[0], random_transforms(rng, 1)[0]
    planar = _edge(rng, X, Y, _single_axis_A(rng, 40, [0, 0, 1]), "x", "y", sigma, kappa)
    turn = _edge(rng, X, Y, _single_axis_A(rng, 40, [0, 0, 1], fixed_line=True), "x", "y",
                 sigma, kappa)
    r_planar = analyze(Problem(["x"], ["y"], [planar])).numeric
    r_turn = analyze(Problem(["x"], ["y"], [turn])).numeric
    # planar motion: rotation fixed through the translations, translation along the axis free
    assert r_planar.null_dim == 1
    assert all("translation along z (in its carrier) not determined" in r
               for r in r_planar.reasons), r_planar.reasons
    # turntable: an exact symmetry (screw about the line). With noise it stays exactly flat at
    # the polished minimiser thanks to the curvature term of the Hessian
    assert r_turn.null_dim == 2
    assert r_turn.smallest_eigenvalues[1] < 1e-10
    assert all("translation along" in r and "rotation about z (in its carrier) not determined"
               in r for r in r_turn.reasons), r_turn.reasons


def test_scale_from_another_component():
    rng = np.random.default_rng(11)
    sphere = _sphere_problem(rng, [1.0], True, alpha=1.0).edges[0]
    good, _ = random_instance(rng, 1, 1, n_per_edge=20, unknown_scale=True)
    e = Edge.build("x9", "y9", good.edges[0].A, good.edges[0].B)
    problem = Problem(["tag", "x9"], ["cam", "y9"], [sphere, e], unknown_scale=True)
    rep = analyze(problem)
    assert len(rep.components) == 2
    comp = next(c for c in rep.components if "tag" in c.x_names)
    assert comp.propagation_status is not S.INSUFFICIENT
    assert any("shared scale comes from edge (x9, y9)" in r for r in comp.reasons)
    assert rep.numeric.null_dim == 0  # alpha is shared, so the Hessian agrees
    assert rep.identifiable and "each component is calibrated on its own" in rep.verdict


def test_disconnected_component_without_identifiable_edge():
    rng = np.random.default_rng(12)
    X, Y = random_transforms(rng, 2), random_transforms(rng, 2)
    good = _edge(rng, X[0], Y[0], random_transforms(rng, 10), "x0", "y0")
    bad = _edge(rng, X[1], Y[1], _single_axis_A(rng, 10, [0, 1, 0]), "x1", "y1")
    rep = analyze(Problem(["x0", "x1"], ["y0", "y1"], [good, bad]), full=False)
    bad_comp = next(c for c in rep.components if "x1" in c.x_names)
    assert bad_comp.status is S.INSUFFICIENT
    assert "no edge is identifiable on its own" in bad_comp.reasons[0]
    assert not rep.identifiable and "x1, y1" in rep.verdict


# ----------------------------------------------------------------------------------------------
# incremental tracker
# ----------------------------------------------------------------------------------------------
def _mixed_problem(rng):
    X, Y = random_transforms(rng, 3), random_transforms(rng, 2)
    edges = [
        _edge(rng, X[0], Y[0], random_transforms(rng, 15), "x0", "y0", 0.01, 125.0),
        _edge(rng, X[1], Y[0], _single_axis_A(rng, 12, [0, 1, 0]), "x1", "y0", 0.01, 125.0),
        _edge(rng, X[2], Y[1], random_transforms(rng, 2), "x2", "y1", 0.01, 125.0),
        _edge(rng, X[0], Y[1], random_transforms(rng, 8), "x0", "y1", 0.01, 125.0),
    ]
    return Problem(["x0", "x1", "x2"], ["y0", "y1"], edges)


def _same(a, b):
    assert {(e.x, e.y) for e in a.edges} == {(e.x, e.y) for e in b.edges}
    for e in a.edges:
        f = b.edge(e.x, e.y)
        assert (f.status, f.rigid_status, f.n_pairs) == (e.status, e.rigid_status, e.n_pairs)
        assert len(f.reasons) == len(e.reasons)
        for k in ("rotation_spread_deg", "second_axis_spread_deg", "rotation_std_deg",
                  "rotation_sv_ratio", "translation_excitation_m", "scale_rel_std"):
            # same sums accumulated in a different order: rounding only
            assert getattr(f, k) == pytest.approx(getattr(e, k), rel=1e-7, abs=1e-9), k
    comps_a = {frozenset(c.frames): c.status for c in a.components}
    comps_b = {frozenset(c.frames): c.status for c in b.components}
    assert comps_a == comps_b
    assert a.identifiable == b.identifiable


def test_tracker_matches_batch_analysis():
    rng = np.random.default_rng(13)
    problem = _mixed_problem(rng)
    tracker = IdentifiabilityTracker()
    items = [(e, i) for e in problem.edges for i in range(e.n)]
    for idx in rng.permutation(len(items)):  # interleaved arrival, shuffled
        e, i = items[idx]
        tracker.add_pair(e.x, e.y, e.A[i], e.B[i], sigma=e.sigma[i], kappa=e.kappa[i])
    assert tracker.n_pairs == problem.n_measurements
    fast, batch = tracker.report(), analyze(problem, full=False)
    _same(fast, batch)
    assert fast.numeric is None
    full, batch_full = tracker.report(full=True), analyze(problem)
    _same(full, batch_full)
    assert full.numeric.null_dim == batch_full.numeric.null_dim
    assert full.numeric.frame_status == batch_full.numeric.frame_status


def test_tracker_grows_from_insufficient_to_identifiable():
    rng = np.random.default_rng(14)
    X, Y = random_transforms(rng, 1)[0], random_transforms(rng, 1)[0]
    A = random_transforms(rng, 6)
    B = invert_transform(Y) @ A @ X
    tracker = IdentifiabilityTracker()
    statuses = []
    for a, b in zip(A, B):
        tracker.add_pair("tag", "cam", a, b)
        statuses.append(tracker.report().edges[0].status)
    assert statuses[:2] == [S.INSUFFICIENT, S.INSUFFICIENT]
    assert statuses[-1] is S.IDENTIFIABLE


def test_tracker_validation():
    tracker = IdentifiabilityTracker(keep_pairs=False)
    with pytest.raises(ValueError, match="no pairs"):
        tracker.report()
    tracker.add_pair("tag", "cam", np.eye(4), np.eye(4))
    with pytest.raises(ValueError, match="'tag' is already an X frame"):
        tracker.add_pair("x", "tag", np.eye(4), np.eye(4))
    with pytest.raises(ValueError, match=r"edge \(tag, cam\) sigma\[0\]"):
        tracker.add_pair("tag", "cam", np.eye(4), np.eye(4), sigma=0.0)
    bad = np.eye(4)
    bad[0, 0] = 2.0
    with pytest.raises(ValueError, match=r"edge \(tag, cam\) B\[0\]"):
        tracker.add_pair("tag", "cam", np.eye(4), bad)
    with pytest.raises(ValueError, match="keep_pairs=False"):
        tracker.report(full=True)
    with pytest.raises(ValueError, match="min_pairs"):
        IdentifiabilityThresholds(min_pairs=-1)


# ----------------------------------------------------------------------------------------------
# outputs: grid, PNG, dict
# ----------------------------------------------------------------------------------------------
def test_grid_text_and_png(tmp_path):
    rng = np.random.default_rng(15)
    rep = analyze(_mixed_problem(rng), full=False)
    text = rep.grid_text()
    lines = text.splitlines()
    row_y0 = next(ln for ln in lines if ln.startswith("y0"))
    row_y1 = next(ln for ln in lines if ln.startswith("y1"))
    # columns x0 x1 x2: y0 sees x0 (good) and x1 (single axis); y1 sees x0 and x2 (2 pairs)
    assert row_y0.split()[1:] == ["#", "x", "."]
    assert row_y1.split()[1:] == ["#", ".", "x"]
    assert "legend" in text and "0=x0" in text
    path = tmp_path / "grid.png"
    rep.save_grid_png(path)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import matplotlib.image

    img = matplotlib.image.imread(str(path))[..., :3]
    blue = (img[..., 2] > 0.7) & (img[..., 0] < 0.3)
    red = (img[..., 0] > 0.7) & (img[..., 2] < 0.3)
    amber = (img[..., 0] > 0.9) & (img[..., 1] > 0.7) & (img[..., 2] > 0.35) & \
        (img[..., 2] < 0.55)
    # the graph fixes the insufficient edges (one component with a good edge): amber, no alarm red
    assert rep.identifiable
    assert blue.sum() > 100 and amber.sum() > 100 and red.sum() == 0
    # a problem that is not identifiable keeps the red
    bad = analyze(_sphere_problem(np.random.default_rng(16), [1.0], True))
    assert not bad.identifiable
    bad.save_grid_png(path)
    img = matplotlib.image.imread(str(path))[..., :3]
    assert ((img[..., 0] > 0.7) & (img[..., 2] < 0.3)).sum() > 100


def test_to_dict_is_plain_yaml():
    rng = np.random.default_rng(16)
    rep = analyze(_sphere_problem(rng, [1.0], True))
    d = rep.to_dict()
    back = yaml.safe_load(yaml.safe_dump(d))
    assert back["identifiable"] is False
    assert back["edges"][0]["status"] == "insufficient"
    assert back["numeric"]["scale_undetermined"] is True
    assert back["edges"][0]["scale_rel_std"] == float("inf")
    assert back["thresholds"]["min_pairs"] == 3


def _assert_flags_agree_with_stds(report):
    """The report's flags and numbers agree by construction: an edge whose reasons say the
    rotation (or the scale) is not determined carries an infinite std for it, and one whose
    reasons do not carries a finite std; the same for the whole-problem numeric check."""
    rot_words = ("no rotation", "only about one axis", "kernel of dimension",
                 "rotation not determined")
    for e in report.edges:
        rot_undetermined = any(w in r for r in e.reasons for w in rot_words)
        assert np.isinf(e.rotation_std_deg) == rot_undetermined, (e.reasons, e.rotation_std_deg)
        d = e.to_dict()
        assert np.isinf(d["rotation_std_deg"]) == rot_undetermined
        if rot_undetermined:
            continue  # the scale is not examined without the rotations
        scale_undetermined = any("translation direction degenerate" in r for r in e.reasons)
        assert np.isinf(e.scale_rel_std) == scale_undetermined, (e.reasons, e.scale_rel_std)
        assert np.isinf(d["scale_rel_std"]) == scale_undetermined
    num = report.numeric
    if num is not None and num.scale_rel_std is not None:
        assert np.isinf(num.scale_rel_std) == num.scale_undetermined
        if num.scale_undetermined:
            assert all(np.isinf(v) for v in num.translation_std_m.values())
    if num is not None:
        for name in num.undetermined_frames:
            assert np.isinf(num.translation_std_m[name]) or np.isinf(num.rotation_std_deg[name])


@pytest.mark.parametrize("unknown_scale", [False, True])
@pytest.mark.parametrize("jitter", [0.0, 1e-15, 1e-12, 1e-9])
def test_undetermined_flags_and_stds_agree_under_rounding(unknown_scale, jitter):
    """Degenerate motions (a single sphere around the target, one rotation axis, no rotation)
    with perturbations at and above the rounding level, which move the exact zeros of the rank
    decisions to tiny numbers of either sign: whatever a machine's rounding gives, a quantity
    reported undetermined has no finite std (issue: 1672 reported for an undetermined scale)."""
    rng = np.random.default_rng(16)
    problems = [_sphere_problem(rng, [1.0], unknown_scale)]
    X, Y = random_transforms(rng, 1)[0], random_transforms(rng, 1)[0]
    for axis_case in ("planar", "turntable", "translation"):
        if axis_case == "translation":
            A = make_transform(np.repeat(np.eye(3)[None], 20, axis=0), rng.standard_normal((20, 3)))
        else:
            A = _single_axis_A(rng, 20, [0.0, 0.0, 1.0], fixed_line=axis_case == "turntable")
        problems.append(Problem(["tag"], ["cam"], [_edge(rng, X, Y, A, "tag", "cam")],
                                unknown_scale=unknown_scale))
    for problem in problems:
        if jitter:
            e = problem.edges[0]
            A = e.A.copy()
            A[:, :3, 3] += jitter * rng.standard_normal(A[:, :3, 3].shape)
            problem = Problem(problem.x_names, problem.y_names,
                              [Edge.build(e.x, e.y, A, e.B, sigma=1e-3, kappa=1e4)],
                              unknown_scale=unknown_scale)
        _assert_flags_agree_with_stds(analyze(problem))


# ----------------------------------------------------------------------------------------------
# the paper's real data (Figure 10)
# ----------------------------------------------------------------------------------------------
def test_real_data_grid():
    data = SHARED / "data" / "paper_real_world"
    if not data.is_dir():
        pytest.skip("shared paper data not available")
    paper_csv = pytest.importorskip("rwhec_ros.data.paper_csv")
    problem = paper_csv.read_paper_csv(data)
    rep = analyze(problem)
    # Figure 10: every camera observes a target and the graph is weakly connected
    assert len(rep.components) == 1
    assert rep.identifiable and rep.numeric.null_dim == 0
    one_axis = [e for e in rep.edges if any("only about one axis" in r for r in e.reasons)]
    assert len(one_axis) >= 10
    # the planar first half of the run rotates about the world y axis (paper Fig. 9)
    about_y = [e for e in one_axis if abs(e.dominant_axis[1]) > 0.99]
    assert len(about_y) >= 0.8 * len(one_axis)
    assert sum(e.identifiable for e in rep.edges) > len(rep.edges) / 2
