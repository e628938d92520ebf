"""The verdict's check for a gross mistake in the inputs: poses the other way round, in other
units, or paired with the wrong image.

The commonest faults of a hand-eye bring-up are not noise but a wrong reading of the inputs:

* the robot poses read the other way round (a file of ``T_tool_base`` read as ``T_base_tool``,
  ``pose_source.parent`` and ``.child`` swapped) or the cameras on the other carrier (eye-to-hand
  data calibrated as eye-in-hand): for a single pose stream both mean ``A_i`` in place of
  ``A_i^-1`` in eq. (7);
* the target-in-camera poses the other way round (``cam2target`` for ``target2cam``; only where
  the user gives ``B``: CSV pose pairs, pose lists);
* translations in millimetres, centimetres or inches where metres are expected (the pose stream,
  or target sizes): a common factor of 1000, 100 or 39.37 between the pose stream and the
  camera-target distances;
* every image paired with the pose of the view before or after it (a pose list one row off).

With the noise estimated from the data, such data still give a certified optimum, of a problem
that fits nothing: the noise estimate swells to tens of millimetres and degrees and the verdict,
without this check, could only say that the frames are imprecise ("record more views"). Measured
on a real 28-view chessboard set (`RWHE-Calib`'s ``kuka_2``) with the poses inverted: a CAUTION
(usable) with the camera 1.9 m from the flange, the pairs fitting 38 mm / 15.6 deg RMS against
0.6 mm / 0.05 deg as read.

So the same pairs are solved once per alternative reading (mode ``fast``, the scale free so that
units show as ``alpha``; milliseconds to a third of a second on the paper's 3230 pairs), each
with its own noise: the problem's relative weights, started at 1 cm and 1 deg (medians) and then
scaled by one factor for translation and one for rotation that make the mean of each term of eq.
(33) its 3 degrees of freedom, re-solved until the factors settle (``_ROUNDS``). The weights the
session estimated for the configured reading cannot judge the others: a reading whose
translations fit nothing gets a translation noise of hundreds of metres, and then no alternative
can fit better in translation. The configured reading goes through the same steps (known scale),
and so does the trimming of each reading's gross pairs after its first solve (beyond 9 times the
median normalised residual, at most a fifth of the pairs: a view with no detection shifts the
pairs after it by one more, and a real set has its outlying views).
A reading's misfit is the product
of its RMS translation and rotation residuals (the likelihood of a reading with its noise
estimated falls with the product of its noise levels); an alternative is named when it is at
most ``1 / GROSS_MISFIT_RATIO`` of the configured one's and its scale is positive. Correct data
fit at the noise level as read, and an alternative reading cannot fit better than the noise, so
on them the ratio stays near or below 1 (at most 1.6 on the real sets as read); every fault
above gave hundreds to thousands, and the planted ones of ``benchmarks/input_faults.md`` 17 or
more.
A single edge cannot tell ``A`` inverted from
``B`` inverted (``A^-1 X = Y B`` is ``X^-1 A = B^-1 Y^-1`` with the roles swapped) but by the
noise model (inverting ``B`` carries its rotation noise into its translation): both are named
where both fit far better than the configured reading, the better first. The units are named
when the free scale of the best reading lies within 15 % of a unit factor.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..lie import invert_transform
from ..outliers.pairs import pair_residuals, restrict_problem
from ..problem import Edge, Problem
from .model import Builder
from .words import deg, mm

__all__ = ["Reading", "InputCheck", "check_inputs", "input_reasons", "GROSS_MISFIT_RATIO", "UNITS"]

#: An alternative reading is named when the configured reading's misfit (RMS translation x RMS
#: rotation residual) is at least this many times its own (e.g. both ~3x larger as read). On the
#: data as read no alternative came above 1.6 (real and drawn sets); the planted mistakes on
#: the real sets of ``benchmarks/input_faults.md`` gave 17 to 10^6.
GROSS_MISFIT_RATIO = 10.0
#: Solves per reading, the noise factors re-estimated after each but the last.
_ROUNDS = 3
#: Median translation noise [m] and rotation noise per axis [deg] of every reading's first solve
#: (its relative weights kept): the level of a hand-eye set, so that no term is ignored at start.
_START_SIGMA_M, _START_ROTATION_DEG = 0.01, 1.0
#: After the first solve of a reading, pairs whose normalised residual exceeds this many times
#: the median are left out, at most this share of them (:func:`_trimmed`).
_TRIM_FACTOR, _TRIM_SHARE = 9.0, 0.2

#: Factor ``alpha`` (camera-tag translations / pose-stream translations) -> what it means.
UNITS = {
    1e-3: "the pose stream's translations are in millimetres (the camera-target distances are "
          "1/1000 of them): convert the poses to metres",
    1e-2: "the pose stream's translations are in centimetres: convert the poses to metres",
    0.0254: "the pose stream's translations are in inches: convert the poses to metres",
    1e3: "the camera-target distances are 1000x the pose stream's: the target sizes are given "
         "in millimetres (tags.sizes, targets.<name>.square_size ... are in metres), or the "
         "target-in-camera poses are in millimetres",
    1e2: "the camera-target distances are 100x the pose stream's: the target sizes are given in "
         "centimetres (they are in metres), or the target-in-camera poses are in centimetres",
    1 / 0.0254: "the camera-target distances are 39.4x the pose stream's: the target sizes are "
                "given in inches (they are in metres)",
}
#: ``alpha`` within this relative distance of a unit factor names that unit.
UNIT_TOLERANCE = 0.15

_READINGS = {
    "pose_inverted": "with every robot pose inverted",
    "camera_inverted": "with every target-in-camera pose inverted",
    "both_inverted": "with the robot poses and the target-in-camera poses inverted",
    "next_pose": "with each image paired with the pose of the view after it",
    "previous_pose": "with each image paired with the pose of the view before it",
    "units": "with the translations rescaled",
}


@dataclass(frozen=True)
class Reading:
    """One reading of the pairs, solved.

    Attributes
    ----------
    name : str
        ``configured``, ``units`` (the configured reading, scale free), ``pose_inverted``,
        ``camera_inverted``, ``both_inverted``, ``next_pose``, ``previous_pose``.
    scale : float
        Its free scale ``alpha`` (1 for the configured reading).
    translation_rms_m, rotation_rms_deg : float
        RMS residual of ``A X = Y B`` over its pairs (translation in the units of ``B``, divided
        by the scale where it exceeds 1).
    """

    name: str
    scale: float
    translation_rms_m: float
    rotation_rms_deg: float

    @property
    def misfit(self) -> float:
        """RMS translation [m] x RMS rotation [deg] residual."""
        return self.translation_rms_m * self.rotation_rms_deg

    def to_dict(self) -> dict:
        return {"reading": self.name, "scale": float(self.scale),
                "translation_rms_m": float(self.translation_rms_m),
                "rotation_rms_deg": float(self.rotation_rms_deg)}


@dataclass(frozen=True)
class InputCheck:
    """The configured reading and every alternative tried (module docstring)."""

    configured: Reading
    alternatives: tuple[Reading, ...]

    def to_dict(self) -> dict:
        return {"configured": self.configured.to_dict(),
                "alternatives": [dict(r.to_dict(), fits_better_x=float(self.ratio(r)))
                                 for r in self.alternatives],
                "named": [r.name for r in self.found()]}

    def ratio(self, r: Reading) -> float:
        """Configured misfit over ``r``'s (large: ``r`` fits far better)."""
        return self.configured.misfit / r.misfit if r.misfit > 0 else float("inf")

    def found(self) -> list[Reading]:
        """The alternatives that fit far better than the configured reading, best first."""
        good = [r for r in self.alternatives
                if self.ratio(r) >= GROSS_MISFIT_RATIO and r.scale > 0]
        return sorted(good, key=lambda r: r.misfit)


