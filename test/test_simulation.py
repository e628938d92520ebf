"""The demo simulation: consistent ground truth, visible tags, rotation about several axes."""

from __future__ import annotations

import numpy as np
import pytest

from rwhec_ros.core.lie import invert_transform, rotation_angle, rotation_distance, so3_log
from rwhec_ros.simulation import SimulatedRig, Trajectory, demo_rig, simulated_stream
from rwhec_ros.vision.boards import AprilGridSpec, CharucoSpec
from rwhec_ros.vision.target_detector import TargetDetector
from rwhec_ros.vision.targets import TargetSpec


@pytest.fixture(scope="module")
def rig() -> SimulatedRig:
    return demo_rig()


def test_measurement_model_closes_the_loop(rig):
    # A X_j = Y_k B with A = T_rig_world (inverse of the pose stream), B = T_cam_tag
    T_world_rig = rig.T_world_rig(3.7)
    A = invert_transform(T_world_rig)
    for cam in rig.cameras:
        for tag in rig.tag_ids:
            B = rig.T_cam_tag(cam, tag, T_world_rig)
            lhs = A @ rig.T_world_tag[tag]
            rhs = rig.T_rig_cam[cam] @ B
            assert np.allclose(lhs, rhs, atol=1e-12)  # exact algebra, rounding only


def test_ground_truth_is_rigid(rig):
    for T in list(rig.T_rig_cam.values()) + list(rig.T_world_tag.values()):
        R = T[:3, :3]
        assert np.allclose(R.T @ R, np.eye(3), atol=1e-12)  # orthonormal to rounding
        assert np.isclose(np.linalg.det(R), 1.0, atol=1e-12)


def test_one_turn_gives_a_connected_camera_tag_graph(rig):
    seen = set()
    for t in np.arange(0.0, 24.0, 0.2):
        T = rig.T_world_rig(t)
        for cam in rig.cameras:
            for tag in rig.visible_tags(cam, T):
                seen.add((cam, tag.tag_id))
                assert tag.T_cam_tag[2, 3] > 0  # in front of the camera
    for cam in rig.cameras:  # the yaw turn sweeps each camera over most of the ring
        assert sum(1 for c, _ in seen if c == cam) >= 4
    # weakly connected bipartite graph (paper Section 4.5): one component holds every frame
    reached, frontier = {rig.cameras[0]}, [rig.cameras[0]]
    while frontier:
        node = frontier.pop()
        for cam, tag in seen:
            for a, b in ((cam, tag), (tag, cam)):
                if a == node and b not in reached:
                    reached.add(b)
                    frontier.append(b)
    assert reached == set(rig.cameras) | set(rig.tag_ids)


def test_trajectory_rotates_about_several_axes():
    traj = Trajectory()
    R0 = traj.pose(0.0)[:3, :3]
    axes = np.array([so3_log(R0.T @ traj.pose(t)[:3, :3]) for t in np.arange(0.5, 6.0, 0.5)])
    # the relative rotation vectors span 3D (rank 3): not a single-axis motion (paper Sec. 6)
    s = np.linalg.svd(axes, compute_uv=False)
    assert s[2] > 0.05 * s[0]
    assert rotation_angle(traj.pose(12.0)[:3, :3] @ R0.T) > np.pi / 2


def test_render_is_deterministic_given_the_rng(rig):
    T = rig.T_world_rig(1.0)
    a = rig.render("cam1", T, np.random.default_rng(5), supersample=1)
    b = rig.render("cam1", T, np.random.default_rng(5), supersample=1)
    assert a.shape == (480, 640) and a.dtype == np.uint8
    assert np.array_equal(a, b)


def test_pose_noise_needs_an_rng(rig):
    with pytest.raises(ValueError, match="rng"):
        rig.pose_measurement(0.0, None, 1e-3)
    T = rig.pose_measurement(0.0, np.random.default_rng(0), 1e-3, 1e-3)
    assert not np.allclose(T, rig.T_world_rig(0.0))


def test_demo_rig_validates_sizes():
    with pytest.raises(ValueError, match="n_cameras"):
        demo_rig(0)
    with pytest.raises(ValueError, match="room_radius"):
        demo_rig(room_radius=0.1)


