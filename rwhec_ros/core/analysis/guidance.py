"""Next-motion guidance: which motion would most reduce the largest remaining uncertainty.

From the information matrix of the data so far (:mod:`rwhec_ros.core.analysis.information`), every
candidate motion is scored by the uncertainty the calibration would have *after* adding a few
pairs of that motion, predicted with the same Hessian formulas on synthetic, noise-free pairs
built from the current estimate (``B = Y^-1 A X``, the edge's median ``sigma`` and ``kappa``):

* **candidates**: for every edge ``(tag x, camera y)`` with data, starting from the latest pose
  in which the camera saw the tag, a sweep of the moving carrier (``GuidanceOptions.moving``: the
  camera carrier -- a mobile rig, an arm carrying the cameras -- or the tag carrier -- a
  hand-held target) back and forth about each of its own axes by each of ``angles_deg``, or
  along each of its axes by each of ``translations_m`` (``poses_per_motion`` poses evenly over
  ``[-amount, +amount]``); and, for frames with an unobservable axis (or when no such motion
  helps the worst frame), the same sweeps on *new* edges that would connect them, from a view of
  the tag straight in front of the camera at the typical distance of the data.
* **criterion** (lexicographic): first the number of unobservable axes (fewer is better), then
  the largest standard deviation over all frames and axes, each divided by its target
  (``target_std_translation_m``, ``target_std_rotation_deg``), so that millimetres and degrees
  compare -- the motion that most reduces the *worst* remaining std; ratios within 2 % count as
  equal, and then the sum of the squared ratios over all axes (a normalised trace, so that of
  several nearly equally bad frames as many as possible improve), an edge with data before a new
  one, and the gentler motion decide.
* **answer** in words an operator can follow, e.g. "rotate the rig back and forth about its x
  axis by about +-30 deg while cam2 sees tag_5", with the std it is predicted to bring down;
  or that nothing is needed when every std is already below its target.

Adding the information of a candidate is a rank-``<= 13`` update: when every direction is
determined, the new covariance comes from the Woodbury identity on the 12-13 coordinates of the
edge; otherwise (a candidate touching a frame with an unobservable axis) it is recomputed in full,
since the motion may make a direction observable.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..lie import invert_transform, make_transform, so3_exp
from ..model.recentre import recentred_analysis
from ..numerics.blas import blas_threads
from ..problem import Problem
from .information import (
    Information,
    check_result_frames,
    information_matrix,
    pair_terms,
    scatter_information,
)
from .uncertainty import UncertaintyOptions, covariance_of, frame_covariances

__all__ = ["GuidanceOptions", "MotionCandidate", "Guidance", "suggest_next_motion"]

_AXES = ("x", "y", "z")
#: ``T_cam_tag`` rotation of a tag seen face-on and upright (tag z towards the camera).
_FACING = np.diag([1.0, -1.0, -1.0])


@dataclass
class GuidanceOptions:
    """Options of :func:`suggest_next_motion`.

    Attributes
    ----------
    target_std_translation_m, target_std_rotation_deg : float
        The stds a frame should reach (5 mm, 0.25 deg); they make translation and rotation stds
        comparable and decide when nothing more is needed.
    angles_deg : tuple of float
        Rotation sweeps tried (+- each angle about each axis of the moving carrier).
    translations_m : tuple of float
        Translation sweeps tried (+- each distance along each axis); empty for none.
    poses_per_motion : int
        Synthetic pairs per candidate, evenly over the sweep (8).
    moving : str
        ``"y"``: the camera carrier (the Y frames' parent) moves; ``"x"``: the tag carrier.
    x_carrier, y_carrier : str
        Names of the carriers in the sentences (e.g. ``"the world"``, ``"the rig"``).
    new_edges : bool
        Also try edges without data (module docstring).
    view_distance_m : float or None
        Camera-tag distance of a new edge's view (default: the median of the data).
    uncertainty : UncertaintyOptions
        As for :func:`~rwhec_ros.core.analysis.uncertainty.frame_uncertainty` (pass the solve's
        gauge).
    """

    target_std_translation_m: float = 0.005
    target_std_rotation_deg: float = 0.25
    angles_deg: tuple[float, ...] = (15.0, 30.0, 45.0)
    translations_m: tuple[float, ...] = (0.2,)
    poses_per_motion: int = 8
    moving: str = "y"
    x_carrier: str = "the tag carrier"
    y_carrier: str = "the camera carrier"
    new_edges: bool = True
    view_distance_m: float | None = None
    uncertainty: UncertaintyOptions = field(default_factory=UncertaintyOptions)

    def __post_init__(self) -> None:
        for name in ("target_std_translation_m", "target_std_rotation_deg"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name}: must be finite and > 0, got {v!r}")
        for name in ("angles_deg", "translations_m"):
            vals = tuple(float(v) for v in getattr(self, name))
            bad = [v for v in vals if not (np.isfinite(v) and v > 0)]
            if bad:
                raise ValueError(f"{name}: every entry must be finite and > 0, got {bad[0]!r}")
            setattr(self, name, vals)
        if not self.angles_deg and not self.translations_m:
            raise ValueError("angles_deg, translations_m: need at least one motion to try")
        if int(self.poses_per_motion) < 2:
            raise ValueError(f"poses_per_motion: must be >= 2, got {self.poses_per_motion!r}")
        if self.moving not in ("x", "y"):
            raise ValueError(f"moving: expected 'x' or 'y', got {self.moving!r}")
        if self.view_distance_m is not None and not (np.isfinite(self.view_distance_m)
                                                     and self.view_distance_m > 0):
            raise ValueError(f"view_distance_m: must be finite and > 0, got "
                             f"{self.view_distance_m!r}")


@dataclass
class MotionCandidate:
    """One candidate motion and the uncertainty predicted after it.

    Attributes
    ----------
    x, y : str
        The tag (X) and camera (Y) frame that must see each other during the motion.
    kind : str
        ``"rotate"`` or ``"translate"``.
    axis : int
        Axis (0, 1, 2 = x, y, z) of the moving carrier.
    amount : float
        Sweep half-width: degrees for ``rotate``, metres for ``translate``.
    new_edge : bool
        The camera has not seen this tag yet.
    n_unobservable : int
        Unobservable axes after the motion.
    worst_ratio : float
        Largest std over its target after the motion.
    worst : str
        Which std that is, in words with its predicted value.
    total_ratio : float
        Sum of (std / target)^2 over all observable axes after the motion (the tie-breaker).
    """

    x: str
    y: str
    kind: str
    axis: int
    amount: float
    new_edge: bool
    n_unobservable: int
    worst_ratio: float
    worst: str
    total_ratio: float = float("nan")

    @property
    def score(self) -> tuple[int, float]:
        return (self.n_unobservable, self.worst_ratio)

    def words(self, options: GuidanceOptions) -> str:
        """The motion as an instruction, e.g. ``rotate the rig back and forth about its x axis by
        about +-30 deg while cam2 sees tag_5``."""
        carrier = options.y_carrier if options.moving == "y" else options.x_carrier
        if self.kind == "rotate":
            how = (f"rotate {carrier} back and forth about its {_AXES[self.axis]} axis by about "
                   f"+-{self.amount:.0f} deg")
        else:
            how = (f"move {carrier} back and forth along its {_AXES[self.axis]} axis by about "
                   f"+-{self.amount:.2g} m")
        if self.new_edge:
            return f"bring {self.x} into the view of {self.y} and {how} while it stays in view"
        return f"{how} while {self.y} sees {self.x}"

    def to_dict(self) -> dict:
        return {"x": self.x, "y": self.y, "kind": self.kind, "axis": _AXES[self.axis],
                "amount": float(self.amount), "new_edge": bool(self.new_edge),
                "n_unobservable": int(self.n_unobservable),
                "worst_ratio": float(self.worst_ratio), "worst": self.worst,
                "total_ratio": float(self.total_ratio)}


@dataclass
class Guidance:
    """The answer of :func:`suggest_next_motion`.

    Attributes
    ----------
    needed : bool
        Some std is above its target or some axis is unobservable.
    message : str
        One sentence for the operator.
    best : MotionCandidate or None
        The recommended motion (the least bad one when nothing is needed; ``None`` when no
        candidate improves anything).
    candidates : list of MotionCandidate
        The best few, best first.
    n_unobservable : int
        Unobservable axes now.
    worst_ratio : float
        Largest std over its target now (``nan`` when nothing is observable).
    worst : str
        Which std that is, in words.
    """

    needed: bool
    message: str
    best: MotionCandidate | None
    candidates: list[MotionCandidate]
    n_unobservable: int
    worst_ratio: float
    worst: str

    def to_dict(self) -> dict:
        return {"needed": bool(self.needed), "message": self.message,
                "best": None if self.best is None else self.best.to_dict(),
                "candidates": [c.to_dict() for c in self.candidates],
                "n_unobservable": int(self.n_unobservable),
                "worst_ratio": float(self.worst_ratio), "worst": self.worst}


def _ratios(C: np.ndarray, opts: GuidanceOptions) -> np.ndarray:
    """Stds over their targets (..., F, 6) from per-frame covariances (..., F, 6, 6) in the
    reporting convention (NaN on unobservable axes stays NaN)."""
    d = np.diagonal(C, axis1=-2, axis2=-1)
    st = np.sqrt(np.maximum(d[..., :3], 0.0)) / opts.target_std_translation_m
    sr = np.degrees(np.sqrt(np.maximum(d[..., 3:], 0.0))) / opts.target_std_rotation_deg
    return np.concatenate([st, sr], axis=-1)


def _assess(ratios: np.ndarray, names: tuple[str, ...], opts: GuidanceOptions,
            scale_null: bool) -> tuple[int, float, float, str, int]:
    """(unobservable axes, worst std / target, sum of (std / target)^2 over the observable
    axes, words for the worst, its frame index or -1) from :func:`_ratios` (F, 6)."""
    n_unobs = int(np.isnan(ratios).sum()) + int(scale_null)
    if not np.isfinite(ratios).any():
        return n_unobs, float("nan"), float("nan"), "nothing observable", -1
    f, i = np.unravel_index(int(np.nanargmax(ratios)), ratios.shape)
    if i < 3:
        words = (f"{names[f]} translation {_AXES[i]} "
                 f"+-{1e3 * ratios[f, i] * opts.target_std_translation_m:.3g} mm")
    else:
        words = (f"{names[f]} rotation {_AXES[i - 3]} "
                 f"+-{ratios[f, i] * opts.target_std_rotation_deg:.3g} deg")
    return n_unobs, float(ratios[f, i]), float(np.nansum(ratios**2)), words, int(f)


def _sweep(A0: np.ndarray, kind: str, axis: int, amount: float, opts: GuidanceOptions
           ) -> np.ndarray:
    """Pose-stream transforms (n, 4, 4) of a sweep of the moving carrier from ``A0``
    (``A = T_<camera carrier>_<tag carrier>``)."""
    s = np.linspace(-1.0, 1.0, int(opts.poses_per_motion)) * amount
    e = np.zeros((s.size, 3))
    if kind == "rotate":
        e[:, axis] = np.radians(s)
        D = make_transform(so3_exp(e), np.zeros((s.size, 3)))
    else:
        e[:, axis] = s
        D = make_transform(np.broadcast_to(np.eye(3), (s.size, 3, 3)), e)
    # the camera carrier moved by D (in its own frame): A' = D^-1 A; the tag carrier: A' = A D
    return invert_transform(D) @ A0 if opts.moving == "y" else A0 @ D


@dataclass
class _Base:
    """Where a candidate edge starts: frame indices, a pose ``A0`` and the precisions."""

    j: int
    k: int
    A0: np.ndarray
    sigma: float
    kappa: float
    new_edge: bool


def _bases(problem: Problem, info: Information, opts: GuidanceOptions, frames_in_need: set[int]
           ) -> tuple[list[_Base], list[_Base]]:
    """Existing-edge bases and new-edge bases (for ``frames_in_need``)."""
    M = problem.M
    existing = []
    for e, j, k in zip(problem.edges, problem.edge_x, problem.edge_y, strict=True):
        existing.append(_Base(int(j), int(k), e.A[-1], float(np.median(e.sigma)),
                              float(np.median(e.kappa)), False))
    if not (opts.new_edges and frames_in_need):
        return existing, []
    st = problem.stacked()
    dist = opts.view_distance_m or float(np.median(np.linalg.norm(st["B"][:, :3, 3], axis=1)))
    dist /= info.alpha  # metric
    B0 = make_transform(_FACING, np.array([0.0, 0.0, dist]))
    have = set(zip(problem.edge_x.tolist(), problem.edge_y.tolist(), strict=True))
    sig, kap = float(np.median(st["sigma"])), float(np.median(st["kappa"]))
    T = make_transform(info.R, info.t)
    new = []
    for j in range(M):
        for k in range(problem.P):
            if (j, k) in have or not ({j, M + k} & frames_in_need):
                continue
            A0 = T[M + k] @ B0 @ invert_transform(T[j])  # A X = Y B
            new.append(_Base(j, k, A0, sig, kap, True))
    return existing, new


def _candidate_terms(info: Information, base: _Base, motions: list, opts: GuidanceOptions):
    """The information of every motion on ``base``, one group of pairs per motion."""
    T = make_transform(info.R, info.t)
    A = np.concatenate([_sweep(base.A0, kind, axis, amount, opts)
                        for kind, axis, amount in motions])
    n = A.shape[0]
    X = np.broadcast_to(T[base.j], (n, 4, 4))
    Y = np.broadcast_to(T[info.layout.M + base.k], (n, 4, 4))
    B = invert_transform(Y) @ A @ X
    B[:, :3, 3] *= info.alpha
    starts = np.arange(len(motions)) * int(opts.poses_per_motion)
    return pair_terms(A, B, np.full(n, base.sigma), np.full(n, base.kappa), X, Y, info.alpha,
                      starts)


def _evaluate(problem, info, cov, base_ratios, bases, opts, touch_null: set[int]):
    """Score every motion on every base (module docstring: Woodbury or full recomputation)."""
    lay = info.layout
    motions = [("rotate", a, v) for v in opts.angles_deg for a in range(3)] + \
              [("translate", a, v) for v in opts.translations_m for a in range(3)]
    idx_f = lay.frame_indices(np.arange(lay.n_frames))
    C_ff = cov.sigma[idx_f[:, :, None], idx_f[:, None, :]]  # (F, 6, 6), internal coordinates
    unobs = np.isnan(base_ratios)
    keep = np.r_[0:6, 7:13] if not lay.unknown_scale else np.arange(13)
    out = []
    for b in bases:
        S = lay.pair_indices(np.array([b.j]), np.array([b.k]))[0]
        full = bool({b.j, lay.M + b.k} & touch_null) or cov.pinned
        terms = _candidate_terms(info, b, motions, opts)
        if full:
            ratios = []
            for m in range(len(motions)):
                one = dataclasses.replace(terms, hessian=terms.hessian[m:m + 1],
                                          translation_block=terms.translation_block[m:m + 1])
                dH, dQ = scatter_information(lay, np.array([b.j]), np.array([b.k]), one)
                new = dataclasses.replace(info, H=info.H + dH, Q_ee=info.Q_ee + dQ)
                c2 = covariance_of(new, problem, opts.uncertainty)
                C, _, _, scale_null = frame_covariances(c2, new, opts.uncertainty.axis_tol)
                ratios.append((_ratios(C, opts), scale_null))
        else:  # Woodbury on the edge's coordinates S, all motions at once
            h = terms.hessian[:, keep][:, :, keep]  # (m, s, s)
            K = np.linalg.solve(np.eye(S.size) + h @ cov.sigma[np.ix_(S, S)], h)
            Wf = cov.sigma[:, S][idx_f]  # (F, 6, s)
            Cf = C_ff - np.einsum("fis,mst,fjt->mfij", Wf, K, Wf, optimize=True)
            d_t = np.diagonal(Cf[:, :, :3, :3], axis1=2, axis2=3)
            d_r = np.einsum("fij,mfjk,fik->mfi", info.R, Cf[:, :, 3:, 3:], info.R,
                            optimize=True)  # diag(R C R^T): rotations in the parent
            d = np.concatenate([d_t, d_r], axis=2)  # (m, F, 6)
            Cd = np.zeros(d.shape + (6,))
            Cd[..., np.arange(6), np.arange(6)] = d  # diagonal covariances for _ratios
            r = np.where(unobs, np.nan, _ratios(Cd, opts))
            ratios = [(r[m], False) for m in range(len(motions))]
        for (kind, axis, amount), (rat, scale_null) in zip(motions, ratios, strict=True):
            n_unobs, worst, total, words, _ = _assess(rat, info.names, opts, scale_null)
            out.append(MotionCandidate(problem.x_names[b.j], problem.y_names[b.k], kind, axis,
                                       amount, b.new_edge, n_unobs, worst, words, total))
    return out


#: Ratios within this factor of the best count as equal when ranking candidates.
_RATIO_TIE = 1.02


def _rank(cands: list[MotionCandidate]) -> list[MotionCandidate]:
    """Best first: fewest unobservable axes; of those, the candidates whose worst ratio is
    within 2 % of the smallest; of those, the ones whose total is within 2 % of the smallest;
    of those an edge with data before a new one, then the gentler motion (smaller sweep). The
    rest follow by (unobservable axes, worst ratio, total)."""
    if not cands:
        return []
    n0 = min(c.n_unobservable for c in cands)
    pool = [c for c in cands if c.n_unobservable == n0]
    w0 = min(_finite(c.worst_ratio) for c in pool)
    if np.isfinite(w0):
        pool = [c for c in pool if c.worst_ratio <= w0 * _RATIO_TIE]
    t0 = min(_finite(c.total_ratio) for c in pool)
    if np.isfinite(t0):
        pool = [c for c in pool if c.total_ratio <= t0 * _RATIO_TIE]
    first = sorted(pool, key=lambda c: (c.new_edge, c.amount, _finite(c.worst_ratio)))
    chosen = {id(c) for c in first}
    rest = sorted((c for c in cands if id(c) not in chosen),
                  key=lambda c: (c.n_unobservable, _finite(c.worst_ratio),
                                 _finite(c.total_ratio)))
    return first + rest


def _finite(v: float) -> float:
    return v if np.isfinite(v) else np.inf


def suggest_next_motion(
    problem: Problem,
    result,
    options: GuidanceOptions | None = None,
    *,
    info: Information | None = None,
    top: int = 5,
) -> Guidance:
    """The motion that would most reduce the largest remaining std (module docstring).

    Parameters
    ----------
    problem : Problem
        The data so far.
    result : CalibrationResult
        The current estimate (``X``, ``Y``, ``scale``) for ``problem``.
    options : GuidanceOptions, optional
    info : Information, optional
        The information matrix at ``result`` if already computed.
    top : int
        Number of candidates kept in :attr:`Guidance.candidates`.
    """
    opts = options or GuidanceOptions()
    with blas_threads(opts.uncertainty.blas_threads):
        return _suggest(problem, result, opts, info, top)


def _suggest(problem: Problem, result, opts: GuidanceOptions, info: Information | None,
             top: int) -> Guidance:
    check_result_frames(problem, result)
    # far from the pose stream's origin: the same analysis about a nearby point (exact; a given
    # ``info`` is the same matrix in exact arithmetic)
    problem, result = recentred_analysis(problem, result,
                                         priors=bool(opts.uncertainty.gauge.priors))
    if info is None:
        info = information_matrix(problem, result.X, result.Y, result.scale)
    cov = covariance_of(info, problem, opts.uncertainty)
    C, ut, ur, scale_null = frame_covariances(cov, info, opts.uncertainty.axis_tol)
    base_ratios = _ratios(C, opts)
    n_unobs, ratio, _, worst, worst_frame = _assess(base_ratios, info.names, opts, scale_null)
    touch_null = {f for f in range(info.layout.n_frames) if ut[f].any() or ur[f].any()}
    if scale_null:
        touch_null = set(range(info.layout.n_frames))
    existing, new = _bases(problem, info, opts, touch_null)
    cands = _evaluate(problem, info, cov, base_ratios, existing, opts, touch_null)
    best_existing = _rank(cands)[0] if cands else None
    weak_help = (best_existing is None or best_existing.score[0] > 0
                 or best_existing.worst_ratio > 0.9 * ratio)
    if not new and opts.new_edges and weak_help and worst_frame >= 0 and ratio > 1:
        _, new = _bases(problem, info, opts, {worst_frame})
    if new:
        cands += _evaluate(problem, info, cov, base_ratios, new, opts, touch_null)
    cands = _rank(cands)
    best = cands[0] if cands and (cands[0].n_unobservable, _finite(cands[0].worst_ratio)) < (
        n_unobs, _finite(ratio)) else None
    needed = n_unobs > 0 or not (ratio <= 1.0)
    if not needed:
        message = (f"nothing needed: every std is below its target (largest: {worst}, "
                   f"{ratio:.2g} of its target)")
    elif best is None:
        message = (f"largest std: {worst}; none of the motions tried would reduce it: collect "
                   "more data with other motions, or check the data")
    else:
        now = f"now {n_unobs} unobservable axes" if n_unobs else f"largest std now {worst}"
        if best.n_unobservable:
            after = f"{best.n_unobservable} unobservable axes, largest std {best.worst}"
        elif n_unobs:
            after = f"all observable, largest std {best.worst}"
        else:
            after = f"largest std {best.worst}"
            gain = 1.0 - best.worst_ratio / ratio
            if gain < 0.1:
                after += (f"; only {100 * gain:.0f} % lower: other frames are about as "
                          "uncertain, one motion cannot fix them all")
        message = f"{best.words(opts)} ({now}; predicted after it: {after})"
    return Guidance(needed=needed, message=message, best=best, candidates=cands[:top],
                    n_unobservable=n_unobs, worst_ratio=ratio, worst=worst)