def _length(value_m: float) -> str:
    """:func:`~.words.mm`, in metres from 10 m (a reading in other units)."""
    return f"{value_m:.0f} m" if value_m >= 10 else mm(value_m)


def unit_of(alpha: float) -> str | None:
    """The words of :data:`UNITS` for a scale within :data:`UNIT_TOLERANCE` of a unit factor."""
    for factor, words in UNITS.items():
        if np.isfinite(alpha) and abs(alpha / factor - 1.0) <= UNIT_TOLERANCE:
            return words
    return None


def unit_prescale(problem: Problem) -> float:
    """The unit factor (1 or one of :data:`UNITS`) nearest, in ratio, to a rough scale of the
    data: the median over edges of the spread of the camera-target translations over the spread
    of the pose stream's (each the median distance to the median). A robot's motion and the
    camera-target distances vary by comparable amounts (a few to tens of centimetres), so the
    rough scale lies within a few times the true one, and the unit factors are 25 times or more
    apart. The alternative readings are solved with the pose stream's translations multiplied
    by it: a free scale of ``1e-3`` is found by the solver from data in metres, not from data a
    thousand times off (a real single-tag set's millimetre reading ended at a scale of -1.5e-4,
    the other readings at 1e-3)."""
    ratios = []
    for e in problem.edges:
        sa = np.median(np.linalg.norm(e.A[:, :3, 3] - np.median(e.A[:, :3, 3], axis=0), axis=1))
        sb = np.median(np.linalg.norm(e.B[:, :3, 3] - np.median(e.B[:, :3, 3], axis=0), axis=1))
        if sa > 0 and sb > 0:
            ratios.append(sb / sa)
    if not ratios:
        return 1.0
    guess = float(np.median(ratios))
    factors = (1.0, *UNITS)
    return min(factors, key=lambda f: abs(np.log(guess / f)))


