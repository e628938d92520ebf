"""Deprecated path, kept for one release: the seeded generators of synthetic data are
:mod:`rwhec_ros.simulation.synthetic`.

Import from there; this module only re-exports its public names.
"""

from ..simulation.synthetic import *  # noqa: F403
from ..simulation.synthetic import __all__  # noqa: F401