def test_simulated_stream_is_ordered_and_reproducible():
    rig = demo_rig(2, 2)
    a = list(simulated_stream(rig, np.random.default_rng(3), seconds=0.2, supersample=1))
    b = list(simulated_stream(rig, np.random.default_rng(3), seconds=0.2, supersample=1))
    stamps = [s.stamp_ns for s in a]
    assert stamps == sorted(stamps)
    assert [s.camera for s in a if s.camera] == ["cam0", "cam1"]
    assert all(np.array_equal(x.data, y.data) for x, y in zip(a, b, strict=True))


def test_render_with_boards_puts_each_board_at_its_tag_pose():
    """Demo rig with tags 2 m away; tag 0 becomes a ChArUco board, tag 1 a Kalibr grid: the
    detected board poses are the rig's true B = T_cam_tag of those ids."""
    rig = demo_rig(n_cameras=3, n_tags=6, room_radius=2.0)
    boards = {0: CharucoSpec(5, 4, 0.1, 0.075, "DICT_4X4_50"),
              1: AprilGridSpec(3, 3, 0.12, 0.3, first_id=100)}
    det = TargetDetector([TargetSpec("board0", board=boards[0]),
                          TargetSpec("board1", board=boards[1]),
                          TargetSpec("tag_2", tag_id=2, tag_size=rig.tag_size)])
    seen = set()
    rng = np.random.default_rng(0)
    for t in np.arange(0.0, 24.0, 1.5):
        if len(seen) == 3:
            break
        T_world_rig = rig.T_world_rig(t)
        for cam in rig.cameras:
            img = rig.render(cam, T_world_rig, rng, supersample=2, boards=boards)
            for o in det.detect(img, rig.intrinsics[cam]).observations:
                j = {"board0": 0, "board1": 1, "tag_2": 2}[o.name]
                T = rig.T_cam_tag(cam, j, T_world_rig)
                # ~2 m, f = 500 px, tens of corners (one tag for tag_2): centimetre / degree
                # level at most; a wrong frame or id would be off by the board size or more.
                dt = np.linalg.norm(o.T_cam_target[:3, 3] - T[:3, 3])
                dr = np.degrees(rotation_distance(o.T_cam_target[:3, :3], T[:3, :3]))
                assert dt < 0.03 and dr < 2.0, (o.name, dt, dr)
                seen.add(o.name)
    assert seen == {"board0", "board1", "tag_2"}
    with pytest.raises(ValueError, match="boards"):
        rig.render("cam0", rig.T_world_rig(0.0), boards={17: boards[0]})


def test_demo_board_rig_is_the_cli_demo_and_the_node_rig():
    from rwhec_ros.simulation import (
        DEMO_GRID_KINDS,
        DEMO_RIG_FRAME,
        DEMO_WORLD_FRAME,
        demo_board,
        demo_board_rig,
    )

    rig = demo_board_rig(["aprilgrid", "charuco"])
    assert rig.boards == {0: demo_board("aprilgrid", 0), 1: demo_board("charuco", 1)}
    assert list(rig.target_names()) == ["tag_2", "tag_3", "tag_4", "tag_5", "board_0", "board_1"]
    assert demo_board_rig([]).boards == {} and demo_board_rig().tag_ids == demo_rig().tag_ids
    grids = demo_board_rig(list(DEMO_GRID_KINDS))
    assert [b.kind for _, b in sorted(grids.boards.items())] == list(DEMO_GRID_KINDS)
    assert list(grids.target_names()) == ["tag_3", "tag_4", "tag_5", "board_0", "board_1",
                                          "board_2"]
    with pytest.raises(ValueError, match=r"boards\[1\]: must be one of \['aprilgrid', "
                                         r"'charuco', 'chessboard', .*\], got 'chess'"):
        demo_board_rig(["aprilgrid", "chess"])
    with pytest.raises(ValueError, match="--board: 3 boards for 2 tag positions"):
        demo_board_rig(["charuco"] * 3, 2, 2, what="--board")
    # the truth the node publishes: cameras on the rig, targets named as the calibrator's
    frames = {child: (parent, T) for parent, child, T in rig.true_frames()}
    assert set(frames) == {f"{c}_optical_true" for c in rig.cameras} | {
        f"{n}_true" for n in rig.target_names()}
    assert frames["board_1_true"][0] == DEMO_WORLD_FRAME
    assert frames["cam0_optical_true"][0] == DEMO_RIG_FRAME
    np.testing.assert_array_equal(frames["board_1_true"][1], rig.T_world_tag[1])
    np.testing.assert_array_equal(frames["tag_4_true"][1], rig.T_world_tag[4])
