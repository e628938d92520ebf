"""Re-centring a carrier's frame for data far from its origin, keeping the certificate rigorous.

``A_i X_j = Y_k B_i`` (eq. (7)) holds as well for ``T A_i S``, ``T Y_k`` and ``S^-1 X_j``, for any
fixed rigid ``T`` (on the camera carrier's side: ``A`` maps the tag carrier into the camera
carrier, ``Y_k`` a camera into the camera carrier) and ``S`` (on the tag carrier's side). For
translations -- ``T`` by ``-c``, ``S`` by ``+c`` -- every residual of eq. (22) is unchanged in
exact arithmetic, so are the cost (eq. (33)) and its optimum, and the optimal frames move by
``-c``:

* **camera carrier** (:data:`CAMERA`): ``t_A -> t_A - c``, ``t_Y -> t_Y - c`` (the translation
  residual ``alpha (R_A t_X + t_A - t_Y) - R_Y t_B`` loses ``alpha c`` twice), for known and
  unknown scale. Far when the pose translations ``t_A`` cluster far from the origin: e.g. fixed
  cameras in a world frame far from a robot-held target.
* **tag carrier** (:data:`TAG`): ``t_A -> t_A + R_A c``, ``t_X -> t_X - c``, for known and
  unknown scale. Far when the camera carrier's positions in the tag carrier (``-R_A^T t_A``)
  cluster far from the origin: e.g. a rig's cameras seeing tags in a world frame whose origin
  is far away.

Numerically they are not the same problem. With translations of size ``L`` and residuals of
size ``r``, double precision loses about ``u L`` per residual: the cost matrix's rounding bound
grows like ``L^2`` and the certificate fails on its own rounding (a simulated rig 1 km from the
origin: ``rho_hat`` 1.5e-5 at a 1e-6 tolerance); with unknown scale the direction "scale up,
move the frame" is conditioned like ``(spread / L)^2`` and is taken for an unobservable one
(100 m away: a negative scale, "not identifiable"). About a nearby origin both are certified as
at the origin.

The certificate stays one of the *given* problem:

* The camera carrier's shift is exact: :func:`recentring_for` shifts an axis only when
  ``t_A - c`` is exact for every pose (the error-free TwoSum; the values then lie within a
  factor 2 of ``c``, Sterbenz's lemma), so the re-centred data are the given data minus ``c``
  and the dual bound ``d`` of the re-centred problem bounds the given problem's optimum.
* The tag carrier's shift rounds (``R_A c``): the re-centred data ``D'`` are the exactly shifted
  data ``D''`` (same optimum as the given ``D``) plus translation errors ``delta_i`` with a
  proven bound ``beta_i`` (:func:`_tag_shift`), and ``E = (sum_i |beta_i|^2 / (2 sigma_i^2))^(1/2)``
  bounds them in the cost's metric. The translation residuals of ``D'`` and ``D''`` differ by
  ``alpha delta_i``, so for any estimate ``x`` Minkowski's inequality on the translation part
  ``T`` of the cost gives ``|T''(x)^(1/2) - T'(x)^(1/2)| <= |alpha| E``, hence
  ``f''(x) >= f'(x) - 2 |alpha| E f'(x)^(1/2)``. At the optimum ``|alpha| <= a`` (``a = 1`` for
  known scale; for unknown scale the proven :func:`scale_bound`: the pose translations alone
  misfit a rigid chain by ``m > 0``, so a large scale costs at least
  ``(|alpha| m^(1/2) - T_B^(1/2))^2``); the right side grows with ``f'(x) >= d'`` once
  ``d' >= (a E)^2``, so ``d = d' - 2 a E d'^(1/2)`` bounds ``min f = min f''`` from below (the
  margin ``recentring`` of the certificate). Where no bound on the scale can be proven the
  data are solved as given, and a not-identifiable status says the coordinates may be why.
* The estimate is mapped back (``+ c``, rounded once) and its cost ``p`` is a proven upper bound
  on the cost of the *returned* estimate on the given data: when subtracting ``c`` again is
  exact (as it is near the data), it is the cost on ``D'`` at that point with its rounding bound
  (:func:`~rwhec_ros.core.model.cost.direct_cost_error`), plus ``2 |alpha| E p'^(1/2) + alpha^2
  E^2`` on the tag carrier's side; otherwise the cost on the given data with the (larger) rounding
  bound there.

Solved as given: data within a few of their spreads (or a metre) of the origin (nothing to
gain), problems with translation priors (their values are about the given origin), and problems
whose re-centred solve finds an unobservable translation direction (the default that fixes it is
about the given origin too).
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, replace

import numpy as np

from ..numerics.verified import UNIT_ROUNDOFF, gamma
from ..problem import Edge, Problem

__all__ = ["CAMERA", "TAG", "Recentring", "recentring_for", "recentred_problem",
           "recentred_frames", "recentred_options", "restore_estimate", "scale_bound",
           "pose_misfit_lower_bound", "recentred_analysis", "far_scale_words",
           "RECENTRE_MIN_OFFSET_M", "RECENTRE_MIN_GAIN"]

#: Re-centre only when the offset is at least this long (metres): closer than that the
#: translations are small enough for the rounding not to matter.
RECENTRE_MIN_OFFSET_M = 1.0
#: ... and when it shrinks the largest pose translation at least this many times.
RECENTRE_MIN_GAIN = 4.0
#: The carrier whose origin is moved.
CAMERA, TAG = "camera carrier", "tag carrier"


@dataclass(frozen=True)
class Recentring:
    """The move of one carrier's origin to ``offset`` (3,), metres in that carrier's frame."""

    carrier: str
    offset: np.ndarray

    def words(self) -> str:
        return f"the point ({', '.join(f'{v:.6g}' for v in self.offset)}) m of the {self.carrier}"


def _exact_difference(a: np.ndarray, c: float) -> bool:
    """Whether ``fl(a - c) == a - c`` for every entry of ``a`` (TwoSum's error term is zero;
    round to nearest, no overflow)."""
    b = -c
    s = a + b
    bb = s - a
    err = (a - (s - bb)) + (b - bb)
    return bool(np.all(err == 0.0)) and bool(np.all(np.isfinite(s)))


def _midpoint(t: np.ndarray) -> np.ndarray:
    """The midpoint of the range of each row of ``t`` (3, N)."""
    return 0.5 * (t.min(axis=1) + t.max(axis=1))


def _worth_it(c: np.ndarray, before: np.ndarray, after: np.ndarray) -> bool:
    """The offset is long enough and shrinks the largest translation enough."""
    return (float(np.linalg.norm(c)) >= RECENTRE_MIN_OFFSET_M
            and float(np.abs(after).max()) * RECENTRE_MIN_GAIN <= float(np.abs(before).max()))


def _pose_arrays(problem: Problem) -> tuple[np.ndarray, np.ndarray]:
    """Every pair's ``t_A`` as rows (3, N) and ``R_A`` as ``R[a, b]`` (3, 3, N), contiguous
    (reductions along the pairs are then ~30x faster than on (N, 3) columns)."""
    rows = np.ascontiguousarray(
        np.concatenate([e.A.reshape(-1, 16) for e in problem.edges], axis=0).T)  # (16, N)
    return rows[[3, 7, 11]], rows[[0, 1, 2, 4, 5, 6, 8, 9, 10]].reshape(3, 3, -1)


def recentring_for(problem: Problem) -> Recentring | None:
    """How to re-centre ``problem``, or None to solve it as given.

    The camera carrier first: per axis the midpoint of the range of ``t_A``'s component, kept
    only when subtracting it is exact for every pose (else that axis keeps 0). Else the tag
    carrier: the midpoint of the camera carrier's positions ``-R_A^T t_A``. Each
    only when the offset is at least :data:`RECENTRE_MIN_OFFSET_M` long and shrinks the largest
    pose translation component at least :data:`RECENTRE_MIN_GAIN` times.
    """
    key = (RECENTRE_MIN_OFFSET_M, RECENTRE_MIN_GAIN)
    cached = problem.__dict__.get("_recentring")
    if cached is not None and cached[0] is problem.edges and cached[1] == key:
        return cached[2]
    rc = _recentring_for(problem) if problem.edges else None
    problem.__dict__["_recentring"] = (problem.edges, key, rc)  # once per problem
    return rc


def _recentring_for(problem: Problem) -> Recentring | None:
    t, R = _pose_arrays(problem)
    mid = _midpoint(t)
    c = np.zeros(3)
    for i in range(3):
        if mid[i] != 0.0 and _exact_difference(t[i], float(mid[i])):
            c[i] = mid[i]
    if _worth_it(c, t, t - c[:, None]):
        return Recentring(CAMERA, c)
    c = _tag_offset(t, R)
    return Recentring(TAG, c) if _worth_it(c, t, _tag_moved(t, R, c)) else None


def _tag_offset(t: np.ndarray, R: np.ndarray) -> np.ndarray:
    """The midpoint of the camera carrier's positions in the tag carrier, ``-R_A^T t_A``
    (``t`` (3, N), ``R`` (3, 3, N) as :func:`_pose_arrays`)."""
    return _midpoint(-(R[0] * t[0] + R[1] * t[1] + R[2] * t[2]))


def _tag_moved(t: np.ndarray, R: np.ndarray, c: np.ndarray) -> np.ndarray:
    """``t_A + R_A c`` (3, N), in floating point (an estimate: for the offset's choice)."""
    return t + R[:, 0] * c[0] + R[:, 1] * c[1] + R[:, 2] * c[2]


def _tag_shift(A: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``fl(t_A + R_A c)`` (N, 3) and a componentwise bound (N, 3) on its error: an inner
    product of 4 terms (``R_A c`` and ``t_A``), ``gamma_4 (|t_A| + |R_A| |c|)`` in any order of
    summation (with fused multiply-adds too), taken as ``gamma_6`` and the bound's own rounding
    covered by ``1 + 8 u``."""
    R, t = A[:, :3, :3], A[:, :3, 3]
    shifted = t + R @ c
    beta = gamma(6) * (np.abs(t) + np.abs(R) @ np.abs(c)) * (1.0 + 8.0 * UNIT_ROUNDOFF)
    return shifted, beta


def recentred_problem(problem: Problem, rc: Recentring) -> tuple[Problem, float]:
    """``problem`` about ``rc``'s point and the bound ``E`` on the shift's rounding in the cost's
    metric (0 for the exact camera carrier's shift; see the module docstring). Frames,
    precisions and the scale model unchanged, cached edge blocks dropped (they belong to the
    given data). ``ValueError`` when a camera carrier's offset is not exact (use
    :func:`recentring_for`)."""
    c = np.asarray(rc.offset, dtype=float).reshape(3)
    edges, e2 = [], 0.0
    for e in problem.edges:
        A = e.A.copy()
        if rc.carrier == CAMERA:
            for i in range(3):
                if c[i] != 0.0 and not _exact_difference(e.A[:, i, 3], float(c[i])):
                    raise ValueError(f"offset c[{i}] = {c[i]!r}: t_A - c is not exact for edge "
                                     f"({e.x}, {e.y}); use recentring_for")
            A[:, :3, 3] -= c
        else:
            A[:, :3, 3], beta = _tag_shift(e.A, c)
            e2 += float(np.sum(np.sum(beta * beta, axis=1) / (2.0 * e.sigma * e.sigma)))
        edges.append(Edge(e.x, e.y, A, e.B, e.sigma, e.kappa))
    # e2's own rounding: at most 3 N + (number of edges) terms and their products and quotients
    terms = 3 * problem.n_measurements + len(edges) + 8
    E = float(np.sqrt(e2 * (1.0 + gamma(terms)))) * (1.0 + 4.0 * UNIT_ROUNDOFF)
    return (Problem(problem.x_names, problem.y_names, edges,
                    unknown_scale=problem.unknown_scale), E)


def recentred_frames(X: np.ndarray, Y: np.ndarray, rc: Recentring, back: bool = False
                     ) -> tuple[np.ndarray, np.ndarray]:
    """``(X, Y)`` expressed about ``rc``'s point: the moved carrier's frames (``Y`` for the
    camera carrier, ``X`` for the tag carrier) copied with their translations ``- c``
    (``+ c`` with ``back``, to the given frames); the other stack as it is."""
    moved = np.array(Y if rc.carrier == CAMERA else X, dtype=float, copy=True)
    moved[:, :3, 3] += rc.offset if back else -rc.offset
    return (X, moved) if rc.carrier == CAMERA else (moved, Y)


def recentred_options(options, rc: Recentring):
    """``options`` with its warm start ``(X, Y)``, if any, expressed about ``rc``'s point; a
    shallow copy, the caller's options are not changed."""
    if options.initial is None:
        return options
    return replace(options, initial=recentred_frames(*options.initial, rc))


def restore_estimate(result, problem: Problem, recentred: Problem, rc: Recentring, E: float,
                     proven_cost) -> bool:
    """Map ``result`` of the ``recentred`` problem back to ``problem``'s frames in place (the
    moved frames ``+ c``, rounded once) and replace its certificate's bounds by ones of the
    given problem and the returned estimate (module docstring); ``proven_cost(P, X, Y, alpha)``
    is a proven upper bound on the cost of ``(X, Y, alpha)`` on ``P``'s data. Adds a note.
    False (and ``result`` unchanged) when, with unknown scale, no bound on the scale at the
    optimum could be proven (:func:`pose_misfit_lower_bound`): then solve as given."""
    c = rc.offset
    X_r, Y_r = recentred_frames(result.X, result.Y, rc, back=True)  # what is returned
    moved = Y_r if rc.carrier == CAMERA else X_r
    exact = all(_exact_difference(moved[:, i, 3], float(c[i])) for i in range(3) if c[i] != 0.0)
    alpha = float(result.scale) if problem.unknown_scale else 1.0
    if exact:  # the returned estimate, exactly about the point again
        p = proven_cost(recentred, *recentred_frames(X_r, Y_r, rc), result.scale)
        if E > 0.0:  # the shifted data's rounding, alpha delta_i per pair
            aE = abs(alpha) * E * (1.0 + 4.0 * UNIT_ROUNDOFF)
            p = float(np.nextafter((p + 2.0 * aE * np.sqrt(p) + aE * aE)
                                   * (1.0 + 8.0 * UNIT_ROUNDOFF), np.inf))
        where = "evaluated about the point, with the bounds on its rounding"
    else:
        p = proven_cost(problem, X_r, Y_r, result.scale)
        where = "evaluated in the given frames, with the bound on its rounding there"
    cert = result.certificate
    d, margin = cert.dual_bound, None
    if E > 0.0 and np.isfinite(d):
        a_max = 1.0
        if problem.unknown_scale:
            a_max = scale_bound(recentred, E, p)
            if not np.isfinite(a_max):
                return False
        aE = a_max * E * (1.0 + 4.0 * UNIT_ROUNDOFF)
        loss = 2.0 * aE * np.sqrt(max(d, 0.0)) * (1.0 + 8.0 * UNIT_ROUNDOFF)
        lower = float(np.nextafter(d - loss, -np.inf)) if d >= aE * aE else 0.0
        # a cost is a sum of squares: 0 bounds it too (and is what is left when d' < (aE)^2)
        loss, d = max(d - max(lower, 0.0), 0.0), max(lower, 0.0)
        margin = ("recentring", loss)
    result.X, result.Y = X_r, Y_r
    result.certificate = cert.with_bounds(
        p, d, f"the cost of the estimate in the given frames ({where})", margin)
    result.notes.append(
        f"solved about {rc.words()}: the data's translations are far from its origin, where "
        "double precision rounds them too coarsely for a certificate; the same optimum (the "
        "shift and its rounding are in the bounds), the estimate given in the original frames "
        f"and its cost {where}")
    return True


def scale_bound(recentred: Problem, E: float, P: float) -> float:
    """A proven bound on ``|alpha|`` at every point whose cost on the exactly shifted data is
    at most ``P`` (in particular at the optimum, when ``P`` bounds the cost of an estimate):
    with ``m`` the least-squares misfit of the pose translations alone,
    ``min_t sum_i |R_A t_X + t_A - t_Y|^2 / (2 sigma_i^2)``, and ``T_B = sum_i |t_B|^2 /
    (2 sigma_i^2)``, the translation residual ``alpha (R_A t_X + t_A - t_Y) - R_Y t_B`` has
    weighted norm at least ``|alpha| m^(1/2) - T_B^(1/2)`` (Minkowski), so
    ``|alpha| <= (P^(1/2) + T_B^(1/2)) / m^(1/2)``; ``m^(1/2)`` of the exactly shifted data is at
    least that of ``recentred``'s data less ``E``. ``inf`` when nothing can be proven."""
    m = pose_misfit_lower_bound(recentred)
    root_m = np.sqrt(m) * (1.0 - 4.0 * UNIT_ROUNDOFF) - E * (1.0 + 4.0 * UNIT_ROUNDOFF)
    if not root_m > 0.0:
        return float("inf")
    n = 3 * recentred.n_measurements + 8
    t_b = 0.0
    for e in recentred.edges:
        w_up = (1.0 + gamma(6)) / (2.0 * e.sigma * e.sigma)
        t_b += float(np.sum(w_up * np.sum(e.B[:, :3, 3] ** 2, axis=1)))
    t_b *= 1.0 + gamma(n)
    bound = (np.sqrt(max(P, 0.0)) + np.sqrt(t_b)) * (1.0 + 8.0 * UNIT_ROUNDOFF) / root_m
    return float(bound * (1.0 + 4.0 * UNIT_ROUNDOFF))


def pose_misfit_lower_bound(problem: Problem) -> float:
    """A proven lower bound on ``m = min_{t_X, t_Y} q(t)``,
    ``q = sum_i w_i |R_A t_X + t_A - t_Y|^2`` with ``w_i = 1 / (2 sigma_i^2)`` (rounded down): how
    badly the pose translations alone fit a rigid chain (0 when nothing can be proven).

    For any point ``z`` (the solution of the normal equations, in floating point),
    ``m >= q(z) - |grad q(z)|^2 / (4 lambda_min(H))`` for the convex quadratic ``q`` with
    Hessian ``2 H`` (strong convexity); ``q(z)`` from below and ``|grad q(z)|`` from above with
    the rounding of the residuals (``gamma_5`` of each of their 5-term sums) and of the sums,
    ``lambda_min(H)`` by a verified Cholesky bound less the rounding in forming ``H``."""
    from ..numerics.verified import verified_min_eigenvalue

    M, n = problem.M, problem.n_frames
    N = problem.n_measurements
    st = problem.stacked()
    R, t = st["A"][:, :3, :3], st["A"][:, :3, 3]
    w = (1.0 - gamma(6)) / (2.0 * st["sigma"] * st["sigma"])  # below the exact weights
    ix, iy = 3 * st["xi"], 3 * (M + st["yi"])
    # H = sum_i w_i J_i^T J_i, J_i = [R_A at X_j, -I at Y_k]; |H| the same of |J_i|
    d = 3 * n
    H = np.zeros((d, d))
    H_abs = np.zeros((d, d))
    RtR = np.einsum("nab,nac->nbc", R, R) * w[:, None, None]
    absR = np.abs(R)
    RtR_abs = np.einsum("nab,nac->nbc", absR, absR) * w[:, None, None]
    wI = w[:, None, None] * np.eye(3)
    for blocks, absb, rows, cols in ((RtR, RtR_abs, ix, ix), (wI, wI, iy, iy),
                                     (-np.swapaxes(R, 1, 2) * w[:, None, None],
                                      np.swapaxes(absR, 1, 2) * w[:, None, None], ix, iy)):
        r_idx = rows[:, None, None] + np.arange(3)[None, :, None]
        c_idx = cols[:, None, None] + np.arange(3)[None, None, :]
        np.add.at(H, (r_idx, c_idx), blocks)
        np.add.at(H_abs, (r_idx, c_idx), absb)
        if rows is not cols:
            np.add.at(H, (c_idx, r_idx), blocks)
            np.add.at(H_abs, (c_idx, r_idx), absb)
    H = 0.5 * (H + H.T)  # symmetric as stored (verified_min_eigenvalue); u |H| more below
    dH = gamma(N + 10) * float(np.max(H_abs.sum(axis=1))) * (1.0 + gamma(d + 2))
    vb = verified_min_eigenvalue(H)
    lam = (vb.lower - dH) * (1.0 - 4.0 * UNIT_ROUNDOFF)
    if not (vb.verified and lam > 0.0):
        return 0.0
    # b = sum_i w_i J_i^T t_A,i; z solves H z = -b (any z gives a valid bound)
    b = np.zeros(d)
    np.add.at(b, ix[:, None] + np.arange(3), np.einsum("nab,na->nb", R, t) * w[:, None])
    np.add.at(b, iy[:, None] + np.arange(3), -t * w[:, None])
    try:
        z = np.linalg.solve(H, -b)
    except np.linalg.LinAlgError:
        return 0.0
    tX, tY = z[ix[:, None] + np.arange(3)], z[iy[:, None] + np.arange(3)]
    g = np.einsum("nab,nb->na", R, tX) + t - tY
    eps = gamma(5) * (np.einsum("nab,nb->na", absR, np.abs(tX)) + np.abs(t) + np.abs(tY))
    k = gamma(3 * N + 8)
    q = float(np.sum(w * np.sum(g * g, axis=1))) * (1.0 - k)
    s_eps = float(np.sum(w * np.sum(eps * eps, axis=1))) * (1.0 + k)
    root_q = np.sqrt(q) * (1.0 - 4.0 * UNIT_ROUNDOFF) - np.sqrt(s_eps) * (1.0 + 4.0 * UNIT_ROUNDOFF)
    if not root_q > 0.0:
        return 0.0
    # grad q = 2 sum_i w_i J_i^T g_i: computed, plus the residuals' and the sums' rounding
    grad = np.zeros(d)
    err = np.zeros(d)
    wg, we = w[:, None] * g, w[:, None] * (eps + gamma(N + 8) * np.abs(g))
    np.add.at(grad, ix[:, None] + np.arange(3), np.einsum("nab,na->nb", R, wg))
    np.add.at(grad, iy[:, None] + np.arange(3), -wg)
    np.add.at(err, ix[:, None] + np.arange(3), np.einsum("nab,na->nb", absR, we))
    np.add.at(err, iy[:, None] + np.arange(3), we)
    g_norm = 2.0 * (np.linalg.norm(grad) + np.linalg.norm(err) * (1.0 + gamma(N + 8))) \
        * (1.0 + gamma(d + 8))
    m = (root_q * root_q - g_norm * g_norm / (4.0 * lam)) * (1.0 - 8.0 * UNIT_ROUNDOFF)
    return float(max(m, 0.0))


def recentred_analysis(problem: Problem, result, priors: bool = False):
    """``(problem, result)`` about :func:`recentring_for`'s point, for the analyses of an
    estimate that the shift leaves unchanged in exact arithmetic -- the information matrix
    (:mod:`rwhec_ros.core.analysis.information`: every residual and its derivatives with respect to
    ``t_X, t_Y, alpha`` and the rotations are the same), hence the covariances and the
    next-motion guidance -- and that far from the origin suffer the same rounding as the solve
    (with unknown scale an observable direction taken for an unobservable one). ``result`` is a
    shallow copy with its moved frames ``- c``; the inputs are returned as they are when there
    is nothing to re-centre or ``priors`` (translation priors are about the given origin)."""
    rc = None if priors else recentring_for(problem)
    if rc is None:
        return problem, result
    shifted = copy.copy(result)
    shifted.X, shifted.Y = recentred_frames(result.X, result.Y, rc)
    return recentred_problem(problem, rc)[0], shifted


def far_scale_words(rc: Recentring) -> str:
    """Words for a not-identifiable status of data solved as given because, with unknown scale,
    no bound on the scale could be proven for ``rc``'s re-centring: far from the origin an
    observable scale can look unobservable."""
    return (f"the data are about {np.linalg.norm(rc.offset):.3g} m from the {rc.carrier}'s "
            "origin, where double precision rounds the translations too coarsely to tell the "
            "scale from a shift, and with the unknown scale they could not be solved about a "
            "nearby point (no bound on the scale could be proven): express the poses about an "
            "origin near the data and solve again")
