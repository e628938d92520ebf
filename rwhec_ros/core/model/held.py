"""Frames held at known values: the reference as pseudo-measurements of an ordinary problem.

A bring-up check (:mod:`rwhec_ros.session.bringup`) solves with some frames *held* at the values
of a stored calibration, e.g. the cameras that passed the check while a moved camera is
re-estimated. The certified solver (:func:`rwhec_ros.core.solve.solve`) knows no fixed
variables, so the held values enter as **pseudo-measurements** in the paper's own form
``A_i X_j = Y_k B_i`` (eq. (7)) and the augmented problem is solved and certified like any other:
the certificate is for the MAP problem "the data's negative log-likelihood (eq. (33)) plus these
pseudo-measurements", nothing else.

Two anchor frames ``X_a`` (:data:`ANCHOR_X`) and ``Y_a`` (:data:`ANCHOR_Y`) are added and tied
to the identity by the edge ``(X_a, Y_a)`` with the pairs ``A = B = G`` for ``G`` in
``{I, R_x(90 deg), R_y(90 deg), R_z(90 deg)}``: ``G X_a = Y_a G`` for these ``G`` holds only for
``X_a = Y_a = I`` (``G = I`` gives ``X_a = Y_a``, then ``X_a`` commutes with rotations about
three axes, so its rotation is ``I`` and its translation is fixed by ``(R_G - I) t = 0``). Then

* a held X frame (tag) ``j`` with value ``X_ref`` gets one pair on ``(X_j, Y_a)``:
  ``A = X_ref^-1``, ``B = I``, i.e. ``X_ref^-1 X_j = Y_a B`` (``X_j = X_ref`` at ``Y_a = I``);
* a held Y frame (camera) ``k`` with value ``Y_ref`` gets one pair on ``(X_a, Y_k)``:
  ``A = Y_ref``, ``B = I``, i.e. ``Y_ref X_a = Y_k B`` (``Y_k = Y_ref`` at ``X_a = I``).

Every pseudo-pair has ``t_B = 0``, so it does not involve the unknown scale of Problem 3 (its
translation residual is ``alpha`` times a metric one). Its precision is ``strength`` times the
whole data set's: ``sigma_p = min(sigma) / sqrt(strength N)`` and
``kappa_p = strength N max(kappa, |t_B|^2 / sigma^2)`` (``N`` pairs; the second term is the
rotation information a pair's translation carries through its lever arm ``t_B``), so that a held
frame moves by about ``1 / strength`` of what the data alone would pull it by (``strength =
1e4``: a 5 mm / 0.3 deg offset moves by < 1 um / < 1e-3 deg in ``test/core/test_held.py``) while
the cost stays well conditioned for the certificate.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from ..lie import invert_transform, make_transform, so3_exp
from ..problem import Edge, Problem, check_transforms
from ..result import CalibrationResult

__all__ = ["ANCHOR_X", "ANCHOR_Y", "DEFAULT_STRENGTH", "HeldProblem", "hold_frames",
           "without_anchors"]

#: Names of the two anchor frames (never a frame name of a configuration: not a valid name).
ANCHOR_X = "__held_anchor_x"
ANCHOR_Y = "__held_anchor_y"
#: Default precision of the pseudo-measurements relative to all the data's (module docstring).
DEFAULT_STRENGTH = 1e4


class HeldProblem:
    """A problem with frames held at given values (module docstring).

    Attributes
    ----------
    problem : Problem
        The augmented problem to solve: the data's edges, then the anchor edge and one edge per
        held frame; frames in the data's order with :data:`ANCHOR_X` last among the X frames and
        :data:`ANCHOR_Y` last among the Y frames.
    data : Problem
        The data alone.
    held : dict of str to ndarray (4, 4)
        The held frames and their values.
    sigma_p, kappa_p : float
        The pseudo-measurements' translation std [m] and rotation concentration.
    """

    def __init__(self, problem: Problem, data: Problem, held: dict[str, np.ndarray],
                 sigma_p: float, kappa_p: float) -> None:
        self.problem, self.data, self.held = problem, data, held
        self.sigma_p, self.kappa_p = float(sigma_p), float(kappa_p)

    def describe(self) -> str:
        """What the certificate of a solve of :attr:`problem` is for, in words."""
        names = ", ".join(sorted(self.held)) or "none"
        return (f"the data's maximum-likelihood cost plus pseudo-measurements holding "
                f"{names} at the reference (std {self.sigma_p:.2g} m, kappa "
                f"{self.kappa_p:.3g})")


def _quarter_turns() -> np.ndarray:
    """``I`` and the rotations by 90 deg about x, y and z, shape (4, 4, 4)."""
    turns = [np.eye(4)]
    for axis in range(3):
        v = np.zeros(3)
        v[axis] = np.pi / 2
        turns.append(make_transform(so3_exp(v), np.zeros(3)))
    return np.stack(turns)


def hold_frames(data: Problem, held: Mapping[str, np.ndarray], *,
                strength: float = DEFAULT_STRENGTH) -> HeldProblem:
    """The data plus pseudo-measurements that hold ``held`` (frame name -> 4x4 value in its
    parent, the same convention as the estimate) at their values.

    Raises ``ValueError`` for a name that is not a frame of ``data``, a value that is not a
    rigid transform, or a ``strength`` that is not finite and > 0. With nothing held the
    augmented problem is still built (anchors only); callers solve ``data`` instead.
    """
    if not (np.isfinite(strength) and strength > 0):
        raise ValueError(f"strength: must be finite and > 0, got {strength!r}")
    values: dict[str, np.ndarray] = {}
    for name, T in held.items():
        if name not in data.frame_names:
            raise ValueError(f"held frame {name!r}: not a frame of the data; frames: "
                             f"{list(data.frame_names)}")
        values[name] = check_transforms(T, what=f"held frame {name}", rotation_tol=1e-6)[0]
    st = data.stacked()
    n = data.n_measurements
    sigma_p = float(st["sigma"].min()) / np.sqrt(strength * n)
    # rotation information per pair: kappa, or the lever arm |t_B|^2 / sigma^2 of the
    # translation residual, whichever is larger (module docstring)
    lever = float(np.max(np.einsum("ni,ni->n", st["B"][:, :3, 3], st["B"][:, :3, 3])
                         / st["sigma"] ** 2))
    kappa_p = max(float(st["kappa"].max()), lever) * strength * n
    turns = _quarter_turns()
    edges = list(data.edges)
    edges.append(Edge.build(ANCHOR_X, ANCHOR_Y, turns, turns, sigma=sigma_p, kappa=kappa_p))
    eye = np.eye(4)[None]
    for name, T in values.items():
        if name in data.x_names:
            edges.append(Edge.build(name, ANCHOR_Y, invert_transform(T)[None], eye,
                                    sigma=sigma_p, kappa=kappa_p))
        else:
            edges.append(Edge.build(ANCHOR_X, name, T[None], eye, sigma=sigma_p,
                                    kappa=kappa_p))
    problem = Problem((*data.x_names, ANCHOR_X), (*data.y_names, ANCHOR_Y), edges,
                      unknown_scale=data.unknown_scale)
    return HeldProblem(problem, data, values, sigma_p, kappa_p)


def without_anchors(result: CalibrationResult) -> CalibrationResult:
    """``result`` of a held problem with the anchor frames dropped (frames in the data's order);
    the certificate, notes and timings are the augmented solve's. Anything else: unchanged."""
    if ANCHOR_X not in result.x_names and ANCHOR_Y not in result.y_names:
        return result
    kx = [i for i, n in enumerate(result.x_names) if n != ANCHOR_X]
    ky = [i for i, n in enumerate(result.y_names) if n != ANCHOR_Y]
    return CalibrationResult(
        x_names=tuple(result.x_names[i] for i in kx), y_names=tuple(result.y_names[i] for i in ky),
        X=np.asarray(result.X)[kx], Y=np.asarray(result.Y)[ky], scale=result.scale,
        certificate=result.certificate, mode=result.mode, timing_s=dict(result.timing_s),
        solver_status=result.solver_status, rounding_displacement=result.rounding_displacement,
        notes=list(result.notes), unobservable=list(result.unobservable))
