"""The generated ``static_transforms.launch.py`` read by a real ROS 2 ``ros2 launch``: it loads,
and every node is tf2_ros's ``static_transform_publisher`` with the flags it takes since Humble
(``--x --y --z --qx --qy --qz --qw --frame-id --child-frame-id``), the transform's values and the
frame names. (The test Jazzy has no tf2_ros C++ package: the nodes are printed, not run.)"""

from __future__ import annotations

import re
import shutil
import subprocess

import numpy as np
import pytest

pytest.importorskip("rclpy")
pytest.importorskip("launch_ros")

from rwhec_ros.core.lie import make_transform, so3_exp, transform_to_quat_xyzw  # noqa: E402
from rwhec_ros.session.outputs import static_transforms_launch  # noqa: E402


def test_the_generated_launch_file_loads_in_ros2_launch(tmp_path):
    if shutil.which("ros2") is None:
        pytest.skip("no ros2 command (source a ROS 2 Jazzy)")
    frames = [("base_link", "cam0_optical", make_transform(so3_exp(np.array([0.1, -2.0, 0.3])),
                                                           [0.12, -0.5, 1e-7])),
              ("world", "tag 7/board", make_transform(so3_exp(np.array([3.1, 0.0, 0.0])),
                                                      [-3.0, 2.5, 0.0]))]
    path = tmp_path / "static_transforms.launch.py"
    path.write_text(static_transforms_launch(
        frames, header="GOOD: certified \u00b1 1.2 mm \"quoted\"\nleft out: none"))
    out = subprocess.run(["ros2", "launch", "--print", str(path)], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
    nodes = [line for line in out.stdout.splitlines()
             if "ExecInPkg(pkg='tf2_ros', exec='static_transform_publisher')" in line]
    assert len(nodes) == len(frames), out.stdout
    for line, (parent, child, T) in zip(nodes, frames, strict=True):
        ours = line.split("'--ros-args'")[0]  # launch_ros appends the node's name remap
        flags = dict(re.findall(r"'(--[a-z-]+)', '([^']*)'", ours))
        assert set(flags) == {"--x", "--y", "--z", "--qx", "--qy", "--qz", "--qw", "--frame-id",
                              "--child-frame-id"}, line
        assert (flags["--frame-id"], flags["--child-frame-id"]) == (parent, child)
        q, t = transform_to_quat_xyzw(T)
        got_t = [float(flags[k]) for k in ("--x", "--y", "--z")]
        got_q = [float(flags[k]) for k in ("--qx", "--qy", "--qz", "--qw")]
        assert got_t == pytest.approx(list(t), abs=1e-15)
        assert got_q == pytest.approx(list(q), abs=1e-15)
