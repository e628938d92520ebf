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
``MAX_ITERATIONS``). The standard deviation is the marginal one (extrinsics free), a posteriori
(scaled by the residuals' variance factor).

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
as they are: zero is as good an estimate).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from ..core.analysis.information import information_from_edge_blocks, information_matrix
from ..core.analysis.time_offset import offset_step, offset_terms
from ..core.numerics.blas import blas_threads
from ..core.problem import Edge, Problem
from ..sync.pose_track import MOTION_HALF_WINDOW_NS, PoseTrackData

__all__ = ["TimeOffsetOptions", "CameraOffset", "TimeOffsetReport", "estimate_offsets",
           "one_step_offsets", "add_offset_reasons", "shift_dataset",
           "MOVING_SPEED_M_S", "MOVING_RATE_RAD_S", "MIN_MOVING_PAIRS", "SIGNIFICANT_SIGMAS",
           "CAUTION_S", "MAX_ITERATIONS", "correct_time_offsets"]

_NS = 1_000_000_000
#: A pair counts as moving when the stream moved faster than this [m/s] ...
MOVING_SPEED_M_S = 0.05
#: ... or turned faster than this [rad/s] (5.7 deg/s) around it (over +-50 ms).
MOVING_RATE_RAD_S = 0.1
#: Fewest moving pairs of a camera for its offset to count as determined.
MIN_MOVING_PAIRS = 6
#: An offset beyond this many standard deviations is significant (applied) ...
SIGNIFICANT_SIGMAS = 3.0
#: ... and the verdict names one beyond this too [s].
CAUTION_S = 0.002
#: Newton steps at most (each a re-interpolation and a solve); 2-3 suffice in the benchmark.
MAX_ITERATIONS = 6
#: Stop when every step is below this fraction of its offset's std (or below 50 us).
_STEP_TOL_STD = 0.1
_STEP_TOL_S = 5e-5


@dataclass(frozen=True)
class TimeOffsetOptions:
    """What to do about time offsets (``sync.*`` of the configuration).

    Attributes
    ----------
    estimate : bool
        ``sync.estimate_time_offset``.
    range_s : float
        ``sync.time_offset_range_s``: the offsets searched lie within +- this [s].
    max_std_s : float
        ``sync.time_offset_max_std_s``: a larger standard deviation is "not determined".
    configured_s : tuple of (str, float)
        The offsets already in the pairs' stamps: ``sync.time_offset.<camera>`` in a session, a
        data set's ``time_offsets_s``.
    parameter_s : tuple of (str, float) or None
        ``sync.time_offset.<camera>`` of the configuration, when it differs from
        ``configured_s`` (a data set whose pairs carry an offset found before): the verdict
        compares the whole offset with it. None: ``configured_s``.
    """

    estimate: bool = True
    range_s: float = 0.1
    max_std_s: float = 0.005
    configured_s: tuple[tuple[str, float], ...] = ()
    parameter_s: tuple[tuple[str, float], ...] | None = None

    @classmethod
    def from_config(cls, config) -> TimeOffsetOptions:
        """From a :class:`~rwhec_ros.config.CalibratorConfig`, or from flat parameters (a
        mapping: the ``sync.*`` keys present, defaults for the others); None: the defaults."""
        if config is None:
            return cls()
        if isinstance(config, Mapping):
            d = cls()
            prefix = "sync.time_offset."
            offsets = tuple((k[len(prefix):], float(v)) for k, v in config.items()
                            if k.startswith(prefix))
            return cls(bool(config.get("sync.estimate_time_offset", d.estimate)),
                       float(config.get("sync.time_offset_range_s", d.range_s)),
                       float(config.get("sync.time_offset_max_std_s", d.max_std_s)), offsets)
        s = config.sync
        return cls(bool(s.estimate_time_offset), float(s.time_offset_range_s),
                   float(s.time_offset_max_std_s), tuple(s.time_offsets))

    def configured(self, camera: str) -> float:
        return float(dict(self.configured_s).get(camera, 0.0))

    def parameter(self, camera: str) -> float:
        table = self.configured_s if self.parameter_s is None else self.parameter_s
        return float(dict(table).get(camera, 0.0))


