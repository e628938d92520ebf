"""What the dense and the large-problem paths share: the cost floor, the numerical failures that
become ``solver_failed``, and how a result and a failed certificate are built."""

from __future__ import annotations

import numpy as np
import scipy.sparse.linalg

from ..lie import make_transform
from ..result import CalibrationResult, Certificate, Status
from .options import SolveOptions

__all__ = ["COST_FLOOR_REL", "NUMERICAL_ERRORS", "calibration_result", "failed_certificate"]

#: Costs below this fraction of the largest entry of ``Q'`` count as zero (noise-free data).
COST_FLOOR_REL = 1e-4

#: Exceptions of the numerical back ends that become the status ``solver_failed``.
NUMERICAL_ERRORS: tuple[type[BaseException], ...] = (
    np.linalg.LinAlgError,
    scipy.sparse.linalg.ArpackError,
    scipy.sparse.linalg.ArpackNoConvergence,
    ArithmeticError,
)


def calibration_result(prep, est, cert: Certificate, mode: str, solver_status: str,
                       moved: float, notes: list[str]) -> CalibrationResult:
    """The result for the estimate ``est`` (rotations, translations and scale) of the problem that
    ``prep`` (either path's prepared data: ``problem`` and ``timing``) holds."""
    T = make_transform(est.R, est.t)
    M = prep.problem.M
    res = CalibrationResult(
        x_names=prep.problem.x_names,
        y_names=prep.problem.y_names,
        X=T[:M],
        Y=T[M:],
        scale=float(est.alpha),
        certificate=cert,
        mode=mode,
        timing_s=dict(prep.timing),
        solver_status=solver_status,
        rounding_displacement=moved,
        notes=notes,
    )
    return res


def failed_certificate(options: SolveOptions, cost: float, message: str) -> Certificate:
    """A ``solver_failed`` certificate for an estimate of cost ``cost``; ``message`` says why."""
    return Certificate(Status.SOLVER_FAILED, float(cost), float("nan"), float("nan"),
                       float("nan"), np.zeros(0), -1, options.certificate.rho_tol, message)

