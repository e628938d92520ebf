"""Deprecated path, kept for one release: the SDP relaxation (``SdpOptions``, ...) is
:mod:`rwhec_ros.core.certify.relaxation`.

Import from there; this module only re-exports its public names.
"""

from .certify.relaxation import *  # noqa: F403
from .certify.relaxation import __all__  # noqa: F401
