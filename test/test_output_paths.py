"""Where the node and the CLI write, and the service answers that say where (no ROS needed)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from rwhec_ros.cli.common import DEFAULT_OUTPUT as CLI_DEFAULT_OUTPUT
from rwhec_ros.config import OutputConfig
from rwhec_ros.session import SolveOutcome
from rwhec_ros.session.paths import (
    DEFAULT_OUTPUT,
    node_output_root,
    plain_output_root,
    ros_home,
)
from rwhec_ros.session.responses import (
    calibrate_message,
    output_directory,
    save_dataset_message,
    should_publish_tf,
)


@pytest.mark.parametrize("env, expected", [
    ({"HOME": "/home/u"}, "/home/u/.ros"),  # the ROS default
    ({"HOME": "/home/u", "ROS_HOME": ""}, "/home/u/.ros"),  # empty counts as unset
    ({"HOME": "/home/u", "ROS_HOME": "/data/ros"}, "/data/ros"),
    ({"HOME": "/home/u", "ROS_HOME": "~/myros"}, "/home/u/myros"),
    ({"HOME": "/home/u", "ROS_HOME": "rel/ros"}, "/work/dir/rel/ros"),
])
def test_ros_home(env, expected):
    assert ros_home(env, cwd=Path("/work/dir")) == Path(expected)


@pytest.mark.parametrize("directory, expected", [
    ("", "/data/ros/rwhec_ros"),  # default: $ROS_HOME/rwhec_ros
    ("rig1", "/data/ros/rwhec_ros/rig1"),  # relative: under that, never under the cwd
    ("rig1/../rig2", "/data/ros/rwhec_ros/rig2"),
    ("/mnt/calib", "/mnt/calib"),
    ("~/calib", "/home/u/calib"),
])
def test_node_output_root(directory, expected):
    env = {"HOME": "/home/u", "ROS_HOME": "/data/ros"}
    assert node_output_root(directory, env, cwd=Path("/launched/from/here")) == Path(expected)


def test_node_output_root_default_without_ros_home_is_absolute_and_cwd_independent(
        tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    env = {"HOME": "/home/u"}
    assert node_output_root("", env) == Path("/home/u/.ros/rwhec_ros")
    assert node_output_root("out", env) == Path("/home/u/.ros/rwhec_ros/out")


def test_plain_output_root():
    assert plain_output_root("") == Path("rwhec_output") == Path(DEFAULT_OUTPUT)
    assert plain_output_root("results") == Path("results")  # relative to the current directory
    assert CLI_DEFAULT_OUTPUT == DEFAULT_OUTPUT  # the CLI keeps a literal copy (import time)


def output_config(**kw) -> OutputConfig:
    base = dict(directory="", frame_suffix="_calibrated", publish_tf=True,
                publish_uncertified=False)
    base.update(kw)
    return OutputConfig(**base)


def outcome(certified: bool | None, files: dict | None = None) -> SolveOutcome:
    if certified is None:
        return SolveOutcome(False, "not enough data: 0 pairs on 0 edges; all data kept")
    result = SimpleNamespace(certified=certified)
    head = "CERTIFIED globally optimal" if certified else "NOT certified: not_tight"
    return SolveOutcome(True, head + "; 12 pairs on 2 edges", result=result,
                        files=files or {})


@pytest.mark.parametrize("certified, publish_tf, uncertified, expected", [
    (True, True, False, True),
    (False, True, False, False),
    (False, True, True, True),
    (True, False, True, False),
    (None, True, True, False),  # no solution: nothing to publish
])
def test_should_publish_tf(certified, publish_tf, uncertified, expected):
    out = output_config(publish_tf=publish_tf, publish_uncertified=uncertified)
    assert should_publish_tf(outcome(certified), out) is expected


def test_calibrate_message_names_the_absolute_output_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    files = {"result": "out/calibration_1/result.yaml",
             "launch": "out/calibration_1/static_transforms.launch.py"}
    msg = calibrate_message(outcome(True, files), output_config(), published=True)
    assert msg == ("CERTIFIED globally optimal; 12 pairs on 2 edges; "
                   f"files in {tmp_path / 'out' / 'calibration_1'}")
    assert output_directory(outcome(True, files)) == str(tmp_path / "out" / "calibration_1")


def test_calibrate_message_says_when_estimates_are_withheld():
    files = {"result": "/r/calibration_2/result.yaml"}
    msg = calibrate_message(outcome(False, files), output_config(), published=False)
    assert msg.split("; ")[0] == "NOT certified: not_tight"  # the first part stays the verdict
    assert "not published on /tf_static" in msg and msg.endswith("files in /r/calibration_2")
    # publish_tf off: nothing to say about /tf_static
    msg = calibrate_message(outcome(False, files), output_config(publish_tf=False),
                            published=False)
    assert "tf_static" not in msg


def test_calibrate_message_without_solution_or_files():
    msg = calibrate_message(outcome(None), output_config(), published=False)
    assert msg == "not enough data: 0 pairs on 0 edges; all data kept"
    assert output_directory(outcome(None)) is None


def test_save_dataset_message_is_absolute(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert save_dataset_message("a/dataset.yaml") == (
        f"data set written: {tmp_path / 'a' / 'dataset.yaml'}")
