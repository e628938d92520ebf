"""A target or an edge that does not fit is excluded and the rest solved again
(rwhec_ros.core.verdict.exclusion, through rwhec_ros.session.solving.solve_and_assess), the
verdict's rules for tags and cameras on misfits, the per-frame noise factor and the reprojection
check."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from rwhec_ros.core.lie import invert_transform, make_transform, rotation_distance, so3_exp
from rwhec_ros.core.problem import Edge, Problem
from rwhec_ros.core.verdict import VerdictOptions
from rwhec_ros.core.verdict.exclusion import exclude_misfits, misfits
from rwhec_ros.core.verdict.fit import EdgeFit, FitStatistics
from rwhec_ros.core.verdict.model import Builder
from rwhec_ros.core.verdict.precision import frame_noise_ratios
from rwhec_ros.core.verdict.reasons import edge_reasons
from rwhec_ros.core.verdict.reprojection_check import reprojection_reasons
from rwhec_ros.session.accuracy import AccuracyOptions
from rwhec_ros.session.solving import solve_and_assess
from rwhec_ros.simulation import demo_rig
from rwhec_ros.simulation.synthetic import perturb_measurements

#: The rendered pipeline's stated noise (benchmarks/verdict.py: RENDER_SIGMA, RENDER_KAPPA).
SIGMA, KAPPA = 0.001, 20000.0
FAST = AccuracyOptions(folds=0, guidance=False)


def rig_pairs(rng, *, bad=2, size_factor=1.0, unknown_scale=False):
    """The demo rig's visible pairs at 5 Hz for 12 s at the stated noise, tag ``bad``'s
    translations scaled by ``size_factor`` (its size configured wrong: PnP distances scale)."""
    rig = demo_rig(3, 6)
    pairs: dict = {}
    for t in np.arange(0.05, 12.0, 0.2):
        Tw = rig.T_world_rig(t)
        A = invert_transform(Tw)
        for cam in rig.cameras:
            for tag in rig.visible_tags(cam, Tw):
                B = perturb_measurements(rng, tag.T_cam_tag[None], SIGMA, KAPPA)[0]
                if tag.tag_id == bad:
                    B[:3, 3] *= size_factor
                a, b = pairs.setdefault((f"tag_{tag.tag_id}", cam), ([], []))
                a.append(A)
                b.append(B)
    edges = [Edge.build(x, y, np.array(a), np.array(b), sigma=SIGMA, kappa=KAPPA)
             for (x, y), (a, b) in sorted(pairs.items()) if len(a) >= 3]
    return rig, Problem(sorted({e.x for e in edges}), sorted({e.y for e in edges}), edges,
                        unknown_scale=unknown_scale)


def camera_sigmas(rig, result, verdict, cameras=None):
    """Per camera: its error against the truth in its own std (the larger of translation and
    rotation)."""
    out = {}
    for cam in cameras or rig.cameras:
        f = verdict.frames[cam]
        Y, T = result.transform(cam), rig.T_rig_cam[cam]
        out[cam] = max(np.linalg.norm(Y[:3, 3] - T[:3, 3]) / f.std_translation_m,
                       np.degrees(rotation_distance(Y[:3, :3], T[:3, :3])) / f.std_rotation_deg)
    return out


@pytest.mark.parametrize("robust", [False, True])
@pytest.mark.parametrize("unknown_scale", [False, True])
def test_a_tag_of_the_wrong_size_is_excluded_and_the_cameras_are_right(robust, unknown_scale):
    rig, problem = rig_pairs(np.random.default_rng(0), size_factor=0.75,
                             unknown_scale=unknown_scale)
    solved = solve_and_assess(problem, reject_outliers=robust, accuracy=FAST)
    v, ex = solved.verdict, solved.exclusion
    # tag_2 (or its bad edge) is excluded, named, and tag_2 is not published
    assert ex.excluded and all("tag_2" in m.name for m in ex.excluded)
    assert v.reasons[0].code == "excluded" and "tag_2" in v.reasons[0].message
    assert not v.frames["tag_2"].usable
    # the cameras decide: they are right, so the result is usable (exit 0) ...
    assert v.usable and all(v.frames[c].usable for c in rig.cameras)
    # ... within 3 of their own std of the truth (measured: <= 1.4)
    assert max(camera_sigmas(rig, solved.result, v).values()) <= 3.0
    # the excluded edges are left out of the published solve, with their reason
    for m in ex.excluded:
        for e in m.edges:
            assert e in solved.dropped and e not in {x.name for x in solved.problem.edges}
    # the all-data solve is kept for reference, the shifts measured against it
    assert ex.first.pairs == problem.n_measurements and ex.pairs_kept < problem.n_measurements
    assert {s.name for s in ex.shifts if s.role == "Y"} == set(rig.cameras)
    assert "certificate is for that problem" in v.reasons[0].message
    assert any("exclusion: the published estimate is the solve of the remaining" in n
               for n in solved.result.notes)


def test_without_rejection_the_all_data_solve_was_pulled_off_by_the_bad_tag():
    """What the exclusion mends: the first solve's cameras are off by more than 3 std."""
    rig, problem = rig_pairs(np.random.default_rng(0), size_factor=0.75)
    solved = solve_and_assess(problem, accuracy=FAST)
    ex = solved.exclusion
    std = {c: solved.verdict.frames[c].std_translation_m for c in rig.cameras}
    off = {c: np.linalg.norm(np.array(ex.first.frames[c]["translation"])
                             - rig.T_rig_cam[c][:3, 3]) for c in rig.cameras}
    assert max(off[c] / std[c] for c in rig.cameras) > 3.0
    # and the shift the exclusion reports is that error, up to the published one's
    for s in ex.shifts:
        if s.role == "Y":
            final = np.linalg.norm(solved.result.transform(s.name)[:3, 3]
                                   - rig.T_rig_cam[s.name][:3, 3])
            assert abs(s.translation_m - off[s.name]) <= final + 1e-9


