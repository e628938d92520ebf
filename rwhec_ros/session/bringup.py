"""Bring-up check: is the stored calibration still right, which camera moved, by how much?

:func:`run_check` takes the pairs recorded at bring-up (a :class:`~rwhec_ros.core.problem.
Problem`) and a :class:`~rwhec_ros.data.reference.Reference` (a previous result, a frames.yaml,
a URDF or the frames on tf) and answers per camera ``consistent``, ``moved`` (by how much, with
its std) or ``undecided`` (not enough data yet), re-estimates only what moved and gives the
verdict of that solve (GOOD / CAUTION / UNUSABLE, :func:`~rwhec_ros.core.verdict.assess`).

1. **The gauge** (what holds the reference while a frame is tested), ``CheckOptions.hold``:

   * ``"none"`` (default): nothing is held; the pose stream ``A`` defines both carriers, so
     with enough motion every frame is determined absolutely (paper Section 6) and every frame
     in the reference is tested, cameras and targets (a target placed anew for the check is
     simply reported as moved; targets never decide the answer). Axes the data do not
     determine (e.g. heights of a ground robot that only yaws) are not tested and said so.
   * ``"targets"``: the targets are held at the reference (they define the gauge: tags fixed
     in the room that were not touched); only cameras are tested, each relative to them. More
     power, and camera heights become testable on a robot that only yaws; a target that did
     move makes the cameras that see it look moved and the fit worse (the verdict says so).

2. **The test** (:mod:`rwhec_ros.core.analysis.change`): the certified solve of the data with
   the held frames as pseudo-measurements (:mod:`rwhec_ros.core.model.held`), each tested
   frame's change against the reference with its covariance (the noise the data show per
   camera, plus the reference's covariance when it has one), a confidence region at level
   ``a``, and the decision against the tolerance. ``a`` is ``false_alarm_rate`` split by
   Bonferroni over the cameras (and, separately, over the targets) and, with ``sequential``
   (the node, which looks again as data grow), spent over the looks: the probability of any
   wrong camera decision over all looks is at most ``false_alarm_rate``.

3. **Recalibrate only what moved**: the frames that passed (``consistent``) are held at the
   reference, with the targets when they are the gauge; the moved frames, and the frames that
   are undecided or not in the reference, are estimated from the data. Its certificate is for
   :meth:`~rwhec_ros.core.model.held.HeldProblem.describe`. The output frames
   (:attr:`CheckReport.frames`) are the reference with the moved frames replaced.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from ..core.analysis.change import (
    ChangeOptions,
    ChangeTolerance,
    FrameChange,
    frame_changes,
    look_level,
    noise_reweighted,
)
from ..core.model.held import ANCHOR_X, ANCHOR_Y, DEFAULT_STRENGTH, hold_frames, without_anchors
from ..core.problem import Problem
from ..core.result import CalibrationResult
from ..core.verdict import Verdict, VerdictOptions, assess
from ..data.reference import Reference

__all__ = ["HOLDS", "STATUSES", "CheckOptions", "CheckReport", "run_check", "BringupCheck",
           "reference_lookup_names", "session_problem"]

#: Values of :attr:`CheckOptions.hold`.
HOLDS = ("none", "targets")
#: The answers of a check, over the cameras.
STATUSES = ("consistent", "moved", "undecided")


@dataclass(frozen=True)
class CheckOptions:
    """Options of :func:`run_check`.

    Attributes
    ----------
    tolerance : ChangeTolerance
        The change the user accepts (2 mm, 0.2 deg).
    false_alarm_rate : float
        ``alpha``: the probability of any wrong camera decision (0.01).
    hold : str
        The gauge: ``"none"`` or ``"targets"`` (module docstring).
    noise : str
        ``"data"`` (the noise the residuals show, per camera) or ``"stated"``.
    sequential : bool
        Spend ``alpha`` over repeated looks (the node); False for one look (the CLI).
    reference_covariance : bool
        Add the reference's covariance where it has one (True).
    mode : str
        Solver mode of the solves (``fast``).
    strength : float
        Precision of the pseudo-measurements holding frames
        (:data:`~rwhec_ros.core.model.held.DEFAULT_STRENGTH`).
    """

    tolerance: ChangeTolerance = field(default_factory=ChangeTolerance)
    false_alarm_rate: float = 0.01
    hold: str = "none"
    noise: str = "data"
    sequential: bool = False
    reference_covariance: bool = True
    mode: str = "fast"
    strength: float = DEFAULT_STRENGTH

    def __post_init__(self) -> None:
        if self.hold not in HOLDS:
            raise ValueError(f"hold: expected one of {HOLDS}, got {self.hold!r}")
        look_level(self.false_alarm_rate, 1)  # validates the rate
        ChangeOptions(noise=self.noise)  # validates the noise


@dataclass
class CheckReport:
    """The answer of :func:`run_check`.

    Attributes
    ----------
    status : str
        Over the cameras: ``moved`` (at least one), ``consistent`` (every camera of the
        reference that is expected), else ``undecided``.
    changes : dict of str to FrameChange
        Every tested frame (cameras, then targets).
    cameras : list of str
        The cameras the answer is about (expected and in the reference), in order.
    unseen : list of str
        Frames of the reference that are expected but have no pairs.
    unreferenced : list of str
        Frames of the data that the reference does not have (estimated, not tested).
    frames : dict of str to ndarray (4, 4)
        The output: every reference frame, the moved ones replaced by their new estimate.
    updated : list of str
        The frames replaced.
    test_result, result : CalibrationResult
        The test's solve and the final solve (the recalibration when a frame moved, else the
        test's), anchors dropped.
    verdict : Verdict or None
        Of the final solve (anchor frames dropped), None when not asked for.
    certificate_for : str
        The problem the final certificate is for, in words.
    level : float
        The error rate of each camera's decision (after Bonferroni and the looks).
    look : int
    options : CheckOptions
    reference : Reference
    n_pairs : int
        Pairs of the data.
    solved, solved_problem : CalibrationResult, Problem
        The final solve as solved (with the anchor frames of held frames) and its problem.
    variance_factors : dict of str to (float, float)
        Per camera, the translation and rotation variance factors used.
    notes : list of str
    """

    status: str
    changes: dict[str, FrameChange]
    cameras: list[str]
    unseen: list[str]
    unreferenced: list[str]
    frames: dict[str, np.ndarray]
    updated: list[str]
    test_result: CalibrationResult
    result: CalibrationResult
    verdict: Verdict | None
    certificate_for: str
    level: float
    look: int
    options: CheckOptions
    reference: Reference
    n_pairs: int = 0
    solved: CalibrationResult | None = None
    solved_problem: Problem | None = None
    variance_factors: dict[str, tuple[float, float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def camera_decision(self, name: str) -> str:
        """``consistent``, ``moved`` or ``undecided`` for an expected camera."""
        c = self.changes.get(name)
        return "undecided" if c is None else c.decision

    @property
    def moved(self) -> list[str]:
        return [n for n in self.cameras if self.camera_decision(n) == "moved"]


def _solve_held(problem: Problem, held: Mapping[str, np.ndarray], opts: CheckOptions):
    """``(result without anchors, result as solved, problem as solved, words)`` of ``problem``
    with ``held`` frames held (a plain solve when nothing is held)."""
    from ..core.solve import SolveOptions, solve

    options = SolveOptions(mode=opts.mode)
    if not held:
        res = solve(problem, options)
        return res, res, problem, "the data's maximum-likelihood problem (eq. (33))"
    hp = hold_frames(problem, held, strength=opts.strength)
    res = solve(hp.problem, options)
    return without_anchors(res), res, hp.problem, hp.describe()


def _noise_from_data(problem: Problem, held: Mapping[str, np.ndarray], opts: CheckOptions):
    """The solve of ``problem`` with ``held`` frames held, with the noise the data show: solved
    at the stated noise, each camera's ``sigma`` and ``kappa`` rescaled by its variance factors
    (:func:`~rwhec_ros.core.analysis.change.noise_reweighted`), solved again. An estimate
    weighted with the wrong ratio of translation to rotation noise is not the MLE its
    information describes (its covariance is larger): the second solve is. Returns
    ``(_solve_held's four, the reweighted problem, the factors)``."""
    first = _solve_held(problem, held, opts)
    res = first[0]
    n_free = 6 * (problem.n_frames - len(held)) + (1 if problem.unknown_scale else 0)
    weighted, factors = noise_reweighted(problem, res.X, res.Y, res.scale, n_free)
    out = _solve_held(weighted, held, opts)
    words = out[3].replace("the data's", "the data's (noise per camera from the residuals)")
    return (*out[:3], words), weighted, factors


def _stated_twin(solved: Problem, data: Problem) -> Problem:
    """``solved`` (the data reweighted, then the pseudo-measurements of held frames, if any)
    with the data's edges as stated."""
    edges = [*data.edges, *solved.edges[len(data.edges):]]
    return Problem(solved.x_names, solved.y_names, edges, unknown_scale=solved.unknown_scale)


def _assess(result: CalibrationResult, problem: Problem, thresholds, expected_x, expected_y,
            carriers) -> Verdict:
    verdict = assess(result, problem, options=thresholds,
                     expected_x=[n for n in expected_x if n != ANCHOR_X],
                     expected_y=[n for n in expected_y if n != ANCHOR_Y], carriers=carriers)
    for anchor in (ANCHOR_X, ANCHOR_Y):
        verdict.frames.pop(anchor, None)
    return verdict


def run_check(
    problem: Problem,
    reference: Reference,
    options: CheckOptions | None = None,
    *,
    look: int = 1,
    expected_cameras: Iterable[str] | None = None,
    thresholds: VerdictOptions | None = None,
    carriers: tuple[str, str] = ("the camera carrier", "the tag carrier"),
    verdict: bool = True,
    on_phase: Callable[[str], None] | None = None,
) -> CheckReport:
    """Check ``problem``'s pairs against ``reference`` (module docstring).

    ``look`` is the number of this look (sequential options); ``expected_cameras`` the cameras
    the configuration names (default: the data's); ``thresholds`` the verdict's; ``verdict``
    False skips the verdict (benchmarks); ``on_phase("analysing")`` is called when the test's
    solve is done (the CLI's run phases). ``ValueError`` when no camera of the data is in the
    reference. Exceptions of the solver propagate.
    """
    opts = options or CheckOptions()
    ref = reference.frames
    expected = list(expected_cameras) if expected_cameras is not None else list(problem.y_names)
    cams = [n for n in problem.y_names if n in ref]
    if not cams:
        raise ValueError(f"no camera of the data {list(problem.y_names)} is in the reference "
                         f"({reference.source}: frames {sorted(ref)})")
    held_test = ({n: ref[n] for n in problem.x_names if n in ref} if opts.hold == "targets"
                 else {})
    weighted, factors = problem, {}
    if opts.noise == "data":
        (test_res, solved, solved_problem, words), weighted, factors = _noise_from_data(
            problem, held_test, opts)
    else:
        test_res, solved, solved_problem, words = _solve_held(problem, held_test, opts)
    if on_phase is not None:
        on_phase("analysing")
    free = [n for n in problem.frame_names if n not in held_test]
    a = look_level(opts.false_alarm_rate, look, sequential=opts.sequential)
    tags = [n for n in problem.x_names if n in ref and n not in held_test]
    cov = reference.covariance if opts.reference_covariance else {}
    change_opts = ChangeOptions(tolerance=opts.tolerance, noise=opts.noise)
    changes: dict[str, FrameChange] = {}
    notes = list(reference.notes)
    second: dict[str, tuple[float, float]] = {}
    for group in (cams, tags):
        if not group:
            continue
        ct = frame_changes(weighted, test_res.X, test_res.Y, test_res.scale, free=free,
                           reference={n: ref[n] for n in group}, level=a / len(group),
                           reference_covariance=cov, options=change_opts)
        changes.update(ct.frames)
        notes += ct.notes
        second = ct.variance_factors or second
    factors = {k: (f[0] * second.get(k, (1.0, 1.0))[0], f[1] * second.get(k, (1.0, 1.0))[1])
               for k, f in factors.items()} or second
    if not test_res.certified:
        notes.append(f"the test's solve is not certified ({test_res.certificate.status.value}):"
                     " its decisions rest on a local solution")
    moved_frames = [n for n, c in changes.items() if c.decision == "moved"]
    final_res, final_solved, final_problem = test_res, solved, solved_problem
    if moved_frames:
        held = {n: ref[n] for n, c in changes.items() if c.decision == "consistent"}
        held.update(held_test)
        final_res, final_solved, final_problem, words = _solve_held(weighted, held, opts)
        if opts.noise == "data":
            words = words.replace("the data's", "the data's (noise per camera from the residuals)")
    frames = {n: np.array(T, float) for n, T in ref.items()}
    updated = [n for n in moved_frames if n in final_res.x_names + final_res.y_names]
    for n in updated:
        frames[n] = np.array(final_res.transform(n), float)
    v = None
    if verdict:  # as for any calibration: the fit judged against the stated noise
        stated = final_problem if weighted is problem else _stated_twin(final_problem, problem)
        v = _assess(final_solved, stated, thresholds, problem.x_names,
                    [*expected, *problem.y_names], carriers)
    checked = [n for n in dict.fromkeys([*expected, *cams]) if n in ref]
    unseen = [n for n in checked if n not in problem.frame_names]
    decisions = [changes[n].decision if n in changes else "undecided" for n in checked]
    status = ("moved" if "moved" in decisions else
              "consistent" if decisions and all(d == "consistent" for d in decisions) else
              "undecided")
    return CheckReport(
        status=status, changes=changes, cameras=checked, unseen=unseen,
        unreferenced=[n for n in problem.frame_names if n not in ref], frames=frames,
        updated=updated, test_result=test_res, result=final_res, verdict=v,
        certificate_for=words, level=a / len(cams), look=int(look), options=opts,
        reference=reference, n_pairs=problem.n_measurements, solved=final_solved,
        solved_problem=final_problem, variance_factors=factors,
        notes=notes)


class BringupCheck:
    """The check as a sequence of looks at growing data (the node's ``~/check``).

    Each :meth:`check` at new data is one more look (``look_level`` spends the false-alarm rate
    over them, so that repeated looks keep it); the same data (same ``version``) give the last
    answer again without a new look.
    """

    def __init__(self, reference: Reference, options: CheckOptions | None = None) -> None:
        self.reference = reference
        self.options = options or CheckOptions(sequential=True)
        self.looks = 0
        self.last: CheckReport | None = None
        self._version = None

    def check(self, problem: Problem, *, version=None, **kwargs) -> CheckReport:
        """:func:`run_check` of ``problem`` as the next look; ``version`` identifies the data
        (default: the pairs per edge), ``kwargs`` go to :func:`run_check`."""
        key = version if version is not None else tuple((e.x, e.y, e.n) for e in problem.edges)
        if self.last is not None and key == self._version:
            return self.last
        self.looks += 1
        report = run_check(problem, self.reference, self.options, look=self.looks, **kwargs)
        self.last, self._version = report, key
        return report


def reference_lookup_names(config, prefer: str | None = None) -> dict[str, tuple[str, list[str]]]:
    """Per frame of a :class:`~rwhec_ros.config.CalibratorConfig`: its carrier and the child
    names to look it up under in a frames.yaml, a URDF or tf: the published child
    (``<frame><output.frame_suffix>`` or ``calibrated_frame``) and its own frame name (a
    camera's ``frame``, a target's name), in the order ``prefer`` says (``"calibrated"``: the
    published one first, ``"sensor"``: its own first; default ``check.tf_frames``)."""
    prefer = prefer or getattr(getattr(config, "check", None), "tf_frames", "calibrated")
    out: dict[str, tuple[str, list[str]]] = {}
    published = config.published_frames()
    for name in (*config.y_names, *config.x_names):
        parent, child = published[name]
        own = (config.camera(name).frame or name) if name in config.y_names else name
        order = [child, own] if prefer != "sensor" else [own, child]
        out[name] = (parent, list(dict.fromkeys(order)))
    return out


def session_problem(session) -> tuple[Problem | None, object, str]:
    """The session's kept pairs as a problem (its configuration's frames and ``min_pairs``):
    ``(problem or None, data version, why none)``."""
    from ..sync.accumulator import problem_from_edges

    c = session.config
    snap = session.pairs_snapshot()
    try:
        problem, _ = problem_from_edges(snap.edges, c.x_names, c.y_names, c.tags.unknown_scale,
                                        c.solver.min_pairs, snap.rotation_tol, validate=False)
    except ValueError as exc:
        return None, snap.version, (f"not enough data yet: {snap.n_pairs} pairs, no edge with "
                                    f"solver.min_pairs={c.solver.min_pairs} pairs ({exc})")
    return problem, snap.version, ""
