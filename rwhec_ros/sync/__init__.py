"""rwhec_ros.sync: pose buffers, SE(3) interpolation, pairing of poses with image stamps."""

from .accumulator import PairAccumulator
from .buffer import LookupStatus, PoseBuffer
from .edge_pairs import DatasetEdge
from .interpolation import interpolate_se3, se3_exp, se3_log

__all__ = [
    "DatasetEdge",
    "LookupStatus",
    "PairAccumulator",
    "PoseBuffer",
    "interpolate_se3",
    "se3_exp",
    "se3_log",
]