def test_the_outputs_name_the_exclusion_and_keep_the_all_data_solve():
    import yaml

    from rwhec_ros.data.results import FrameNaming, result_document
    from rwhec_ros.session.outputs import publishable, summary

    rig, problem = rig_pairs(np.random.default_rng(0), size_factor=0.75)
    solved = solve_and_assess(problem, reject_outliers=True, accuracy=FAST,
                              expected_x=problem.x_names, expected_y=problem.y_names)
    naming = FrameNaming.from_carriers(problem.x_names, problem.y_names, camera_carrier="rig",
                                       tag_carrier="world")
    doc = yaml.safe_load(yaml.safe_dump(result_document(
        solved.result, naming, excluded=solved.dropped, verdict=solved.verdict,
        accuracy=solved.accuracy, rejected_pairs=solved.rejected_pairs), sort_keys=False))
    ex = doc["exclusion"]
    assert ex["excluded_tags"] == ["tag_2"] and set(ex["shifts"]) >= set(rig.cameras)
    assert ex["first_solve"]["pairs"] == problem.n_measurements
    assert set(ex["first_solve"]["frames"]) == set(problem.frame_names)
    assert "its certificate is for that problem" in ex["certificate_note"]
    assert doc["reasons"][0].startswith("CAUTION: tag_2: excluded and not calibrated")
    assert all(k in doc["excluded_edges"] for k in ex["excluded"][0]["edges"])
    assert "tag_2" not in [f["name"] for f in doc["frames"]]
    text = summary(solved.result, solved.problem, solved.dropped, naming, solved.verdict,
                   solved.accuracy)
    assert "world->tag_2_calibrated: NOT CALIBRATED (excluded: does not fit)" in text
    assert f"all-data solve (not published): {problem.n_measurements} pairs" in text
    assert "without tag_2: cam0 " in text
    names = list(solved.result.y_names) + list(solved.result.x_names)
    kept, _ = publishable(naming.transforms(solved.result), names, solved.verdict)
    assert "tag_2_calibrated" not in [child for _, child, _ in kept]
    assert dict(solved.verdict.exclusion.diagnostic_values())["excluded"] == "tag_2"


def test_good_data_exclude_nothing():
    rig, problem = rig_pairs(np.random.default_rng(1))
    for robust in (False, True):
        solved = solve_and_assess(problem, reject_outliers=robust, accuracy=FAST)
        assert solved.exclusion is not None and not solved.exclusion.excluded
        assert solved.verdict.level == "good" and solved.exclusion.shifts == []
        assert solved.problem.n_measurements == problem.n_measurements


