"""Process-wide memory allocator settings of the long-running entry points (node, CLI).

The live re-solve (:mod:`rwhec_ros.session.live_solve`) allocates and frees a few dozen
temporaries of 300-400 KB each time (217 x 217 matrices). glibc's ``malloc`` serves blocks
above its ``mmap`` threshold with fresh ``mmap`` calls and returns freed memory at the top of
the heap to the system, so each re-solve on the paper's 16 x 8 data took ~625 minor page
faults to map the same memory again, about 1.5 ms of its ~22 ms (measured with
``resource.getrusage``; results unchanged). :func:`retain_freed_memory` raises the thresholds
with ``mallopt`` (the settings of the ``MALLOC_MMAP_THRESHOLD_``, ``MALLOC_TRIM_THRESHOLD_`` and
``MALLOC_TOP_PAD_`` environment variables, as real-time ROS 2 guides advise for the same reason):
the process keeps up to :data:`TRIM_THRESHOLD_BYTES` of freed memory for reuse instead of
returning it at once. It is called at the start of the console scripts (``calibrator`` and
``rwhec_demo_sim`` through :func:`rwhec_ros.ros.process.rclpy_main`, ``rwhec-calibrate``),
never by the library, since it changes the whole process.
"""

from __future__ import annotations

import ctypes
import functools

__all__ = ["retain_freed_memory", "MMAP_THRESHOLD_BYTES", "TRIM_THRESHOLD_BYTES",
           "TOP_PAD_BYTES"]

#: Blocks up to this size come from the heap (reused), not from a fresh ``mmap`` each time.
MMAP_THRESHOLD_BYTES = 4 * 1024 * 1024
#: Freed memory at the top of the heap is returned to the system only above this much.
TRIM_THRESHOLD_BYTES = 64 * 1024 * 1024
#: Extra memory requested whenever the heap grows.
TOP_PAD_BYTES = 16 * 1024 * 1024

# mallopt parameters (glibc <malloc.h>)
_M_TRIM_THRESHOLD = -1
_M_TOP_PAD = -2
_M_MMAP_THRESHOLD = -3


@functools.cache
def retain_freed_memory() -> bool:
    """Raise glibc's ``mmap`` and trim thresholds and the top pad (module docstring).

    Returns True when ``mallopt`` accepted all three settings; False where there is no glibc
    ``mallopt`` (musl, macOS, Windows): nothing changes there. Done once per process (later
    calls return the first answer).
    """
    try:  # the symbols the interpreter is linked with: glibc's mallopt on Linux
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError, TypeError):  # TypeError: Windows has no CDLL(None)
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    return all(mallopt(param, value) == 1 for param, value in (
        (_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES),
        (_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES),
        (_M_TOP_PAD, TOP_PAD_BYTES)))
