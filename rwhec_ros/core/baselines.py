"""Baseline RWHEC solvers the paper compares against (Section 8), behind one interface.

Every baseline maps a validated :class:`~rwhec_ros.core.problem.Problem` (``A_i X_j = Y_k B_i``,
eq. (7)) to ``(X (M, 4, 4), Y (P, 4, 4), alpha)``; :func:`run_baseline` dispatches by name.

* ``shah`` / ``shah_direct``: Shah (2013), Kronecker product, via OpenCV (1X1Y, known scale;
  the two differ in how the data are handed to OpenCV, see below).
* ``li`` / ``li_direct``: Li, Wang and Wu (2010), dual quaternions, via OpenCV (1X1Y, known).
* ``tsai``, ``park``, ``horaud``, ``andreff``, ``daniilidis``: hand-eye ``AX = XB`` methods via
  OpenCV -- Tsai & Lenz (1989), Park & Martin (1994), Horaud & Dornaika (1995), Andreff et al.
  (1999), Daniilidis (1999); ``Y`` recovered afterwards (1X1Y, known).
* ``wang``: Wang et al. (2022), generalized closed form (any connected graph, known scale (+)).
* ``dornaika``: Dornaika & Horaud (1998), joint nonlinear least squares (any connected graph,
  known scale).
* ``lom``: LOM of the paper's Appendix A, :mod:`rwhec_ros.core.lom` (any graph, both scales).

(+) ``wang`` with ``unknown_scale`` solves the translation stage for ``alpha`` too (a linear
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
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from .lie import hat, invert_transform, make_transform, project_to_so3, so3_exp, unvec
from .problem import Problem

__all__ = [
    "BaselineInfo",
    "BASELINES",
    "baseline_names",
    "run_baseline",
    "average_transforms",
    "opencv_robot_world_hand_eye",
    "opencv_hand_eye",
    "wang2022",
    "wang2022_rotations",
    "translations_given_rotations",
    "dornaika1998",
    "dornaika_cost",
    "lom",
]

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


# --------------------------------------------------------------------------------------------
# Wang et al. (2022)
# --------------------------------------------------------------------------------------------
def wang2022_rotations(problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """Rotation stage of Wang et al. (2022): null vector of the stacked Kronecker system.

    For every pair ``i`` of edge ``(j, k)`` the rotation constraint (8a)
    ``R_A R_Xj - R_Yk R_B = 0`` is, with column-major ``vec`` (eq. (26)),

    .. math:: (I \\otimes R_A)\\,\\mathrm{vec} R_{X_j} - (R_B^\\top \\otimes I)\\,\\mathrm{vec}
              R_{Y_k} = 0 .

    All 9-row blocks are stacked (unweighted) into a ``(9 N, 9 (M + P))`` matrix whose right
    singular vector of smallest singular value is ``c [vec R_X1 .. vec R_YP]`` for an unknown
    common ``c``. The sign of ``c`` is fixed so that the sum of the cube-rooted block
    determinants is positive (its magnitude does not matter for the projection), and every
    block is projected onto SO(3).

    Returns
    -------
    RX : ndarray, shape (M, 3, 3)
    RY : ndarray, shape (P, 3, 3)
    """
    M, n = problem.M, problem.n_frames
    rows = []
    I3 = np.eye(3)
    for e, j, k in zip(problem.edges, problem.edge_x, problem.edge_y, strict=True):
        N = e.n
        blk = np.zeros((N, 9, 9 * n))
        RA = e.A[:, :3, :3]
        RB = e.B[:, :3, :3]
        cx = 9 * int(j)
        cy = 9 * (M + int(k))
        blk[:, :, cx : cx + 9] = np.einsum("ab,nij->naibj", I3, RA).reshape(N, 9, 9)
        blk[:, :, cy : cy + 9] = -np.einsum("nba,ij->naibj", RB, I3).reshape(N, 9, 9)
        rows.append(blk.reshape(9 * N, 9 * n))
    K = np.concatenate(rows)
    _, _, Vt = np.linalg.svd(K, full_matrices=False)
    v = Vt[-1]
    blocks = unvec(v.reshape(n, 9))
    if np.sum(np.cbrt(np.linalg.det(blocks))) < 0:
        blocks = -blocks
    R = project_to_so3(blocks)
    return R[:M], R[M:]


def translations_given_rotations(
    problem: Problem, RX: np.ndarray, RY: np.ndarray
) -> tuple[np.ndarray, np.ndarray, float]:
    """Linear least-squares translations (and ``alpha``) with the rotations held fixed.

    Stacks eq. (8b), ``R_A t_Xj - t_Yk = R_Yk t_B - t_A`` for every pair (unweighted). For
    ``problem.unknown_scale`` the unknowns are the scaled ``alpha t_X, alpha t_Y`` and ``alpha``
    (eq. (22): ``R_A (alpha t_X) + alpha t_A - alpha t_Y = R_Y t_B``); the metric translations
    are returned. Minimum-norm solution when the translations are not identifiable.

    Returns
    -------
    tX : ndarray, shape (M, 3)
    tY : ndarray, shape (P, 3)
    alpha : float
    """
    M, n = problem.M, problem.n_frames
    scale = problem.unknown_scale
    ncol = 3 * n + (1 if scale else 0)
    blocks, rhs = [], []
    for e, j, k in zip(problem.edges, problem.edge_x, problem.edge_y, strict=True):
        N = e.n
        blk = np.zeros((N, 3, ncol))
        cx = 3 * int(j)
        cy = 3 * (M + int(k))
        blk[:, :, cx : cx + 3] = e.A[:, :3, :3]
        blk[:, :, cy : cy + 3] = -np.eye(3)
        b = e.B[:, :3, 3] @ RY[k].T
        if scale:
            blk[:, :, -1] = e.A[:, :3, 3]
        else:
            b = b - e.A[:, :3, 3]
        blocks.append(blk.reshape(3 * N, ncol))
        rhs.append(b.reshape(3 * N))
    sol = np.linalg.lstsq(np.concatenate(blocks), np.concatenate(rhs), rcond=None)[0]
    alpha = float(sol[-1]) if scale else 1.0
    t = sol[: 3 * n].reshape(n, 3)
    if scale and abs(alpha) > 1e-12:
        t = t / alpha
    return t[:M], t[M:], alpha


def wang2022(problem: Problem) -> BaselineOutput:
    """Closed-form generalized RWHEC of Wang et al. (2022) for any connected graph.

    Rotations from :func:`wang2022_rotations`, then translations (and ``alpha`` for unknown
    scale, our linear extension) from :func:`translations_given_rotations`. The paper's
    "Shah" and "Wang" rows coincide on 1X1Y problems (Table 2).

    Returns
    -------
    X : ndarray, shape (M, 4, 4)
    Y : ndarray, shape (P, 4, 4)
    alpha : float
    """
    if not isinstance(problem, Problem):
        raise ValueError(f"wang: problem must be a Problem, got {type(problem).__name__}")
    if len(problem.components()) != 1:
        raise ValueError(
            f"wang: the problem graph must be connected, got components {problem.components()}"
        )
    RX, RY = wang2022_rotations(problem)
    tX, tY, alpha = translations_given_rotations(problem, RX, RY)
    return make_transform(RX, tX), make_transform(RY, tY), alpha


# --------------------------------------------------------------------------------------------
# Dornaika & Horaud (1998)
# --------------------------------------------------------------------------------------------
def _vec_hat_generators() -> np.ndarray:
    """``vec(hat(e_k))`` for k = 0, 1, 2 as columns (9, 3), column-major ``vec``."""
    return np.stack([hat(np.eye(3)[k]).T.reshape(9) for k in range(3)], axis=1)


def _dornaika_residuals(
    problem: Problem,
    X: np.ndarray,
    Y: np.ndarray,
    lambda_rot: float,
    lambda_trans: float,
    with_jacobian: bool,
):
    """Stacked residuals (12 per pair) and optionally the Jacobian w.r.t. the local
    perturbation ``[dphi_X (3M), dphi_Y (3P), dt_X (3M), dt_Y (3P)]`` with
    ``R <- R exp(dphi^)`` and ``t <- t + dt``."""
    M, n = problem.M, problem.n_frames
    G = _vec_hat_generators()
    wr, wt = np.sqrt(lambda_rot), np.sqrt(lambda_trans)
    res, jacs = [], []
    for e, j, k in zip(problem.edges, problem.edge_x, problem.edge_y, strict=True):
        N = e.n
        RA, tA = e.A[:, :3, :3], e.A[:, :3, 3]
        RB, tB = e.B[:, :3, :3], e.B[:, :3, 3]
        RX, tX = X[j, :3, :3], X[j, :3, 3]
        RY, tY = Y[k, :3, :3], Y[k, :3, 3]
        RARX = RA @ RX
        rR = RARX - RY @ RB  # (N, 3, 3)
        rt = RA @ tX + tA - tY - tB @ RY.T  # (N, 3)
        r = np.concatenate([wr * np.swapaxes(rR, 1, 2).reshape(N, 9), wt * rt], axis=1)
        res.append(r.reshape(-1))
        if not with_jacobian:
            continue
        J = np.zeros((N, 12, 6 * n))
        I3 = np.eye(3)
        # d vec(R_A R_X exp(w^)) / dw = (I (x) R_A R_X) G
        kx = np.einsum("ab,nij->naibj", I3, RARX).reshape(N, 9, 9)
        J[:, :9, 3 * j : 3 * j + 3] = wr * kx @ G
        # d vec(-R_Y exp(w^) R_B) / dw = -(R_B^T (x) R_Y) G
        ky = np.einsum("nba,ij->naibj", RB, RY).reshape(N, 9, 9)
        J[:, :9, 3 * (M + k) : 3 * (M + k) + 3] = -wr * ky @ G
        # d(-R_Y exp(w^) t_B)/dw = R_Y hat(t_B)
        J[:, 9:, 3 * (M + k) : 3 * (M + k) + 3] = wt * RY @ hat(tB)
        o = 3 * n
        J[:, 9:, o + 3 * j : o + 3 * j + 3] = wt * RA
        J[:, 9:, o + 3 * (M + k) : o + 3 * (M + k) + 3] = -wt * I3
        jacs.append(J.reshape(12 * N, 6 * n))
    r = np.concatenate(res)
    return (r, np.concatenate(jacs)) if with_jacobian else (r, None)


def dornaika_cost(
    problem: Problem,
    X: np.ndarray,
    Y: np.ndarray,
    *,
    lambda_rot: float = 1.0,
    lambda_trans: float = 1.0,
) -> float:
    """Dornaika & Horaud's joint objective
    ``sum lambda_rot |R_A R_X - R_Y R_B|_F^2 + lambda_trans |R_A t_X + t_A - R_Y t_B - t_Y|^2``."""
    r, _ = _dornaika_residuals(problem, X, Y, lambda_rot, lambda_trans, with_jacobian=False)
    return float(r @ r)


def dornaika1998(
    problem: Problem,
    X0: np.ndarray | None = None,
    Y0: np.ndarray | None = None,
    *,
    lambda_rot: float = 1.0,
    lambda_trans: float = 1.0,
    max_iterations: int = 100,
    tol: float = 1e-12,
) -> BaselineOutput:
    """Simultaneous nonlinear RWHEC of Dornaika & Horaud (1998), generalized to graphs.

    Minimises :func:`dornaika_cost` jointly over rotations and translations by
    Levenberg-Marquardt on the manifold (right perturbations ``R exp(phi^)``), starting from
    ``X0, Y0`` (default: :func:`wang2022`, as in the paper's tables). Dornaika & Horaud use
    unit quaternions with a penalty ``lambda (1 - q^T q)^2`` on the norm; the on-manifold
    parametrisation enforces the constraint exactly (the limit of a large penalty). Their
    rotation term is the chordal (Frobenius) error, the translation term is in metres, and both
    weights are 1, i.e. **not** the noise-model weighting of the MLE.

    Parameters
    ----------
    problem : Problem
        Known scale, connected graph.
    X0 : ndarray, shape (M, 4, 4), optional
    Y0 : ndarray, shape (P, 4, 4), optional
    lambda_rot, lambda_trans : float
        Weights of the rotation and translation terms.
    max_iterations : int
    tol : float
        Stop when the relative cost decrease or the step norm falls below ``tol``.

    Returns
    -------
    X : ndarray, shape (M, 4, 4)
    Y : ndarray, shape (P, 4, 4)
    alpha : float
        Always 1.0.
    """
    if not isinstance(problem, Problem):
        raise ValueError(f"dornaika: problem must be a Problem, got {type(problem).__name__}")
    if problem.unknown_scale:
        raise ValueError("dornaika: unknown_scale=True is not supported (known-scale method)")
    for name, val in (("lambda_rot", lambda_rot), ("lambda_trans", lambda_trans)):
        if not np.isfinite(val) or val <= 0:
            raise ValueError(f"dornaika: {name} must be finite and > 0, got {val!r}")
    if X0 is None or Y0 is None:
        Xw, Yw, _ = wang2022(problem)
        X0 = Xw if X0 is None else X0
        Y0 = Yw if Y0 is None else Y0
    X = np.array(X0, dtype=float).reshape(problem.M, 4, 4)
    Y = np.array(Y0, dtype=float).reshape(problem.P, 4, 4)
    M, n = problem.M, problem.n_frames
    r, J = _dornaika_residuals(problem, X, Y, lambda_rot, lambda_trans, True)
    cost = float(r @ r)
    mu = 1e-6
    for _ in range(max_iterations):
        H = J.T @ J
        g = J.T @ r
        while True:
            step = -np.linalg.solve(H + mu * np.diag(np.diag(H) + 1e-12), g)
            Xn, Yn = _retract(X, Y, step, M, n)
            rn, _ = _dornaika_residuals(problem, Xn, Yn, lambda_rot, lambda_trans, False)
            cn = float(rn @ rn)
            if cn <= cost or mu > 1e12:
                break
            mu *= 10.0
        if cn > cost:
            break
        decrease = cost - cn
        X, Y = Xn, Yn
        r, J = _dornaika_residuals(problem, X, Y, lambda_rot, lambda_trans, True)
        cost = float(r @ r)
        mu = max(mu / 10.0, 1e-12)
        if decrease <= tol * max(cost, 1e-300) or np.linalg.norm(step) <= tol:
            break
    return X, Y, 1.0


def _retract(X: np.ndarray, Y: np.ndarray, step: np.ndarray, M: int, n: int):
    T = np.concatenate([X, Y]).copy()
    dphi = step[: 3 * n].reshape(n, 3)
    dt = step[3 * n :].reshape(n, 3)
    T[:, :3, :3] = project_to_so3(T[:, :3, :3] @ so3_exp(dphi))
    T[:, :3, 3] = T[:, :3, 3] + dt
    return T[:M], T[M:]


# --------------------------------------------------------------------------------------------
# LOM (paper Appendix A), implemented in rwhec_ros.core.lom
# --------------------------------------------------------------------------------------------
def lom(
    problem: Problem,
    X0: np.ndarray | None = None,
    Y0: np.ndarray | None = None,
    alpha0: float = 1.0,
    **kw,
) -> BaselineOutput:
    """LOM of the paper's Appendix A via ``rwhec_ros.core.lom.solve_lom`` (imported lazily).

    Defaults to the :func:`wang2022` initialisation (Tables 2 and 4) when ``X0``/``Y0`` are
    omitted. Extra keywords go to ``solve_lom``.
    """
    mod = importlib.import_module("rwhec_ros.core.lom")
    if X0 is None or Y0 is None:
        Xw, Yw, aw = wang2022(problem)
        X0 = Xw if X0 is None else X0
        Y0 = Yw if Y0 is None else Y0
    out = mod.solve_lom(problem, X0, Y0, alpha0=alpha0, **kw)
    if hasattr(out, "X") and hasattr(out, "Y"):
        alpha = getattr(out, "scale", getattr(out, "alpha", 1.0))
        return np.asarray(out.X), np.asarray(out.Y), float(alpha)
    X, Y, alpha = out[:3]
    return np.asarray(X), np.asarray(Y), float(alpha)


# --------------------------------------------------------------------------------------------
# registry
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class BaselineInfo:
    """One registered baseline.

    Attributes
    ----------
    name : str
        Registry key.
    label : str
        Row label used in the paper's tables.
    reference : str
        The paper that defines the method.
    single_edge_only : bool
        Only defined for 1X1Y problems.
    unknown_scale : bool
        Handles ``problem.unknown_scale``.
    function : callable
        ``function(problem, **kw) -> (X, Y, alpha)``.
    """

    name: str
    label: str
    reference: str
    single_edge_only: bool
    unknown_scale: bool
    function: Callable[..., BaselineOutput]


def _rwhe(method: str, mapping: str = "frames") -> Callable[..., BaselineOutput]:
    return lambda problem, **kw: opencv_robot_world_hand_eye(
        problem, method, **{"mapping": mapping, **kw}
    )


def _he(method: str) -> Callable[..., BaselineOutput]:
    return lambda problem, **kw: opencv_hand_eye(problem, method, **kw)


_OPENCV = "via OpenCV"
_DIRECT = "via OpenCV, direct A X = Y B mapping"

BASELINES: Mapping[str, BaselineInfo] = MappingProxyType(
    {
        info.name: info
        for info in (
            BaselineInfo("shah", "Shah", f"Shah (2013), {_OPENCV}", True, False, _rwhe("shah")),
            BaselineInfo(
                "shah_direct", "Shah (direct)", f"Shah (2013), {_DIRECT}", True, False,
                _rwhe("shah", "direct"),
            ),
            BaselineInfo("li", "Li", f"Li et al. (2010), {_OPENCV}", True, False, _rwhe("li")),
            BaselineInfo(
                "li_direct", "Li (direct)", f"Li et al. (2010), {_DIRECT}", True, False,
                _rwhe("li", "direct"),
            ),
            BaselineInfo(
                "tsai", "Tsai", f"Tsai and Lenz (1989), {_OPENCV}", True, False, _he("tsai")
            ),
            BaselineInfo(
                "park", "Park", f"Park and Martin (1994), {_OPENCV}", True, False, _he("park")
            ),
            BaselineInfo(
                "horaud", "Horaud", f"Horaud and Dornaika (1995), {_OPENCV}", True, False,
                _he("horaud"),
            ),
            BaselineInfo(
                "andreff", "Andreff", f"Andreff et al. (1999), {_OPENCV}", True, False,
                _he("andreff"),
            ),
            BaselineInfo(
                "daniilidis", "Daniilidis", f"Daniilidis (1999), {_OPENCV}", True, False,
                _he("daniilidis"),
            ),
            BaselineInfo("wang", "Wang", "Wang et al. (2022)", False, True, wang2022),
            BaselineInfo(
                "dornaika", "Dornaika", "Dornaika and Horaud (1998)", False, False, dornaika1998
            ),
            BaselineInfo("lom", "LOM", "Wise et al. (2025), Appendix A", False, True, lom),
        )
    }
)


def baseline_names() -> tuple[str, ...]:
    """Registered baseline names, in table order."""
    return tuple(BASELINES)


def run_baseline(name: str, problem: Problem, **kw) -> BaselineOutput:
    """Run the baseline called ``name`` (see :data:`BASELINES`) on ``problem``.

    Returns
    -------
    X : ndarray, shape (M, 4, 4)
    Y : ndarray, shape (P, 4, 4)
    alpha : float
        The estimated scale (1.0 for known-scale methods).
    """
    key = str(name).lower()
    if key not in BASELINES:
        raise ValueError(f"name: unknown baseline {name!r}, expected one of {baseline_names()}")
    X, Y, alpha = BASELINES[key].function(problem, **kw)
    return np.asarray(X, float), np.asarray(Y, float), float(alpha)
