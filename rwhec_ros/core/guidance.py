"""Deprecated path, kept for one release: the next-motion guidance is
:mod:`rwhec_ros.core.analysis.guidance`.

Import from there; this module only re-exports its public names.
"""

from .analysis.guidance import *  # noqa: F403
from .analysis.guidance import __all__  # noqa: F401