def test_exclusion_off_names_the_tag_but_keeps_it():
    rig, problem = rig_pairs(np.random.default_rng(0), size_factor=0.75)
    solved = solve_and_assess(problem, accuracy=FAST,
                              thresholds=VerdictOptions(exclude_misfits=False))
    assert solved.exclusion is None and solved.verdict.exclusion is None
    assert solved.problem.n_measurements == problem.n_measurements
    assert any("tag_2" in str(r.edges) or "tag_2" in r.frames for r in solved.verdict.reasons)


def test_a_budget_too_small_excludes_nothing_and_the_cameras_on_it_are_not_usable():
    rig, problem = rig_pairs(np.random.default_rng(0), size_factor=0.75)
    solved = solve_and_assess(problem, accuracy=FAST,
                              thresholds=VerdictOptions(exclusion_max_share=0.01))
    ex = solved.exclusion
    assert not ex.excluded and "verdict.exclusion_max_share" in ex.stopped and ex.remaining
    # the misfit remains: a camera resting on it is not usable, so neither is the result
    assert not solved.verdict.usable
    assert any("rests on" in w or "pulled by" in w for c in rig.cameras
               for w in solved.verdict.frames[c].why if not solved.verdict.frames[c].usable)


# --- the verdict's rules ------------------------------------------------------------------------


def _edge(x, y, *, flagged=False, ratio=1.0, pairs=10):
    e = EdgeFit(x, y, pairs, 3.0 * pairs, 3.0 * pairs, ratio, ratio, ratio, ratio,
                rms_translation_m=1e-3 * ratio, rms_rotation_deg=0.1 * ratio)
    e.flagged = flagged
    return e


def _fit(edges):
    return FitStatistics(pairs=sum(e.pairs for e in edges), frames=6, dof_translation=100.0,
                         dof_rotation=100.0, chi2_translation=100.0, chi2_rotation=100.0,
                         p_translation=0.5, p_rotation=0.5, p_value=0.5, sigma_stated_m=1e-3,
                         kappa_stated=2e4, edges=edges)


def test_an_outlier_edge_that_is_its_tags_only_edge_makes_a_caution_not_unusable():
    """docs/verdict.md: a tag that cannot be used makes the result a caution only (it was
    unusable, exit 4, with outlier rejection leaving the bad tag one edge)."""
    edges = [_edge("t0", "c0"), _edge("t1", "c0"), _edge("t0", "c1"), _edge("t1", "c1"),
             _edge("t2", "c1", flagged=True, ratio=9.0)]
    b = Builder(["t0", "t1", "t2"], ["c0", "c1"])
    edge_reasons(b, _fit(edges), None, VerdictOptions())
    v = b.verdict(None, None, "", VerdictOptions())
    assert v.level == "caution" and v.usable
    assert not v.frames["t2"].usable and v.frames["c1"].usable
    # after an exclusion that could not remove it (strict) its camera rests on it: unusable
    b = Builder(["t0", "t1", "t2"], ["c0", "c1"])
    edge_reasons(b, _fit(edges), None, VerdictOptions(), strict=True)
    v = b.verdict(None, None, "", VerdictOptions())
    assert v.level == "unusable" and not v.frames["c1"].usable and v.frames["c0"].usable


