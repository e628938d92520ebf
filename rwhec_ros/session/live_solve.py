"""Live convergence: the session re-solved in the background while data arrive.

:class:`LiveSolver` belongs to a :class:`~rwhec_ros.session.CalibrationSession` (its ``live``
attribute). Whoever drives it calls :meth:`LiveSolver.tick` now and then (the node from a timer
in its own callback group, ``rwhec-calibrate bag`` from its read loop); ``tick`` only looks at
the clock and a few counters and, when a re-solve is due, hands it to the solver's own worker
thread and returns at once. The re-solve takes the kept pairs under the session's lock
(read-only views that the accumulator never changes afterwards, or copies), then builds the
problem, solves it in ``fast`` mode (paper Section 7.3, no SDP fallback: a live estimate never
waits for the SDP) and computes every frame's uncertainty
(:func:`~rwhec_ros.core.analysis.uncertainty.frame_uncertainty`) outside it. So the sensor path
(``add_pose``/``add_image``, the detection workers) never waits for a live solve.

A re-solve is due when (1) ``solver.live_period_s`` > 0 (0 = off; read at every tick, so it can
change while the node runs), (2) new pairs arrived (or the stated noise changed) since the last
attempt, (3) no live solve is running and none started in the last ``live_period_s`` seconds,
(4) the last one did not take more than ``max_duty`` of the time since it ended (a large problem
is re-solved less often, never hogging a core), and (5) no ``calibrate`` is running.

``calibrate`` and the live solve: ``calibrate`` never waits for a live solve and never cancels
one (the two work on separate copies of the data). No live solve starts while ``calibrate``
runs (counted ``skipped_calibrating``); a live solve still running when ``calibrate`` starts
finishes, but its estimate is dropped (counted ``discarded``), so a live estimate is never
older than the latest calibration; the next tick re-solves. ``reset`` forgets the estimate
and drops a running solve's result likewise.

A failed live solve (any exception) keeps all data, is counted with its message
(:attr:`LiveStatus.failures`, :attr:`LiveStatus.last_error`) and never raises into the caller;
the next one runs when new pairs arrive.

Each re-solve after the first starts the local solver from the previous certified estimate of
the same frames (:func:`warm_start_of`) instead of the closed-form estimate: fewer Newton steps
and no closed-form initialisation. The certificate is the same whatever the start; a warm start
that does not certify is solved again from the closed form, so the statuses are those of a cold
start (``test/test_live_solve.py`` checks estimates and certificates against cold solves).

The cost's edge blocks are kept from one re-solve to the next
(:class:`~rwhec_ros.core.model.edge_cache.EdgeBlockCache`: an edge that only gained pairs at its
end, as the accumulator's lineages tell without a look at the pairs, has only those summed) and set
as the problem's ``precomputed_blocks``, which the solve and the
uncertainty (``information="edge_blocks"``: the information matrix from the blocks, not from
the pairs) both use; the results equal the fresh, pair-by-pair ones to rounding.

Each estimate carries its convergence verdict (:mod:`.convergence`: every configured frame
estimated, every std at or below ``convergence.*``) and the ``~/estimate`` document
(:func:`~rwhec_ros.session.convergence.estimate_document`).
"""

from __future__ import annotations

import functools
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..core.analysis.uncertainty import Uncertainty, UncertaintyOptions, frame_uncertainty
from ..core.model.edge_cache import EdgeBlockCache
from ..core.noise.words import noise_values
from ..core.problem import Problem
from ..core.result import CalibrationResult
from ..messages import LEVEL_OK, LEVEL_WARN
from ..sync.accumulator import problem_from_edges
from .convergence import Convergence, convergence_of, estimate_document
from .time_offsets import live_offsets

__all__ = [
    "PairsSnapshot",
    "LiveEstimate",
    "LiveStatus",
    "LiveSolver",
    "solve_with_uncertainty",
    "warm_start_of",
    "warm_noise_of",
]


