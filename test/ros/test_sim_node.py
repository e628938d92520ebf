"""The demo simulator node's ``boards`` parameter (needs rclpy, i.e. a sourced ROS 2 Jazzy;
skipped otherwise). The rig it builds is tested without ROS in ``test/test_simulation.py``."""

from __future__ import annotations

import pytest

rclpy = pytest.importorskip("rclpy")
pytest.importorskip("tf2_ros")

from rclpy.parameter import Parameter  # noqa: E402

from rwhec_ros.ros.sim_node import DemoSimulatorNode  # noqa: E402
from rwhec_ros.simulation import demo_board_rig  # noqa: E402


def _node(context, **params):
    return DemoSimulatorNode(context=context, parameter_overrides=[
        Parameter(k, value=v) for k, v in params.items()])


def test_no_boards_by_default(context):
    node = _node(context)
    try:
        assert node.rig.boards == {}
        assert list(node.rig.target_names()) == [f"tag_{j}" for j in range(6)]
    finally:
        node.stop_activity()
        node.destroy_node()


def test_boards_parameter_renders_the_boards_of_demo_boards_yaml(context):
    node = _node(context, boards=["aprilgrid", "charuco"])
    try:
        assert node.rig.boards == demo_board_rig(["aprilgrid", "charuco"]).boards
        assert list(node.rig.target_names())[-2:] == ["board_0", "board_1"]
    finally:
        node.stop_activity()
        node.destroy_node()


def test_a_bad_board_kind_is_named(context):
    with pytest.raises(ValueError, match=r"boards\[0\]: must be one of"):
        _node(context, boards=["hexagon"])  # chessboard is a demo board since issue 41
