"""Deprecated path, kept for one release: the paper's simulation scenarios are
:mod:`rwhec_ros.simulation.scenarios`.

Import from there; this module only re-exports its public names.
"""

from ..simulation.scenarios import *  # noqa: F403
from ..simulation.scenarios import __all__  # noqa: F401
