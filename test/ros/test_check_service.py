"""The node's ``~/check`` service and its ``/diagnostics`` rows in-process (needs rclpy, i.e. a
sourced ROS 2 Jazzy; skipped otherwise).

The pairs are given to the node's session directly (the demo rig's visible tags along its
trajectory, the noise of its rendered PnP, camera cam1 moved by 8 mm): rendering and detection
are tested elsewhere; here the service, the reference (a frames.yaml, or the frames on tf), the
answer, the files, the re-estimated frame on ``/tf_static`` and the diagnostics rows are.
"""

from __future__ import annotations

import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml

rclpy = pytest.importorskip("rclpy")
pytest.importorskip("tf2_ros")

from diagnostic_msgs.msg import DiagnosticArray  # noqa: E402
from geometry_msgs.msg import TransformStamped  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy  # noqa: E402
from test_node import call, overrides, spinning, wait_for  # noqa: E402
from tf2_msgs.msg import TFMessage  # noqa: E402

from rwhec_ros.core.lie import invert_transform, make_transform  # noqa: E402
from rwhec_ros.data.export import frames_yaml  # noqa: E402
from rwhec_ros.messages import fill_message, transform_to_transform_stamped_fields  # noqa: E402
from rwhec_ros.simulation import demo_rig  # noqa: E402
from rwhec_ros.simulation.synthetic import perturb_measurements  # noqa: E402

NS = 1_000_000_000
SIGMA, KAPPA = 0.0005, 1.0 / (2.0 * np.radians(0.17) ** 2)


def _cam1_moved(rig):
    import dataclasses

    T = rig.T_rig_cam["cam1"]
    moved = make_transform(T[:3, :3], T[:3, 3] + np.array([0.008, 0.0, 0.0]))
    return dataclasses.replace(rig, T_rig_cam={**rig.T_rig_cam, "cam1": moved})


