"""Baselines via OpenCV: Shah, Li (robot-world/hand-eye) and the hand-eye methods (1X1Y only).

extension of ours; the paper notes Wang et al. cannot solve monocular problems).

Mapping ``A X = Y B`` onto OpenCV
---------------------------------
Write the four transforms with their frames, ``A = T_p_q``, ``X = T_q_r``, ``Y = T_p_s``,
``B = T_s_r`` (both sides equal ``T_p_r``). In Section 8.1 ``p, q, r, s`` are the base, hand,
camera and target.

* ``cv2.calibrateRobotWorldHandEye`` solves ``cTw wTb = cTg gTb`` (its ``A X = Z B``) for
  ``wTb`` ("base2world", which maps base coordinates to world, i.e. ``T_w_b``) and ``cTg``
  ("gripper2cam", ``T_c_g``). Our constraint inverted and rearranged reads
  ``B^-1 Y^-1 = X^-1 A^-1``, i.e. ``T_r_s T_s_p = T_r_q T_q_p``, so with camera ``c = r``,
  world ``w = s``, gripper ``g = q``, base ``b = p``::

      R/t_world2cam    = B_i^-1      R/t_base2gripper = A_i^-1
      Y = (base2world)^-1            X = (gripper2cam)^-1

  This is ``mapping="frames"`` (the default): OpenCV receives the camera measurement where it
  expects one. ``mapping="direct"`` instead feeds OpenCV's algebraic ``A X = Z B`` with our
  ``A, B`` unchanged (``world2cam = A_i``, ``base2gripper = B_i``, ``X = base2world``,
  ``Y = gripper2cam``). Both are exact on noise-free data, but the least-squares residuals live
  in different frames, so on noisy data they differ; with ``direct`` the rotation and
  translation equations are exactly those of Wang et al. (2022), which is why the paper's
  "Shah" and "Wang" rows of Table 2 coincide.

* ``cv2.calibrateHandEye`` solves ``bTg(i) gTc cTt(i) = bTt`` (constant) for ``gTc``
  ("cam2gripper"). Our ``A_i X B_i^-1 = Y`` is ``T_p_q T_q_r T_r_s = T_p_s``, so with base
  ``b = p``, gripper ``g = q``, camera ``c = r``, target ``t = s``::

      R/t_gripper2base = A_i         R/t_target2cam = B_i^-1         X = cam2gripper

  These methods only estimate ``X``; ``Y`` is the chordal mean of ``A_i X B_i^-1`` (rotation
  average projected onto SO(3), arithmetic mean of the translations).

All OpenCV methods are defined for one X and one Y only: multi-edge problems raise
``ValueError`` naming the method, as do unknown-scale problems. The joint linear methods (Li,
Andreff) are exact on generic data but not on trajectories whose camera always looks at one
point (paper Section 8.1): there their homogeneous system is rank-deficient (the degeneracy that
makes the single-sphere monocular problem unidentifiable) and they return wrong answers or raise
``cv2.error`` even without noise.
"""

from __future__ import annotations

import importlib

import numpy as np

from ..lie import invert_transform, make_transform, project_to_so3
from ..problem import Problem

__all__ = ["opencv_robot_world_hand_eye", "opencv_hand_eye", "average_transforms",
           "BaselineOutput"]

#: ``(X (M, 4, 4), Y (P, 4, 4), alpha)``, what every baseline returns.
BaselineOutput = tuple[np.ndarray, np.ndarray, float]

#: OpenCV method flags by our lower-case name (looked up lazily so importing is cheap).
_RWHE_FLAGS = {"shah": "CALIB_ROBOT_WORLD_HAND_EYE_SHAH", "li": "CALIB_ROBOT_WORLD_HAND_EYE_LI"}
_HAND_EYE_FLAGS = {
    "tsai": "CALIB_HAND_EYE_TSAI",
    "park": "CALIB_HAND_EYE_PARK",
    "horaud": "CALIB_HAND_EYE_HORAUD",
    "andreff": "CALIB_HAND_EYE_ANDREFF",
    "daniilidis": "CALIB_HAND_EYE_DANIILIDIS",
}


# --------------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------------
def _single_edge(problem: Problem, method: str, *, min_pairs: int = 3):
    """The one edge of a 1X1Y known-scale problem, else ``ValueError`` naming ``method``."""
    if not isinstance(problem, Problem):
        raise ValueError(f"{method}: problem must be a Problem, got {type(problem).__name__}")
    if len(problem.edges) != 1 or problem.M != 1 or problem.P != 1:
        raise ValueError(
            f"{method}: only defined for one X and one Y (a single edge), got M={problem.M}, "
            f"P={problem.P}, edges={len(problem.edges)}"
        )
    if problem.unknown_scale:
        raise ValueError(f"{method}: unknown_scale=True is not supported (known-scale method)")
    e = problem.edges[0]
    if e.n < min_pairs:
        raise ValueError(f"{method}: needs at least {min_pairs} measurement pairs, got {e.n}")
    return e


