"""rwhec_ros.sync: pose buffers, SE(3) interpolation, pairing of poses with image stamps."""

from .accumulator import PairAccumulator
from .buffer import LookupStatus, PoseBuffer
from .interpolation import interpolate_se3, se3_exp, se3_log

__all__ = [
    "LookupStatus",
    "PairAccumulator",
    "PoseBuffer",
    "interpolate_se3",
    "se3_exp",
    "se3_log",
]
