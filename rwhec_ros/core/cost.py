"""Deprecated path, kept for one release: the cost is :mod:`rwhec_ros.core.model.cost`.

Import from there; this module only re-exports its public names.
"""

from .model.cost import *  # noqa: F403
from .model.cost import __all__  # noqa: F401
