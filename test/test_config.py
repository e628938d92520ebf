"""Configuration: the example files load, round trips are exact, bad input names the parameter."""

from __future__ import annotations

import array
import re
from pathlib import Path

import pytest
import yaml

from rwhec_ros.config import (
    GLOBAL_SPECS,
    CalibratorConfig,
    flatten_parameters,
    fully_qualified_name,
    load_config,
    matching_sections,
    parameter_specs,
    read_parameter_file,
    section_pattern,
)

CONFIG_DIR = Path(__file__).resolve().parents[1] / "config"
EXAMPLES = sorted(CONFIG_DIR.glob("*.yaml"))


def minimal() -> dict:
    """Smallest valid flat parameter set (mobile rig, motion capture)."""
    return {
        "camera_carrier.frame": "rig",
        "camera_carrier.moving": True,
        "tag_carrier.frame": "world",
        "tag_carrier.moving": False,
        "pose_source.type": "topic",
        "pose_source.topic": "/mocap/rig/pose",
        "pose_source.parent": "world",
        "pose_source.child": "rig",
        "cameras.names": ["cam0", "cam1"],
        "cameras.cam0.image_topic": "/cam0/image_raw",
        "cameras.cam0.camera_info_topic": "/cam0/camera_info",
        "cameras.cam1.image_topic": "/cam1/image_raw",
        "cameras.cam1.camera_info_topic": "/cam1/camera_info",
        "tags.ids": [0, 1, 2],
        "tags.default_size": 0.16,
    }


def write_params(tmp_path: Path, params: dict, node: str = "calibrator") -> Path:
    path = tmp_path / "params.yaml"
    path.write_text(yaml.safe_dump({node: {"ros__parameters": params}}))
    return path


def test_examples_present():
    names = {p.name for p in EXAMPLES}
    assert {
        "arm_eye_in_hand.yaml",
        "fixed_cameras_handheld_target.yaml",
        "mobile_rig_mocap.yaml",
        "mobile_robot_floor.yaml",
        "demo.yaml",
        "demo_boards.yaml",
        "arm_charuco.yaml",
        "rig_aprilgrid.yaml",
    } <= names


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: p.name)
def test_every_example_loads_and_round_trips(path, tmp_path):
    cfg = load_config(path)
    assert cfg == load_config(path, node_name="calibrator")
    # to_parameters -> from_parameters and to_yaml -> load_config reproduce the configuration
    assert CalibratorConfig.from_parameters(cfg.to_parameters()) == cfg
    out = tmp_path / "again.yaml"
    out.write_text(cfg.to_yaml())
    assert load_config(out) == cfg
    # every tag has a positive size and every published frame is unique
    assert set(cfg.tags.sizes) == set(cfg.tags.ids)
    assert all(s > 0 for s in cfg.tags.sizes.values())
    children = [child for _, child in cfg.published_frames().values()]
    assert len(set(children)) == len(children)


def test_frame_conventions_of_the_examples():
    # A = T_<camera carrier>_<tag carrier>: inverted iff the pose parent is the tag carrier.
    arm = load_config(CONFIG_DIR / "arm_eye_in_hand.yaml")
    assert (arm.camera_carrier.frame, arm.tag_carrier.frame) == ("tool0", "base_link")
    assert arm.pose_source.type == "tf" and arm.pose_source.invert  # A = T_tool0_base = inv
    fixed = load_config(CONFIG_DIR / "fixed_cameras_handheld_target.yaml")
    assert (fixed.camera_carrier.frame, fixed.tag_carrier.frame) == ("base_link", "tool0")
    assert not fixed.pose_source.invert  # A = T_base_tool0 directly
    assert len(fixed.cameras) == 4
    rig = load_config(CONFIG_DIR / "mobile_rig_mocap.yaml")
    assert rig.pose_source.invert  # mocap T_world_rig -> A = T_rig_world
    assert len(rig.cameras) == 8 and len(rig.tags.ids) == 16
    assert rig.tags.sizes[12] == 0.24 and rig.tags.sizes[0] == 0.16
    assert rig.published_frames()["cam3"] == ("rig", "cam3_optical_calibrated")
    assert rig.published_frames()["tag_15"] == ("world", "tag_15_calibrated")


