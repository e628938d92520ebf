"""Misfits the edge statistics miss once the noise is estimated per camera
(rwhec_ros.core.verdict.hidden_misfits): a tag whose size is configured wrong against the other
tags (rwhec_ros.core.verdict.tag_scale_check) and a tag that moved while one camera saw it are
found, measured and excluded; good data, a camera with its own fault and the paper's real tags
are left alone."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from test_exclusion import FAST, KAPPA, SIGMA, camera_sigmas, rig_pairs

from rwhec_ros.core.lie import invert_transform, make_transform
from rwhec_ros.core.noise import NoiseOptions
from rwhec_ros.core.problem import Edge, Problem
from rwhec_ros.core.solve import SolveOptions, solve
from rwhec_ros.core.verdict import VerdictOptions
from rwhec_ros.core.verdict.tag_scale_check import (
    MIN_TAGS,
    scale_misfit_tags,
    tag_scales,
)
from rwhec_ros.session.solving import solve_and_assess
from rwhec_ros.simulation import demo_rig
from rwhec_ros.simulation.synthetic import perturb_measurements

SHARED = Path(__file__).resolve().parents[2] / ".." / "shared"


@pytest.mark.parametrize("unknown_scale", [False, True])
def test_a_tag_10_percent_too_small_is_measured_and_named(unknown_scale):
    # tag_2's PnP distances 0.9x the truth (its size configured 10 % too small)
    _, problem = rig_pairs(np.random.default_rng(1), size_factor=0.9,
                           unknown_scale=unknown_scale)
    res = solve(problem, SolveOptions(mode="fast"))
    scales = tag_scales(problem, res)
    q = scales["tag_2"]
    # measured against the other tags: 0.9 within 3 of its std (std ~0.5 % here)
    assert abs(q.ratio - 0.9) <= 3 * q.std and q.std < 0.02
    # the good tags' own ratios stay near 1 (the bad tag pulls the others' reference a little)
    assert all(abs(s.ratio - 1.0) < 0.05 for t, s in scales.items() if t != "tag_2")
    off = scale_misfit_tags(problem, res, VerdictOptions())
    assert [s.tag for s in off] == ["tag_2"]
    assert "~10 % too small" in off[0].words()


def test_good_data_name_no_tag():
    _, problem = rig_pairs(np.random.default_rng(2))
    res = solve(problem, SolveOptions(mode="fast"))
    scales = tag_scales(problem, res)
    assert len(scales) >= MIN_TAGS
    # each ratio within 4 std of 1 (the data are drawn at the weights' noise)
    assert all(abs(s.ratio - 1.0) <= 4 * s.std for s in scales.values()), scales
    assert scale_misfit_tags(problem, res, VerdictOptions()) == []


def test_too_few_tags_no_spread_no_finding():
    _, problem = rig_pairs(np.random.default_rng(3), size_factor=0.9)
    keep = ["tag_0", "tag_1", "tag_2"]
    small = problem.with_edges([e for e in problem.edges if e.x in keep])
    res = solve(small, SolveOptions(mode="fast"))
    assert 0 < len(tag_scales(small, res)) < MIN_TAGS
    assert scale_misfit_tags(small, res, VerdictOptions()) == []


@pytest.mark.parametrize("robust", [False, True])
def test_noise_estimated_the_tag_is_excluded_and_the_cameras_are_right(robust):
    """With the noise estimated per camera a tag 10 % too small hides among its cameras' edges
    (the fit's edge rule did not name it on the rendered rig); the size check names it, the
    exclusion leaves it out, and the cameras are within 3 of their std."""
    rig, problem = rig_pairs(np.random.default_rng(4), size_factor=0.9, unknown_scale=True)
    solved = solve_and_assess(problem, reject_outliers=robust, accuracy=FAST,
                              noise=NoiseOptions(given="stated"))
    ex, v = solved.exclusion, solved.verdict
    assert [m.name for m in ex.excluded] == ["tag_2"]
    assert "camera-tag distances are 0.9" in ex.excluded[0].finding
    assert v.usable and not v.frames["tag_2"].usable
    assert max(camera_sigmas(rig, solved.result, v).values()) <= 3.0


def test_the_papers_real_tags_are_not_named():
    """The paper's 16 real tags differ by up to 9 % in their ratio (depth biases), each
    significantly: the spread rule keeps them all."""
    data = SHARED / "data" / "paper_real_world"
    if not data.is_dir():
        pytest.skip("shared/ data set not present")
    from rwhec_ros.core.noise import solve_with_noise
    from rwhec_ros.data.paper_csv import read_paper_csv

    problem = read_paper_csv(data, sigma=0.1, kappa=125.0, min_pairs=3)
    ns = solve_with_noise(problem, SolveOptions(mode="fast"), NoiseOptions())
    scales = tag_scales(ns.problem, ns.result)
    assert len(scales) == 16
    significant = [s for s in scales.values() if s.off(VerdictOptions())]
    assert len(significant) >= 5  # what a test against the std alone would exclude
    assert scale_misfit_tags(ns.problem, ns.result, VerdictOptions()) == []


def seen_by(rng, change):
    """The demo rig's pairs at the stated noise (as ``test_exclusion.rig_pairs``), each ``B``
    passed through ``change(tag_id, camera, B)``."""
    rig = demo_rig(3, 6)
    pairs: dict = {}
    for t in np.arange(0.05, 12.0, 0.2):
        Tw = rig.T_world_rig(t)
        for cam in rig.cameras:
            for tag in rig.visible_tags(cam, Tw):
                B = change(tag.tag_id, cam,
                           perturb_measurements(rng, tag.T_cam_tag[None], SIGMA, KAPPA)[0])
                a, b = pairs.setdefault((f"tag_{tag.tag_id}", cam), ([], []))
                a.append(invert_transform(Tw))
                b.append(B)
    edges = [Edge.build(x, y, np.array(a), np.array(b), sigma=SIGMA, kappa=KAPPA)
             for (x, y), (a, b) in sorted(pairs.items()) if len(a) >= 3]
    return rig, Problem(sorted({e.x for e in edges}), sorted({e.y for e in edges}), edges)


def test_a_tag_moved_where_one_camera_saw_it_is_excluded():
    """tag_1 5 cm off in cam0's views only (it moved before cam0 saw it; cam2 saw it before):
    cam0's estimated noise is far above the others', no edge stands out; leaving tag_1 out
    brings it back, so tag_1 is excluded with that finding and the cameras are right."""
    moved = make_transform(np.eye(3), np.array([0.05, 0.0, 0.0]))
    rig, problem = seen_by(np.random.default_rng(6), lambda j, cam, B: B @ moved
                           if (j, cam) == (1, "cam0") else B)
    assert {e.y for e in problem.edges if e.x == "tag_1"} == {"cam0", "cam2"}
    solved = solve_and_assess(problem, accuracy=FAST, noise=NoiseOptions(given="stated"))
    ex, v = solved.exclusion, solved.verdict
    assert [m.name for m in ex.excluded] == ["tag_1"]
    assert "cam0's translation noise is" in ex.excluded[0].finding
    assert "without it" in ex.excluded[0].finding and ex.excluded[0].camera == "cam0"
    assert v.usable and all(v.frames[c].usable for c in rig.cameras)
    assert max(camera_sigmas(rig, solved.result, v).values()) <= 3.0


def test_a_camera_with_its_own_fault_keeps_its_tags():
    """cam0's depth 8 % off on every tag (a focal length): its noise is far above the others',
    but no single tag's exclusion brings it back: no tag is excluded for cam0's misfit."""
    def deeper(j, cam, B):
        if cam != "cam0":
            return B
        out = B.copy()
        out[:3, 3] *= 1.08
        return out

    _, problem = seen_by(np.random.default_rng(7), deeper)
    solved = solve_and_assess(problem, accuracy=FAST, noise=NoiseOptions(given="stated"))
    far = [g.name for g, *_ in solved.noise.far_above(VerdictOptions().noise_group_ratio)]
    assert far == ["cam0"]  # the camera candidates were tried (measured: 14.6x) ...
    assert not any(m.camera for m in solved.exclusion.excluded)  # ... and none explained it
    assert any(r.code == "camera" and "cam0" in r.message for r in solved.verdict.reasons)


def test_a_tag_found_by_its_edges_gets_its_size_in_the_finding():
    """A tag 25 % too small is found by its edges (every one far worse than the others); the
    size check adds what its size is, so the reason names the fix."""
    _, problem = rig_pairs(np.random.default_rng(8), size_factor=0.75)
    solved = solve_and_assess(problem, accuracy=FAST, noise=NoiseOptions(given="stated"))
    (m,) = solved.exclusion.excluded
    assert m.name == "tag_2" and "~25 % too small" in m.finding
    assert m.causes.startswith("its size is wrong")
    assert any("true size = configured / 0.7" in r.message for r in solved.verdict.reasons)
