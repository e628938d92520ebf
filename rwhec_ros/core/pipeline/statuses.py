"""The statuses the certificate alone cannot know, set after either path: translation directions
fixed by default, an unobservable scale, a non-positive unknown scale, a rotation the data do
not determine (:func:`check_identifiability`)."""

from __future__ import annotations

import numpy as np

from ..model.gauge import axis_words
from ..result import CalibrationResult, Status
from .common import NUMERICAL_ERRORS
from .options import SolveOptions

__all__ = ["check_identifiability"]


def _downgrade(res: CalibrationResult, status: Status, message: str) -> None:
    """Replace a certificate's status and message by a more specific one (keeping its numbers);
    the certified part, if any, is quoted in the message."""
    cert = res.certificate
    if cert.status in (Status.SOLVER_FAILED, Status.LOCAL_ONLY):
        res.notes.append(message)
        return
    if cert.status is Status.CERTIFIED_OPTIMAL:
        tail = (f" With that, the rest is certified optimal "
                f"(rho_hat={cert.suboptimality_bound:.3g}).")
    else:
        tail = f" [{cert.message}]"
    cert.message = message + tail
    cert.status = status


def check_identifiability(prep, options: SolveOptions,
                           res: CalibrationResult) -> None:
    """Statuses the certificate alone cannot know: translation directions fixed by default, an
    unobservable scale, a non-positive unknown scale, a rotation the data do not determine."""
    problem = prep.problem
    gauge = prep.gauge
    reasons: list[str] = []
    cert = res.certificate
    if not cert.certified and cert.null_space_dim > 1:
        words = _rotation_gauge_words(prep, res, options.certificate.null_tol)
        if words:
            reasons.append(words)
    if gauge is not None and not gauge.empty:
        t = np.concatenate([res.X, res.Y])[:, :3, 3].reshape(-1)
        translations = {name: T[:3, 3] for name, T in zip(
            problem.frame_names, np.concatenate([res.X, res.Y]), strict=True)}
        for d in gauge.directions:
            d.value_m = d.component_of(translations)
        res.unobservable = list(gauge.directions)
        words = "; ".join(d.describe(x_names=problem.x_names) for d in gauge.directions)
        if any(d.involves_scale for d in gauge.directions):
            reasons.append(words)
        elif gauge.pinned:
            res.notes.append(f"{words}: fixed by the given priors (certificate with the priors)")
            for p, row in gauge.prior_rows:
                got = float(row @ t)
                if abs(got - p.value_m) > 1e-4:
                    res.notes.append(f"prior {p.frame} {np.round(p.axis, 3).tolist()} = "
                                     f"{p.value_m:.4f} m: estimate {got:.4f} m (the priors "
                                     "disagree with each other or with the data)")
        else:
            reasons.append(f"{words}. It was set by default (the cameras' translations along it "
                           "are zero on average); give a prior for it (a known translation "
                           "component of one of these frames)")
    if problem.unknown_scale and not res.scale > options.min_scale:
        reasons.append(f"the estimated scale alpha = {res.scale:.4g} is not above the floor "
                       f"{options.min_scale:g}: the data do not determine the scale (too much "
                       "noise, outliers, or too little translation relative to the tags)")
    if reasons:
        _downgrade(res, Status.NOT_IDENTIFIABLE, "not identifiable: " + "; ".join(reasons) + ".")


def _rotation_gauge_words(prep, res: CalibrationResult, null_tol: float) -> str:
    """Words for rotation directions the data do not determine (near-null directions of the
    Riemannian Hessian of the reduced cost at the estimate, at a minimum), or ``""``."""
    R = np.concatenate([res.X, res.Y])[:, :3, :3]
    try:
        w, V = prep.hessian_eigenpairs(R, null_tol)
    except NUMERICAL_ERRORS:
        return ""
    # flat directions of the scaled cost: the Riemannian Hessian is ~4 Z on the tangent space
    # (|d vec(R w^)/d w|^2 = 2), so a second null direction of Z that is a rotation of the frames
    # shows as an eigenvalue of H within a few null_tol
    if w[0] < -10.0 * null_tol:  # a saddle point, not a flat minimum
        return ""
    weak = np.where(np.abs(w) <= 10.0 * null_tol)[0]
    names = prep.problem.frame_names
    parts = []
    for i in weak:
        v = V[:, i].reshape(-1, 3)
        frames = [f for f in range(len(names)) if np.linalg.norm(v[f]) >= 0.1]
        # right perturbation R exp(w^): the axis in the frame's parent is R w (sign canonical:
        # the largest component of the first frame's axis positive)
        par = [R[f] @ v[f] for f in frames]
        if par and par[0][int(np.argmax(np.abs(par[0])))] < 0:
            par = [-a for a in par]
        axes = {axis_words(a) for a in par}
        about = axes.pop() if len(axes) == 1 else "different axes"
        parts.append(f"rotation of {', '.join(names[f] for f in frames)} about {about} (in "
                     "their carriers) not determined by the data")
    return "; ".join(parts)