def test_board_examples():
    arm = load_config(CONFIG_DIR / "arm_charuco.yaml")
    assert arm.tags.ids == () and arm.x_names == ("charuco_board",)
    (board,) = arm.target_specs()
    assert board.kind == "charuco" and board.board.n_corners == 24 and board.min_corners == 8
    assert arm.published_frames()["charuco_board"] == ("base_link",
                                                       "charuco_board_calibrated")
    assert arm.pose_source.invert and arm.noise.from_reprojection
    rig = load_config(CONFIG_DIR / "rig_aprilgrid.yaml")
    assert rig.x_names == ("tag_300", "grid_north", "grid_east", "grid_south")
    kinds = [t.kind for t in rig.target_specs()]
    assert kinds == ["tag", "aprilgrid", "aprilgrid", "aprilgrid"]
    ids = [m for t in rig.target_specs() for m in t.marker_ids()]
    assert len(ids) == len(set(ids)) == 1 + 36 + 36 + 20  # every marker id belongs to one target
    assert rig.ros.detections_rate_hz == 2.0


def test_demo_config_matches_the_simulation():
    from rwhec_ros.simulation import DEMO_POSE_TOPIC, demo_camera_topics, demo_rig

    cfg = load_config(CONFIG_DIR / "demo.yaml")
    rig = demo_rig()
    assert cfg.camera_names == rig.cameras
    assert cfg.tags.ids == rig.tag_ids
    assert all(s == rig.tag_size for s in cfg.tags.sizes.values())
    assert cfg.pose_source.topic == DEMO_POSE_TOPIC
    for cam in cfg.cameras:
        assert (cam.image_topic, cam.camera_info_topic) == demo_camera_topics(cam.name)


def test_defaults_and_derived_values():
    cfg = CalibratorConfig.from_parameters(minimal())
    assert cfg.camera("cam1").frame == "cam1"  # default optical frame: the camera name
    assert cfg.camera("cam1").calibrated_frame == "cam1_calibrated"
    assert cfg.x_names == ("tag_0", "tag_1", "tag_2") and cfg.y_names == ("cam0", "cam1")
    assert cfg.solver.mode == "fast" and cfg.solver.min_pairs == 3
    defaults = {s.name: s.default for s in GLOBAL_SPECS}
    assert cfg.noise.sigma == defaults["noise.sigma"]
    assert cfg.sync.max_gap_s == defaults["sync.max_gap_s"]


def test_auto_or_integer_parameters_and_image_transport():
    cfg = CalibratorConfig.from_parameters(minimal())
    assert cfg.sync.detection_threads == "auto" and cfg.detection.decimate == "auto"
    assert cfg.detection.motion_gate is True and cfg.sync.image_queue_size == 8
    # auto: the cores available, at most one thread per camera (2 cameras here)
    assert cfg.detection_thread_count(available_cores=1) == 1
    assert cfg.detection_thread_count(available_cores=16) == 2
    assert 1 <= cfg.detection_thread_count() <= 2
    p = minimal()
    p.update({"sync.detection_threads": 3, "detection.decimate": 1,
              "cameras.cam1.image_transport": "compressed"})
    cfg = CalibratorConfig.from_parameters(p)
    assert cfg.detection_thread_count(available_cores=1) == 3  # an explicit number is kept
    assert cfg.detection.decimate == 1
    assert cfg.camera("cam0").image_transport == "raw"
    assert cfg.camera("cam0").subscribed_topic == "/cam0/image_raw"
    assert cfg.camera("cam1").subscribed_topic == "/cam1/image_raw/compressed"
    assert CalibratorConfig.from_parameters(cfg.to_parameters()) == cfg
    p["detection.decimate"] = "AUTO"  # the string is read case-insensitively
    assert CalibratorConfig.from_parameters(p).detection.decimate == "auto"


def test_values_as_rclpy_returns_them():
    # rclpy hands INTEGER_ARRAY / DOUBLE_ARRAY values over as array.array, unset ones as None.
    p = minimal()
    p["tags.ids"] = array.array("q", [0, 1, 2])
    p["tags.sizes.ids"] = array.array("q", [1])
    p["tags.sizes.values"] = array.array("d", [0.08])
    p["tags.frame_prefix"] = None
    p["use_sim_time"] = False  # declared by ROS itself: ignored
    p["qos_overrides./tf.subscription.depth"] = 10
    cfg = CalibratorConfig.from_parameters(p)
    assert cfg.tags.ids == (0, 1, 2)
    assert cfg.tags.sizes == {0: 0.16, 1: 0.08, 2: 0.16}
    assert cfg.tags.frame_prefix == "tag_"


