"""Turn-symmetric boards: which views' corner order is turned, told from the pose stream
(:mod:`rwhec_ros.sync.board_turns`), on pairs with a known truth.

Pairs ``A_i X = Y B_i`` of random rigs; a random subset of the views is turned (``B F``, the
labelling the detector may give a board that looks the same turned by 180 degrees). The
resolution must find exactly the planted subset (or its complement: the board frame of a
symmetric board is defined only up to that turn), leave out what no view witnesses, and match
the turns of one board seen by two cameras.
"""

from __future__ import annotations

import numpy as np
import pytest

from rwhec_ros.core.lie import invert_transform, make_transform, rotation_distance, so3_exp
from rwhec_ros.sync.accumulator import PairAccumulator
from rwhec_ros.sync.board_turns import TURN, resolve_edges, resolve_turns, turn_lines
from rwhec_ros.sync.edge_pairs import DatasetEdge


def _pose(rng, rot_std, t_std):
    return make_transform(so3_exp(rng.normal(0.0, rot_std, 3)), rng.normal(0.0, t_std, 3))


def _pairs(rng, X, Y, n, *, yaw_range=np.pi, noise_deg=0.3, noise_m=0.002):
    """``n`` pairs ``A_i X = Y B_i`` (``B = Y^-1 A X`` times noise): the rig yaws over
    ``yaw_range`` and tilts by ~20 deg."""
    A = np.array([make_transform(
        so3_exp(np.r_[rng.normal(0.0, 0.35, 2), rng.uniform(-yaw_range, yaw_range)]),
        rng.normal(0.0, 0.3, 3)) for _ in range(n)])
    noise = [make_transform(so3_exp(rng.normal(0.0, np.radians(noise_deg), 3)),
                            rng.normal(0.0, noise_m, 3)) for _ in range(n)]
    B = np.array([invert_transform(Y) @ a @ X @ e for a, e in zip(A, noise, strict=True)])
    return A, B


@pytest.mark.parametrize("seed", range(8))
def test_the_planted_turns_are_found(seed):
    """Every view resolved, its turn the planted one up to one turn of the whole edge; a
    third of the views turned; rigs yawing over +-180 deg (most pairs of views too far apart
    to witness each other directly) or +-30 deg."""
    rng = np.random.default_rng(seed)
    X, Y = _pose(rng, 1.0, 0.5), _pose(rng, 1.0, 0.5)
    A, B = _pairs(rng, X, Y, int(rng.integers(3, 120)),
                  yaw_range=np.pi if seed % 2 else np.radians(30))
    planted = rng.random(len(A)) < 0.33
    B[planted] = B[planted] @ TURN
    res = resolve_turns(A, B)
    assert res.resolved.all()
    assert np.array_equal(res.turned, planted) or np.array_equal(res.turned, ~planted)
    # the labelling kept is the one most views have
    assert res.n_turned <= len(A) / 2


def test_nothing_turned_is_left_as_it_is():
    rng = np.random.default_rng(11)
    X, Y = _pose(rng, 1.0, 0.5), _pose(rng, 1.0, 0.5)
    A, B = _pairs(rng, X, Y, 40)
    res = resolve_turns(A, B)
    assert res.resolved.all() and not res.turned.any()


def test_a_view_no_other_view_witnesses_is_left_out_not_guessed():
    """Two views turned by 180 deg about an axis in the board's plane: the board turned about
    its normal turns by 180 deg too (about the other in-plane axis), so neither labelling of
    the second view fits the stream better: both views are left out. A third view half-way
    (90 deg from each) ties them together."""
    X = Y = np.eye(4)
    half_turns = [0.0, np.pi]
    A = np.array([make_transform(so3_exp(np.r_[a, 0.0, 0.0]), np.zeros(3)) for a in half_turns])
    B = np.array([invert_transform(Y) @ a @ X for a in A])
    B[1] = B[1] @ TURN
    res = resolve_turns(A, B)
    assert res.n_unresolved == 2
    A3 = np.concatenate([A, make_transform(so3_exp(np.r_[0.5 * np.pi, 0.0, 0.0]),
                                           np.zeros(3))[None]])
    B3 = np.concatenate([B, (invert_transform(Y) @ A3[2] @ X)[None]])
    res = resolve_turns(A3, B3)
    assert res.resolved.all()
    assert res.turned.tolist() in ([False, True, False], [True, False, True])


def _edge(x, y, A, B, corners=None, points=None):
    n = len(A)
    return DatasetEdge(x=x, y=y, stamps_ns=np.arange(n, dtype=np.int64), A=A, B=B,
                       sigma=np.full(n, 0.002), kappa=np.full(n, 1e4),
                       corners_px=corners, corner_points_m=points)