@dataclass(frozen=True)
class PairsSnapshot:
    """The kept pairs at one instant (arrays that never change), from
    :meth:`~rwhec_ros.session.CalibrationSession.pairs_snapshot`.

    Attributes
    ----------
    version : int
        The session's data version (grows with every kept pair, noise change and reset).
    edges : dict of (x, y) to KeptPairs
        Kept pairs per edge (:meth:`~rwhec_ros.sync.accumulator.PairAccumulator.kept_pairs`).
    rotation_tol : float
        Tolerance for building the problem's edges.
    track : PoseTrackData or None
        The pose stream recorded around the kept pairs (time offsets).
    """

    version: int
    edges: dict
    rotation_tol: float
    track: Any = None

    @property
    def n_pairs(self) -> int:
        return int(sum(e.n for e in self.edges.values()))


def solve_with_uncertainty(problem: Problem, config, initial: tuple | None = None,
                           warm_noise: dict | None = None
                           ) -> tuple[CalibrationResult, Uncertainty]:
    """The live re-solve: ``fast`` without SDP fallback or outlier rejection, with the
    configuration's priors, ``solver.unobservable_std_m`` and ``solver.min_scale``, then
    :func:`~rwhec_ros.core.analysis.uncertainty.frame_uncertainty` with the same gauge options.

    With ``noise.estimate`` the noise of each group is estimated from the data and solved with
    (:func:`~rwhec_ros.core.noise.solve_with_noise`, at most 3 solves per re-solve, the
    information from the edge blocks), starting from ``warm_noise`` (the previous live
    estimate's factors, ``result.noise.factors()``): with a few more pairs they still fit, so
    one solve usually suffices. ``result.noise`` holds the estimate, and the uncertainty is that
    of the estimated weights.

    ``initial`` ``(X (M, 4, 4), Y (P, 4, 4))``: a warm start (the previous live estimate, in the
    problem's frame order) for the local solver instead of the closed-form estimate. The
    certificate decides as for a cold start (it proves global optimality whatever the start);
    when the warm-started solve is not certified, the problem is solved again from the
    closed-form start and that result is returned, so a warm start never changes a status.
    """
    from ..core.solve import blas_threads, solve
    from .solving import solve_options

    c = config.solver
    options, notes = solve_options(problem, mode="fast", priors=config.priors.entries,
                                   unobservable_std_m=c.unobservable_std_m,
                                   min_scale=c.min_scale)
    options.fallback_to_sdp = False
    result = None
    # one BLAS thread limit around the whole re-solve: the solve's and the uncertainty's own
    # (the same count, UncertaintyOptions' default) then find it set and skip set and restore
    noise = None
    if config.noise.estimate:
        from .solving import config_noise

        noise = config_noise(config, information="edge_blocks", max_solves=3)

    def run(opts):
        if noise is None:
            return solve(problem, opts), problem
        from ..core.noise import solve_with_noise

        ns = solve_with_noise(problem, opts, noise, warm=warm_noise)
        return ns.result, ns.problem

    with blas_threads(options.blas_threads):
        if initial is not None:
            options.initial = initial
            result, solved = run(options)
            options.initial = None
            if result.certified:
                notes = [*notes, "live: started from the previous live estimate"]
            else:
                result = None  # solved again from the closed-form start
        if result is None:
            result, solved = run(options)
        result.notes.extend(notes)
        # the uncertainty's own limit (1 thread, its default) is this one when the solve's is 1:
        # None then (no second look at the BLAS libraries); else its own, as before
        return result, frame_uncertainty(solved, result, UncertaintyOptions(
            gauge=options.gauge, information="edge_blocks",
            blas_threads=None if options.blas_threads == 1 else 1))


def warm_start_of(estimate: LiveEstimate | None, problem: Problem) -> tuple | None:
    """``(X, Y)`` of ``estimate`` to start the local solver of ``problem`` from, or None: only a
    certified estimate of the same frames in the same order is used (a new frame, a reset or an
    uncertified estimate start from the closed form)."""
    if estimate is None or not estimate.result.certified:
        return None
    r = estimate.result
    if tuple(r.x_names) != problem.x_names or tuple(r.y_names) != problem.y_names:
        return None
    return r.X, r.Y