def test_both_carriers_moving_with_a_direct_relative_pose_is_accepted():
    # e.g. cameras on one arm, tags on another, tf lookup between the two flanges
    p = minimal()
    p.update({"tag_carrier.moving": True, "pose_source.type": "tf", "pose_source.topic": ""})
    cfg = CalibratorConfig.from_parameters(p)
    assert cfg.camera_carrier.moving and cfg.tag_carrier.moving and cfg.pose_source.invert


def test_unknown_scale_allows_missing_sizes():
    p = minimal()
    del p["tags.default_size"]
    with pytest.raises(ValueError, match="tags.default_size"):
        CalibratorConfig.from_parameters(p)
    p["tags.unknown_scale"] = True
    cfg = CalibratorConfig.from_parameters(p)
    assert cfg.tags.unknown_scale and set(cfg.tags.sizes.values()) == {1.0}


BAD = [
    # (change, parameter named in the message)
    ({"noise.sigmaa": 0.1}, "noise.sigmaa"),
    ({"cameras.cam2.image_topic": "/x"}, "cameras.cam2.image_topic"),
    ({"cameras.cam0.image_topic": None}, "cameras.cam0.image_topic"),
    ({"cameras.cam0.camera_info_topic": ""}, "cameras.cam0.camera_info_topic"),
    ({"cameras.cam0.image_topic": "not a topic"}, "cameras.cam0.image_topic"),
    ({"pose_source.topic": ""}, "pose_source.topic"),
    ({"tags.default_size": -0.16}, "tags.default_size"),
    ({"tags.sizes.ids": [1], "tags.sizes.values": [-0.1]}, "tags.sizes.values[0]"),
    ({"tags.sizes.ids": [1, 2], "tags.sizes.values": [0.1]}, "tags.sizes.values"),
    ({"tags.sizes.ids": [7], "tags.sizes.values": [0.1]}, "tags.sizes.ids[0]"),
    ({"tags.ids": [0, -1]}, "tags.ids[1]"),
    ({"tags.ids": [0, 0]}, "tags.ids"),
    ({"tags.family": "DICT_6X6_25"}, "tags.family"),
    ({"tags.ids": []}, "tags.ids"),
    ({"noise.sigma": 1}, "noise.sigma"),  # an integer for a double: ROS rejects it too
    ({"noise.kappa": "125"}, "noise.kappa"),
    ({"noise.kappa": -1.0}, "noise.kappa"),  # 0: not stated (estimated from the data)
    ({"noise.groups": "per_tag"}, "noise.groups"),
    ({"camera_carrier.moving": "yes"}, "camera_carrier.moving"),
    ({"tags.ids": [0, 1.5]}, "tags.ids[1]"),
    ({"tags.sizes.ids": [1], "tags.sizes.values": [1]}, "tags.sizes.values[0]"),
    ({"cameras.names": "cam0"}, "cameras.names"),
    ({"cameras.names": []}, "cameras.names"),
    ({"cameras.names": ["cam0", "cam0"]}, "cameras.names"),
    ({"cameras.names": ["cam-0"]}, "cameras.names[0]"),
    ({"solver.mode": "fastest"}, "solver.mode"),
    ({"solver.min_pairs": 0}, "solver.min_pairs"),
    ({"sync.max_gap_s": -0.1}, "sync.max_gap_s"),
    ({"sync.image_queue_size": 0}, "sync.image_queue_size"),
    ({"keyframe.min_rotation_rad": 0.0}, "keyframe.min_rotation_rad"),
    ({"detection.max_obliquity_deg": 95.0}, "detection.max_obliquity_deg"),
    ({"pose_source.type": "odometry"}, "pose_source.type"),
    ({"tag_carrier.moving": False, "camera_carrier.moving": False}, "camera_carrier.moving"),
    ({"pose_source.parent": "map"}, "pose_source.parent"),
    ({"pose_source.child": "base_link"}, "pose_source.child"),
    ({"tag_carrier.frame": "rig", "pose_source.parent": "rig"}, "tag_carrier.frame"),
    ({"camera_carrier.frame": "/rig"}, "camera_carrier.frame"),
    ({"tags.frame_prefix": "cam", "tags.ids": [0, 1]}, "tags.frame_prefix"),
    ({"ros.image_qos": "best"}, "ros.image_qos"),
    ({"ros.image_queue_depth": 0}, "ros.image_queue_depth"),
    ({"output.directory": 3}, "output.directory"),
    ({"sync.detection_threads": 0}, "sync.detection_threads"),
    ({"sync.detection_threads": "many"}, "sync.detection_threads"),
    ({"sync.detection_threads": True}, "sync.detection_threads"),
    ({"detection.decimate": 0}, "detection.decimate"),
    ({"detection.decimate": 2.0}, "detection.decimate"),
    ({"detection.motion_gate": "on"}, "detection.motion_gate"),
    ({"cameras.cam1.image_transport": "theora"}, "cameras.cam1.image_transport"),
    ({"solver.live_period_s": -1.0}, "solver.live_period_s"),
    ({"solver.live_period_s": float("nan")}, "solver.live_period_s"),
    ({"convergence.max_std_translation_m": 0.0}, "convergence.max_std_translation_m"),
    ({"convergence.max_std_rotation_deg": -0.1}, "convergence.max_std_rotation_deg"),
]


