"""The simulated rig, its sensor stream and its recording as a rosbag2 file (no ROS needed).

* :mod:`.rig`: the scene (:class:`SimulatedRig`, :func:`demo_rig`) and the demo's topic names;
* :mod:`.stream`: its sensor stream in stamp order (:func:`simulated_stream`), as the CLI's
  ``demo`` and the simulator node consume it;
* :mod:`.bag`: that stream as the messages ``rwhec_demo_sim`` publishes
  (:func:`simulation_messages`) and recorded into a bag (:func:`write_simulated_bag`);
* :mod:`.synthetic` and :mod:`.scenarios`: seeded ``(Problem, GroundTruth)`` generators at the
  level of the solver's input -- random rigs and the paper's noise model, and the paper's Section
  8 scenarios (import them from their modules; they are not re-exported here).
"""

from . import bag, rig, stream
from .bag import *  # noqa: F403 - simulation_messages, write_simulated_bag
from .rig import *  # noqa: F403 - the scene and the demo's names, listed in rig.__all__
from .stream import *  # noqa: F403 - SimulatedSample, simulated_stream

__all__ = [*rig.__all__, *stream.__all__, *bag.__all__]