def warm_noise_of(estimate: LiveEstimate | None) -> dict | None:
    """The noise factors per group of ``estimate``'s solve (``result.noise``), to start the next
    re-solve's noise estimate from (*warm weights*); None without one."""
    noise = None if estimate is None else getattr(estimate.result, "noise", None)
    return None if noise is None else noise.factors()


@dataclass(frozen=True)
class LiveEstimate:
    """One live re-solve's outcome.

    Attributes
    ----------
    result : CalibrationResult
    uncertainty : Uncertainty
    convergence : Convergence
    config : CalibratorConfig
        The configuration of the re-solve.
    excluded : dict of str to str
        Edges ``"(x, y)"`` left out (fewer than ``solver.min_pairs`` pairs), and why.
    version : int
        The data version solved.
    n_pairs, n_edges : int
        Pairs and edges in the solved problem.
    solve_s : float
        Wall time of snapshot, solve and uncertainty [s].
    cpu_s : float
        CPU time of the worker thread for the same [s] (less sensitive to machine load).
    finished : float
        The solver's clock when it finished.
    sequence : int
        1 for the first estimate, then counting up (to publish each one once).
    time_offsets : TimeOffsetReport or None
        Each camera's time offset, one Newton step from this estimate
        (:func:`~rwhec_ros.session.time_offsets.one_step_offsets`; shown, not applied); None
        when the re-solve was injected or failed to give it.
    """

    result: CalibrationResult
    uncertainty: Uncertainty
    convergence: Convergence
    config: Any
    excluded: dict
    version: int
    n_pairs: int
    n_edges: int
    solve_s: float
    cpu_s: float
    finished: float
    sequence: int
    time_offsets: Any = None

    @property
    def converged(self) -> bool:
        return self.convergence.converged

    def line(self) -> str:
        """``<n> pairs: <convergence words>``, for a progress line or a log."""
        return f"{self.n_pairs} pairs: {self.convergence.words()}"

    @functools.cached_property
    def document(self) -> dict:
        """The ``~/estimate`` mapping (:func:`~rwhec_ros.session.convergence.estimate_document`,
        YAML-safe), built on first use: only the node publishes it."""
        live = {"pairs": self.n_pairs, "edges": self.n_edges, "data_version": self.version,
                "solve_s": self.solve_s, "cpu_s": self.cpu_s,
                "period_s": self.config.solver.live_period_s}
        doc = estimate_document(self.result, self.uncertainty, self.config, self.convergence,
                                excluded=self.excluded, live=live)
        if self.time_offsets is not None:
            doc["time_offsets"] = self.time_offsets.to_dict()
        return doc


