"""Time offsets between the pose stream and each camera: estimated, applied, reported.

A camera's offset ``delta_k`` (``t_pose = t_image + delta_k``) is the delay between the stamps of
its images and the pose stream's clock: the pose that belongs to an image is the stream at its
stamp plus ``delta_k``. A known offset is applied where the images come in
(``sync.time_offset.<camera>``: the session then works in the stream's time); this module
estimates what is left of it from the data, per camera, and applies what the data show.

Method (:func:`estimate_offsets`; the maths and why it is done this way:
:mod:`rwhec_ros.core.analysis.time_offset`): the certified solve of the pairs as they are, then
profile Newton steps on all cameras' offsets at once, each followed by the pairs re-interpolated
from the recorded stream (:mod:`rwhec_ros.sync.pose_track`) at their shifted stamps and a warm
started solve, until a step is below a tenth of the offsets' standard deviations (at most
``MAX_ITERATIONS``). The standard deviation is the marginal one (extrinsics free), cluster-robust
(pairs within 100 ms of each other share a cluster: the stream's error is shared), and never below
the model-based one (the residuals' variance factor times the inverse information).

Only pairs taken while the stream moved say anything about an offset (a pair at rest pairs with
the same pose whatever the offset): a pair counts when the stream moved more than
``MOVING_SPEED_M_S`` or ``MOVING_RATE_RAD_S`` over the 100 ms around it (well above the jitter of
a motion-capture stream at rest, 0.5 mm / 0.5 mrad per sample giving ~7 mm/s). A camera's offset
is **not determined** -- reported in words, never as a number -- when fewer than
``MIN_MOVING_PAIRS`` of its pairs moved (a rig that barely moved; stop-and-go data), when the
motion does not separate it from the extrinsics, when its standard deviation exceeds
``sync.time_offset_max_std_s``, or when the estimate runs into the search range
(``sync.time_offset_range_s``). A determined offset beyond 3 standard deviations is
**significant**: it is applied (the final pairs are re-interpolated at the corrected stamps and
solved, certified as usual) and, beyond 2 ms too, the verdict names it as a caution with the
fix. A determined offset within 3 standard deviations is reported and not applied (the pairs stay
as they are: zero is as good an estimate). How the offsets are reported (result, summary,
``/diagnostics``, the verdict's caution): :mod:`rwhec_ros.session.time_offset_report`.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping

import numpy as np

from ..core.analysis.information import information_from_edge_blocks, information_matrix
from ..core.analysis.time_offset import offset_step, offset_terms
from ..core.numerics.blas import blas_threads
from ..core.outliers.pairs import pair_residuals
from ..core.problem import Edge, Problem
from ..sync.pose_track import MOTION_HALF_WINDOW_NS, PoseTrackData
from .offset_rates import glitch_free, plausible
from .offset_significance import likelihood_ratio_sigmas
from .time_offset_report import (
    CAUTION_S,
    SIGNIFICANT_SIGMAS,
    CameraOffset,
    TimeOffsetOptions,
    TimeOffsetReport,
    add_offset_reasons,
)

__all__ = ["TimeOffsetOptions", "CameraOffset", "TimeOffsetReport", "estimate_offsets",
           "one_step_offsets", "add_offset_reasons", "shift_dataset",
           "MOVING_SPEED_M_S", "MOVING_RATE_RAD_S", "MIN_MOVING_PAIRS", "SIGNIFICANT_SIGMAS",
           "CAUTION_S", "MAX_ITERATIONS", "correct_time_offsets", "live_offsets",
           "offsets_then_assess"]

_NS = 1_000_000_000
#: A pair counts as moving when the stream moved faster than this [m/s] ...
MOVING_SPEED_M_S = 0.05
#: ... or turned faster than this [rad/s] (5.7 deg/s) around it (over +-50 ms).
MOVING_RATE_RAD_S = 0.1
#: Fewest moving pairs of a camera for its offset to count as determined.
MIN_MOVING_PAIRS = 6
#: A pair whose ``J_i`` (eq. (33)) exceeds this many times the median of its camera's pairs is
#: left out of the offsets at that step (an outlier: wrong tag pose, glitch of the stream); the
#: residuals of a camera whose offset is still uncorrected grow with each pair's speed squared
#: (a factor ~10 between the median and the fastest pair in the benchmark's motions).
OUTLIER_RATIO = 30.0
#: Pairs whose (shifted) stamps fall in the same window of this length share a cluster of the
#: offsets' cluster-robust covariance: the motion window of the moving test (100 ms).
CLUSTER_WINDOW_NS = 2 * MOTION_HALF_WINDOW_NS
#: Newton steps at most (each a re-interpolation and a solve); 2-3 suffice in the benchmark.
MAX_ITERATIONS = 6
#: Stop when every step is below this fraction of its offset's std (or below 50 us).
_STEP_TOL_STD = 0.1
_STEP_TOL_S = 5e-5


# --- re-interpolation ----------------------------------------------------------------------------
def _reinterpolated(problem: Problem, stamps: list[np.ndarray], track: PoseTrackData,
                    delta_ns: np.ndarray) -> tuple[Problem, list[np.ndarray]]:
    """``problem`` with each edge's ``A`` re-interpolated at its stamps shifted by its camera's
    ``delta_ns`` (cameras with 0 keep their pairs), and per edge the mask of the pairs kept
    (pairs the stream does not cover at the shifted stamp are left out). One batched lookup:
    the per-call cost of the SE(3) logarithm dominates small batches."""
    shift = [int(delta_ns[k]) for k in problem.edge_y]
    moved = [i for i, d in enumerate(shift) if d]
    looked = {}
    if moved:
        q = np.concatenate([stamps[i] + shift[i] for i in moved])
        A, ok = track.lookup(q)
        ends = np.cumsum([stamps[i].shape[0] for i in moved])[:-1]
        looked = dict(zip(moved, zip(np.split(A, ends), np.split(ok, ends), strict=True),
                          strict=True))
    edges, masks = [], []
    for i, e in enumerate(problem.edges):
        if i not in looked:
            edges.append(e)
            masks.append(np.ones(e.n, dtype=bool))
            continue
        A, ok = looked[i]
        masks.append(ok)
        if ok.any():
            edges.append(Edge._of(e.x, e.y, A[ok], e.B[ok], e.sigma[ok], e.kappa[ok]))
    return problem.with_edges(edges), masks


def _rates(problem: Problem, stamps: list[np.ndarray], track: PoseTrackData,
           delta_ns: np.ndarray, moving: np.ndarray) -> np.ndarray:
    """Twist rates (N, 6) at the shifted stamps of the ``moving`` (N,) pairs (NaN elsewhere),
    in one batch."""
    if not stamps:
        return np.zeros((0, 6))
    q = _shifted_stamps(problem, stamps, delta_ns)
    xi, ok = track.rates(q)
    xi[~(ok & moving & plausible(xi) & glitch_free(track, q))] = np.nan
    return xi


def _fitting(problem: Problem, result, rates: np.ndarray) -> np.ndarray:
    """``rates`` with the pairs that fit far worse than their camera's others (:data:`
    OUTLIER_RATIO`) set to NaN: outliers say nothing reliable about an offset."""
    res = pair_residuals(problem, result.X, result.Y, result.scale)
    J = np.concatenate([res[e.name].normalised for e in problem.edges])
    camera = np.repeat(problem.edge_y, [e.n for e in problem.edges])
    out = rates.copy()
    for k in range(problem.P):
        mine = (camera == k) & np.isfinite(rates).all(axis=1)
        if mine.any():
            limit = OUTLIER_RATIO * float(np.median(J[mine]))
            out[mine & (J > limit)] = np.nan
    return out


def _moving(track: PoseTrackData, q: np.ndarray) -> np.ndarray:
    """Whether the stream moved around each stamp of ``q`` (N,) (module docstring)."""
    shift, angle = track.motion(q, MOTION_HALF_WINDOW_NS)
    window = 2 * MOTION_HALF_WINDOW_NS / _NS
    with np.errstate(invalid="ignore"):
        return (shift > MOVING_SPEED_M_S * window) | (angle > MOVING_RATE_RAD_S * window)


def _clusters(problem: Problem, stamps: list[np.ndarray], delta_ns: np.ndarray) -> np.ndarray:
    """A cluster label (N,) per pair: the :data:`CLUSTER_WINDOW_NS` window of the pose stream its
    shifted stamp falls in, whatever the camera (pairs of one image, of images taken together,
    of neighbouring stream samples share the stream's error: the offsets' cluster-robust
    covariance, :func:`~rwhec_ros.core.analysis.time_offset.offset_step`)."""
    if not stamps:
        return np.zeros(0, dtype=np.int64)
    return np.floor_divide(_shifted_stamps(problem, stamps, delta_ns), CLUSTER_WINDOW_NS)


def _shifted_stamps(problem: Problem, stamps: list[np.ndarray], delta_ns: np.ndarray
                    ) -> np.ndarray:
    """Every pair's stamp (N,) in problem order, shifted by its camera's ``delta_ns``."""
    return np.concatenate([s + int(delta_ns[k]) for s, k in zip(stamps, problem.edge_y,
                                                                 strict=True)])


def _per_camera(problem: Problem, stamps: list[np.ndarray], flags: np.ndarray) -> np.ndarray:
    """How many of the pairs ``flags`` (N,) marks each camera (P,) has."""
    camera = np.repeat(problem.edge_y, [s.shape[0] for s in stamps])
    return np.bincount(camera, weights=flags, minlength=problem.P).astype(int)


def _check_stamps(problem: Problem, stamps: Mapping[tuple[str, str], np.ndarray]
                  ) -> list[np.ndarray] | None:
    out = []
    for e in problem.edges:
        s = stamps.get((e.x, e.y))
        if s is None or len(s) != e.n:
            return None
        out.append(np.asarray(s, dtype=np.int64))
    return out


# --- estimation ----------------------------------------------------------------------------------
def _not(problem: Problem, options: TimeOffsetOptions, status: str, why: str,
         elapsed: float = 0.0) -> TimeOffsetReport:
    counts = {y: 0 for y in problem.y_names}
    for e in problem.edges:
        counts[e.y] += e.n
    cams = {y: CameraOffset(y, status, options.configured(y), options.parameter(y),
                            pairs=counts[y], why=why) for y in problem.y_names}
    return TimeOffsetReport(cams, elapsed_s=elapsed, range_s=options.range_s)


def _unavailable(problem: Problem, stamps, track, options) -> TimeOffsetReport | None:
    if not options.estimate:
        return _not(problem, options, "not_estimated", "sync.estimate_time_offset is off")
    if track is None or track.n < 2:
        return _not(problem, options, "not_estimated",
                    "no pose stream kept: the poses are given per image (pose_source.type: tf, "
                    "looked up at each image stamp; pose lists, samples, a data set without "
                    "its stream); a PoseStamped topic (pose_source.type: topic) keeps the "
                    "stream the estimate needs")
    if _check_stamps(problem, stamps) is None:
        return _not(problem, options, "not_estimated", "the pairs' stamps are not known")
    return None


def _judge(problem: Problem, options: TimeOffsetOptions, delta: np.ndarray, step,
           moving_counts: np.ndarray, clipped: np.ndarray,
           lr: Mapping[int, float] | None = None) -> dict[str, CameraOffset]:
    out = {}
    counts = np.zeros(problem.P, dtype=int)
    for e, k in zip(problem.edges, problem.edge_y, strict=True):
        counts[k] += e.n
    std = step.std_s
    for k, cam in enumerate(problem.y_names):
        o = CameraOffset(cam, "not_determined", options.configured(cam), options.parameter(cam),
                         moving_pairs=int(moving_counts[k]), pairs=int(counts[k]))
        if moving_counts[k] < MIN_MOVING_PAIRS:
            o.why = (f"{moving_counts[k]} of its {counts[k]} pairs were taken while the pose "
                     f"stream moved (faster than {MOVING_SPEED_M_S:g} m/s or "
                     f"{math.degrees(MOVING_RATE_RAD_S):.1f} deg/s), {MIN_MOVING_PAIRS} needed: "
                     "pairs at rest say nothing about a time offset")
        elif not step.determined[k]:
            o.why = "the motion does not separate it from the extrinsics"
        elif clipped[k]:
            o.why = (f"the estimate runs into the search range +-{1e3 * options.range_s:g} ms "
                     "(sync.time_offset_range_s): a larger offset, or pairs that fit no offset")
        elif not std[k] <= options.max_std_s:
            o.why = (f"std {1e3 * std[k]:.1f} ms > sync.time_offset_max_std_s = "
                     f"{1e3 * options.max_std_s:g} ms: move faster or longer")
        else:
            o.status, o.estimate_s, o.std_s = "estimated", float(delta[k]), float(std[k])
            o.lr_sigmas = float((lr or {}).get(k, math.nan))
            o.applied = o.significant
        out[cam] = o
    return out


def _solved(out, problem: Problem) -> tuple[object, Problem]:
    """``(result, weighted problem)`` of a ``solve_fn`` answer: a result (the weights of
    ``problem``) or ``(result, problem with the weights it was solved with)``."""
    if isinstance(out, tuple):
        return out
    return out, problem


def estimate_offsets(
    problem: Problem,
    stamps: Mapping[tuple[str, str], np.ndarray],
    track: PoseTrackData | None,
    options: TimeOffsetOptions,
    solve_fn: Callable[[Problem, tuple | None], object],
    solve_fixed: Callable[[Problem, tuple], object] | None = None,
) -> tuple[TimeOffsetReport, Problem]:
    """Estimate every camera's offset and return the problem with the significant ones applied
    (module docstring).

    Parameters
    ----------
    problem : Problem
        The pairs at their stamps (pose-stream time: image stamp + configured offset).
    stamps : mapping (x, y) -> ndarray (N_e,) int64
        The stamps of each edge's pairs, in the problem's pair order.
    track : PoseTrackData or None
        The recorded pose stream around the pairs (:mod:`rwhec_ros.sync.pose_track`).
    options : TimeOffsetOptions
    solve_fn : callable(problem, initial) -> CalibrationResult or (CalibrationResult, Problem)
        The solve (``initial``: ``(X, Y)`` warm start or None); with the problem it solved when
        that carries other weights (the noise estimated from the data): the Newton steps and
        the offsets' std are then those of these weights.
    solve_fixed : callable(problem, initial) -> CalibrationResult, optional
        A solve that keeps the problem's weights: given, an offset that the Newton steps find
        beyond 3 std is tested again by the likelihood ratio of a solve without it
        (:mod:`rwhec_ros.session.offset_significance`), and is significant only when that
        agrees. None: the 3-std test alone.

    Returns
    -------
    report : TimeOffsetReport
    problem : Problem
        ``problem`` itself when nothing is applied, else its pairs re-interpolated at the
        corrected stamps of the cameras whose offset is applied (pairs the stream does not
        reach there left out, counted in :attr:`CameraOffset.dropped`).
    """
    with blas_threads(1):  # small dense matrices: threads only add contention
        return _estimate_offsets(problem, stamps, track, options, solve_fn, solve_fixed)


def _estimate_offsets(problem, stamps, track, options, solve_fn, solve_fixed=None):
    t0 = time.perf_counter()
    missing = _unavailable(problem, stamps, track, options)
    if missing is not None:
        return missing, problem
    st = _check_stamps(problem, stamps)
    moving = _moving(track, np.concatenate(st))
    moving_counts = _per_camera(problem, st, moving)
    delta = np.zeros(problem.P)
    dns = np.zeros(problem.P, dtype=np.int64)
    current, kept = problem, np.ones(problem.n_measurements, dtype=bool)
    masks = [np.ones(e.n, dtype=bool) for e in problem.edges]
    result, weighted = _solved(solve_fn(problem, None), problem)
    solves, iterations = 1, 0
    clipped = np.zeros(problem.P, dtype=bool)
    step, change, notes = None, np.zeros(problem.P), []
    for iterations in range(1, MAX_ITERATIONS + 1):  # noqa: B007 - reported
        rates = _fitting(weighted, result, _rates(problem, st, track, dns, moving)[kept])
        step = offset_step(offset_terms(weighted, result.X, result.Y, result.scale, rates),
                           information_matrix(weighted, result.X, result.Y, result.scale).H,
                           _clusters(problem, st, dns)[kept])
        new = np.where(step.determined, delta + step.step_s, 0.0)
        clipped = np.abs(new) > options.range_s
        new = np.clip(new, -options.range_s, options.range_s)
        change = np.abs(new - delta)
        delta = new
        tol = np.maximum(_STEP_TOL_STD * np.nan_to_num(step.std_s, nan=np.inf), _STEP_TOL_S)
        if not step.determined.any() or (change <= tol).all():
            break
        dns = np.round(delta * _NS).astype(np.int64)
        current, masks = _reinterpolated(problem, st, track, dns)
        kept = np.concatenate(masks)
        if current.x_names != problem.x_names or current.y_names != problem.y_names:
            notes.append("a frame lost every pair at the trial offsets (the recorded stream "
                         "does not reach them): the estimate stops there")
            break
        result, weighted = _solved(solve_fn(current, (result.X, result.Y)), current)
        solves += 1
        if not result.certified:
            notes.append(f"a solve at trial offsets was not certified "
                         f"({result.certificate.status.value}); its local solution was used")
    else:
        notes.append(f"the offsets moved by up to {1e3 * change.max():.2f} ms at the last of "
                     f"{MAX_ITERATIONS} Newton steps")
    lr = {}
    if solve_fixed is not None and step is not None:
        wald = [k for k in range(problem.P) if step.determined[k]
                and abs(delta[k]) > SIGNIFICANT_SIGMAS * step.std_s[k]]
        lr = likelihood_ratio_sigmas(problem, lambda d: _reinterpolated(problem, st, track, d),
                                     dns, masks, weighted, result, step, wald, solve_fixed)
        solves += len(lr)
    cams = _judge(problem, options, delta, step, moving_counts, clipped, lr)
    report = TimeOffsetReport(cams, iterations, solves, 0.0, options.range_s, notes)
    out = _shifted(problem, st, track, report)
    report.elapsed_s = time.perf_counter() - t0
    return report, out


def _shifted(problem: Problem, st: list[np.ndarray], track: PoseTrackData,
             report: TimeOffsetReport) -> Problem:
    """``problem`` with the pairs of the cameras whose offset ``report`` applies re-interpolated
    at the corrected stamps (``st``: per edge); the pairs the stream does not reach there are
    left out and counted in the cameras' :attr:`CameraOffset.dropped`."""
    applied = report.applied
    shift = np.array([applied.get(c, 0.0) for c in problem.y_names])
    if not shift.any():
        return problem
    out, masks = _reinterpolated(problem, st, track, np.round(shift * _NS).astype(np.int64))
    for m, e in zip(masks, problem.edges, strict=True):
        if e.y in report.cameras:
            report.cameras[e.y].dropped += int((~m).sum())
    return Problem(out.x_names, out.y_names,
                   [Edge.build(e.x, e.y, e.A, e.B, sigma=e.sigma, kappa=e.kappa)
                    for e in out.edges], unknown_scale=out.unknown_scale)


def one_step_offsets(problem: Problem, result, stamps: Mapping[tuple[str, str], np.ndarray],
                     track: PoseTrackData | None, options: TimeOffsetOptions,
                     cache: dict | None = None) -> TimeOffsetReport:
    """The live estimate: one profile Newton step from the live solution (no further solve),
    each camera's offset judged as by :func:`estimate_offsets` (for offsets of tens of
    milliseconds one step lands within a fraction of a millisecond of the converged estimate,
    see ``benchmarks/time_offset.md``). The live problem's edge blocks
    (``problem.precomputed_blocks``) give the information of ``X, Y`` when set.

    ``cache`` (a dict kept by the caller from one call to the next, e.g. the live solver's):
    each pair's rate and motion by stamp, computed once when the recorded stream covers it (the
    stream around a kept pair does not change afterwards; a sample arriving out of order inside
    a window already used is the exception, and shifts a rate by its own jitter at most):
    halves the live cost (``benchmarks/time_offset.md``)."""
    with blas_threads(1):
        return _one_step_offsets(problem, result, stamps, track, options, cache)


def _cached_rates(st, track, cache) -> tuple[np.ndarray, np.ndarray]:
    """``(rates (N, 6), moving (N,))`` at the stamps ``st``, from ``cache`` where it has them."""
    q = np.concatenate(st)
    rates = np.full((q.shape[0], 6), np.nan)
    moving = np.zeros(q.shape[0], dtype=bool)
    todo = []
    for i, stamp in enumerate(q.tolist()):
        hit = cache.get(stamp)
        if hit is None:
            todo.append(i)
        else:
            rates[i], moving[i] = hit
    if todo:
        idx = np.array(todo)
        mv = _moving(track, q[idx])
        xi, ok = track.rates(q[idx])
        _, okm = track.lookup(np.concatenate([q[idx] + MOTION_HALF_WINDOW_NS,
                                              q[idx] - MOTION_HALF_WINDOW_NS]))
        okm = okm[: idx.shape[0]] & okm[idx.shape[0]:]
        xi[~(ok & mv & plausible(xi) & glitch_free(track, q[idx]))] = np.nan
        rates[idx], moving[idx] = xi, mv
        passed = track.stamps_ns[-1] - MOTION_HALF_WINDOW_NS - 2 * track.max_gap_ns
        for j, i in enumerate(todo):
            if (ok[j] and okm[j]) or q[i] < passed:  # the stream around it is final
                cache[int(q[i])] = (xi[j].copy(), bool(mv[j]))
    return rates, moving


def _one_step_offsets(problem, result, stamps, track, options, cache) -> TimeOffsetReport:
    t0 = time.perf_counter()
    missing = _unavailable(problem, stamps, track, options)
    if missing is not None:
        return missing
    st = _check_stamps(problem, stamps)
    rates, moving = _cached_rates(st, track, {} if cache is None else cache)
    rates = _fitting(problem, result, rates)
    moving_counts = _per_camera(problem, st, moving)
    info = (information_from_edge_blocks if getattr(problem, "precomputed_blocks", None)
            is not None else information_matrix)
    step = offset_step(offset_terms(problem, result.X, result.Y, result.scale, rates),
                       info(problem, result.X, result.Y, result.scale).H,
                       _clusters(problem, st, np.zeros(problem.P, dtype=np.int64)))
    delta = np.where(step.determined, step.step_s, 0.0)
    clipped = np.abs(delta) > options.range_s
    cams = _judge(problem, options, np.clip(delta, -options.range_s, options.range_s), step,
                  moving_counts, clipped)
    for o in cams.values():
        o.applied = False  # the live estimate shows them; calibrate applies them
    return TimeOffsetReport(cams, 1, 0, time.perf_counter() - t0, options.range_s,
                            ["live: one Newton step from the live estimate, not applied"])


# --- data set ------------------------------------------------------------------------------------
def shift_dataset(dataset, report: TimeOffsetReport | None, track: PoseTrackData | None):
    """``dataset`` with the applied offsets in its pairs (stamps shifted, ``A`` re-interpolated;
    pairs the stream does not reach dropped with their corners) and in its ``time_offsets_s``;
    the same object when nothing was applied."""
    if dataset is None or report is None or track is None or not report.applied:
        return dataset
    from ..sync.edge_pairs import DatasetEdge

    applied = report.applied
    edges = []
    for e in dataset.edges:
        d = applied.get(e.y)
        if not d:
            edges.append(e)
            continue
        s = e.stamps_ns + int(round(d * _NS))
        A, ok = track.lookup(s)
        corners = None if e.corners_px is None else e.corners_px[ok]
        points = None if e.corner_points_m is None else e.corner_points_m[ok]
        if ok.any():
            edges.append(DatasetEdge(e.x, e.y, s[ok], A[ok], e.B[ok], e.sigma[ok], e.kappa[ok],
                                     corners_px=corners, corner_points_m=points))
    offsets = dict(dataset.time_offsets_s)
    for cam, d in applied.items():
        offsets[cam] = offsets.get(cam, 0.0) + d
    return dataclasses.replace(dataset, edges=tuple(edges), time_offsets_s=offsets)


def correct_time_offsets(problem: Problem, dataset, config, *, mode: str = "fast", priors=(),
                         unobservable_std_m: float = 1.0, min_scale: float = 0.01,
                         reject_outliers: bool = False, noise=None):
    """The calibrate step's one call: estimate the offsets of ``problem``'s cameras from
    ``dataset`` (its stamps, ``pose_stream`` and ``time_offsets_s``) with ``config``'s
    ``sync.*`` options (a configuration, flat parameters, or None: the defaults), solving as
    the final solve does but without SDP fallback (``sdp`` mode: ``fast``); returns ``(problem,
    dataset, report)`` with the significant offsets applied to both (the same objects when none
    is). With ``reject_outliers`` (``solver.reject_outliers``, ``--robust``) every solve of the
    estimate is the robust one (RANSAC + GNC-TLS) where it keeps every frame: the pairs it
    rejects then stand out of their camera's residuals and are left out of the offsets (two
    pose samples 90 deg off made a plain solve's offsets 12.8 and 4.4 ms, significant, where
    the clean stream gives 0.3-0.6 +- 0.4-0.7 ms; without ``--robust`` such glitches still move
    the offsets); with ``noise`` (:class:`~rwhec_ros.core.noise.NoiseOptions`, the final solve's)
    that robust solve estimates the noise first, as the final one does, so that its thresholds
    are in units of the data's noise, not of the pairs' start values; without ``--robust`` every
    solve estimates the noise as the final one does, and the Newton steps weigh the pairs with
    it (on the benchmark's 0.2 m/s bags the frames' largest error against the truth then drops
    a little in each of 4 runs, e.g. 0.535 -> 0.528 mm: the offsets' remaining error, 0.1-0.3
    ms, is that of the motion-capture noise; a noise-free stream gives 0.01-0.02 ms). An
    unexpected error of the estimate is reported as ``not_estimated`` with its message; the
    calibration goes on with the pairs as they are."""
    from ..core.solve import solve
    from .solving import _solve, solve_options

    def options_for(p: Problem, initial):
        opts, _ = solve_options(p, mode="fast" if mode == "sdp" else mode, priors=priors,
                                unobservable_std_m=unobservable_std_m, min_scale=min_scale)
        opts.fallback_to_sdp = False
        opts.initial = initial
        return opts

    def solve_fn(p: Problem, initial):
        opts = options_for(p, initial)
        if reject_outliers:
            robust = _solve(p, opts, True, noise)[0]
            if (list(robust.x_names), list(robust.y_names)) == (list(p.x_names),
                                                                 list(p.y_names)):
                return robust
        elif noise is not None and noise.estimate:
            # the final solve's weights (the noise of each camera estimated from the data): the
            # offsets' Newton steps and their std are those of the problem it solves
            result, weighted = _solve(p, opts, False, noise)[:2]
            return result, weighted
        return solve(p, opts)

    def solve_fixed(p: Problem, initial):  # the problem's own weights
        return solve(p, options_for(p, initial))

    options = TimeOffsetOptions.from_config(config)
    stamps = {} if dataset is None else {(e.x, e.y): e.stamps_ns for e in dataset.edges}
    track = None if dataset is None else dataset.pose_stream
    if dataset is not None and dict(options.configured_s) != dataset.time_offsets_s:
        options = TimeOffsetOptions(options.estimate, options.range_s, options.max_std_s,
                                    tuple(dataset.time_offsets_s.items()), options.configured_s)
    try:
        # with --robust the pairs the robust solve rejects stay in the problem's cost: there
        # the likelihood ratio would weigh them, and the 3-std test stands alone
        report, out = estimate_offsets(problem, stamps, track, options, solve_fn,
                                       None if reject_outliers else solve_fixed)
        return out, shift_dataset(dataset, report, track), report
    except Exception as exc:  # noqa: BLE001 - an extra of the calibration, never its failure
        why = f"the estimate failed: {type(exc).__name__}: {exc}"
        return problem, dataset, _not(problem, options, "not_estimated", why)


def offsets_then_assess(problem: Problem, dataset, estimate: Callable, assess: Callable):
    """The calibrate step's time offsets and solve, in order: ``estimate(problem, dataset) ->
    (problem, dataset, report)`` (:func:`correct_time_offsets` with the caller's options), then
    ``assess(problem, dataset) -> Solved`` (:func:`~rwhec_ros.session.solving.solve_and_assess`
    with the caller's options). When the assessment's exclusion left targets or edges out
    (:mod:`rwhec_ros.core.verdict.exclusion`) and offsets were applied, the offsets are estimated
    again without them, applied to all the pairs, and the problem is assessed again: a target
    that does not fit (a wrong size, a move) leaves residuals that grow with the motion, which
    an offset partly explains (with ``--robust``, a tag of the rendered rig configured 10 %
    too small made a camera's offset 48-52 ms, applied, and that camera 1-2 deg off). The
    estimate without them then says whether the offsets were real; when it applies the same
    offsets (the same cameras, each within its std), the first solve stands. (Estimating again
    when none was applied, in case the misfit hid one, made a rendered camera 3.0 std off with
    ``--robust`` in ``benchmarks/verdict.md`` part 4: not done.) Returns
    ``(problem, dataset, report, solved)``."""
    p, d, report = estimate(problem, dataset)
    solved = assess(p, d)
    ex = solved.exclusion
    if not report.applied or ex is None or not ex.excluded or dataset is None:
        return p, d, report, solved
    gone = {n for m in ex.excluded for n in m.edges}
    rest = [e for e in problem.edges if e.name not in gone]
    if not rest:
        return p, d, report, solved
    rest_d = dataclasses.replace(dataset, edges=tuple(
        e for e in dataset.edges if f"({e.x}, {e.y})" not in gone))
    again = estimate(problem.with_edges(rest), rest_d)[2]
    first, second = report.applied, again.applied
    if set(first) == set(second) and all(abs(first[c] - v) <= again.cameras[c].std_s
                                         for c, v in second.items()):
        return p, d, report, solved  # the same offsets (within their std): the solve stands
    stamps = {(e.x, e.y): e.stamps_ns for e in dataset.edges}
    st = _check_stamps(problem, stamps)
    if st is None:
        return p, d, report, solved
    for o in again.cameras.values():
        o.dropped = 0  # counted again on all the pairs
    out = _shifted(problem, st, dataset.pose_stream, again)
    names = ", ".join(m.name for m in ex.excluded)
    before = (", ".join(f"{c} {1e3 * v:+.1f} ms" for c, v in report.applied.items())
              or "none (not significant)")
    again.notes.append(f"estimated without {names} (excluded by the verdict: it does not fit); "
                       f"with it the estimate applied {before}")
    d2 = shift_dataset(dataset, again, dataset.pose_stream)
    return out, d2, again, assess(out, d2)


def live_offsets(problem, result, snap, config, cache: dict):
    """The live time offsets (:func:`one_step_offsets`) of the re-solved ``problem`` (``snap``:
    the live solver's :class:`~rwhec_ros.session.live_solve.PairsSnapshot`), or None when they
    cannot be had (an injected re-solve's result of another kind, a failure: the live estimate
    stands without them)."""
    options = TimeOffsetOptions.from_config(config)
    if not options.estimate or snap.track is None:
        return None
    try:
        stamps = {k: e.stamps_ns for k, e in snap.edges.items()}
        if len(cache) > 4 * max(problem.n_measurements, 1000):  # pairs replaced over time
            cache.clear()
        return one_step_offsets(problem, result, stamps, snap.track, options, cache)
    except Exception:  # noqa: BLE001 - an extra of the live estimate, never its failure
        return None
