"""The options of :func:`rwhec_ros.core.solve.solve`: the mode, each stage's options and the
choice between the dense and the large-problem path."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..certify.dense import CertificateOptions
from ..certify.relaxation import SdpOptions
from ..local.dense import LocalSolverOptions
from ..model.gauge import GaugeOptions

__all__ = ["SolveOptions", "MODES", "FAST_FORMS"]

MODES = ("sdp", "fast", "local")
FAST_FORMS = ("auto", "dense", "sparse")


@dataclass
class SolveOptions:
    """Options of :func:`solve`.

    Attributes
    ----------
    mode : str
        ``"fast"`` (default), ``"sdp"`` or ``"local"``.
    sdp : SdpOptions
        Clarabel settings for the SDP.
    certificate : CertificateOptions
        Tolerances of the certificate.
    local : LocalSolverOptions
        Options of the local refinement.
    initial : tuple (X (M,4,4), Y (P,4,4)) or None
        Start for ``fast``/``local`` instead of the closed-form estimate (rotations are used).
    fallback_to_sdp : bool
        In ``fast`` mode, run the SDP when the fast certificate is inconclusive (True).
    blas_threads : int or None
        BLAS threads during the solve (default 1). Multi-threaded BLAS only added contention in
        every measurement on the 2-core target machines (real 16x8 data: 24 ms single-threaded
        vs. 60-600 ms with two threads on a busy machine; 100 cameras: 1.9 s vs. 9.1 s); ``None``
        leaves the BLAS library's own setting.
    gauge : GaugeOptions
        When a translation direction counts as unobservable, and the user's priors that fix such
        directions (:mod:`rwhec_ros.core.model.gauge`).
    min_scale : float
        Unknown scale only: an estimate ``alpha`` at or below this positive floor (0.01: tags 100
        times smaller than their nominal size) is never certified -- the data do not determine
        the scale (noise, outliers, too little translation).
    fast_form : str
        How ``fast`` and ``local`` represent the problem: ``"dense"`` (the reduced ``Q'`` of eq.
        (48)), ``"sparse"`` (the unreduced sparse cost and certificate of
        :mod:`rwhec_ros.core.pipeline.sparse`, for large rigs) or ``"auto"`` (default: sparse from
        :data:`~rwhec_ros.core.pipeline.sparse.SPARSE_MIN_FRAMES` frames when the camera-tag graph
        keeps a sparse factorisation sparse).
    sdp_fallback_max_frames : int
        On the sparse path, an inconclusive certificate is followed by the dense path (and its SDP
        fallback) only up to this many frames (400); above, the uncertified result is returned
        with a note (the dense path would need minutes and gigabytes).
    """

    mode: str = "fast"
    sdp: SdpOptions = field(default_factory=SdpOptions)
    certificate: CertificateOptions = field(default_factory=CertificateOptions)
    local: LocalSolverOptions = field(default_factory=LocalSolverOptions)
    initial: tuple[np.ndarray, np.ndarray] | None = None
    fallback_to_sdp: bool = True
    blas_threads: int | None = 1
    gauge: GaugeOptions = field(default_factory=GaugeOptions)
    min_scale: float = 0.01
    fast_form: str = "auto"
    sdp_fallback_max_frames: int = 400

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"mode: expected one of {MODES}, got {self.mode!r}")
        if self.fast_form not in FAST_FORMS:
            raise ValueError(f"fast_form: expected one of {FAST_FORMS}, got {self.fast_form!r}")
        if int(self.sdp_fallback_max_frames) < 0:
            raise ValueError(f"sdp_fallback_max_frames: must be >= 0, got "
                             f"{self.sdp_fallback_max_frames!r}")
        if not (np.isfinite(self.min_scale) and self.min_scale > 0):
            raise ValueError(f"min_scale: must be finite and > 0, got {self.min_scale!r}")