@dataclass(frozen=True)
class LiveStatus:
    """What the live solver has done (a consistent copy, :meth:`LiveSolver.status`).

    Attributes
    ----------
    enabled : bool
        ``solver.live_period_s > 0``.
    period_s : float
    running : bool
        A re-solve is in flight.
    solves, failures, discarded, skipped_calibrating, waiting_for_data : int
        Estimates made, solves that raised, estimates dropped (a ``calibrate`` or ``reset``
        overlapped), ticks skipped while ``calibrate`` ran, attempts without an edge of
        ``solver.min_pairs`` pairs.
    last_error : str
        The latest failure in words ("" when the latest attempt worked).
    estimate : LiveEstimate or None
        The latest estimate.
    """

    enabled: bool
    period_s: float
    running: bool
    solves: int
    failures: int
    discarded: int
    skipped_calibrating: int
    waiting_for_data: int
    last_error: str
    estimate: LiveEstimate | None

    @property
    def converged(self) -> bool:
        return self.estimate is not None and self.estimate.converged

    def line(self) -> str:
        """One line for a progress display."""
        if not self.enabled:
            return "live estimate off (solver.live_period_s = 0)"
        if self.last_error:
            return f"live solve failed: {self.last_error}"
        if self.estimate is None:
            return "live: no estimate yet" + (
                " (no edge had solver.min_pairs pairs at the last live solve)"
                if self.waiting_for_data else "")
        return "live: " + self.estimate.line()

    def diagnostic_row(self, prefix: str, hardware_id: str = "") -> dict[str, Any]:
        """A ``/diagnostics`` row as :func:`rwhec_ros.messages.diagnostic_rows` makes them,
        named ``<prefix>: live estimate``: OK when off or converged, WARN otherwise (not
        converged yet, no estimate yet, or the latest live solve failed)."""
        est = self.estimate
        values = [("enabled", str(self.enabled).lower()), ("period_s", f"{self.period_s:g}"),
                  ("converged", str(self.converged).lower()), ("live_solves", str(self.solves)),
                  ("live_failures", str(self.failures)), ("live_discarded", str(self.discarded)),
                  ("live_skipped_calibrating", str(self.skipped_calibrating))]
        if est is not None:
            c = est.convergence
            values += [("pairs", str(est.n_pairs)), ("edges", str(est.n_edges)),
                       ("worst_std_translation_m", f"{c.worst_translation_m:.6g}"),
                       ("worst_std_translation_at", c.worst_translation_frame),
                       ("worst_std_rotation_deg", f"{c.worst_rotation_deg:.6g}"),
                       ("worst_std_rotation_at", c.worst_rotation_frame),
                       ("max_std_translation_m", f"{c.max_std_translation_m:g}"),
                       ("max_std_rotation_deg", f"{c.max_std_rotation_deg:g}"),
                       ("certified", str(bool(est.result.certified)).lower()),
                       ("solve_ms", f"{1e3 * est.solve_s:.1f}")]
            if est.time_offsets is not None:
                values += est.time_offsets.diagnostic_values()
            values += noise_values(getattr(est.result, "noise", None))
        if self.last_error:
            values.append(("last_error", self.last_error))
        level = (LEVEL_OK if (not self.enabled or self.converged) and not self.last_error
                 else LEVEL_WARN)
        return {"name": f"{prefix}: live estimate", "level": level,
                "message": self.line().removeprefix("live: "), "hardware_id": hardware_id,
                "values": values}


@dataclass
class _Job:
    version: int
    calibrations: int
    resets: int


@dataclass
class _State:
    running: bool = False
    attempted_version: int = -1
    last_start: float = -math.inf
    last_end: float = -math.inf
    last_duration: float = 0.0
    solves: int = 0
    failures: int = 0
    discarded: int = 0
    skipped_calibrating: int = 0
    waiting_for_data: int = 0
    last_error: str = ""
    estimate: LiveEstimate | None = None
    delivered: int = 0
    job: _Job | None = None
    stopped: bool = False
    idle: threading.Event = field(default_factory=threading.Event)


