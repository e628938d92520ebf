"""The node's parameter declaration plan covers the schema with ROS types (no rclpy needed)."""

from __future__ import annotations

from rwhec_ros.config import CAMERA_SPECS, GLOBAL_SPECS
from rwhec_ros.ros.params import ROS_TYPE_NAMES, declaration_plan


def test_declaration_plan_covers_the_schema():
    plan = declaration_plan(["cam0"], declared={"cameras.names", "noise.sigma"})
    names = {p[0] for p in plan}
    expected = {s.name for s in GLOBAL_SPECS} | {f"cameras.cam0.{s.name}" for s in CAMERA_SPECS}
    expected.add("sync.time_offset.cam0")  # the per-camera sync.time_offset.<camera>
    assert names == expected - {"cameras.names", "noise.sigma"}
    by_name = {p[0]: p for p in plan}
    assert by_name["noise.kappa"][1:3] == ("DOUBLE", 0.0)  # 0: not stated, estimated
    assert by_name["sync.pose_buffer_size"][1] == "INTEGER"
    # no default or an empty array: declared by type only (an empty list has no ROS type)
    assert by_name["tags.ids"][1:3] == ("INTEGER_ARRAY", None)
    assert by_name["tags.sizes.values"][1:3] == ("DOUBLE_ARRAY", None)
    assert by_name["tags.default_size"][1:3] == ("DOUBLE", None)
    assert by_name["cameras.cam0.image_topic"][1:3] == ("STRING", None)
    assert "(required)" in by_name["cameras.cam0.image_topic"][3]
    for _, type_name, default, _ in plan:
        assert type_name in ROS_TYPE_NAMES.values()
        if default is not None:  # the default's Python type matches the declared ROS type
            py = {"BOOL": bool, "INTEGER": int, "DOUBLE": float, "STRING": str}[type_name]
            assert type(default) is py