@pytest.mark.parametrize("change, name", BAD, ids=[b[1] for b in BAD])
def test_bad_parameters_name_the_parameter(change, name):
    p = minimal()
    for k, v in change.items():
        if v is None:
            del p[k]
        else:
            p[k] = v
    with pytest.raises(ValueError) as info:
        CalibratorConfig.from_parameters(p)
    message = str(info.value)
    assert message.startswith(name + ":"), message


def test_single_tags_of_an_aruco_dictionary():
    p = minimal()
    p["tags.family"] = "DICT_6X6_250"
    assert CalibratorConfig.from_parameters(p).tags.family == "DICT_6X6_250"


def test_bad_value_is_shown_in_the_message():
    p = minimal()
    p["noise.sigma"] = 1
    with pytest.raises(ValueError, match=re.escape("write 1.0")):
        CalibratorConfig.from_parameters(p)
    p = minimal()
    p["tags.default_size"] = -0.5
    with pytest.raises(ValueError, match=re.escape("-0.5")):
        CalibratorConfig.from_parameters(p)


def test_unknown_key_suggests_close_names():
    p = minimal()
    p["noise.kapa"] = 100.0
    with pytest.raises(ValueError, match="noise.kappa"):
        CalibratorConfig.from_parameters(p)


def test_every_schema_parameter_is_accepted_with_its_default():
    p = minimal()
    for spec in parameter_specs(p["cameras.names"]):
        if spec.name not in p and spec.default is not None:
            p[spec.name] = list(spec.default) if isinstance(spec.default, tuple) else spec.default
    assert CalibratorConfig.from_parameters(p) == CalibratorConfig.from_parameters(minimal())


def test_live_solve_and_convergence_settings():
    c = CalibratorConfig.from_parameters(minimal())
    assert (c.solver.live_period_s, c.convergence.max_std_translation_m,
            c.convergence.max_std_rotation_deg) == (2.0, 0.005, 0.25)
    p = minimal()
    p.update({"solver.live_period_s": 0.0, "convergence.max_std_translation_m": 0.002,
              "convergence.max_std_rotation_deg": 0.1})
    c = CalibratorConfig.from_parameters(p)  # 0 = off is valid
    assert (c.solver.live_period_s, c.convergence.max_std_translation_m,
            c.convergence.max_std_rotation_deg) == (0.0, 0.002, 0.1)


# --- the file format -------------------------------------------------------------------------


def test_nested_and_dotted_yaml_are_the_same(tmp_path):
    nested = tmp_path / "nested.yaml"
    nested.write_text(
        """
calibrator:
  ros__parameters:
    camera_carrier: {frame: rig, moving: true}
    tag_carrier: {frame: world, moving: false}
    pose_source: {type: topic, topic: /mocap/rig/pose, parent: world, child: rig}
    cameras:
      names: [cam0, cam1]
      cam0: {image_topic: /cam0/image_raw, camera_info_topic: /cam0/camera_info}
      cam1: {image_topic: /cam1/image_raw, camera_info_topic: /cam1/camera_info}
    tags: {ids: [0, 1, 2], default_size: 0.16}
"""
    )
    assert load_config(nested) == CalibratorConfig.from_parameters(minimal())
    assert load_config(write_params(tmp_path, minimal())) == load_config(nested)


