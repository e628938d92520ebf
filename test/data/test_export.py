"""Export for the robot description: URDF/xacro snippet and plain YAML, read back exactly."""

import xml.etree.ElementTree as ET

import numpy as np
import pytest
import yaml

from rwhec_ros.core.lie import make_transform, quat_xyzw_to_wxyz, so3_exp
from rwhec_ros.data.export import (
    frames_yaml,
    matrix_from_rpy,
    rpy_from_matrix,
    urdf_fixed_joints,
    urdf_snippet,
)


def elementary(axis: int, angle: float) -> np.ndarray:
    """Rotation about the x (0), y (1) or z (2) axis, written out (independent of scipy)."""
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def urdf_rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """URDF's fixed-axis convention: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    return elementary(2, yaw) @ elementary(1, pitch) @ elementary(0, roll)


def frames(rng):
    out = [("rig", f"cam{k}_calibrated",
            make_transform(so3_exp(rng.normal(0.0, 1.5, 3)), rng.normal(0.0, 0.5, 3)))
           for k in range(4)]
    # Gimbal lock (pitch = +-90 deg) and the identity.
    out.append(("rig", "cam_up_calibrated", make_transform(urdf_rotation(0.3, np.pi / 2, 0.2),
                                                           [0.1, 0.0, 0.2])))
    out.append(("rig", "cam_down_calibrated", make_transform(urdf_rotation(-1.0, -np.pi / 2, 2.5),
                                                             [0.0, 0.0, 0.0])))
    out.append(("world", "tag_0_calibrated", np.eye(4)))
    return out


def test_urdf_snippet_round_trip_with_xml_etree():
    given = frames(np.random.default_rng(0))
    text = urdf_snippet(given, comment="certified: True")
    root = ET.fromstring(text)
    assert root.tag == "robot"
    links = [e.get("name") for e in root.findall("link")]
    assert links == [child for _, child, _ in given]
    joints = root.findall("joint")
    assert len(joints) == len(given)
    for joint, (parent, child, T) in zip(joints, given, strict=True):
        assert joint.get("type") == "fixed" and joint.get("name") == f"{child}_joint"
        assert joint.find("parent").get("link") == parent
        assert joint.find("child").get("link") == child
        origin = joint.find("origin")
        xyz = np.array([float(v) for v in origin.get("xyz").split()])
        rpy = np.array([float(v) for v in origin.get("rpy").split()])
        # 1e-9: the brief's round-trip bound; repr() writes shortest round-trip floats, so the
        # only loss is the Euler conversion (~1e-15; worse near gimbal lock, still << 1e-9).
        np.testing.assert_allclose(xyz, T[:3, 3], atol=1e-9)
        np.testing.assert_allclose(urdf_rotation(*rpy), T[:3, :3], atol=1e-9)
    # The module's own reader agrees.
    for (p, c, T), (p2, c2, T2) in zip(given, urdf_fixed_joints(text), strict=True):
        assert (p, c) == (p2, c2)
        np.testing.assert_allclose(T2, T, atol=1e-9)


def test_rpy_convention_is_urdfs():
    rng = np.random.default_rng(1)
    for _ in range(20):
        rpy = rng.uniform([-np.pi, -np.pi / 2 + 0.01, -np.pi], [np.pi, np.pi / 2 - 0.01, np.pi])
        R = urdf_rotation(*rpy)
        # 1e-12: away from gimbal lock the angles are recovered to rounding.
        np.testing.assert_allclose(rpy_from_matrix(R), rpy, atol=1e-12)
        np.testing.assert_allclose(matrix_from_rpy(rpy), R, atol=1e-12)


def test_frames_yaml_round_trip():
    given = frames(np.random.default_rng(2))
    doc = yaml.safe_load(frames_yaml(given, metadata={"certified": True, "scale": 1.0}))
    assert doc["metadata"] == {"certified": True, "scale": 1.0}
    assert len(doc["frames"]) == len(given)
    for entry, (parent, child, T) in zip(doc["frames"], given, strict=True):
        assert (entry["parent"], entry["child"]) == (parent, child)
        np.testing.assert_allclose(entry["xyz"], T[:3, 3], atol=1e-9)  # the brief's bound
        np.testing.assert_allclose(urdf_rotation(*entry["rpy"]), T[:3, :3], atol=1e-9)
        q = np.array(entry["quaternion_xyzw"])
        assert np.linalg.norm(q) == pytest.approx(1.0, abs=1e-12)
        w, x, y, z = quat_xyzw_to_wxyz(q)
        R = np.array([  # unit quaternion (x, y, z, w) -> rotation, written out
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ])
        np.testing.assert_allclose(R, T[:3, :3], atol=1e-9)


def test_names_are_escaped_and_links_optional():
    T = make_transform(np.eye(3), [1.0, 2.0, 3.0])
    text = urdf_snippet([("base", 'cam<"&>', T)], declare_links=False, comment="a -- b")
    root = ET.fromstring(text)
    assert root.findall("link") == []
    assert root.find("joint/child").get("link") == 'cam<"&>'
    assert urdf_fixed_joints(text)[0][1] == 'cam<"&>'


@pytest.mark.parametrize(
    "frames_arg, match",
    [
        ([("", "c", np.eye(4))], r"frames\[0\]: parent"),
        ([("p", " ", np.eye(4))], r"frames\[0\]: child"),
        ([("p", "p", np.eye(4))], "parent and child"),
        ([("p", "c", np.eye(4)), ("q", "c", np.eye(4))], r"frames\[1\]: child 'c' already"),
        ([("p", "c", np.eye(3))], "finite 4x4"),
        ([("p", "c", np.diag([1.0, 1.0, -1.0, 1.0]))], "not a rigid transform"),
        ([("p", "c")], r"frames\[0\] must be"),
    ],
)
def test_bad_frames_raise_value_error(frames_arg, match):
    with pytest.raises(ValueError, match=match):
        urdf_snippet(frames_arg)
    with pytest.raises(ValueError, match=match):
        frames_yaml(frames_arg)


def test_reader_errors():
    with pytest.raises(ValueError, match="not valid XML"):
        urdf_fixed_joints("<robot>")
    bad = '<robot><joint name="j" type="fixed"><parent link="a"/></joint></robot>'
    with pytest.raises(ValueError, match="joint 'j'"):
        urdf_fixed_joints(bad)
    bad_origin = ('<robot><joint name="j" type="fixed"><parent link="a"/><child link="b"/>'
                  '<origin xyz="1 2" rpy="0 0 0"/></joint></robot>')
    with pytest.raises(ValueError, match="3 numbers"):
        urdf_fixed_joints(bad_origin)
