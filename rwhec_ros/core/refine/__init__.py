"""The corner-level refinement: the certified pose-level optimum refined on the detected corners.

The certified solve is the global optimum of the paper's pose-level model (every camera-target
pose ``B`` with isotropic noise). A pose from a planar target is nothing like isotropic -- its
depth and tilt are far less precise than its lateral position -- and users judge a calibration by
its overlay on their images. After the certified solve, when the data keep their corners and the
cameras' intrinsics, this stage refines ``X``, ``Y`` (and an unknown scale) on the reprojection
error of every kept corner through the pose stream's pose at each image stamp and each camera's
projection with its distortion, started from the certified optimum:

* :mod:`.views` -- the corners as flat arrays, grouped by pose sample;
* :mod:`.model` -- the measurement model (with each pose sample's error) and its Jacobians;
* :mod:`.normal` -- Gauss-Newton on the block structure, the pose errors eliminated;
* :mod:`.fit` -- the fits, the noise estimated from the residuals, the covariances;
* :mod:`.estimate` -- the entry point :func:`refine_views` (which fit is kept and why);
* :mod:`.decision` -- which estimate is published, certified or refined, and why.

Nothing here is certified: :data:`SCOPE` says what the certificate covers once a refinement is
published.
"""

from .decision import Decision, DecisionOptions, decide
from .estimate import (
    MODELS,
    SCOPE,
    PoseLevelFit,
    Refinement,
    RefinementFailed,
    RefineOptions,
    refine_views,
)
from .views import CornerViews, corner_views

__all__ = ["CornerViews", "corner_views", "RefineOptions", "Refinement", "RefinementFailed",
           "refine_views", "SCOPE", "MODELS", "PoseLevelFit", "Decision", "DecisionOptions",
           "decide"]
