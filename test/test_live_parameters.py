"""Run-time parameter changes: live ones validated and applied, the others refused with a reason."""

from __future__ import annotations

import array
from pathlib import Path

import pytest

from rwhec_ros.config import load_config, parameter_specs
from rwhec_ros.config.live_parameters import (
    LIVE_PARAMETERS,
    RESTART_REASONS,
    live_effect,
    restart_only_differences,
    restart_reason,
    review_changes,
)

DEMO_YAML = Path(__file__).resolve().parents[1] / "config" / "demo.yaml"


@pytest.fixture(scope="module")
def cfg():
    return load_config(DEMO_YAML)


def test_restart_only_change_is_refused_with_the_reason(cfg):
    review = review_changes(cfg, {"cameras.names": ["cam0"]})
    assert not review.accepted and review.config is None
    assert review.reason == ("restart the node to change cameras.names: the camera list and the "
                             "image subscriptions are set up at start-up")


@pytest.mark.parametrize("name, value, why", [
    ("cameras.cam0.image_topic", "/other/image", "subscriptions"),
    ("pose_source.topic", "/other/pose", "pose subscription"),
    ("tags.ids", [0, 1], "tag detector"),
    ("detection.min_side_px", 30.0, "detectors"),
    ("sync.image_queue_size", 3, "image queue"),
    ("ros.image_queue_depth", 50, "QoS"),
    ("keyframe.max_pairs_per_edge", 20, "pair store"),
    ("noise.from_reprojection", True, "precision stored with every pair"),
    ("camera_carrier.frame", "base", "frames of the problem"),
])
def test_each_restart_only_section_says_why(cfg, name, value, why):
    review = review_changes(cfg, {name: value})
    assert not review.accepted
    assert review.reason.startswith(f"restart the node to change {name}: ") and why in review.reason


def test_live_change_gives_the_new_configuration(cfg):
    review = review_changes(cfg, {"solver.min_pairs": 1000})
    assert review.accepted and review.changed == ("solver.min_pairs",)
    assert review.config.solver.min_pairs == 1000 and cfg.solver.min_pairs == 3
    assert review.reason == "solver.min_pairs=1000 (used by the next calibrate)"
    # everything else is the same configuration
    assert restart_only_differences(cfg, review.config) == []
    assert review.config.to_parameters() == {**cfg.to_parameters(), "solver.min_pairs": 1000}


def test_several_live_changes_at_once(cfg):
    review = review_changes(cfg, {"noise.sigma": 0.02, "keyframe.min_rotation_rad": 0.2,
                                  "output.directory": "rig1", "solver.mode": "sdp"})
    assert review.accepted, review.reason
    c = review.config
    assert (c.noise.sigma, c.keyframe.min_rotation_rad, c.output.directory, c.solver.mode) == (
        0.02, 0.2, "rig1", "sdp")
    assert "pairs offered from now on" in review.reason and "save_dataset" in review.reason


@pytest.mark.parametrize("change, needle", [
    ({"solver.min_pairs": 0}, "solver.min_pairs: must be >= 1"),
    ({"solver.mode": "fastest"}, "solver.mode"),
    ({"noise.sigma": 1}, "noise.sigma"),  # an integer for a double, as ROS refuses it
    ({"noise.kappa": -3.0}, "noise.kappa"),
    ({"output.directory": 3}, "output.directory"),
])
def test_invalid_live_value_is_refused_naming_the_parameter(cfg, change, needle):
    review = review_changes(cfg, change)
    assert not review.accepted and needle in review.reason


def test_a_mix_with_a_restart_only_change_is_refused_as_a_whole(cfg):
    review = review_changes(cfg, {"solver.min_pairs": 10, "sync.pose_buffer_size": 10})
    assert not review.accepted and "sync.pose_buffer_size" in review.reason


def test_setting_current_values_is_accepted_even_for_restart_only_parameters(cfg):
    # `ros2 param load` of the file the node started with sets every parameter to its value
    flat = cfg.to_parameters()
    same = {k: (array.array("q", v) if k == "tags.ids" else v) for k, v in flat.items()}
    review = review_changes(cfg, same)
    assert review.accepted and review.changed == () and review.config is cfg
    # ... and a real change among them is still judged
    same["cameras.cam1.frame"] = "elsewhere"
    assert not review_changes(cfg, same).accepted


def test_ros_managed_unknown_and_unset_parameters(cfg):
    assert review_changes(cfg, {"use_sim_time": True}).accepted
    assert review_changes(cfg, {"qos_overrides./tf.publisher.depth": 10}).accepted
    review = review_changes(cfg, {"solver.min_pair": 3})
    assert not review.accepted and "solver.min_pair: not a parameter" in review.reason
    review = review_changes(cfg, {"solver.min_pairs": None})
    assert not review.accepted and "cannot be unset" in review.reason


def test_current_values_from_the_node_are_compared_as_plain_values(cfg):
    current = {**cfg.to_parameters(), "tags.ids": array.array("q", [0, 1, 2, 3, 4, 5])}
    assert review_changes(cfg, {"tags.ids": [0, 1, 2, 3, 4, 5]}, current).changed == ()
    # a bool is not the integer 1 (ROS parameters are typed)
    assert not review_changes(cfg, {"output.publish_tf": 1}).accepted


def test_tables_name_real_parameters():
    # a typo in either table would silently make a parameter restart-only or give no reason
    names = [s.name for s in parameter_specs(["cam0"])]
    for key in list(LIVE_PARAMETERS) + list(RESTART_REASONS):
        if key.endswith("."):
            assert any(n.startswith(key) for n in names), key
        else:
            assert key in names, key
    # exact names win over their section (noise.sigma live, noise.from_reprojection not)
    assert live_effect("noise.sigma") and live_effect("noise.from_reprojection") is None
    assert live_effect("keyframe.min_translation_m")
    assert live_effect("keyframe.max_pairs_per_edge") is None
    assert restart_reason("verdict.something").endswith("it is read once at start-up")


def test_restart_only_differences(cfg):
    flat = cfg.to_parameters()
    flat["cameras.cam0.image_topic"] = "/x/image"
    flat["solver.min_pairs"] = 7
    other = type(cfg).from_parameters(flat)
    assert restart_only_differences(cfg, other) == ["cameras.cam0.image_topic"]


def test_priors_are_live_but_must_stay_parallel():
    cfg = load_config(DEMO_YAML.parent / "mobile_robot_floor.yaml")
    review = review_changes(cfg, {"priors.values_m": [0.5, 0.5, 0.5]})
    assert review.accepted and review.config.to_parameters()["priors.values_m"] == [0.5] * 3
    # one array alone cannot add or remove a prior: refused, naming the arrays
    review = review_changes(cfg, {"priors.frames": ["cam_front"]})
    assert not review.accepted and "must have the same length" in review.reason
    # all three together (one atomic set) can
    frames = cfg.to_parameters()["priors.frames"][:1]
    review = review_changes(cfg, {"priors.frames": frames, "priors.axes": ["z"],
                                  "priors.values_m": [0.6]})
    assert review.accepted, review.reason
