"""``rwhec-calibrate``: offline calibration from files, rosbag2 recordings and a simulation.

No ROS is needed. Every solving subcommand prints the summary of the node's ``calibrate`` service
(the verdict first, then the certificate, each usable frame's estimate ``parent->child`` or ``NOT
CALIBRATED (why)``, edges excluded and why) and
writes the session's output files into one directory: ``result.yaml`` (``certified``,
``suboptimality_bound``, ``scale``, ``frames``, ``timing_s``, ``identifiability``, ``config``,
...), ``static_transforms.launch.py`` (``static_transform_publisher`` nodes), ``dataset.yaml`` and,
with ``--report``, ``report.png``/``report.html`` (:mod:`rwhec_ros.report`). ``-o DIR`` names that
directory (existing files refused unless ``--force``); without it a new
``calibration_<UTC stamp>`` directory under the configuration's ``output.directory`` (else
``rwhec_output``). Every written file is printed as ``<what>: <path>``.

Subcommands (shared options: ``-o DIR``, ``--force``, ``--config FILE``, ``--node-name NAME``,
``--mode fast|sdp|local``, ``--min-pairs N``, ``--robust``, ``--report``, ``-q``)::

    rwhec-calibrate csv DIR [shared] [--sigma S] [--kappa K] [--unknown-scale]
                            [--camera-carrier FRAME] [--tag-carrier FRAME]
    rwhec-calibrate bag BAG --config FILE [shared]
    rwhec-calibrate samples DIR [shared] [--eye-in-hand | --eye-to-hand]
                            [--intrinsics [CAMERA=]FILE] [--layout NAME]
    rwhec-calibrate poses FILE [shared] [--eye-in-hand | --eye-to-hand] [--sigma S] [--kappa K]
                          [--unknown-scale]
    rwhec-calibrate dataset FILE [shared] [--camera-carrier FRAME] [--tag-carrier FRAME]
    rwhec-calibrate demo [shared] [--cameras N] [--tags N] [--seconds S] [--rate HZ] [--seed S]
    rwhec-calibrate report RESULT.yaml [--dataset FILE] [-o DIR] [--force]

``csv`` reads the paper's layout (:func:`rwhec_ros.data.paper_csv.read_paper_csv`; tags
``tag_<j>`` are X, cameras ``cam_<k>`` are Y; defaults sigma 0.1 m, kappa 125, 3 pairs per edge
as the authors). ``bag`` feeds a rosbag2 recording (sqlite3 or mcap) message by message, in log
time order, into a :class:`~rwhec_ros.session.CalibrationSession` through the node's
:class:`~rwhec_ros.session.handlers.MessageHandlers`, with the same configuration file as the node
(PoseStamped topic, or ``/tf`` + ``/tf_static`` looked up at each image stamp). Unlike the node,
images are processed synchronously (none is dropped) and the tf lookup sees the whole recording
(the node waits ``sync.tf_timeout_s``). ``samples``
feeds a folder of stop-and-go views (our manifest, industrial_calibration's and
camera_calibration_toolkit's folders; :mod:`.samples`) through the same session, ``poses`` solves
a list of robot and target-in-camera poses like ``csv`` (:mod:`.pose_list`); formats in
``docs/formats.md``. ``dataset`` solves a saved data set
(:mod:`rwhec_ros.data.dataset`). ``demo`` runs the simulated rig of :mod:`rwhec_ros.simulation`
through rendering, detection, synchronisation and the solver, and compares with the truth.

Every solving subcommand prints the verdict first (``GOOD: ...``, ``CAUTION: <reason>``,
``UNUSABLE: <reason>``; :mod:`rwhec_ros.core.verdict`). Exit codes: 0 a usable result (verdict
good or caution; files written); 2 bad input or output (the message names the file and line or
the parameter); 3 no solution (not enough data, the solver stopped with an error); 4 a result
whose verdict is unusable (files written, do not use it); 130 interrupted (Ctrl-C), 143
terminated (SIGTERM); 141 the output pipe closed. However a run ends, the pairs gathered are
kept: the data set is written as soon as reading ends, before the solve, and an interrupted or
failed run prints the ``rwhec-calibrate dataset ...`` command that resumes it
(:mod:`.run`; ``docs/robustness.md``).

Modules: :mod:`.parser` (options and help), :mod:`.common` (output rule, settings, solving),
:mod:`.run` (a run's phases, the data set kept, interrupts),
:mod:`.files` (``csv``, ``dataset``, ``report``), :mod:`.replay` (``bag``, ``demo``),
:mod:`.samples` (``samples``), :mod:`.pose_list` (``poses``),
:mod:`.main` (dispatch).
"""

from .common import (
    EXIT_BAD_INPUT,
    EXIT_INTERRUPTED,
    EXIT_NO_SOLUTION,
    EXIT_OK,
    EXIT_TERMINATED,
    EXIT_UNUSABLE,
)
from .main import main
from .parser import build_parser
from .replay import demo_parameters

__all__ = ["main", "build_parser", "demo_parameters", "EXIT_OK", "EXIT_BAD_INPUT",
           "EXIT_NO_SOLUTION", "EXIT_UNUSABLE", "EXIT_INTERRUPTED", "EXIT_TERMINATED"]
