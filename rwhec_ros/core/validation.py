"""Deprecated path, kept for one release: cross-validation is
:mod:`rwhec_ros.core.analysis.validation`.

Import from there; this module only re-exports its public names.
"""

from .analysis.validation import *  # noqa: F403
from .analysis.validation import __all__  # noqa: F401
