"""Deprecated path, kept for one release: the local solver (``LocalSolverOptions``, ...) is
:mod:`rwhec_ros.core.local.dense`, the fast certificate's multipliers
:mod:`rwhec_ros.core.certify.multipliers`.

Import from there; this module only re-exports their public names.
"""

from .certify import multipliers as _multipliers
from .certify.multipliers import *  # noqa: F403
from .local import dense as _dense
from .local.dense import *  # noqa: F403

__all__ = [*_dense.__all__, *_multipliers.__all__]
