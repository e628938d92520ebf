"""Reprojection error of detected corners through the calibrated chain (issue 11)."""

import numpy as np
import pytest

from rwhec_ros.core.lie import invert_transform, make_transform, so3_exp
from rwhec_ros.core.problem import Edge, Problem
from rwhec_ros.core.result import CalibrationResult, Certificate
from rwhec_ros.core.solve import solve
from rwhec_ros.simulation.rig import demo_rig
from rwhec_ros.vision.detection import tag_object_points
from rwhec_ros.vision.reprojection import CornerObservation, reprojection_errors

DISTORTION = np.array([-0.2, 0.05, 0.001, -0.001, 0.0])  # a typical plumb_bob lens


def _scene(alpha=1.0):
    """Demo rig (3 cameras, 6 tags) with distortion; noise-free detected corners and pairs."""
    rig = demo_rig()
    intr = {c: rig.intrinsics[c].with_distortion(DISTORTION, "plumb_bob") for c in rig.cameras}
    tags = [f"tag_{j}" for j in rig.tag_ids]
    obs, pairs = [], {}
    for t in np.arange(0.0, 24.0, 0.5):
        T_world_rig = rig.T_world_rig(t)
        A = invert_transform(T_world_rig)  # T_rig_world
        for cam in rig.cameras:
            for seen in rig.visible_tags(cam, T_world_rig):
                T = seen.T_cam_tag
                corners = intr[cam].project_points(tag_object_points(rig.tag_size), T)
                obs.append(CornerObservation(f"tag_{seen.tag_id}", cam, A, corners,
                                             rig.tag_size * alpha))
                B = T.copy()
                B[:3, 3] *= alpha
                pairs.setdefault((f"tag_{seen.tag_id}", cam), []).append((A, B))
    edges = [Edge.build(x, y, np.array([p[0] for p in v]), np.array([p[1] for p in v]))
             for (x, y), v in pairs.items() if len(v) >= 3]
    used = {e.x for e in edges}
    problem = Problem([t for t in tags if t in used], list(rig.cameras), edges,
                      unknown_scale=alpha != 1.0)
    X = np.array([rig.T_world_tag[int(n.split("_")[1])] for n in problem.x_names])
    Y = np.array([rig.T_rig_cam[c] for c in problem.y_names])
    obs = [o for o in obs if o.x in used]
    return problem, obs, intr, X, Y


def _result(problem, X, Y, scale=1.0):
    return CalibrationResult(problem.x_names, problem.y_names, X, Y, scale,
                             Certificate.local_only(0.0), "local")


def test_truth_reprojects_exactly_through_distortion():
    problem, obs, intr, X, Y = _scene()
    out = reprojection_errors(obs, intr, _result(problem, X, Y))
    assert set(out) == set(problem.y_names)
    for r in out.values():
        assert r.n_pairs > 10 and r.n_behind == 0
        assert r.rms_px < 1e-6  # same model both ways: rounding only


def test_solved_noise_free_data_reprojects_to_zero():
    problem, obs, intr, _, _ = _scene()
    res = solve(problem)
    out = reprojection_errors(obs, intr, res)
    # the solve recovers exact data to ~1e-9 relative; at 500 px focal length that is << 1e-3 px
    assert max(r.rms_px for r in out.values()) < 1e-3


def test_unknown_scale_uses_the_true_tag_size():
    """Monocular data: B translations and the nominal tag size both x alpha; the metric estimate
    with scale alpha reprojects exactly."""
    problem, obs, intr, X, Y = _scene(alpha=0.5)
    out = reprojection_errors(obs, intr, _result(problem, X, Y, scale=0.5))
    assert max(r.rms_px for r in out.values()) < 1e-6


def test_a_wrong_camera_rotation_shows_in_its_pixels_only():
    """cam1 rotated by 0.2 deg about its x axis: its corners move by about f * 0.2 deg =
    500 px * 3.5e-3 = 1.7 px (30 %: off-axis corners and distortion); the others are unaffected."""
    problem, obs, intr, X, Y = _scene()
    k = problem.y_names.index("cam1")
    Y_bad = Y.copy()
    Y_bad[k] = Y[k] @ make_transform(so3_exp(np.radians([0.2, 0.0, 0.0])), np.zeros(3))
    out = reprojection_errors(obs, intr, _result(problem, X, Y_bad))
    assert out["cam1"].rms_px == pytest.approx(500 * np.radians(0.2), rel=0.3)
    assert out["cam0"].rms_px < 1e-6 and out["cam2"].rms_px < 1e-6


def test_bad_inputs_name_the_field():
    problem, obs, intr, X, Y = _scene()
    res = _result(problem, X, Y)
    with pytest.raises(ValueError, match="no intrinsics for camera 'cam2'"):
        reprojection_errors(obs, {k: v for k, v in intr.items() if k != "cam2"}, res)
    with pytest.raises(ValueError, match="tag frame 'tag_99'"):
        reprojection_errors([CornerObservation("tag_99", "cam0", np.eye(4), np.zeros((4, 2)),
                                               0.1)], intr, res)
    with pytest.raises(ValueError, match="corners_px"):
        CornerObservation("tag_0", "cam0", np.eye(4), np.zeros((3, 2)), 0.1)
    with pytest.raises(ValueError, match="tag_size_m"):
        CornerObservation("tag_0", "cam0", np.eye(4), np.zeros((4, 2)), -1.0)


