"""Deprecated path, kept for one release: the gauge fix is :mod:`rwhec_ros.core.model.gauge`.

Import from there (``GaugeOptions``, ``TranslationPrior``, ...); this module only re-exports its
public names.
"""

from .model.gauge import *  # noqa: F403
from .model.gauge import __all__  # noqa: F401