def test_exponent_floats_read_as_doubles(tmp_path):
    # PyYAML (YAML 1.1) would read 5e-3 as a string; the ROS parser reads a double.
    p = minimal()
    path = write_params(tmp_path, p)
    text = path.read_text() + "    noise.sigma: 5e-3\n"
    path.write_text(text)
    assert load_config(path).noise.sigma == 0.005


def test_wildcard_and_node_sections(tmp_path):
    # ROS's rule: a section applies when its key matches the node's fully qualified name.
    p = minimal()
    path = tmp_path / "multi.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "/**": {"ros__parameters": {"solver.mode": "sdp"}},
                "other_node": {"ros__parameters": {"rate_hz": 3.0}},
                "/rig1/calibrator": {"ros__parameters": p},
            },
            sort_keys=False,
        )
    )
    cfg = load_config(path, node_name="/rig1/calibrator")
    assert cfg.solver.mode == "sdp"
    assert load_config(path, node_name="calibrator", namespace="rig1") == cfg
    assert load_config(path, node_name="calibrator", namespace="/rig1/") == cfg
    # without a namespace the node is /calibrator: only '/**' applies to it
    with pytest.raises(ValueError, match="cameras.names: missing"):
        load_config(path)
    with pytest.raises(ValueError, match="cameras.names: missing"):
        load_config(path, node_name="calibrator", namespace="rig2")
    path.write_text(yaml.safe_dump({"other_node": {"ros__parameters": {"rate_hz": 3.0}}}))
    with pytest.raises(ValueError, match="no section applies to node '/calibrator'.*'/\\*\\*'"):
        load_config(path, node_name="calibrator")


@pytest.mark.parametrize(
    "key, fqn, applies",
    [
        ("/**", "/calibrator", True),
        ("/**", "/rig1/calibrator", True),
        ("/**", "/a/b/other", True),
        ("/**/calibrator", "/calibrator", True),
        ("/**/calibrator", "/rig1/calibrator", True),
        ("/**/calibrator", "/a/b/calibrator", True),
        ("/**/calibrator", "/rig1/other", False),
        ("/**/calibrator", "/rig1/calibrator2", False),
        ("calibrator", "/calibrator", True),  # a bare key is /calibrator: no namespace
        ("calibrator", "/rig1/calibrator", False),  # the failure of issue 17, item 1
        ("/calibrator", "/calibrator", True),
        ("/rig1/calibrator", "/rig1/calibrator", True),
        ("/rig1/calibrator", "/calibrator", False),
        ("/rig1/calibrator", "/rig2/calibrator", False),
        ("/*/calibrator", "/rig1/calibrator", True),  # exactly one namespace level
        ("/*/calibrator", "/calibrator", False),
        ("/*/calibrator", "/a/b/calibrator", False),
        ("rig1/*", "/rig1/calibrator", True),
        ("/rig.1/calibrator", "/rigx1/calibrator", False),  # the rest is literal
    ],
)
def test_section_keys_match_as_in_ros(key, fqn, applies):
    assert bool(section_pattern(key).fullmatch(fqn)) is applies
    assert matching_sections([key], fqn) == ([key] if applies else [])


def test_later_matching_sections_override_earlier_ones(tmp_path):
    # rclpy merges the matching sections in file order: the later one wins, whatever its key
    p = minimal()
    path = tmp_path / "order.yaml"
    for first, second, expected in [("/**", "/**/calibrator", "local"),
                                    ("/**/calibrator", "/**", "sdp")]:
        values = {"/**": "sdp", "/**/calibrator": "local"}
        doc = {first: {"ros__parameters": {**p, "solver.mode": values[first]}},
               second: {"ros__parameters": {"solver.mode": values[second]}}}
        path.write_text(yaml.safe_dump(doc, sort_keys=False))
        assert load_config(path, "calibrator", "rig1").solver.mode == expected


@pytest.mark.parametrize(
    "name, namespace, fqn",
    [("calibrator", "", "/calibrator"), ("calibrator", "rig1", "/rig1/calibrator"),
     ("calibrator", "/a/b/", "/a/b/calibrator"), ("/rig1/calibrator", "", "/rig1/calibrator")],
)
def test_fully_qualified_name(name, namespace, fqn):
    assert fully_qualified_name(name, namespace) == fqn


