"""The simulated rig, its sensor stream and its recording as a rosbag2 file (no ROS needed).

* :mod:`.rig`: the scene (:class:`SimulatedRig`, :func:`demo_rig`) and the demo's topic names;
* :mod:`.stream`: its sensor stream in stamp order (:func:`simulated_stream`), as the CLI's
  ``demo`` and the simulator node consume it;
* :mod:`.bag`: that stream as the messages ``rwhec_demo_sim`` publishes
  (:func:`simulation_messages`) and recorded into a bag (:func:`write_simulated_bag`).
"""

from .bag import simulation_messages, write_simulated_bag
from .rig import (
    DEMO_POSE_TOPIC,
    DEMO_RIG_FRAME,
    DEMO_WORLD_FRAME,
    SimulatedRig,
    Trajectory,
    demo_camera_topics,
    demo_rig,
)
from .stream import SimulatedSample, simulated_stream

__all__ = [
    "DEMO_POSE_TOPIC",
    "DEMO_WORLD_FRAME",
    "DEMO_RIG_FRAME",
    "demo_camera_topics",
    "Trajectory",
    "SimulatedRig",
    "demo_rig",
    "SimulatedSample",
    "simulated_stream",
    "simulation_messages",
    "write_simulated_bag",
]
