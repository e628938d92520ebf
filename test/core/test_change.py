"""The change of a frame against a reference, its test and decision
(rwhec_ros.core.analysis.change)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from rwhec_ros.core.analysis.change import (
    ChangeOptions,
    ChangeTolerance,
    decide,
    frame_changes,
    look_level,
    norm_bounds,
)
from rwhec_ros.core.lie import invert_transform, make_transform, so3_exp
from rwhec_ros.core.problem import Edge, Problem
from rwhec_ros.core.solve import solve
from rwhec_ros.simulation.synthetic import (
    perturb_measurements,
    planar_instance,
    random_transforms,
)


def _ellipsoid_surface(m, S, c, n, rng):
    """Points on the boundary of (x - m)^T S^-1 (x - m) = c."""
    L = np.linalg.cholesky(S)
    u = rng.standard_normal((n, len(m)))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return m + np.sqrt(c) * u @ L.T


@pytest.mark.parametrize("seed", range(6))
def test_norm_bounds_are_the_extremes_over_the_ellipsoid(seed):
    """Against dense sampling of the boundary (where the extremes of |x| lie unless 0 is
    inside): the bounds enclose every sample and the samples come within 1e-3 of them."""
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((3, 3))
    S = A @ A.T + 0.1 * np.eye(3)
    m = rng.standard_normal(3) * (3.0 if seed % 2 else 0.5)
    c = 2.0
    lo, hi = norm_bounds(m, S, c)
    pts = _ellipsoid_surface(m, S, c, 400_000, rng)
    norms = np.linalg.norm(pts, axis=1)
    inside = m @ np.linalg.solve(S, m) <= c
    assert norms.min() >= lo - 1e-9 and norms.max() <= hi + 1e-9
    assert hi - norms.max() < 1e-3 * hi
    if inside:
        assert lo == 0.0
    else:
        assert norms.min() - lo < 1e-3 * max(lo, 1.0)


def test_norm_bounds_degenerate_cases():
    S = np.diag([1.0, 1.0, 4.0])
    # centre at 0: min 0, max along the largest axis sqrt(c * 4)
    lo, hi = norm_bounds(np.zeros(3), S, 1.0)
    assert lo == 0.0 and hi == pytest.approx(2.0)  # the bound |m| + sqrt(c s_max) is exact here
    # isotropic, far away: [|m| - r, |m| + r]
    lo, hi = norm_bounds(np.array([10.0, 0.0, 0.0]), np.eye(3), 4.0)
    assert lo == pytest.approx(8.0, rel=1e-9) and hi == pytest.approx(12.0, rel=1e-9)


def test_decide_against_the_tolerance():
    tol = ChangeTolerance(0.002, 0.2)
    assert decide((0.0, 0.0015), (0.0, 0.1), tol) == "consistent"
    assert decide((0.0025, 0.004), (0.0, 0.1), tol) == "moved"
    assert decide((0.0, 0.001), (0.3, 0.5), tol) == "moved"  # the rotation alone suffices
    assert decide((0.0, 0.003), (0.0, 0.1), tol) == "undecided"
    assert decide((0.0, 0.001), (0.0, np.inf), tol) == "undecided"


def test_look_levels_spend_at_most_alpha():
    levels = [look_level(0.01, n) for n in range(1, 100_001)]
    assert sum(levels) < 0.01 and sum(levels) > 0.01 * 0.9999
    assert look_level(0.01, 1, sequential=False) == 0.01
    with pytest.raises(ValueError, match="false-alarm rate"):
        look_level(1.5, 1)
    with pytest.raises(ValueError, match="look"):
        look_level(0.01, 0)


def _rig(rng):
    """A rig of 2 targets and 3 cameras (random poses; 0.5 m scale)."""
    X = random_transforms(rng, 2, 0.5)
    Y = random_transforms(rng, 3, 0.5)
    return X, Y


def _data(rng, X, Y, n, sigma=0.002, kappa=2000.0, stated=(0.002, 2000.0)):
    edges = []
    for j in range(len(X)):
        for k in range(len(Y)):
            A = random_transforms(rng, n, 0.5)
            B = perturb_measurements(rng, invert_transform(Y[k]) @ A @ X[j], sigma, kappa)
            edges.append(Edge.build(f"x{j}", f"y{k}", A, B, sigma=stated[0], kappa=stated[1]))
    return Problem([f"x{j}" for j in range(len(X))], [f"y{k}" for k in range(len(Y))], edges)


def test_no_change_is_rejected_at_about_the_stated_rate():
    """Unmoved cameras, the noise stated 2x too large (so it must come from the data), the
    reference exact: the test of "no change" rejects at the nominal rate. 80 instances x 3
    cameras at a = 0.05: 12 expected; the bounds are the binomial 99.9 % interval."""
    rejections = 0
    runs = 80
    a = 0.05
    factors = []
    for seed in range(runs):
        rng = np.random.default_rng(seed)
        X, Y = _rig(rng)
        data = _data(rng, X, Y, 8, stated=(0.004, 500.0))
        res = solve(data)
        ref = {f"y{k}": Y[k] for k in range(3)}
        ct = frame_changes(data, res.X, res.Y, res.scale, free=data.frame_names, reference=ref,
                           level=a)
        rejections += sum(c.p_value < a for c in ct.frames.values())
        factors += list(ct.variance_factors.values())
    # the stated std is twice the true one: variance factors 1/4 for translation and rotation
    # (per camera 16 pairs, ~40 redundant residuals each: their mean over 240 within 15 %)
    np.testing.assert_allclose(np.mean(factors, axis=0), [0.25, 0.25], rtol=0.15)
    lo, hi = stats.binom.ppf([0.0005, 0.9995], 3 * runs, a)
    assert lo <= rejections <= hi, rejections


def test_a_moved_camera_is_named_with_its_change():
    rng = np.random.default_rng(7)
    X, Y = _rig(rng)
    moved = Y.copy()
    step = make_transform(so3_exp(np.array([0.0, np.radians(0.5), 0.0])), [0.0, 0.006, 0.0])
    moved[1] = step @ Y[1]  # left: 6 mm along the carrier's y, 0.5 deg about its y
    data = _data(rng, X, moved, 25)
    res = solve(data)
    ref = {f"y{k}": Y[k] for k in range(3)}
    ct = frame_changes(data, res.X, res.Y, res.scale, free=data.frame_names, reference=ref,
                       level=0.01 / 3)
    c = ct.frames["y1"]
    assert c.decision == "moved"
    # the true change lies within the confidence bounds; the estimate within 4 std
    lo, hi = c.translation_bounds_m
    true_t = np.linalg.norm(moved[1][:3, 3] - Y[1][:3, 3])
    assert lo <= true_t <= hi
    assert abs(c.translation_m - true_t) < 4 * c.translation_std_m
    assert abs(c.rotation_deg - 0.5) < 4 * c.rotation_std_deg
    assert ct.frames["y0"].decision != "moved" and ct.frames["y2"].decision != "moved"


def test_enough_precise_data_make_an_unmoved_camera_consistent():
    rng = np.random.default_rng(3)
    X, Y = _rig(rng)
    data = _data(rng, X, Y, 40, sigma=0.0005, kappa=3e4, stated=(0.0005, 3e4))
    res = solve(data)
    ct = frame_changes(data, res.X, res.Y, res.scale, free=data.frame_names,
                       reference={f"y{k}": Y[k] for k in range(3)}, level=0.01 / 3)
    assert {c.decision for c in ct.frames.values()} == {"consistent"}
    few = _data(rng, X, Y, 3, sigma=0.005, kappa=300.0, stated=(0.005, 300.0))
    res = solve(few)
    ct = frame_changes(few, res.X, res.Y, res.scale, free=few.frame_names,
                       reference={f"y{k}": Y[k] for k in range(3)}, level=0.01 / 3)
    assert {c.decision for c in ct.frames.values()} == {"undecided"}


def test_axes_the_data_do_not_determine_are_not_tested():
    """A ground robot that only yaws: the camera heights relative to the tags are not
    determined, so with nothing held their z is untested and no camera can be consistent;
    held targets make the heights testable."""
    problem, gt = planar_instance(np.random.default_rng(0), M=2, P=2, n_per_edge=30,
                                  sigma=0.002, kappa=2000.0)
    res = solve(problem)
    ref = {n: gt.Y[k] for k, n in enumerate(problem.y_names)}
    ct = frame_changes(problem, res.X, res.Y, res.scale, free=problem.frame_names,
                       reference=ref, level=0.005)
    for c in ct.frames.values():
        assert not c.tested[2] and c.tested[:2].all()
        assert c.translation_bounds_m[1] == np.inf and c.decision != "consistent"
    assert any("not determined" in n for n in ct.notes)
    from rwhec_ros.core.model.held import hold_frames, without_anchors

    held = {n: gt.X[j] for j, n in enumerate(problem.x_names)}
    res = without_anchors(solve(hold_frames(problem, held).problem))
    ct = frame_changes(problem, res.X, res.Y, res.scale, free=problem.y_names, reference=ref,
                       level=0.005)
    assert all(c.tested.all() for c in ct.frames.values())


def test_the_reference_covariance_widens_the_region():
    rng = np.random.default_rng(11)
    X, Y = _rig(rng)
    data = _data(rng, X, Y, 10)
    res = solve(data)
    ref = {"y0": Y[0]}
    exact = frame_changes(data, res.X, res.Y, res.scale, free=data.frame_names, reference=ref,
                          level=0.01)
    wide = frame_changes(data, res.X, res.Y, res.scale, free=data.frame_names, reference=ref,
                         level=0.01, reference_covariance={"y0": np.eye(6) * 1e-4})
    assert wide.frames["y0"].translation_bounds_m[1] > exact.frames["y0"].translation_bounds_m[1]
    assert wide.frames["y0"].statistic < exact.frames["y0"].statistic
    nan_axis = np.eye(6) * 1e-8
    nan_axis[2, :] = nan_axis[:, 2] = np.nan
    part = frame_changes(data, res.X, res.Y, res.scale, free=data.frame_names, reference=ref,
                         level=0.01, reference_covariance={"y0": nan_axis})
    assert part.frames["y0"].dof == 5 and not part.frames["y0"].tested[2]


def test_bad_input_is_refused():
    rng = np.random.default_rng(0)
    X, Y = _rig(rng)
    data = _data(rng, X, Y, 5)
    res = solve(data)
    with pytest.raises(ValueError, match="free frames"):
        frame_changes(data, res.X, res.Y, 1.0, free=["cam7"], reference={}, level=0.01)
    with pytest.raises(ValueError, match="level"):
        frame_changes(data, res.X, res.Y, 1.0, free=[], reference={}, level=0.0)
    with pytest.raises(ValueError, match="noise"):
        ChangeOptions(noise="guess")
    with pytest.raises(ValueError, match="tolerance"):
        ChangeTolerance(-1.0, 0.2)