@pytest.mark.parametrize("name, namespace", [("", ""), ("/", ""), ("/**", ""),
                                             ("/rig1/calibrator", "rig2")])
def test_fully_qualified_name_refuses(name, namespace):
    with pytest.raises(ValueError, match="node name"):
        fully_qualified_name(name, namespace)


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.name for p in EXAMPLES])
def test_examples_apply_under_any_namespace_and_node_name(path):
    # shipped files use '/**' so that namespace:= and a renamed node still get them
    assert list(yaml.safe_load(path.read_text())) == ["/**"]
    cfg = load_config(path)
    for name, namespace in [("calibrator", "rig1"), ("my_calibrator", ""),
                            ("calibrator", "robots/rig2")]:
        assert load_config(path, name, namespace) == cfg


@pytest.mark.parametrize(
    "text, needle",
    [
        ("calibrator:\n  params: {}\n", "ros__parameters"),
        ("calibrator:\n  ros__parameters:\n    cameras: [{name: cam0}]\n", "cameras"),
        ("calibrator:\n  ros__parameters:\n    tags: {ids: [0, 1.5]}\n", "tags.ids"),
        ("calibrator: [\n", "not valid YAML"),
        ("- 1\n- 2\n", "top level"),
    ],
)
def test_malformed_files(tmp_path, text, needle):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ValueError, match=re.escape(needle)):
        load_config(path)


def test_error_names_the_file(tmp_path):
    p = minimal()
    p["noise.sigma"] = -1.0
    path = write_params(tmp_path, p)
    with pytest.raises(ValueError, match=re.escape(str(path))):
        load_config(path)
    with pytest.raises(ValueError, match="cannot read"):
        load_config(tmp_path / "missing.yaml")


def test_flatten_parameters():
    flat = flatten_parameters({"a": {"b": 1, "c": {"d": [1, 2]}}, "e": "x"})
    assert flat == {"a.b": 1, "a.c.d": [1, 2], "e": "x"}
    with pytest.raises(ValueError, match="a.b"):
        flatten_parameters({"a": {"b": None}})


def test_read_parameter_file_returns_dotted_names(tmp_path):
    path = write_params(tmp_path, minimal())
    assert read_parameter_file(path) == minimal()


# --- priors (issue 10) --------------------------------------------------------------------------


def test_ground_robot_example_has_height_priors():
    cfg = load_config(CONFIG_DIR / "mobile_robot_floor.yaml")
    assert cfg.priors.entries == (("cam_front", "z", 0.62), ("cam_left", "z", 0.48),
                                  ("cam_right", "z", 0.48))
    assert cfg.solver.unobservable_std_m == 1.0 and cfg.solver.min_scale == 0.01
    assert cfg.pose_source.invert  # T_map_base_link -> A = T_base_link_map


@pytest.mark.parametrize("priors,message", [
    ({"frames": ["cam0"], "axes": ["z", "x"], "values_m": [0.4]}, "same length"),
    ({"frames": ["cam0"], "axes": ["w"], "values_m": [0.4]}, "priors.axes[0]"),
    ({"frames": ["cam9"], "axes": ["z"], "values_m": [0.4]}, "priors.frames[0]"),
    ({"frames": ["cam0", "cam0"], "axes": ["z", "z"], "values_m": [0.4, 0.5]}, "given twice"),
    ({"frames": ["cam0"], "axes": ["z"], "values_m": [float("inf")]}, "priors.values_m[0]"),
])
def test_bad_priors_are_refused(tmp_path, priors, message):
    params = yaml.safe_load((CONFIG_DIR / "demo.yaml").read_text())
    inner = next(iter(params.values()))["ros__parameters"]
    inner["priors"] = priors
    path = tmp_path / "p.yaml"
    path.write_text(yaml.safe_dump(params))
    with pytest.raises(ValueError, match=re.escape(message)):
        load_config(path)


def test_priors_on_tag_frames_are_accepted(tmp_path):
    params = yaml.safe_load((CONFIG_DIR / "demo.yaml").read_text())
    inner = next(iter(params.values()))["ros__parameters"]
    tag = f"tag_{inner['tags']['ids'][0]}"
    inner["priors"] = {"frames": [tag], "axes": ["z"], "values_m": [1.25]}
    path = tmp_path / "p.yaml"
    path.write_text(yaml.safe_dump(params))
    assert load_config(path).priors.entries == ((tag, "z", 1.25),)
