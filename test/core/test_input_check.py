"""The verdict's check for gross input mistakes (rwhec_ros.core.verdict.input_check).

Each broken case is one real-world mistake applied to data drawn at a known noise: the robot
poses inverted (a pose file of the other convention, or the wrong mount), translations in
millimetres, the target-in-camera poses inverted, the pairs one row off. The check must name
the mistake (code ``inputs``, first reason, UNUSABLE) and never fire on the data as drawn.
"""

from __future__ import annotations

import numpy as np
import pytest

from rwhec_ros.core.lie import invert_transform
from rwhec_ros.core.problem import Edge, Problem
from rwhec_ros.core.solve import solve
from rwhec_ros.core.verdict import assess
from rwhec_ros.core.verdict.input_check import GROSS_MISFIT_RATIO, check_inputs, unit_of
from rwhec_ros.simulation.synthetic import random_instance


def drawn(seed: int, tags: int = 3, cameras: int = 2, n: int = 20,
          kappa: float = 200.0) -> Problem:
    """Pairs at 2 mm and ``kappa`` (200: 2.9 deg per axis, an RMS angle of 5 deg), every tag seen
    by every camera."""
    problem, _ = random_instance(np.random.default_rng(seed), tags, cameras, n_per_edge=n,
                                 sigma=0.002, kappa=kappa)
    return problem


def changed(problem: Problem, change) -> Problem:
    edges = []
    for e in problem.edges:
        A, B, keep = change(e)
        edges.append(Edge.build(e.x, e.y, A, B, sigma=e.sigma[keep], kappa=e.kappa[keep]))
    return problem.with_edges(edges)


def inverted_poses(e):
    return invert_transform(e.A), e.B, slice(None)


def inverted_camera_poses(e):
    return e.A, invert_transform(e.B), slice(None)


def poses_in_mm(e):
    A = e.A.copy()
    A[:, :3, 3] *= 1000.0
    return A, e.B, slice(None)


def sizes_in_mm(e):
    B = e.B.copy()
    B[:, :3, 3] *= 1000.0
    return e.A, B, slice(None)


def pose_one_behind(e):
    # image i + 1 given with the pose of view i: each image needs the pose after the one given
    return e.A[:-1], e.B[1:], slice(1, None)


def pose_one_ahead(e):
    return e.A[1:], e.B[:-1], slice(None, -1)


@pytest.mark.parametrize("shape", [(3, 2), (1, 1)])
@pytest.mark.parametrize("seed", range(3))
def test_data_as_drawn_name_nothing(seed, shape):
    problem = drawn(seed, *shape)
    check = check_inputs(problem, camera_poses_given=True)
    assert check.found() == []
    # every alternative fits worse or alike (a single edge: both inverted is the same problem)
    assert max(check.ratio(r) for r in check.alternatives) < 2.0
    verdict = assess(solve(problem), problem)
    assert not any(r.code == "inputs" for r in verdict.reasons), verdict.messages()
    assert verdict.input_check is not None


@pytest.mark.parametrize("mistake, given, words", [
    (inverted_poses, False, "with every robot pose inverted"),
    (poses_in_mm, False, "in millimetres (the camera-target distances are 1/1000"),
    (sizes_in_mm, False, "the target sizes are given in millimetres"),
    (pose_one_behind, False, "paired with the pose of the view after it"),
    (pose_one_ahead, False, "paired with the pose of the view before it"),
    (inverted_camera_poses, True, "with every target-in-camera pose inverted"),
])
def test_a_mistake_is_named_first(mistake, given, words):
    problem = drawn(1)
    broken = changed(problem, mistake)
    verdict = assess(solve(broken), broken, reprojection=None if given else {})
    assert verdict.level == "unusable", verdict.messages()
    top = verdict.reasons[0]
    assert top.code == "inputs" and words in top.message, verdict.messages()
    assert verdict.headline().startswith("UNUSABLE: the inputs do not fit as read")
    best = verdict.input_check.found()[0]
    # the reading that fits does so at the drawn noise (3.5 mm RMS of a 3-d error of 2 mm per
    # axis, a 5 deg RMS angle), in metres whichever side was in millimetres
    assert best.translation_rms_m < 0.005 and best.rotation_rms_deg < 6.0
    assert verdict.input_check.ratio(best) >= GROSS_MISFIT_RATIO


def test_the_camera_poses_are_not_turned_for_the_package_s_own_detections():
    # B from the package's detections is T_cam_target by construction: not tried
    problem = drawn(2)
    check = check_inputs(problem, camera_poses_given=False)
    assert {r.name for r in check.alternatives} == {"units", "pose_inverted", "next_pose",
                                                    "previous_pose"}
    check = check_inputs(problem.with_edges(problem.edges, unknown_scale=True),
                         camera_poses_given=True)
    assert "units" not in {r.name for r in check.alternatives}  # the scale is free already


def test_a_single_edge_names_both_inversions():
    # one edge cannot tell A^-1 X = Y B from X^-1 A = B^-1 Y^-1 (the same equation with X and Y
    # swapped): both are said where the rotation noise is small enough that inverting B does not
    # carry it into the translations (0.18 deg per axis, 3 mm at 1 m: as on a real arm)
    problem = drawn(4, 1, 1, n=25, kappa=1e5)
    broken = changed(problem, inverted_poses)
    verdict = assess(solve(broken), broken)
    assert ("with every robot pose inverted (or, fitting less well, every target-in-camera "
            "pose inverted)") \
        in verdict.reasons[0].message


def test_a_scale_that_is_no_unit_is_left_to_the_scale_check():
    problem = drawn(3)

    def scaled(e):
        B = e.B.copy()
        B[:, :3, 3] *= 0.8
        return e.A, B, slice(None)

    broken = changed(problem, scaled)
    verdict = assess(solve(broken), broken)
    assert verdict.reasons[0].code == "scale", verdict.messages()
    assert not any(r.code == "inputs" for r in verdict.reasons)


@pytest.mark.parametrize("alpha, unit", [(0.00097, "millimetres"), (0.0105, "centimetres"),
                                         (0.0254, "inches"), (1040.0, "millimetres"),
                                         (1.05, None), (0.5, None), (0.00112, "millimetres"),
                                         (0.0013, None)])
def test_unit_factors(alpha, unit):
    words = unit_of(alpha)
    assert (words is None) if unit is None else (unit in words)


def test_the_units_are_guessed_before_the_readings_are_solved():
    # a real fixed-camera single-tag set with poses in mm: the free-scale solve of the data as
    # they are ended at a scale of -1.5e-4; the readings are solved from data brought to the
    # nearest unit factor of the spreads' ratio, where the scale is near 1
    from rwhec_ros.core.verdict.input_check import unit_prescale

    problem = drawn(2)
    assert unit_prescale(problem) == 1.0
    assert unit_prescale(changed(problem, poses_in_mm)) == 1e-3
    assert unit_prescale(changed(problem, sizes_in_mm)) == 1e3