def _reading(problem: Problem, *, invert_a: bool = False, invert_b: bool = False,
             shift: int = 0, prescale: float = 1.0) -> Problem | None:
    edges = []
    for e in problem.edges:
        A, B, s, k = e.A, e.B, e.sigma, e.kappa
        if prescale != 1.0:
            A = np.array(A, float)
            A[:, :3, 3] *= prescale
        if shift:
            if e.n <= abs(shift):
                continue
            a, b = (slice(shift, None), slice(None, -shift)) if shift > 0 else \
                (slice(None, shift), slice(-shift, None))
            A, B, s, k = A[a], B[b], s[b], k[b]
        edges.append(Edge.build(e.x, e.y, invert_transform(A) if invert_a else A,
                                invert_transform(B) if invert_b else B, s, k))
    if not edges:
        return None
    return problem.with_edges(edges, unknown_scale=True)


def _trimmed(problem: Problem, res: dict) -> tuple[Problem, dict]:
    """``problem`` without its gross pairs (normalised residual beyond :data:`_TRIM_FACTOR`
    times the median, at most :data:`_TRIM_SHARE` of the pairs, the worst first), and their
    residuals: a reading that is right but for a few pairs (a view without a detection shifts
    the pairs after it by one more, a real set's outlying view) is judged by the others."""
    J = np.concatenate([res[e.name].normalised for e in problem.edges])
    limit = _TRIM_FACTOR * float(np.median(J))
    order = np.argsort(J)[::-1][:int(_TRIM_SHARE * J.size)]
    drop = np.zeros(J.size, bool)
    drop[order[J[order] > limit]] = True
    if not drop.any():
        return problem, res
    ends = np.cumsum([e.n for e in problem.edges])
    masks = {e.name: ~m for e, m in zip(problem.edges, np.split(drop, ends[:-1]), strict=True)}
    kept = {name: dataclasses.replace(res[name], **{f.name: getattr(res[name], f.name)[m]
                                                    for f in dataclasses.fields(res[name])})
            for name, m in masks.items() if m.any()}
    return restrict_problem(problem, masks, what="input check"), kept


def _neutral(problem: Problem) -> Problem:
    """``problem`` with its relative weights kept and their levels set to :data:`_START_SIGMA_M`
    and :data:`_START_ROTATION_DEG` (medians): the start of every reading. The weights as solved
    were estimated for the configured reading; with poses in millimetres they carry a
    translation noise of a kilometre, under which a free scale is not determined at all (a real
    single-tag set's units reading ended at a scale of -1.5e-4)."""
    sig = np.concatenate([e.sigma for e in problem.edges])
    kap = np.concatenate([e.kappa for e in problem.edges])
    fs = _START_SIGMA_M / float(np.median(sig))
    fk = 1.0 / (2.0 * np.radians(_START_ROTATION_DEG) ** 2) / float(np.median(kap))
    if not (np.isfinite(fs) and np.isfinite(fk) and fs > 0 and fk > 0):
        return problem
    return _weighted(problem, fs, fk)


def _weighted(problem: Problem, sigma_factor: float, kappa_factor: float) -> Problem:
    """``problem`` with every ``sigma`` times ``sigma_factor`` and ``kappa`` times
    ``kappa_factor``."""
    return problem.with_edges([Edge.build(e.x, e.y, e.A, e.B, e.sigma * sigma_factor,
                                          e.kappa * kappa_factor) for e in problem.edges])


def _fit(name: str, problem: Problem, prescale: float = 1.0) -> Reading:
    """Solve ``problem`` with its noise re-scaled to its own residuals (module docstring);
    ``prescale``: the factor its pose-stream translations were multiplied by
    (:func:`unit_prescale`), so that the reading's scale is the solve's times it."""
    from ..solve import SolveOptions, solve

    p = _neutral(problem)
    for k in range(_ROUNDS):
        r = solve(p, SolveOptions(mode="fast"))
        alpha = float(r.scale) if p.unknown_scale else 1.0
        if not (np.all(np.isfinite(r.X)) and np.all(np.isfinite(r.Y)) and np.isfinite(alpha)):
            raise ArithmeticError(f"{name}: the solve gave no estimate")
        res = pair_residuals(p, r.X, r.Y, alpha)
        if k == _ROUNDS - 1:
            break
        if k == 0:
            p, res = _trimmed(p, res)
        ft = np.mean(np.concatenate([v.normalised_translation for v in res.values()])) / 3.0
        fr = np.mean(np.concatenate([v.normalised_rotation for v in res.values()])) / 3.0
        if not (ft > 0 and fr > 0 and np.isfinite(ft) and np.isfinite(fr)):
            break
        p = _weighted(p, np.sqrt(ft), 1.0 / fr)
    t = np.concatenate([v.translation for v in res.values()])
    R = np.concatenate([v.rotation for v in res.values()])
    # residuals are in the units of B; a scale far above 1 takes B as the unit at fault (sizes
    # in millimetres), so its residuals are given in the pose stream's metres
    scale = alpha * prescale
    t_rms = float(np.sqrt(np.mean(t**2))) / max(scale, 1.0)
    return Reading(name, scale, t_rms,
                   float(np.degrees(np.sqrt(np.mean(R**2)))))


