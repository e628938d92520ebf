"""How many threads BLAS may use during a solve (one by default: see
:attr:`~rwhec_ros.core.pipeline.options.SolveOptions.blas_threads`)."""

from __future__ import annotations

import contextlib
import functools

from threadpoolctl import ThreadpoolController

__all__ = ["blas_threads"]


@functools.lru_cache(maxsize=1)
def _blas_controller() -> ThreadpoolController:
    """One controller per process: scanning the loaded libraries costs ~3 ms, limiting is cheap."""
    return ThreadpoolController()


def blas_threads(threads: int | None):
    """Context manager limiting BLAS to ``threads`` threads (``None``: leave it as it is); see
    :attr:`SolveOptions.blas_threads` for why one thread is the default everywhere. Nothing
    to do (no set and restore) when every BLAS already runs ``threads`` threads, e.g. nested
    inside a caller's limit."""
    if threads is None:
        return contextlib.nullcontext()
    ctl = _blas_controller()
    if all(lib.num_threads == threads for lib in ctl.select(user_api="blas").lib_controllers):
        return contextlib.nullcontext()
    return ctl.limit(limits=threads, user_api="blas")