@dataclass
class CameraOffset:
    """The time offset of one camera.

    Attributes
    ----------
    camera : str
    status : str
        ``estimated`` (determined: ``estimate_s`` +- ``std_s``), ``not_determined`` (the data
        cannot tell: ``why``) or ``not_estimated`` (estimation off, or no recorded stream).
    configured_s : float
        The offset in the pairs' stamps already (``sync.time_offset.<camera>``, or a data
        set's).
    parameter_s : float
        ``sync.time_offset.<camera>`` of the configuration (the verdict compares with it).
    estimate_s : float
        The offset left in the data, on top of the configured one [s] (NaN unless estimated).
    std_s : float
        Its standard deviation [s] (NaN unless estimated).
    applied : bool
        The final pairs are re-interpolated at stamps shifted by ``estimate_s``.
    moving_pairs, pairs : int
        Pairs taken while the stream moved, and all pairs of the camera.
    why : str
        For ``not_determined``/``not_estimated``: why, in words.
    dropped : int
        Pairs left out of the final solve because the recorded stream does not reach their
        corrected stamps.
    """

    camera: str
    status: str
    configured_s: float = 0.0
    parameter_s: float = 0.0
    estimate_s: float = math.nan
    std_s: float = math.nan
    applied: bool = False
    moving_pairs: int = 0
    pairs: int = 0
    why: str = ""
    dropped: int = 0

    @property
    def determined(self) -> bool:
        return self.status == "estimated"

    @property
    def offset_s(self) -> float:
        """The camera's whole offset (configured + estimated) [s]; NaN unless estimated."""
        return self.configured_s + self.estimate_s if self.determined else math.nan

    @property
    def significant(self) -> bool:
        return self.determined and abs(self.estimate_s) > SIGNIFICANT_SIGMAS * self.std_s

    @property
    def caution(self) -> bool:
        """The whole offset differs from ``sync.time_offset.<camera>`` by more than 3 std and
        :data:`CAUTION_S`: the verdict names it."""
        if not self.determined:
            return False
        d = abs(self.offset_s - self.parameter_s)
        return d > SIGNIFICANT_SIGMAS * self.std_s and d > CAUTION_S

    def words(self) -> str:
        """``12.3 +- 0.4 ms (applied)`` or ``not determined (why)``."""
        if not self.determined:
            word = "not determined" if self.status == "not_determined" else "not estimated"
            return f"{word} ({self.why})"
        tail = "applied" if self.applied else "not significant (within 3 std): not applied"
        conf = (f" ({1e3 * self.configured_s:g} ms of it in the pairs' stamps)"
                if self.configured_s else "")
        return (f"{1e3 * self.offset_s:+.1f} +- {1e3 * self.std_s:.1f} ms{conf}, {tail}"
                + (f"; {self.dropped} pairs beyond the recorded stream left out"
                   if self.dropped else ""))

    def to_dict(self) -> dict:
        def num(v: float) -> float | None:
            return None if not math.isfinite(v) else float(v)
        return {"status": self.status, "offset_s": num(self.offset_s),
                "std_s": num(self.std_s), "configured_s": float(self.configured_s),
                "parameter_s": float(self.parameter_s),
                "estimated_s": num(self.estimate_s), "applied": bool(self.applied),
                "significant": bool(self.significant), "moving_pairs": int(self.moving_pairs),
                "pairs": int(self.pairs), "dropped_pairs": int(self.dropped), "why": self.why}


@dataclass
class TimeOffsetReport:
    """Every camera's time offset (:func:`estimate_offsets`).

    Attributes
    ----------
    cameras : dict of str to CameraOffset
    iterations : int
        Newton steps taken.
    solves : int
        Solves made for the estimate (the final certified solve not counted).
    elapsed_s : float
    range_s : float
    notes : list of str
    """

    cameras: dict[str, CameraOffset] = field(default_factory=dict)
    iterations: int = 0
    solves: int = 0
    elapsed_s: float = 0.0
    range_s: float = 0.1
    notes: list[str] = field(default_factory=list)

    @property
    def applied(self) -> dict[str, float]:
        """Camera -> the estimate applied to its pairs [s]."""
        return {c: o.estimate_s for c, o in self.cameras.items() if o.applied}

    def to_dict(self) -> dict:
        """The ``time_offsets`` section of ``result.yaml``."""
        return {"convention": "t_pose = t_image + offset_s",
                "range_s": float(self.range_s), "iterations": int(self.iterations),
                "solves": int(self.solves), "elapsed_s": float(self.elapsed_s),
                "cameras": {c: o.to_dict() for c, o in self.cameras.items()},
                "notes": list(self.notes)}

    def lines(self) -> list[str]:
        """Summary lines: ``time offset cam1: +20.3 +- 0.4 ms, applied``; one line when no
        camera's was estimated for one reason."""
        whys = {(o.status, o.why) for o in self.cameras.values()}
        if len(whys) == 1 and next(iter(whys))[0] == "not_estimated":
            return [f"time offsets: not estimated ({next(iter(whys))[1]})"]
        return [f"time offset {c}: {o.words()}" for c, o in self.cameras.items()]

    def diagnostic_values(self, prefix: str = "time_offset") -> list[tuple[str, str]]:
        """``(key, value)`` pairs for ``/diagnostics``: ``time_offset <camera>`` ->
        ``+20.3 +- 0.4 ms`` or ``not determined (...)``."""
        out = []
        for c, o in self.cameras.items():
            value = (f"{1e3 * o.offset_s:+.1f} +- {1e3 * o.std_s:.1f} ms" if o.determined
                     else o.words())
            out.append((f"{prefix} {c}", value))
        return out


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
    q = np.concatenate([s + int(delta_ns[k]) for s, k in zip(stamps, problem.edge_y,
                                                              strict=True)])
    xi, ok = track.rates(q)
    xi[~(ok & moving)] = np.nan
    return xi


