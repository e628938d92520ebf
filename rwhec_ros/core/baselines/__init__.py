"""Baseline RWHEC solvers the paper compares against (Section 8), behind one interface.

Every baseline maps a validated :class:`~rwhec_ros.core.problem.Problem` (``A_i X_j = Y_k B_i``,
eq. (7)) to ``(X (M, 4, 4), Y (P, 4, 4), alpha)``; :func:`run_baseline` dispatches by name.

* ``shah`` / ``shah_direct``: Shah (2013), Kronecker product, via OpenCV (1X1Y, known scale;
  the two differ in how the data are handed to OpenCV, see below).
* ``li`` / ``li_direct``: Li, Wang and Wu (2010), dual quaternions, via OpenCV (1X1Y, known).
* ``tsai``, ``park``, ``horaud``, ``andreff``, ``daniilidis``: hand-eye ``AX = XB`` methods via
  OpenCV -- Tsai & Lenz (1989), Park & Martin (1994), Horaud & Dornaika (1995), Andreff et al.
  (1999), Daniilidis (1999); ``Y`` recovered afterwards (1X1Y, known).
* ``wang``: Wang et al. (2022), generalized closed form (any connected graph, known scale (+)).
* ``dornaika``: Dornaika & Horaud (1998), joint nonlinear least squares (any connected graph,
  known scale).
* ``lom``: LOM of the paper's Appendix A, :mod:`rwhec_ros.core.baselines.lom_solver` (any graph,
both scales).


Modules: :mod:`.opencv` (the OpenCV methods and how ``A X = Y B`` maps onto them),
:mod:`.wang2022`, :mod:`.dornaika` and :mod:`.registry` (:data:`BASELINES`, :func:`run_baseline`,
the LOM adapter).
"""

from .dornaika import dornaika1998, dornaika_cost
from .opencv import average_transforms, opencv_hand_eye, opencv_robot_world_hand_eye
from .registry import BASELINES, BaselineInfo, BaselineOutput, baseline_names, lom, run_baseline
from .wang2022 import translations_given_rotations, wang2022, wang2022_rotations

__all__ = [
    "BaselineInfo",
    "BASELINES",
    "baseline_names",
    "run_baseline",
    "average_transforms",
    "opencv_robot_world_hand_eye",
    "opencv_hand_eye",
    "wang2022",
    "wang2022_rotations",
    "translations_given_rotations",
    "dornaika1998",
    "dornaika_cost",
    "lom",
    "BaselineOutput",
]