def _board_scene(noise_px, seed=0):
    """The demo rig with an AprilGrid (3 x 3 tags, Kalibr layout) at position 0: per view the
    corners of the grid tags whose four corners are in the image (a partly seen board gives
    fewer), projected through the truth and the distorted lens with Gaussian noise per axis."""
    from rwhec_ros.simulation.rig import demo_board

    rig = demo_rig()
    board = demo_board("aprilgrid", 0)
    intr = {c: rig.intrinsics[c].with_distortion(DISTORTION, "plumb_bob") for c in rig.cameras}
    rng = np.random.default_rng(seed)
    obs, partial = [], 0
    for t in np.arange(0.0, 24.0, 0.25):
        T_world_rig = rig.T_world_rig(t)
        A = invert_transform(T_world_rig)
        for cam in rig.cameras:
            T = rig.T_cam_tag(cam, 0, T_world_rig)
            if T[2, 3] < 0.1 or float(T[:3, 2] @ T[:3, 3]) >= 0:
                continue
            pts, px = [], []
            for m in board.marker_ids:
                P = board.marker_object_points(m)
                uv = intr[cam].project_points(P, T)
                if ((uv >= 2).all() and (uv[:, 0] < 638).all() and (uv[:, 1] < 478).all()):
                    pts.append(P)
                    px.append(uv)
            if len(pts) >= 2:
                partial += len(pts) < len(board.marker_ids)
                uv = np.concatenate(px)
                obs.append(CornerObservation("board_0", cam, A,
                                             uv + noise_px * rng.standard_normal(uv.shape),
                                             object_points=np.concatenate(pts)))
    X = rig.T_world_tag[0][None]
    Y = np.array([rig.T_rig_cam[c] for c in rig.cameras])
    result = CalibrationResult(("board_0",), rig.cameras, X, Y, 1.0,
                               Certificate.local_only(0.0), "local")
    return obs, intr, result, partial


def test_board_corners_reproject_to_their_noise():
    """Board pairs with their board-frame points (varying per view: partly seen boards): through
    the true calibration the per-camera RMS is the corner noise, sqrt(2) x 0.1 px for the 2D
    distance; a 0.2 deg camera error shows as for tags."""
    obs, intr, result, partial = _board_scene(noise_px=0.1)
    assert partial > 0 and len({len(o.corners_px) for o in obs}) > 1  # views differ in points
    out = reprojection_errors(obs, intr, result)
    assert set(out) == {o.y for o in obs}
    for r in out.values():
        # thousands of corners per camera: the RMS of the 2D noise within 10 %
        assert r.rms_px == pytest.approx(0.1 * np.sqrt(2), rel=0.1), r
        assert r.n_behind == 0 and r.n_pairs >= 10
    Y_bad = result.Y.copy()
    k = result.y_names.index("cam1")
    Y_bad[k] = Y_bad[k] @ make_transform(so3_exp(np.radians([0.2, 0.0, 0.0])), np.zeros(3))
    bad = CalibrationResult(result.x_names, result.y_names, result.X, Y_bad, 1.0,
                            Certificate.local_only(0.0), "local")
    out_bad = reprojection_errors(obs, intr, bad)
    # 500 px x 3.5e-3 rad = 1.7 px added to the noise (30 %: off-axis corners, distortion)
    assert out_bad["cam1"].rms_px == pytest.approx(500 * np.radians(0.2), rel=0.3)
    assert out_bad["cam0"].rms_px == pytest.approx(out["cam0"].rms_px, abs=1e-12)


def test_board_points_are_nominal_for_an_unknown_scale():
    """Monocular: the board points are nominal (x alpha) like a tag size; the metric estimate
    with scale alpha reprojects them as the metric ones."""
    obs, intr, result, _ = _board_scene(noise_px=0.0)
    alpha = 0.5
    nominal = [CornerObservation(o.x, o.y, o.A, o.corners_px, object_points=alpha * o.object_points)
               for o in obs]
    scaled = CalibrationResult(result.x_names, result.y_names, result.X, result.Y, alpha,
                               Certificate.local_only(0.0), "local")
    for r in reprojection_errors(nominal, intr, scaled).values():
        assert r.rms_px < 1e-6  # same model both ways: rounding only


def test_bad_board_observations_name_the_field():
    with pytest.raises(ValueError, match=r"object_points of \(board_0, cam0\): expected finite "
                                         r"\(8, 3\)"):
        CornerObservation("board_0", "cam0", np.eye(4), np.zeros((8, 2)),
                          object_points=np.zeros((7, 3)))
    with pytest.raises(ValueError, match="K >= 4"):
        CornerObservation("board_0", "cam0", np.eye(4), np.zeros((3, 2)),
                          object_points=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="tag_size_m of"):  # neither a size nor points
        CornerObservation("tag_0", "cam0", np.eye(4), np.zeros((4, 2)))