def _moving(track: PoseTrackData, q: np.ndarray) -> np.ndarray:
    """Whether the stream moved around each stamp of ``q`` (N,) (module docstring)."""
    shift, angle = track.motion(q, MOTION_HALF_WINDOW_NS)
    window = 2 * MOTION_HALF_WINDOW_NS / _NS
    with np.errstate(invalid="ignore"):
        return (shift > MOVING_SPEED_M_S * window) | (angle > MOVING_RATE_RAD_S * window)


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
                    "no pose stream recorded: poses given per image (tf lookups, pose lists, "
                    "a data set without its stream)")
    if _check_stamps(problem, stamps) is None:
        return _not(problem, options, "not_estimated", "the pairs' stamps are not known")
    return None


def _judge(problem: Problem, options: TimeOffsetOptions, delta: np.ndarray, step,
           moving_counts: np.ndarray, clipped: np.ndarray) -> dict[str, CameraOffset]:
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
            o.applied = o.significant
        out[cam] = o
    return out


def estimate_offsets(
    problem: Problem,
    stamps: Mapping[tuple[str, str], np.ndarray],
    track: PoseTrackData | None,
    options: TimeOffsetOptions,
    solve_fn: Callable[[Problem, tuple | None], object],
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
    solve_fn : callable(problem, initial) -> CalibrationResult
        The solve (``initial``: ``(X, Y)`` warm start or None).

    Returns
    -------
    report : TimeOffsetReport
    problem : Problem
        ``problem`` itself when nothing is applied, else its pairs re-interpolated at the
        corrected stamps of the cameras whose offset is applied (pairs the stream does not
        reach there left out, counted in :attr:`CameraOffset.dropped`).
    """
    with blas_threads(1):  # small dense matrices: threads only add contention
        return _estimate_offsets(problem, stamps, track, options, solve_fn)


def _estimate_offsets(problem, stamps, track, options, solve_fn):
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
    result, solves, iterations = solve_fn(problem, None), 1, 0
    clipped = np.zeros(problem.P, dtype=bool)
    step, change, notes = None, np.zeros(problem.P), []
    for iterations in range(1, MAX_ITERATIONS + 1):  # noqa: B007 - reported
        rates = _rates(problem, st, track, dns, moving)[kept]
        step = offset_step(offset_terms(current, result.X, result.Y, result.scale, rates),
                           information_matrix(current, result.X, result.Y, result.scale).H)
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
        result = solve_fn(current, (result.X, result.Y))
        solves += 1
        if not result.certified:
            notes.append(f"a solve at trial offsets was not certified "
                         f"({result.certificate.status.value}); its local solution was used")
    else:
        notes.append(f"the offsets moved by up to {1e3 * change.max():.2f} ms at the last of "
                     f"{MAX_ITERATIONS} Newton steps")
    cams = _judge(problem, options, delta, step, moving_counts, clipped)
    report = TimeOffsetReport(cams, iterations, solves, 0.0, options.range_s, notes)
    applied = np.array([cams[c].estimate_s if cams[c].applied else 0.0
                        for c in problem.y_names])
    out = problem
    if applied.any():
        out, masks = _reinterpolated(problem, st, track, np.round(applied * _NS).astype(np.int64))
        for m, e in zip(masks, problem.edges, strict=True):
            cams[e.y].dropped += int((~m).sum())
        out = Problem(out.x_names, out.y_names,
                      [Edge.build(e.x, e.y, e.A, e.B, sigma=e.sigma, kappa=e.kappa)
                       for e in out.edges], unknown_scale=out.unknown_scale)
    report.elapsed_s = time.perf_counter() - t0
    return report, out


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
        xi[~(ok & mv)] = np.nan
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
    moving_counts = _per_camera(problem, st, moving)
    info = (information_from_edge_blocks if getattr(problem, "precomputed_blocks", None)
            is not None else information_matrix)
    step = offset_step(offset_terms(problem, result.X, result.Y, result.scale, rates),
                       info(problem, result.X, result.Y, result.scale).H)
    delta = np.where(step.determined, step.step_s, 0.0)
    clipped = np.abs(delta) > options.range_s
    cams = _judge(problem, options, np.clip(delta, -options.range_s, options.range_s), step,
                  moving_counts, clipped)
    for o in cams.values():
        o.applied = False  # the live estimate shows them; calibrate applies them
    return TimeOffsetReport(cams, 1, 0, time.perf_counter() - t0, options.range_s,
                            ["live: one Newton step from the live estimate, not applied"])


# --- verdict and data set ------------------------------------------------------------------------
def add_offset_reasons(verdict, report: TimeOffsetReport | None) -> None:
    """Add a caution to ``verdict`` (in place) for each camera whose offset is significant and
    beyond :data:`CAUTION_S`, naming the fix, and raise its level to caution if it was good."""
    if verdict is None or report is None:
        return
    from ..core.verdict.model import PRIORITY, Reason
    from ..core.verdict.options import level_rank, worst_level

    added = False
    for cam, o in report.cameras.items():
        if not o.caution:
            continue
        late = "late" if o.offset_s < 0 else "early"
        param = (f" (sync.time_offset.{cam} is {o.parameter_s:g})" if o.parameter_s else "")
        verdict.reasons.append(Reason(
            "caution", "time_offset",
            f"camera {cam}'s images are stamped {1e3 * abs(o.offset_s):.1f} +- "
            f"{1e3 * o.std_s:.1f} ms {late} against the pose stream (t_pose = t_image "
            f"{'+' if o.offset_s >= 0 else '-'} {1e3 * abs(o.offset_s):.1f} ms): estimated and "
            f"applied here{param}; set sync.time_offset.{cam}: {o.offset_s:.4f} (or fix the camera "
            "driver's stamps) so that live pairing and keyframes use it from the start",
            frames=(cam,)))
        fv = verdict.frames.get(cam)
        if fv is not None and "time offset" not in fv.why:
            fv.why.append("time offset")
            if level_rank("caution") > level_rank(fv.level):
                fv.level = "caution"
        added = True
    if added:
        order = {code: i for i, code in enumerate(PRIORITY)}
        verdict.reasons.sort(key=lambda r: (-level_rank(r.level), order.get(r.code, len(order))))
        verdict.level = worst_level([verdict.level, "caution"])


def shift_dataset(dataset, report: TimeOffsetReport | None, track: PoseTrackData | None):
    """``dataset`` with the applied offsets in its pairs (stamps shifted, ``A`` re-interpolated;
    pairs the stream does not reach dropped with their corners) and in its ``time_offsets_s``;
    the same object when nothing was applied."""
    if dataset is None or report is None or track is None or not report.applied:
        return dataset
    import dataclasses

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
                         unobservable_std_m: float = 1.0, min_scale: float = 0.01):
    """The calibrate step's one call: estimate the offsets of ``problem``'s cameras from
    ``dataset`` (its stamps, ``pose_stream`` and ``time_offsets_s``) with ``config``'s
    ``sync.*`` options (a configuration, flat parameters, or None: the defaults), solving as
    the final solve does but without SDP fallback (``sdp`` mode: ``fast``); returns ``(problem,
    dataset, report)`` with the significant offsets applied to both (the same objects when none
    is). With ``solver.reject_outliers`` the offsets are estimated on all pairs (before the
    outlier rejection of the final solve)."""
    from ..core.solve import solve
    from .solving import solve_options

    def solve_fn(p: Problem, initial):
        opts, _ = solve_options(p, mode="fast" if mode == "sdp" else mode, priors=priors,
                                unobservable_std_m=unobservable_std_m, min_scale=min_scale)
        opts.fallback_to_sdp = False
        opts.initial = initial
        return solve(p, opts)

    options = TimeOffsetOptions.from_config(config)
    stamps = {} if dataset is None else {(e.x, e.y): e.stamps_ns for e in dataset.edges}
    track = None if dataset is None else dataset.pose_stream
    if dataset is not None and dict(options.configured_s) != dataset.time_offsets_s:
        options = TimeOffsetOptions(options.estimate, options.range_s, options.max_std_s,
                                    tuple(dataset.time_offsets_s.items()), options.configured_s)
    report, out = estimate_offsets(problem, stamps, track, options, solve_fn)
    return out, shift_dataset(dataset, report, track), report
