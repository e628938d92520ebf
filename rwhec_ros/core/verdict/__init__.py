"""The verdict of a calibration: ``good``, ``caution`` or ``unusable``, and why.

The modules, one concept each:

* :mod:`.options`: :class:`VerdictOptions`, every threshold a named, documented parameter;
* :mod:`.fit`: goodness of fit against the stated noise (a-posteriori variance factor with a
  chi-square test, globally and per edge; paper eq. (33));
* :mod:`.noise_check`: with the noise estimated from the data (:mod:`rwhec_ros.core.noise`), a
  stated noise against the estimate per group, a camera far noisier than the others, and the
  estimate's confidence in the precision check;
* :mod:`.scale_check`: a known-scale problem solved with an unknown scale (tag sizes, focal
  lengths, pose-stream units);
* :mod:`.focal_check`: the focal length each camera's detected corners (tags or boards)
  fit (data with corners);
* :mod:`.precision`: each frame's predicted standard deviation (today from the identifiability
  numeric check);
* :mod:`.model`: :class:`Reason`, :class:`FrameVerdict`, :class:`Verdict` and the builder that
  collects them; :mod:`.words`: numbers in words;
* :mod:`.reasons`: the checks (certificate, identifiability, frames without an estimate, scale,
  edges, fit, precision), each adding its reasons;
* :mod:`.verdict`: :func:`assess`, running the checks on a solution.
"""

from .fit import EdgeFit, FitStatistics, goodness_of_fit
from .focal_check import FocalCheck, focal_checks
from .options import LEVELS, VerdictOptions, worst_level
from .precision import FramePrecision, frame_precisions
from .scale_check import ScaleCheck, check_scale
from .verdict import FrameVerdict, Reason, Verdict, assess

__all__ = [
    "LEVELS",
    "VerdictOptions",
    "worst_level",
    "EdgeFit",
    "FitStatistics",
    "goodness_of_fit",
    "FocalCheck",
    "focal_checks",
    "ScaleCheck",
    "check_scale",
    "FramePrecision",
    "frame_precisions",
    "Reason",
    "FrameVerdict",
    "Verdict",
    "assess",
]
