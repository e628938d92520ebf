"""rwhec_ros.sync: pose buffers, SE(3) interpolation, pairing of poses with image stamps."""

from .accumulator import EdgeData, PairAccumulator
from .buffer import LookupStatus, PoseBuffer
from .interpolation import interpolate_se3, se3_exp, se3_log

__all__ = [
    "EdgeData",
    "LookupStatus",
    "PairAccumulator",
    "PoseBuffer",
    "interpolate_se3",
    "se3_exp",
    "se3_log",
]
