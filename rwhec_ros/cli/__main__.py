"""``python -m rwhec_ros.cli``: the same as ``rwhec-calibrate``."""

import sys

from .main import main

sys.exit(main())
