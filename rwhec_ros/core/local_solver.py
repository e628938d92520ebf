"""Deprecated path, kept for one release: the local solver (``LocalSolverOptions``, ...) is
:mod:`rwhec_ros.core.local.dense`.

Import from there; this module only re-exports its public names.
"""

from .local.dense import *  # noqa: F403
from .local.dense import __all__  # noqa: F401