class LiveSolver:
    """Background re-solves of a session (module docstring).

    Parameters
    ----------
    session : CalibrationSession
        Provides ``config``, :meth:`pairs_snapshot` and :meth:`live_counts`.
    solve_fn : callable(Problem, CalibratorConfig) -> (CalibrationResult, Uncertainty), optional
        The re-solve (default :func:`solve_with_uncertainty`); injectable for tests.
    warm_start : bool, optional
        Pass the previous certified estimate of the same frames to ``solve_fn`` as the keyword
        ``initial`` (:func:`warm_start_of`). Default: on for the default ``solve_fn``, off for an
        injected one (which then needs no ``initial`` parameter).
    clock : callable returning float, optional
        Seconds, monotonic (default :func:`time.monotonic`).
    max_duty : float
        Largest share of the wall time the re-solves may take (0.25): after a re-solve of ``d``
        seconds the next starts no earlier than ``d (1 / max_duty - 1)`` after it ended.
    """

    def __init__(self, session, *, solve_fn: Callable | None = None,
                 clock: Callable[[], float] | None = None, max_duty: float = 0.25,
                 warm_start: bool | None = None) -> None:
        if not (isinstance(max_duty, (int, float)) and 0 < max_duty <= 1):
            raise ValueError(f"max_duty: must be in (0, 1], got {max_duty!r}")
        self._warm_start = (solve_fn is None) if warm_start is None else bool(warm_start)
        self._session = session
        self._solve_fn = solve_fn if solve_fn is not None else solve_with_uncertainty
        self._clock = clock if clock is not None else time.monotonic
        self._max_duty = float(max_duty)
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._thread: threading.Thread | None = None
        self._s = _State()
        self._s.idle.set()
        self._blocks = EdgeBlockCache()  # used by the worker thread only
        self._rate_cache: dict = {}  # the pairs' stream rates by stamp (worker thread only)

    # --- driving -------------------------------------------------------------------------------
    def tick(self, now: float | None = None) -> str:
        """Start a re-solve on the worker thread if one is due; never blocks, never raises.

        Returns what happened: ``"started"``, ``"off"``, ``"running"``, ``"waiting"`` (period
        or duty cycle), ``"no_new_pairs"``, ``"calibrating"``, ``"stopped"``, or ``"failed"``
        (an unexpected error, counted as a failure with its message).
        """
        try:
            return self._tick(self._clock() if now is None else float(now))
        except Exception as exc:  # noqa: BLE001 - never into a timer callback
            with self._lock:
                self._s.failures += 1
                self._s.last_error = f"{type(exc).__name__}: {exc}"
            return "failed"

    def _tick(self, now: float) -> str:
        period = float(self._session.config.solver.live_period_s)
        s = self._s
        with self._lock:
            if s.stopped:
                return "stopped"
            if period <= 0:
                return "off"
            if s.running:
                return "running"
            rest = s.last_duration * (1.0 / self._max_duty - 1.0)
            if now < s.last_start + period or now < s.last_end + rest:
                return "waiting"
        version, calibrations, resets, calibrating = self._session.live_counts()
        with self._lock:
            if version == s.attempted_version:
                return "no_new_pairs"
            if calibrating:
                s.skipped_calibrating += 1
                return "calibrating"
            if s.running or s.stopped:
                return "running" if s.running else "stopped"
            s.running = True
            s.idle.clear()
            s.last_start = now
            s.job = _Job(version, calibrations, resets)
            self._ensure_thread()
        self._wake.set()
        return "started"

    def _ensure_thread(self) -> None:
        """Start the worker (lock held)."""
        if self._thread is None or not self._thread.is_alive():
            self._thread = threading.Thread(target=self._loop, name="rwhec-live-solve",
                                            daemon=True)
            self._thread.start()

    def _loop(self) -> None:
        while True:
            self._wake.wait()
            self._wake.clear()
            with self._lock:
                job, self._s.job = self._s.job, None
                if self._s.stopped:
                    self._s.running = False
                    self._s.idle.set()
                    return
            if job is None:
                continue
            try:
                self._run(job)
            finally:
                with self._lock:
                    self._s.running = False
                    self._s.idle.set()

    def _run(self, job: _Job) -> None:
        t0, cpu0 = self._clock(), time.thread_time()
        c = self._session.config
        x_names, y_names = c.x_names, c.y_names  # (formed at each look)
        snap = None
        try:
            snap = self._session.pairs_snapshot()
            try:
                problem, excluded = problem_from_edges(
                    snap.edges, x_names, y_names, c.tags.unknown_scale, c.solver.min_pairs,
                    snap.rotation_tol, validate=False)  # validated when they were offered
                # the cost's edge blocks, reusing the sums of the pairs the last re-solve had
                # (edges that only gained pairs since: known from the accumulator's lineages)
                problem.precomputed_blocks = self._blocks.blocks(problem, lineages={
                    k: getattr(e, "lineage", None) for k, e in snap.edges.items()})
            except ValueError:
                with self._lock:
                    self._s.waiting_for_data += 1
                    self._s.attempted_version = snap.version
                    self._s.last_error = ""
                    self._s.last_end, self._s.last_duration = self._clock(), 0.0
                return
            if self._warm_start:
                with self._lock:
                    initial = warm_start_of(self._s.estimate, problem)
                    warm = warm_noise_of(self._s.estimate)
                extra = {"warm_noise": warm} if self._solve_fn is solve_with_uncertainty else {}
                result, unc = self._solve_fn(problem, c, initial=initial, **extra)
            else:
                result, unc = self._solve_fn(problem, c)
            conv = convergence_of(unc, [*y_names, *x_names],
                                  c.convergence.max_std_translation_m,
                                  c.convergence.max_std_rotation_deg)
            offsets = live_offsets(problem, result, snap, c, self._rate_cache)
            t1, cpu = self._clock(), time.thread_time() - cpu0
            excl = {f"({x}, {y})": r for (x, y), r in excluded.items()}
        except Exception as exc:  # noqa: BLE001 - a live solve never raises; the data stay
            with self._lock:
                self._s.failures += 1
                self._s.last_error = f"{type(exc).__name__}: {exc}"
                if snap is not None:
                    self._s.attempted_version = snap.version
                self._s.last_end = self._clock()
                self._s.last_duration = self._s.last_end - t0
            return
        _, calibrations, resets, calibrating = self._session.live_counts()
        with self._lock:
            s = self._s
            s.last_end, s.last_duration = self._clock(), self._clock() - t0
            if calibrating or calibrations != job.calibrations or resets != job.resets:
                s.discarded += 1  # calibrate or reset overlapped: re-solve at the next tick
                s.attempted_version = -1
                return
            s.attempted_version = snap.version
            s.last_error = ""
            s.solves += 1
            s.estimate = LiveEstimate(result, unc, conv, c, excl, snap.version,
                                      problem.n_measurements, len(problem.edges), t1 - t0, cpu,
                                      t1, s.solves, offsets)

    # --- reading -------------------------------------------------------------------------------
    def status(self) -> LiveStatus:
        """A consistent copy of what the live solver did (thread-safe)."""
        c = self._session.config
        with self._lock:
            s = self._s
            return LiveStatus(c.solver.live_period_s > 0, float(c.solver.live_period_s),
                              s.running, s.solves, s.failures, s.discarded,
                              s.skipped_calibrating, s.waiting_for_data, s.last_error,
                              s.estimate)

    @property
    def estimate(self) -> LiveEstimate | None:
        """The latest live estimate (None before the first)."""
        with self._lock:
            return self._s.estimate

    def take_new(self) -> LiveEstimate | None:
        """The latest estimate if it was not taken before, else None (to publish each once)."""
        with self._lock:
            est = self._s.estimate
            if est is None or est.sequence <= self._s.delivered:
                return None
            self._s.delivered = est.sequence
            return est

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Wait until no re-solve is running (True) or ``timeout`` [s] passed (False)."""
        return self._s.idle.wait(timeout)

    def solve_now(self, timeout: float | None = None) -> LiveEstimate | None:
        """Re-solve now if new pairs arrived (ignoring the period, not the other rules), wait for
        it up to ``timeout`` seconds and return the latest estimate (e.g. at the end of a bag)."""
        self.wait_idle(timeout)
        with self._lock:
            self._s.last_start = self._s.last_end = -math.inf
        if self.tick() == "started":
            self.wait_idle(timeout)
        return self.estimate

    # --- session events ------------------------------------------------------------------------
    def forget(self) -> None:
        """Drop the estimate and the error (the session was reset)."""
        self._rate_cache = {}  # a new dict: a running re-solve keeps the old one
        with self._lock:
            self._s.estimate = None
            self._s.last_error = ""
            self._s.attempted_version = -1

    def stop(self, timeout: float | None = 5.0) -> None:
        """Stop the worker thread after its current re-solve (waits up to ``timeout`` s)."""
        with self._lock:
            self._s.stopped = True
            thread = self._thread
        self._wake.set()
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)
