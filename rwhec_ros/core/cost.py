"""Deprecated path, kept for one release: the cost is :mod:`rwhec_ros.core.model.cost` and its
Schur reduction :mod:`rwhec_ros.core.model.reduction`.

Import from there; this module only re-exports their public names.
"""

from .model import cost as _cost
from .model import reduction as _reduction
from .model.cost import *  # noqa: F403
from .model.reduction import *  # noqa: F403

__all__ = [*_cost.__all__, *_reduction.__all__]