def test_one_board_seen_by_two_cameras_gets_one_frame():
    """The board ``b`` seen by cameras c0 (many views) and c1, each camera's views partly
    turned; c1's labelling of the whole edge may come out turned against c0's: the solve of
    both edges (and a tag seen by both) matches them, so that both edges' pairs fit one board
    frame; the board's corner points are turned with the views."""
    rng = np.random.default_rng(4)
    X_b, X_t = _pose(rng, 1.0, 0.5), _pose(rng, 1.0, 0.5)
    Y0, Y1 = _pose(rng, 1.0, 0.1), _pose(rng, 1.0, 0.1)
    pts = np.array([[[-0.1, 0.05, 0.0], [0.1, -0.05, 0.0], [0.1, 0.05, 0.0], [-0.1, -0.05, 0.0]]])
    edges = {}
    for (x, X), (y, Y), n in (((("b", X_b)), ("c0", Y0), 30), ((("b", X_b)), ("c1", Y1), 12),
                              ((("t", X_t)), ("c0", Y0), 10), ((("t", X_t)), ("c1", Y1), 10)):
        A, B = _pairs(rng, X, Y, n, yaw_range=np.radians(40))
        corners = points = None
        if x == "b":
            turned = rng.random(n) < 0.4
            if y == "c1":
                turned = ~turned  # most of c1's views turned: its edge's labelling is turned
            B[turned] = B[turned] @ TURN
            corners = np.zeros((n, 4, 2))
            points = np.repeat(pts, n, axis=0)
            points[turned, :, :2] *= -1.0
        edges[(x, y)] = _edge(x, y, A, B, corners, points)
    out, report = resolve_edges(edges, {"b"})
    assert set(report) == {("b", "c0"), ("b", "c1")}
    assert all(r["unresolved"] == 0 and "left_out" not in r for r in report.values())
    # every pair of both board edges fits one frame: the truth's or the truth turned
    fits = []
    for y, Y in (("c0", Y0), ("c1", Y1)):
        e = out[("b", y)]
        for a, b, p in zip(e.A, e.B, e.corner_points_m, strict=True):
            err = rotation_distance((a @ X_b)[:3, :3], (Y @ b)[:3, :3])
            err_turned = rotation_distance((a @ X_b @ TURN)[:3, :3], (Y @ b)[:3, :3])
            fits.append(err < err_turned)
            # the corner points turn with the view: in the frame B refers to, they are pts
            want = pts[0] if err < err_turned else pts[0] * [-1.0, -1.0, 1.0]
            assert np.allclose(p, want)
    assert all(fits) or not any(fits)
    assert out[("t", "c0")] is edges[("t", "c0")]
    assert any("turn-symmetric board b" in line for line in turn_lines(report))


def test_the_accumulator_hands_out_resolved_pairs_and_reports_them():
    rng = np.random.default_rng(6)
    X, Y = _pose(rng, 1.0, 0.5), _pose(rng, 1.0, 0.5)
    A, B = _pairs(rng, X, Y, 25, yaw_range=np.radians(60))
    planted = np.zeros(25, dtype=bool)
    planted[[3, 7, 8, 20]] = True
    B[planted] = B[planted] @ TURN
    acc = PairAccumulator(keyframe_rotation_rad=1e-9, keyframe_translation_m=1e-9,
                          turnable=["b"])
    plain = PairAccumulator(keyframe_rotation_rad=1e-9, keyframe_translation_m=1e-9)
    for i, (a, b) in enumerate(zip(A, B, strict=True)):
        for target in (acc, plain):
            assert target.offer("b", "c", i, a, b, 0.002, 1e4)
    fixed = acc.edges()[("b", "c")].B
    assert np.allclose(fixed[planted], B[planted] @ TURN)
    assert np.allclose(fixed[~planted], B[~planted])
    assert np.allclose(acc.kept_pairs()[("b", "c")].B, fixed)
    assert acc.kept_pairs()[("b", "c")].lineage is None  # no promise: turns may change
    assert acc.turn_report() == {("b", "c"): {"pairs": 25, "turned": 4, "unresolved": 0}}
    problem, _ = acc.to_problem()
    assert np.allclose(problem.edges[0].B, fixed)
    assert np.allclose(plain.edges()[("b", "c")].B, B)  # not turnable: as offered
    assert plain.turn_report() == {}
    # the live tracker's pairs: labelled like the edge's first pair
    for i in range(25):
        want = B[i] @ TURN if planted[i] != planted[0] else B[i]
        assert np.allclose(acc.tracker_B("b", "c", i, B[i]), want)
    b3 = B[3]
    assert plain.tracker_B("b", "c", 3, b3) is b3


def test_an_edge_with_no_view_told_is_left_out_whole_with_the_reason():
    """Two views turned by 180 deg about an in-plane axis (neither tells the other's turn): the
    board's edge has no view left. It is left out whole, named with the reason in the report
    and in to_problem's exclusions, and the other edges are handed out; edges() and
    kept_pairs() do not raise (an empty edge is no data-set record)."""
    A = [np.eye(4), make_transform(so3_exp(np.r_[np.pi, 0.0, 0.0]), np.zeros(3))]
    acc = PairAccumulator(keyframe_rotation_rad=1e-9, keyframe_translation_m=1e-9,
                          turnable=["b"])
    for i, a in enumerate(A):
        assert acc.offer("b", "c", i, a, a @ TURN if i else a, 0.002, 1e4)
        assert acc.offer("t", "c", i, a, a, 0.002, 1e4)
    assert set(acc.edges()) == set(acc.kept_pairs()) == {("t", "c")}
    why = acc.turn_report()[("b", "c")]["left_out"]
    assert "none of its 2 views" in why
    _, excluded = acc.to_problem(min_pairs=1)
    assert excluded == {("b", "c"): why}
    assert acc.tracker_B("b", "c", 1, A[1]) is None
