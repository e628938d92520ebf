"""Options and results of the calibration solvers (documented dataclasses, a status enum)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import Enum

import numpy as np

from .lie import rotation_distance, transform_to_quat_xyzw

__all__ = ["Status", "Certificate", "CalibrationResult"]


class Status(str, Enum):
    """Outcome of a solve. "Not certified" is a status, never an exception.

    Only CERTIFIED_OPTIMAL claims global optimality; every other status says why not, and the
    estimate is still returned (use it only as the message says).
    """

    #: Relative suboptimality bound below tolerance (a bound that holds in floating point) AND a
    #: one-dimensional null space of Z.
    CERTIFIED_OPTIMAL = "certified_optimal"
    #: The dual certificate does not prove optimality (gap too large or Z has a larger null
    #: space / negative eigenvalue): the relaxation is not tight at this solution.
    NOT_TIGHT = "not_tight"
    #: The data do not determine the answer: a translation component (or the scale, or a rotation)
    #: is unobservable, or an unknown scale came out <= the positive floor. The message names the
    #: frames and the direction; an unobservable translation is set by the documented default
    #: (or a prior) and the rest may still be the certified optimum (see the message).
    NOT_IDENTIFIABLE = "not_identifiable"
    #: The numbers cannot establish a rigorous bound (e.g. a translation block too ill-conditioned
    #: for the Schur reduction, or a reduced cost that disagrees with the direct cost).
    ILL_CONDITIONED = "ill_conditioned"
    #: The conic solver did not reach its tolerances; numbers are reported but prove nothing.
    SOLVER_INACCURATE = "solver_inaccurate"
    #: A numerical solver failed outright (exception or no solution); the closed-form or local
    #: estimate is returned, see the message.
    SOLVER_FAILED = "solver_failed"
    #: A local solution without any certificate (mode ``local``).
    LOCAL_ONLY = "local_only"


def rounding_decides(status: str, rho: float, tolerance: float, primal_cost: float,
                     dual_bound: float, null_space_dim: int, margins: dict) -> bool:
    """:attr:`Certificate.rounding_decides` from its fields as the result YAML's
    ``certificate`` section holds them (``status`` as its value, e.g. ``"not_tight"``)."""
    rho = float("nan") if rho is None else float(rho)
    if status != Status.NOT_TIGHT.value or int(null_space_dim) != 1 or not (
            np.isfinite(rho) and rho > tolerance):
        return False
    denom = (float(primal_cost) - float(dual_bound)) / rho  # max(d, cost floor) of eq. (73)
    rounding = float(margins.get("rounding", 0.0)) + float(margins.get("schur", 0.0))
    return bool(rounding > tolerance * denom)


@dataclass
class Certificate:
    """Global-optimality certificate of a solution (paper Section 9.3, eq. (71)-(73)).

    Attributes
    ----------
    status : Status
    primal_cost : float
        ``p``: objective of the returned (feasible) solution, eq. (33) with the 1/2.
    dual_bound : float
        ``d``: rigorous lower bound on the global optimum,
        ``lambda_s + min(0, lambda_min(Z)) (3 (M + P) + 1)``.
    suboptimality_bound : float
        ``rho_hat = (p - d) / max(d, cost_floor)`` (eq. (73), with a floor for noise-free data
        whose optimum is 0: the floor is ``1e-4`` of the largest entry of ``Q'``); ``nan`` when
        no dual bound exists.
    lambda_min : float
        Smallest eigenvalue of ``Z(lambda)`` (scaled problem units).
    eigenvalues : ndarray
        The smallest few eigenvalues of ``Z(lambda)`` (scaled problem units); a tight relaxation
        shows one (near-)zero followed by clearly positive values.
    null_space_dim : int
        Number of eigenvalues of ``Z`` at or below ``eig_tol``.
    tolerance : float
        The ``rho_hat`` tolerance used for ``CERTIFIED_OPTIMAL``.
    message : str
        Human-readable explanation of the status.
    lambda_min_lower : float
        Proven lower bound on ``lambda_min(Z)`` (scaled units) used in ``dual_bound``.
    margins : dict of str to float
        What the rounding analysis subtracted from ``lambda_s`` (unscaled cost units):
        ``eigenvalue``, ``rounding``, ``schur`` (see :mod:`rwhec_ros.core.certify.dense`).
    cost_floor : float
        The cost regarded as zero at the scale of the data (unscaled): ``rho_hat``'s denominator
        is ``max(d, cost_floor)``; ``nan`` where no bound was computed.
    weights : str
        The weights of the problem certified: ``"given"`` (the per-pair ``sigma``/``kappa`` as
        the problem states them) or ``"estimated"`` (from the data's residuals,
        :func:`rwhec_ros.core.noise.solve_with_noise`).
    """

    status: Status
    primal_cost: float
    dual_bound: float
    suboptimality_bound: float
    lambda_min: float
    eigenvalues: np.ndarray
    null_space_dim: int
    tolerance: float
    message: str = ""
    lambda_min_lower: float = float("nan")
    margins: dict = field(default_factory=dict)
    cost_floor: float = float("nan")
    weights: str = "given"

    @property
    def certified(self) -> bool:
        return self.status is Status.CERTIFIED_OPTIMAL

    def with_bounds(self, primal_cost: float, dual_bound: float, why: str,
                    margin: tuple[str, float] | None = None) -> Certificate:
        """This certificate with another ``p`` (a proven upper bound on the cost of the estimate
        that is returned) and ``d`` (a proven lower bound on the optimum), e.g. of the same
        problem solved about another origin (:mod:`rwhec_ros.core.model.recentre`): ``rho_hat``
        recomputed with the same cost floor, and a certificate whose ``rho_hat`` then exceeds
        the tolerance is ``not_tight``, with ``why`` (what the new bounds are) in its message.
        Other statuses keep theirs (new bounds cannot prove more than the old ones did; ``rho_hat``
        in the message is updated). ``margin`` ``(name, value)``: what the new ``d`` subtracted,
        added to :attr:`margins`."""
        p, d = float(primal_cost), float(dual_bound)
        floor = float(self.cost_floor)
        denom = max(d, floor) if np.isfinite(floor) else float("nan")
        rho = (p - d) / denom if np.isfinite(d) and np.isfinite(denom) and denom > 0 \
            else float("nan")
        old = f"rho_hat={self.suboptimality_bound:.3g}"
        message = self.message.replace(old, f"rho_hat={rho:.3g}")
        status = self.status
        if status is Status.CERTIFIED_OPTIMAL and not rho <= self.tolerance:
            status = Status.NOT_TIGHT
            message = (f"not certified: rho_hat={rho:.3g} > {self.tolerance:g} with {why} "
                       f"(p={p:.10g}, d={d:.10g})")
        margins = dict(self.margins)
        if margin is not None:
            margins[margin[0]] = float(margin[1])
        return replace(self, primal_cost=p, dual_bound=d, suboptimality_bound=rho, status=status,
                       message=message, eigenvalues=np.array(self.eigenvalues, copy=True),
                       margins=margins)

    @property
    def rounding_decides(self) -> bool:
        """Not certified on the bound alone (one-dimensional null space, ``rho_hat`` above the
        tolerance) while the bound's rounding terms (``margins`` ``rounding`` + ``schur``) by
        themselves exceed the gap the tolerance allows: the floating-point error at the data's
        scale, not the optimisation, keeps the certificate open."""
        return rounding_decides(self.status.value, self.suboptimality_bound, self.tolerance,
                                self.primal_cost, self.dual_bound, self.null_space_dim,
                                self.margins)

    @staticmethod
    def local_only(
        primal_cost: float, message: str = "local solution, not certified"
    ) -> Certificate:
        return Certificate(
            status=Status.LOCAL_ONLY,
            primal_cost=float(primal_cost),
            dual_bound=float("nan"),
            suboptimality_bound=float("nan"),
            lambda_min=float("nan"),
            eigenvalues=np.zeros(0),
            null_space_dim=-1,
            tolerance=float("nan"),
            message=message,
        )


@dataclass
class CalibrationResult:
    """Estimated extrinsics with their certificate.

    Attributes
    ----------
    x_names, y_names : tuple of str
    X : ndarray, shape (M, 4, 4)
        ``X_j`` in metric units (``A X_j = Y_k B``).
    Y : ndarray, shape (P, 4, 4)
    scale : float
        ``alpha`` (1.0 for known scale): B translations are ``alpha`` times metric ones.
    certificate : Certificate
    mode : str
        ``sdp``, ``fast`` or ``local``.
    timing_s : dict of str to float
        Seconds per phase (``build``, ``compile``, ``solve``, ``extract``, ``certify``, ...).
    solver_status : str
        Status string of the underlying numerical solver.
    rounding_displacement : float
        Largest Frobenius distance by which the final projection onto SO(3) moved a rotation
        block of the extracted (normalised) null vector; ~0 when the relaxation is tight.
    notes : list of str
        Anything the user should know (fallbacks, dropped edges, ...).
    unobservable : list
        :class:`~rwhec_ros.core.model.gauge.UnobservableDirection` s: translation directions the
        data do not determine, with how each was fixed (prior or default) and its value.
    noise : NoiseEstimate or None
        The noise per group estimated from the data whose weights this solve used
        (:func:`rwhec_ros.core.noise.solve_with_noise`; ``certificate.weights`` is then
        ``"estimated"``); None: the problem's given weights.
    """

    x_names: tuple[str, ...]
    y_names: tuple[str, ...]
    X: np.ndarray
    Y: np.ndarray
    scale: float
    certificate: Certificate
    mode: str
    timing_s: dict[str, float] = field(default_factory=dict)
    solver_status: str = ""
    rounding_displacement: float = 0.0
    notes: list[str] = field(default_factory=list)
    unobservable: list = field(default_factory=list)
    noise: object = None

    @property
    def certified(self) -> bool:
        return self.certificate.certified

    def transform(self, name: str) -> np.ndarray:
        """The 4x4 estimate of the frame called ``name``."""
        if name in self.x_names:
            return self.X[self.x_names.index(name)]
        if name in self.y_names:
            return self.Y[self.y_names.index(name)]
        raise KeyError(f"no frame named {name!r}; have {list(self.x_names + self.y_names)}")

    def frames(self) -> list[dict]:
        """One mapping per frame: name, role (X or Y), matrix, translation, quaternion_xyzw."""
        out = []
        for role, names, Ts in (("X", self.x_names, self.X), ("Y", self.y_names, self.Y)):
            for name, T in zip(names, Ts, strict=False):
                q, t = transform_to_quat_xyzw(T)
                out.append(
                    {
                        "name": name,
                        "role": role,
                        "matrix": np.asarray(T).tolist(),
                        "translation": t.tolist(),
                        "quaternion_xyzw": q.tolist(),
                    }
                )
        return out

    def errors_to(self, X_true: np.ndarray, Y_true: np.ndarray) -> dict[str, np.ndarray]:
        """Per-frame translation [m] and rotation [rad] errors against ground truth."""
        return {
            "t_x": np.linalg.norm(self.X[:, :3, 3] - X_true[:, :3, 3], axis=1),
            "r_x": rotation_distance(self.X[:, :3, :3], X_true[:, :3, :3]),
            "t_y": np.linalg.norm(self.Y[:, :3, 3] - Y_true[:, :3, 3], axis=1),
            "r_y": rotation_distance(self.Y[:, :3, :3], Y_true[:, :3, :3]),
        }

    def to_dict(self) -> dict:
        """Plain-Python mapping with the acceptance keys of the result YAML."""
        c = self.certificate
        return {
            "certified": bool(self.certified),
            "status": c.status.value,
            "suboptimality_bound": float(c.suboptimality_bound),
            "scale": float(self.scale),
            "mode": self.mode,
            "frames": self.frames(),
            "timing_s": {k: float(v) for k, v in self.timing_s.items()},
            "certificate": {
                "primal_cost": float(c.primal_cost),
                "dual_bound": float(c.dual_bound),
                "lambda_min": float(c.lambda_min),
                "smallest_eigenvalues": [float(v) for v in np.asarray(c.eigenvalues)],
                "null_space_dim": int(c.null_space_dim),
                "tolerance": float(c.tolerance),
                "lambda_min_lower": float(c.lambda_min_lower),
                "margins": {k: float(v) for k, v in c.margins.items()},
                "message": c.message,
                "weights": c.weights,
            },
            "unobservable": [u.to_dict() for u in self.unobservable],
            "solver_status": self.solver_status,
            "rounding_displacement": float(self.rounding_displacement),
            "notes": list(self.notes),
        }