def check_inputs(problem: Problem, *, camera_poses_given: bool) -> InputCheck:
    """Solve ``problem`` as configured and read otherwise (module docstring).

    Parameters
    ----------
    problem : Problem
        The pairs as solved (their relative weights).
    camera_poses_given : bool
        Whether the ``B`` came from the user (CSV, pose lists): only then are the readings with
        ``B`` inverted tried (the package's own detections are ``T_cam_target`` by
        construction).
    """
    configured = _fit("configured", problem)
    plans = [("pose_inverted", {"invert_a": True}), ("next_pose", {"shift": 1}),
             ("previous_pose", {"shift": -1})]
    if not problem.unknown_scale:
        plans.insert(0, ("units", {}))
    if camera_poses_given:
        plans += [("camera_inverted", {"invert_b": True}),
                  ("both_inverted", {"invert_a": True, "invert_b": True})]
    f = unit_prescale(problem)
    out = []
    for name, how in plans:
        p = _reading(problem, prescale=f, **how)
        if p is None:
            continue
        try:
            out.append(_fit(name, p, prescale=f))
        except (ValueError, ArithmeticError, np.linalg.LinAlgError):
            continue
    return InputCheck(configured, tuple(out))


def input_reasons(b: Builder, check: InputCheck | None, *, scale_checked: bool = False) -> None:
    """An ``unusable`` reason (code ``inputs``) when a reading of the inputs fits far better
    than the configured one: what fits, by how much, the likely mistake and the fix.
    ``scale_checked``: the scale check (:mod:`.scale_check`) measured the scale, so a free scale
    that is no unit factor is left to it (its words name tag sizes and focal lengths)."""
    if check is None:
        return
    found = [r for r in check.found()
             if not (r.name == "units" and scale_checked and unit_of(r.scale) is None)]
    if not found:
        return
    best = found[0]
    c = check.configured
    also = [r for r in found[1:] if {r.name, best.name} == {"pose_inverted", "camera_inverted"}]
    how = _READINGS[best.name] + "".join(f" (or, fitting less well, {_READINGS[r.name][5:]})"
                                         for r in also)
    fits = (f"the pairs fit {_length(best.translation_rms_m)} / {deg(best.rotation_rms_deg)} "
            f"RMS {how}, against {_length(c.translation_rms_m)} / {deg(c.rotation_rms_deg)} "
            "as read")
    units = unit_of(best.scale)
    if best.name == "units":
        cause = units or (f"the camera-target distances are {best.scale:.3g} times the pose "
                          "stream's: check the target sizes, the intrinsics and the units of "
                          "the poses")
        b.add("unusable", "inputs", f"the inputs do not fit as read: {fits} (scale "
              f"{best.scale:.4g}): {cause}", why="units")
        return
    causes = {
        "pose_inverted": "the robot poses are the other way round (T_tool_base given where "
                         "T_base_tool is read: a pose file of the other convention, or "
                         "pose_source.parent and .child swapped) or the cameras ride on the "
                         "other carrier (eye-to-hand data calibrated as eye-in-hand, or the "
                         "reverse); fix the pose convention, or the mount (camera_carrier / "
                         "tag_carrier; the CLI's --eye-in-hand, --eye-to-hand)",
        "camera_inverted": "the target-in-camera poses are the other way round (cam2target "
                           "given where target2cam is read); invert them",
        "both_inverted": "the robot poses and the target-in-camera poses are both the other "
                         "way round; invert both",
        "next_pose": "the poses are one view behind the images (a pose list that starts "
                     "one view early or an image missing at the start; in a recording, images "
                     "stamped a view late); pair each image with its own pose",
        "previous_pose": "the poses are one view ahead of the images (a pose list that starts "
                         "one view late or a pose missing at the start; in a recording, images "
                         "stamped a view early); pair each image with its own pose",
    }
    extra = f"; and at that reading {units}" if units else ""
    b.add("unusable", "inputs", f"the inputs do not fit as read: {fits}: {causes[best.name]}"
          f"{extra}", why=best.name.replace("_", " "))