def test_misfits_tag_edges_rejection_and_cameras():
    rng = np.random.default_rng(0)
    eye = np.tile(np.eye(4), (4, 1, 1))

    def e(x, y, n=4):
        return Edge.build(x, y, eye[:n], eye[:n] @ make_transform(so3_exp(rng.normal(size=3)),
                                                                    np.zeros(3)))
    given = Problem(["t0", "t1", "t2"], ["c0", "c1", "c2"],
                    [e("t0", "c0"), e("t0", "c1"), e("t1", "c0"), e("t1", "c1"),
                     e("t2", "c1"), e("t2", "c2"), e("t1", "c2")])
    fits = [_edge(x.x, x.y) for x in given.edges]
    for f in fits:
        f.flagged = f.x == "t2"
    found = {m.name: m for m in misfits(_fit(fits), given)}
    assert set(found) == {"t2"} and found["t2"].kind == "tag" and found["t2"].pairs == 8
    # one flagged edge of t2, the other wholly rejected: still the tag
    for f in fits:
        f.flagged = f.name == "(t2, c1)"
    found = {m.name: m for m in misfits(_fit(fits), given, rejected={"(t2, c2)": 4})}
    assert set(found) == {"t2"}
    # one flagged edge alone: the edge
    assert [m.name for m in misfits(_fit(fits), given)] == ["(t2, c1)"]
    # most of a tag's pairs rejected: the tag, although nothing is flagged
    for f in fits:
        f.flagged = False
    found = misfits(_fit(fits), given, rejected={"(t0, c0)": 4, "(t0, c1)": 3})
    assert [(m.kind, m.name) for m in found] == [("tag", "t0")]
    assert not misfits(_fit(fits), given, rejected={"(t0, c0)": 4},
                       options=VerdictOptions(exclusion_rejected_share=0.6))
    # every edge of a camera flagged: its intrinsics or stamps, no target to exclude
    for f in fits:
        f.flagged = f.y == "c0"
    assert misfits(_fit(fits), given) == []


def test_exclude_misfits_stops_at_the_round_limit():
    rig, problem = rig_pairs(np.random.default_rng(0), size_factor=0.75)
    from rwhec_ros.core.solve import solve
    from rwhec_ros.core.verdict.exclusion import Attempt

    def attempt(p):
        return Attempt(solve(p), p)

    ex, final = exclude_misfits(problem, attempt(problem), attempt,
                                options=VerdictOptions(exclusion_max_rounds=1))
    assert len(ex.excluded) == 1 and final.problem.n_measurements == ex.pairs_kept
    ex0, final0 = exclude_misfits(problem, attempt(problem), attempt,
                                  options=VerdictOptions(exclusion_max_rounds=1,
                                                         exclusion_max_share=0.01))
    assert not ex0.excluded and final0.problem is problem and ex0.shifts == []


def test_a_failing_re_solve_publishes_the_previous_solve():
    rig, problem = rig_pairs(np.random.default_rng(0), size_factor=0.75)
    from rwhec_ros.core.solve import solve
    from rwhec_ros.core.verdict.exclusion import Attempt

    first = Attempt(solve(problem), problem)

    def failing(p):
        raise RuntimeError("no convergence")

    ex, final = exclude_misfits(problem, first, failing)
    assert final is first and not ex.excluded and ex.shifts == []
    assert ex.stopped.startswith("the solve without (tag_2, cam0) failed (RuntimeError: no "
                                 "convergence)")
    assert ex.remaining


def test_frame_noise_ratio_only_where_significant():
    fits = [_edge("t0", "c0", ratio=1.0, pairs=50), _edge("t1", "c0", ratio=1.05, pairs=50),
            _edge("t1", "c1", ratio=4.0, pairs=50)]
    own = frame_noise_ratios(_fit(fits), 1e-3)
    assert set(own) == {"t1", "c1"}  # c0: 1.0x and 1.05x is no misfit at 150 dof each
    assert own["c1"] == pytest.approx(4.0)
    assert 1.0 < own["t1"] < 4.0


def test_reprojection_names_the_camera_far_worse_than_the_others():
    def rep(rms, per=None):
        return SimpleNamespace(rms_px=rms, per_target_rms_px=per)

    b = Builder(["t0"], ["c0", "c1", "c2"])
    reprojection_reasons(b, {"c0": rep(0.4), "c1": rep(0.35),
                             "c2": rep(23.0, {"t0": 0.5, "t2": 51.0})}, VerdictOptions())
    (r,) = b.reasons
    assert r.code == "reprojection" and r.frames == ("c2",) and r.level == "caution"
    assert "23.0 px" in r.message and "worst on t2 (51.0 px)" in r.message
    b = Builder(["t0"], ["c0", "c1", "c2"])  # good: 0.3-0.5 px
    reprojection_reasons(b, {"c0": rep(0.4), "c1": rep(0.35), "c2": rep(0.5)},
                         VerdictOptions())
    assert b.reasons == []
    b = Builder(["t0"], ["c0", "c1"])  # far worse in ratio but below 2 px: not named
    reprojection_reasons(b, {"c0": rep(0.1), "c1": rep(1.5)}, VerdictOptions())
    assert b.reasons == []
