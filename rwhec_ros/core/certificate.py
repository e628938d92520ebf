"""Deprecated path, kept for one release: the dense certificate (``CertificateOptions``,
``certify``, ...) is :mod:`rwhec_ros.core.certify.dense`.

Import from there; this module only re-exports its public names.
"""

from .certify.dense import *  # noqa: F403
from .certify.dense import __all__  # noqa: F401
