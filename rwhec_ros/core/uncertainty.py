"""Deprecated path, kept for one release: the uncertainty of every frame is
:mod:`rwhec_ros.core.analysis.uncertainty`.

Import from there; this module only re-exports its public names.
"""

from .analysis.uncertainty import *  # noqa: F403
from .analysis.uncertainty import __all__  # noqa: F401