def _cv2():
    try:
        return importlib.import_module("cv2")
    except ImportError as exc:  # pragma: no cover - cv2 is a declared dependency
        raise ModuleNotFoundError("OpenCV baselines need opencv (cv2)") from exc


def _as_cv_lists(T: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Rotation and translation lists ((3, 3), (3, 1)) of a stack (N, 4, 4), C-contiguous."""
    Rs = [np.ascontiguousarray(T[i, :3, :3]) for i in range(T.shape[0])]
    ts = [np.ascontiguousarray(T[i, :3, 3:4]) for i in range(T.shape[0])]
    return Rs, ts


def _from_cv(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    return make_transform(np.asarray(R, float).reshape(3, 3), np.asarray(t, float).reshape(3))


def average_transforms(T: np.ndarray) -> np.ndarray:
    """Chordal mean of transforms (N, 4, 4): projected mean rotation, mean translation."""
    T = np.asarray(T, float)
    return make_transform(project_to_so3(T[:, :3, :3].mean(axis=0)), T[:, :3, 3].mean(axis=0))


# --------------------------------------------------------------------------------------------
# OpenCV
# --------------------------------------------------------------------------------------------
def opencv_robot_world_hand_eye(
    problem: Problem, method: str = "shah", *, mapping: str = "frames"
) -> BaselineOutput:
    """Shah (2013) or Li et al. (2010) through ``cv2.calibrateRobotWorldHandEye`` (1X1Y).

    Parameters
    ----------
    problem : Problem
        One X, one Y, one edge with at least 3 pairs, known scale.
    method : {"shah", "li"}
    mapping : {"frames", "direct"}
        How ``A X = Y B`` is handed to OpenCV (module docstring).

    Returns
    -------
    X : ndarray, shape (1, 4, 4)
    Y : ndarray, shape (1, 4, 4)
    alpha : float
        Always 1.0.

    Notes
    -----
    ``frames``: inputs ``world2cam = B_i^-1`` and ``base2gripper = A_i^-1``; outputs give
    ``Y = base2world^-1`` and ``X = gripper2cam^-1``. ``direct``: ``world2cam = A_i``,
    ``base2gripper = B_i``, ``X = base2world``, ``Y = gripper2cam``.
    """
    key = str(method).lower()
    if key not in _RWHE_FLAGS:
        raise ValueError(f"method: expected one of {sorted(_RWHE_FLAGS)}, got {method!r}")
    if mapping not in ("frames", "direct"):
        raise ValueError(f"mapping: expected 'frames' or 'direct', got {mapping!r}")
    e = _single_edge(problem, f"OpenCV calibrateRobotWorldHandEye ({key})")
    cv2 = _cv2()
    if mapping == "frames":
        R_w2c, t_w2c = _as_cv_lists(invert_transform(e.B))
        R_b2g, t_b2g = _as_cv_lists(invert_transform(e.A))
    else:
        R_w2c, t_w2c = _as_cv_lists(e.A)
        R_b2g, t_b2g = _as_cv_lists(e.B)
    R_b2w, t_b2w, R_g2c, t_g2c = cv2.calibrateRobotWorldHandEye(
        R_w2c, t_w2c, R_b2g, t_b2g, method=getattr(cv2, _RWHE_FLAGS[key])
    )
    T_b2w = _from_cv(R_b2w, t_b2w)
    T_g2c = _from_cv(R_g2c, t_g2c)
    if mapping == "frames":
        X, Y = invert_transform(T_g2c), invert_transform(T_b2w)
    else:
        X, Y = T_b2w, T_g2c
    return X[None], Y[None], 1.0


def opencv_hand_eye(problem: Problem, method: str = "tsai") -> BaselineOutput:
    """Classic hand-eye ``AX = XB`` solvers through ``cv2.calibrateHandEye`` (1X1Y).

    ``X`` comes from OpenCV (``gripper2base = A_i``, ``target2cam = B_i^-1``,
    ``X = cam2gripper``); ``Y`` is then the chordal mean of ``A_i X B_i^-1``.

    Parameters
    ----------
    problem : Problem
        One X, one Y, one edge with at least 3 pairs, known scale.
    method : {"tsai", "park", "horaud", "andreff", "daniilidis"}

    Returns
    -------
    X, Y : ndarray, shape (1, 4, 4)
    alpha : float
        Always 1.0.
    """
    key = str(method).lower()
    if key not in _HAND_EYE_FLAGS:
        raise ValueError(f"method: expected one of {sorted(_HAND_EYE_FLAGS)}, got {method!r}")
    e = _single_edge(problem, f"OpenCV calibrateHandEye ({key})")
    cv2 = _cv2()
    R_g2b, t_g2b = _as_cv_lists(e.A)
    R_t2c, t_t2c = _as_cv_lists(invert_transform(e.B))
    R_c2g, t_c2g = cv2.calibrateHandEye(
        R_g2b, t_g2b, R_t2c, t_t2c, method=getattr(cv2, _HAND_EYE_FLAGS[key])
    )
    X = _from_cv(R_c2g, t_c2g)
    Y = average_transforms(e.A @ X @ invert_transform(e.B))
    return X[None], Y[None], 1.0