def _feed(session, rig, seconds: float, seed: int = 0) -> int:
    """Offer the visible (camera, tag) pairs at 5 Hz to the session, as its image path does."""
    rng = np.random.default_rng(seed)
    n = 0
    for i, t in enumerate(np.arange(0.0, seconds, 0.2)):
        T_world_rig = rig.T_world_rig(t)
        A = invert_transform(T_world_rig)
        for cam in rig.cameras:
            obs = []
            for tag in rig.visible_tags(cam, T_world_rig):
                B = perturb_measurements(rng, tag.T_cam_tag[None], SIGMA, KAPPA)[0]
                obs.append(SimpleNamespace(name=f"tag_{tag.tag_id}", kind="tag",
                                           T_cam_target=B, image_points=None,
                                           object_points=None, sigma=None, kappa=None))
            if obs:
                with session._lock:
                    n += len(session._offer(cam, (i + 1) * NS // 5, A, obs))
    return n


def _reference_file(tmp_path: Path, rig) -> Path:
    items = [("rig", f"{c}_optical_calibrated", rig.T_rig_cam[c]) for c in rig.cameras]
    path = tmp_path / "reference_frames.yaml"
    path.write_text(frames_yaml(items))
    return path


def test_check_names_the_moved_camera_publishes_it_and_reports_on_diagnostics(context,
                                                                             tmp_path):
    rig = demo_rig(3, 6)
    params = overrides(tmp_path, **{"check.reference": str(_reference_file(tmp_path, rig)),
                                    "solver.live_period_s": 0.0})
    with spinning(context, params) as (node, helper, _):
        rows: list = []
        helper.create_subscription(DiagnosticArray, "/diagnostics",
                                   lambda m: rows.extend(m.status), 10)
        static: list = []
        latched = QoSProfile(depth=10, durability=DurabilityPolicy.TRANSIENT_LOCAL,
                             reliability=ReliabilityPolicy.RELIABLE)
        helper.create_subscription(TFMessage, "/tf_static",
                                   lambda m: static.extend(m.transforms), latched)
        response = call(helper, "/calibrator/check")  # no pairs yet
        assert response.success is False
        assert response.message.startswith("not enough data yet: 0 pairs")
        assert _feed(node.session, _cam1_moved(rig), 72.0) > 100
        response = call(helper, "/calibrator/check", timeout=120.0)
        lines = response.message.splitlines()
        assert response.success is False
        assert lines[0].startswith("CHECK MOVED: cam1: MOVED by"), response.message
        assert any(ln.startswith("cam0: ") for ln in lines)
        out = Path(lines[-1].removeprefix("output directory: "))
        doc = yaml.safe_load((out / "check.yaml").read_text())
        assert doc["check"]["updated"] == ["cam1"] and doc["check"]["look"] == 1
        assert (out / "frames.yaml").exists() and (out / "dataset.yaml").exists()
        # the re-estimated camera on /tf_static, about 8 mm from its reference
        assert wait_for(lambda: any(t.child_frame_id == "cam1_optical_calibrated"
                                    for t in static), timeout=10.0)
        t = next(t for t in static if t.child_frame_id == "cam1_optical_calibrated")
        p = np.array([t.transform.translation.x, t.transform.translation.y,
                      t.transform.translation.z])
        assert 0.006 < np.linalg.norm(p - rig.T_rig_cam["cam1"][:3, 3]) < 0.010
        assert t.header.frame_id == "rig"
        # one diagnostics row per camera: cam1 ERROR (moved)
        assert wait_for(lambda: any(r.name == "calibrator: check cam1" for r in rows),
                        timeout=10.0)
        cam1 = [r for r in rows if r.name == "calibrator: check cam1"][-1]
        assert cam1.level == bytes([2]) and cam1.message.startswith("MOVED by")
        summary = [r for r in rows if r.name == "calibrator: check"][-1]
        assert summary.message.startswith("CHECK MOVED")
        # the same data again: the same answer, no new look
        again = call(helper, "/calibrator/check", timeout=120.0)
        assert again.message.splitlines()[0] == lines[0]
        assert node._bringup._check.looks == 1


def test_check_against_the_frames_on_tf(context, tmp_path):
    rig = demo_rig(3, 6)
    params = overrides(tmp_path, **{"check.reference": "tf", "check.tf_frames": "sensor",
                                    "solver.live_period_s": 0.0})
    with spinning(context, params) as (node, helper, _):
        from tf2_ros import StaticTransformBroadcaster

        broadcaster = StaticTransformBroadcaster(helper)
        stamp = helper.get_clock().now().nanoseconds
        broadcaster.sendTransform([
            fill_message(TransformStamped(), transform_to_transform_stamped_fields(
                rig.T_rig_cam[c], "rig", f"{c}_optical", stamp)) for c in rig.cameras])
        time.sleep(1.0)
        _feed(node.session, rig, 72.0, seed=1)
        response = call(helper, "/calibrator/check", timeout=120.0)
        lines = response.message.splitlines()
        assert "CHECK MOVED" not in lines[0], response.message
        assert any("against tf" in ln for ln in lines), response.message
        for cam in rig.cameras:
            assert any(ln.startswith(f"{cam}: ") and "MOVED" not in ln for ln in lines)


def test_check_without_a_reference_says_how_to_set_one(context, tmp_path):
    with spinning(context, overrides(tmp_path)) as (node, helper, _):
        _feed(node.session, demo_rig(3, 6), 12.0)
        response = call(helper, "/calibrator/check")
        assert response.success is False
        assert "set check.reference" in response.message


def test_periodic_checks_fill_the_diagnostics_without_a_call(context, tmp_path):
    rig = demo_rig(3, 6)
    params = overrides(tmp_path, **{"check.reference": str(_reference_file(tmp_path, rig)),
                                    "check.period_s": 0.5, "solver.live_period_s": 0.0})
    with spinning(context, params) as (node, helper, _):
        rows: list = []
        helper.create_subscription(DiagnosticArray, "/diagnostics",
                                   lambda m: rows.extend(m.status), 10)
        assert wait_for(lambda: any(r.name == "calibrator: check" for r in rows), timeout=10.0)
        waiting = [r for r in rows if r.name == "calibrator: check"][-1]
        assert waiting.level == bytes([1]) and waiting.message.startswith("not enough data yet")
        _feed(node.session, rig, 24.0, seed=2)
        assert wait_for(lambda: any(r.name == "calibrator: check cam2" for r in rows),
                        timeout=120.0)
        assert node._bringup._check.looks >= 1
        assert not list((tmp_path).glob("check_*"))  # periodic looks write no files
