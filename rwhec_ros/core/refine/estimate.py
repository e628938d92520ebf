"""The corner-level refinement of a solved calibration: the entry point :func:`refine_views`.

From the certified pose-level optimum (``X``, ``Y``, ``alpha``), on every kept corner
(:mod:`.views`) through the chain and the cameras' projections (:mod:`.model`):

1. the fit **with pose errors** and the noise estimated from the residuals
   (:meth:`.fit.CornerFit.estimate_noise`): the corner noise per camera, the pose stream's noise
   per axis of the moving carrier;
2. the **plain** fit (pose errors held at zero, every corner independent: the reprojection-error
   fit of industrial_calibration or Kalibr) at the same corner noise;
3. the model whose estimate predicts the corners of *unseen* pose samples better is kept:
   ``folds``-fold cross-validation over the pose groups at the noise of step 1, the RMS corner
   distance of the held-out views through the chain (pose errors zero: what an overlay on a new
   image shows). The plain fit is kept only when its held-out RMS is lower by more than
   :attr:`RefineOptions.plain_margin`; the fit with pose errors is the maximum-likelihood one
   when the model holds (with a noisy pose stream the plain fit lets the corners of one image
   speak as if independent, and loses accuracy), the plain one wins where something the model
   does not know (intrinsics, a board's size) is better absorbed by the frames, as on real sets
   whose overlay it halves.
4. with a ``pose_level`` fit (the caller's pose-level solve of the pairs without the held-out
   pose samples), the same folds also score the **certified estimate's** way of fitting: each
   fold's pose-level estimate predicts its held-out corners, and
   :attr:`Refinement.held_out_rms_px` gets the key ``"certified"``. :mod:`.decision` publishes
   the refinement only where it predicts unseen corners no worse than that: a corner-level fit
   of a few pose samples can fit their corners closely and predict new ones worse than the
   pose-level estimate (a real 6-view chessboard set: 0.79 -> 0.38 px in-sample, 1.21 -> 2.04 px
   held out).

The covariance of the kept estimate comes from the corner-level model with the noise of step 1
(:meth:`.fit.CornerFit.covariance`), scaled up where the cross-validation folds' estimates
spread significantly more than it says (:mod:`.spread`: a jackknife over the pose samples).
Everything here is a *local* estimate of a different cost
than the certified one; :data:`SCOPE` says so in words and :mod:`.decision` decides what is
published.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from ..numerics.blas import blas_threads
from .fit import CornerFit, Noise, RefinementFailed
from .model import SIDES, State
from .spread import FoldSpread, fold_spread
from .views import CornerViews

__all__ = ["RefineOptions", "Refinement", "RefinementFailed", "refine_views", "SCOPE", "MODELS",
           "PoseLevelFit"]

#: What the certificate proves once a refinement is published, in words.
SCOPE = ("the pose-level optimum is certified global; the corner-level refinement started from "
         "it (a local estimate on the reprojection error of the corners, not certified)")

#: Values of :attr:`RefineOptions.model`.
MODELS = ("auto", "pose_noise", "plain")

#: The pose-level estimate without some pose samples: called with the pose-stream transforms
#: ``A`` (K, 4, 4) of the held-out pose samples, it returns ``(X (M, 4, 4), Y (P, 4, 4), alpha)``
#: in the views' frame order, solved on the pairs of every other pose sample, or None when that
#: cannot be done (a frame left without pairs, a failed solve, a held-out ``A`` that matches no
#: pair).
PoseLevelFit = Callable[[np.ndarray], "tuple[np.ndarray, np.ndarray, float] | None"]


@dataclass(frozen=True)
class RefineOptions:
    """Options of :func:`refine_views`.

    Attributes
    ----------
    moving : str
        ``"y"``: the camera carrier moves (its pose error is ``E A``); ``"x"``: the target
        carrier moves (``A E``) (:mod:`.model`).
    model : str
        ``"auto"`` (module docstring), ``"pose_noise"`` or ``"plain"`` (that fit only; the
        noise is still estimated with pose errors, for the plain fit's covariance).
    huber : float
        Corners farther than this many ``sigma_k`` from their prediction weigh less (Huber).
    max_rounds : int
        Variance-component rounds.
    tolerance : float
        Stop when no noise estimate changes by more than this fraction.
    folds : int
        Cross-validation folds over the pose groups (``auto``, and with a pose-level fit);
        with fewer than ``2 folds`` pose groups, leave-one-out (each fold one pose group: the
        training parts stay as close to all the data as they can, where a few pose samples
        decide how well the frames are determined: on a real 6-view chessboard set, 3 folds of
        2 trained on 4 views and kept a fit that predicted new views worse than the certified
        estimate, 2.04 against 1.21 px, see benchmarks/refinement.md for today's numbers); with
        fewer than 4 pose groups no cross-validation (the fit with pose errors is kept, with a
        note).
    plain_margin : float
        The plain fit is kept when its held-out RMS is below ``1 - plain_margin`` times the
        other's.
    """

    moving: str = "y"
    model: str = "auto"
    huber: float = 3.0
    max_rounds: int = 60
    tolerance: float = 1e-3
    folds: int = 5
    plain_margin: float = 0.1

    def __post_init__(self) -> None:
        if self.moving not in SIDES:
            raise ValueError(f"moving: expected one of {SIDES}, got {self.moving!r}")
        if self.model not in MODELS:
            raise ValueError(f"model: expected one of {MODELS}, got {self.model!r}")
        if not (np.isfinite(self.huber) and self.huber > 0):
            raise ValueError(f"huber: must be finite and > 0, got {self.huber!r}")
        for name in ("max_rounds", "folds"):
            v = getattr(self, name)
            if isinstance(v, bool) or int(v) != v or v < (1 if name == "max_rounds" else 2):
                raise ValueError(f"{name}: must be an integer >= "
                                 f"{1 if name == 'max_rounds' else 2}, got {v!r}")
        if not (np.isfinite(self.tolerance) and 0 < self.tolerance < 1):
            raise ValueError(f"tolerance: must be in (0, 1), got {self.tolerance!r}")
        if not (np.isfinite(self.plain_margin) and 0 <= self.plain_margin < 1):
            raise ValueError(f"plain_margin: must be in [0, 1), got {self.plain_margin!r}")


@dataclass
class Refinement:
    """The refined estimate (module docstring).

    Attributes
    ----------
    x_names, y_names : tuple of str
    X, Y : ndarray, shapes (M, 4, 4), (P, 4, 4)
        Refined frames (metric).
    scale : float
        Refined ``alpha`` (unknown scale), else the start's.
    covariance : ndarray, shape (M + P, 6, 6)
        Per frame (X then Y) the covariance of ``[dt (m), phi (rad)]`` in its parent
        (:data:`rwhec_ros.core.analysis.uncertainty.CONVENTION`).
    scale_std : float or None
        Std of ``alpha`` (None for a known scale).
    model : str
        The fit kept: ``"pose_noise"`` or ``"plain"``.
    sigma_px : dict of str to float
        Per camera the corner noise [px per axis] estimated from the residuals.
    sigma_pose_m, sigma_pose_rad : float
        The pose stream's noise per axis of the moving carrier, estimated.
    rms_start_px, rms_px : dict of str to float
        Per camera the RMS corner distance [px] through the chain (what an overlay shows) at
        the start (the certified estimate) and at the refined one.
    n_corners : dict of str to int
        Corners per camera.
    cost_start, cost : float
        The kept fit's robust corner cost at the final noise, pose errors re-fitted, at the
        certified frames and at the refined ones (:mod:`.decision`).
    held_out_rms_px : dict of str to float
        Pooled held-out RMS [px] of each fit compared (``"pose_noise"``, ``"plain"``, and
        ``"certified"`` for the pose-level fit, module docstring), over the same held-out
        corners; empty without cross-validation.
    n_downweighted : int
        Corners beyond the Huber threshold at the end.
    rounds : int
    converged : bool
        The noise estimates converged.
    message : str
    notes : list of str
    timing_s : float
    spread : FoldSpread or None
        The cross-validation folds' spread against the model's covariance (:mod:`.spread`);
        where significant, ``covariance`` and ``scale_std`` are scaled by its factor.
    """

    x_names: tuple[str, ...]
    y_names: tuple[str, ...]
    X: np.ndarray
    Y: np.ndarray
    scale: float
    covariance: np.ndarray
    scale_std: float | None
    model: str
    sigma_px: dict[str, float]
    sigma_pose_m: float
    sigma_pose_rad: float
    rms_start_px: dict[str, float]
    rms_px: dict[str, float]
    n_corners: dict[str, int]
    cost_start: float = float("nan")
    cost: float = float("nan")
    held_out_rms_px: dict[str, float] = field(default_factory=dict)
    n_downweighted: int = 0
    rounds: int = 0
    converged: bool = False
    message: str = ""
    notes: list[str] = field(default_factory=list)
    timing_s: float = 0.0
    spread: FoldSpread | None = None

    @property
    def names(self) -> tuple[str, ...]:
        return self.x_names + self.y_names

    def transform(self, name: str) -> np.ndarray:
        if name in self.x_names:
            return self.X[self.x_names.index(name)]
        return self.Y[self.y_names.index(name)]

    def frame_covariance(self, name: str) -> np.ndarray:
        return self.covariance[self.names.index(name)]

    def pooled_rms(self, which: str = "refined") -> float:
        """The RMS over every corner of ``rms_px`` (``"refined"``) or ``rms_start_px``."""
        rms = self.rms_px if which == "refined" else self.rms_start_px
        n = sum(self.n_corners[c] for c in rms)
        return float(np.sqrt(sum(rms[c] ** 2 * self.n_corners[c] for c in rms) / n))


def _squared_sum(tester: CornerFit, y_names, X, Y, alpha) -> float:
    """Sum of the squared corner distances [px^2] of ``tester``'s views through ``X, Y, alpha``
    (pose errors zero: what an overlay on a new image shows)."""
    rms = tester.rms(State.start(X, Y, alpha, tester.views.n_groups))
    return sum(rms[c] ** 2 * int(np.sum(tester.camera_of_corner == j))
               for j, c in enumerate(y_names) if c in rms)


def _held_out(views: CornerViews, cameras, unknown_scale, opts, starts: dict[str, State],
              noise: dict[str, Noise], pose_level: PoseLevelFit | None
              ) -> tuple[dict[str, float], list[str], dict[str, list[State]]]:
    """Pooled held-out RMS [px] of each fit of ``starts`` (and of the pose-level fit with
    ``pose_level``, key ``"certified"``) over ``opts.folds`` folds of the pose groups, and notes
    on folds left out; each fold's corner fit starts from the frames of ``starts`` (the fits on
    all the data: fewer steps to the fold's optimum) at the noise ``noise[name]``. A fold enters
    only when every fit could score it, so that all compare on the same corners. Also returns
    each fit's estimate per fold entered (the jackknife of :mod:`.spread`)."""
    fold = (np.arange(views.n_groups) % opts.folds)[views.view_group]
    names = [*starts, *(["certified"] if pose_level is not None else [])]
    sums = dict.fromkeys(names, 0.0)
    n_held, notes = 0, []
    fold_states: dict[str, list[State]] = {name: [] for name in starts}
    for k in range(opts.folds):
        test = fold == k
        train_views, test_views = views.subset(~test), views.subset(test)
        if train_views.frames_seen() != set(views.x_names + views.y_names):
            notes.append(f"cross-validation fold {k + 1} left out: its training part lacks a "
                         "frame")
            continue
        train = CornerFit(train_views, cameras, unknown_scale, opts.moving, opts.huber)
        tester = CornerFit(test_views, cameras, unknown_scale, opts.moving, opts.huber)
        part, fitted_states = {}, {}
        try:
            for name, s0 in starts.items():
                s = train.gauss_newton(
                    State.start(s0.X, s0.Y, s0.alpha, train_views.n_groups), noise[name],
                    tol=0.1)
                part[name] = _squared_sum(tester, views.y_names, s.X, s.Y, s.alpha)
                fitted_states[name] = s
        except RefinementFailed as exc:
            notes.append(f"cross-validation fold {k + 1} left out: {exc}")
            continue
        if pose_level is not None:
            fitted = pose_level(test_views.A)
            if fitted is None:
                notes.append(f"cross-validation fold {k + 1} left out: no pose-level estimate "
                             "without its pose samples")
                continue
            part["certified"] = _squared_sum(tester, views.y_names, *fitted)
        for name, v in part.items():
            sums[name] += v
        for name, st in fitted_states.items():
            fold_states[name].append(st)
        n_held += test_views.n_corners
    if not n_held:
        return {}, notes, fold_states
    return {m: float(np.sqrt(v / n_held)) for m, v in sums.items()}, notes, fold_states


def refine_views(views: CornerViews, cameras: Mapping, X: np.ndarray, Y: np.ndarray,
                 alpha: float, unknown_scale: bool, options: RefineOptions | None = None,
                 pose_level: PoseLevelFit | None = None) -> Refinement:
    """Refine ``X``, ``Y`` (and ``alpha`` with ``unknown_scale``) on the corners of ``views``
    (module docstring).

    Parameters
    ----------
    views : CornerViews
        Every frame of ``X`` and ``Y`` must have a view.
    cameras : mapping of str to camera
        Per camera name an object with ``project_with_jacobian(points (N, 3)) -> (pixels (N, 2),
        d pixels / d points (N, 2, 3))`` (:class:`rwhec_ros.vision.projection.
        IntrinsicsProjector`).
    X, Y : ndarray, shapes (M, 4, 4), (P, 4, 4)
        The start (the certified estimate), frames in ``views``' order.
    alpha : float
    unknown_scale : bool
    options : RefineOptions, optional
    pose_level : PoseLevelFit, optional
        The pose-level solve without given pose samples: the cross-validation then scores the
        certified estimate's model too (module docstring, step 4).

    Raises
    ------
    RefinementFailed
        A frame without corners, a corner behind its camera at the start, or a direction the
        corners do not determine.
    """
    t0 = time.perf_counter()
    opts = options or RefineOptions()
    missing = [n for n in views.x_names + views.y_names if n not in views.frames_seen()]
    if missing:
        raise RefinementFailed(f"no corners of {', '.join(missing)}")
    with blas_threads(1):
        out = _refine(views, cameras, X, Y, alpha, unknown_scale, opts, pose_level)
    out.timing_s = time.perf_counter() - t0
    return out


def _refine(views, cameras, X, Y, alpha, unknown_scale, opts, pose_level) -> Refinement:
    fit = CornerFit(views, cameras, unknown_scale, opts.moving, opts.huber)
    start = State.start(X, Y, alpha, views.n_groups)
    if not np.isfinite(fit.cost(start, Noise(np.ones(len(views.y_names)), 1.0, 1.0))):
        raise RefinementFailed("a corner lies behind its camera at the certified estimate")
    rms0 = fit.rms(start)
    noise0 = Noise(np.array([max(rms0[n] / np.sqrt(2.0), 0.05) for n in views.y_names]),
                   1e-3, 1e-3)
    state, noise, rounds, converged, change = fit.estimate_noise(
        start, noise0, opts.max_rounds, opts.tolerance)
    notes = []
    held: dict[str, float] = {}
    fold_states: dict[str, list[State]] = {}
    model = "plain" if opts.model == "plain" else "pose_noise"
    plain = fit.gauss_newton(start, noise.as_plain()) if opts.model != "pose_noise" else None
    fits = {"pose_noise": state, "plain": plain} if opts.model == "auto" else \
        {model: plain if model == "plain" else state}
    if opts.model == "auto" or pose_level is not None:
        folds = opts.folds if views.n_groups >= 2 * opts.folds else views.n_groups  # else LOO
        if folds < 4:
            notes.append(f"{views.n_groups} pose samples: too few to compare the fits by "
                         "cross-validation" + ("; the fit with pose errors kept"
                                               if opts.model == "auto" else ""))
        else:
            held, cv_notes, fold_states = _held_out(
                views, cameras, unknown_scale, replace(opts, folds=folds), fits,
                {"pose_noise": noise, "plain": noise.as_plain()}, pose_level)
            notes += cv_notes
            if opts.model == "auto" and held and \
                    held["plain"] < (1.0 - opts.plain_margin) * held["pose_noise"]:
                model = "plain"
    kept = noise.as_plain() if model == "plain" else noise
    if model == "plain":
        state = plain
    cov, n_down = fit.covariance(state, kept)
    cost_start = fit.cost(fit.gauss_newton(start, kept, frames_fixed=True), kept)
    M, P = len(views.x_names), len(views.y_names)
    frames = np.stack([cov[6 * f:6 * f + 6, 6 * f:6 * f + 6] for f in range(M + P)])
    scale_var = max(cov[-1, -1], 0.0) if unknown_scale else None
    spread = fold_spread(fold_states.get(model, []), state, frames)
    if spread is not None and spread.significant:
        frames = frames * spread.factor
        scale_var = None if scale_var is None else scale_var * spread.factor
        notes.append(f"the covariance of the corner-level model scaled by {spread.factor:.3g} "
                     f"(std x{np.sqrt(spread.factor):.2g}): the estimates of the "
                     f"{spread.folds} cross-validation folds spread that much more than it "
                     "says (the model misses something: intrinsics, the target's print, the "
                     "structure of the pose errors)")
    message = (f"noise estimates converged in {rounds} rounds" if converged else
               f"noise estimates not converged in {rounds} rounds (still changing by "
               f"{100 * change:.2g} %)")
    return Refinement(
        x_names=views.x_names, y_names=views.y_names, X=state.X, Y=state.Y,
        scale=float(state.alpha), covariance=frames,
        scale_std=float(np.sqrt(scale_var)) if scale_var is not None else None,
        model=model, sigma_px={n: float(noise.sigma_px[k]) for k, n in enumerate(views.y_names)},
        sigma_pose_m=float(noise.sigma_m), sigma_pose_rad=float(noise.sigma_rad),
        rms_start_px=rms0, rms_px=fit.rms(state),
        n_corners={n: int(np.sum(fit.camera_of_corner == k)) for k, n in
                   enumerate(views.y_names)},
        cost_start=cost_start, cost=fit.cost(state, kept),
        held_out_rms_px=held, n_downweighted=n_down, rounds=rounds, converged=converged,
        message=message, notes=notes, spread=spread)
