"""Deprecated path, kept for one release: LOM, the paper's Appendix A solver (a baseline), is
:mod:`rwhec_ros.core.baselines.lom_solver`.

Import from there; this module only re-exports its public names.
"""

from .baselines.lom_solver import *  # noqa: F403
from .baselines.lom_solver import __all__  # noqa: F401
