"""The accuracy of a calibration in what users read (issue 11 phase 2): the per-frame uncertainty,
the cross-validation and the guidance, computed once in the solve step (session.accuracy), in the
result YAML, the summary, /diagnostics and the verdict's precision.

These tests check the *wiring*: that what is written equals what the core modules compute for the
same problem, with the documented shapes, units and words. The core numbers themselves are
checked elsewhere (test/core/test_uncertainty.py, test_validation.py, test_guidance.py and the
Monte-Carlo benchmark benchmarks/uncertainty.md).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from rwhec_ros.core.analysis.uncertainty import UncertaintyOptions, frame_uncertainty
from rwhec_ros.core.analysis.validation import cross_validate
from rwhec_ros.core.model.gauge import GaugeOptions, TranslationPrior
from rwhec_ros.data.results import FrameNaming, result_document
from rwhec_ros.messages import diagnostic_rows
from rwhec_ros.session import summary
from rwhec_ros.session.accuracy import AccuracyOptions
from rwhec_ros.session.solving import solve_and_assess
from rwhec_ros.simulation.synthetic import random_instance

REPO = Path(__file__).resolve().parents[1]


def _naming(problem):
    return FrameNaming.from_carriers(problem.x_names, problem.y_names, camera_carrier="rig",
                                     tag_carrier="world")


def _document(problem, **kw):
    solved = solve_and_assess(problem, carriers=("rig", "world"), **kw)
    doc = result_document(solved.result, _naming(problem), verdict=solved.verdict,
                          accuracy=solved.accuracy)
    # through YAML text, as written: NaN must not appear, None stays None
    return solved, yaml.safe_load(yaml.safe_dump(doc, sort_keys=False))


@pytest.fixture(scope="module")
def good():
    problem, truth = random_instance(np.random.default_rng(3), 3, 2, n_per_edge=25,
                                     sigma=0.01, kappa=200.0)
    return problem, *_document(problem)


@pytest.fixture(scope="module")
def planar():
    sys.path.insert(0, str(REPO / "test" / "core"))
    from test_gauge import _planar_rig

    problem, X, Y = _planar_rig(np.random.default_rng(1), jitter=1e-6)
    return problem, X, Y


def test_yaml_frame_stds_are_core_uncertainty_of_the_same_problem(good):
    problem, solved, doc = good
    # independent computation on the same problem and result
    unc = frame_uncertainty(problem, solved.result)
    frames = {f["name"]: f for f in doc["frames"]}
    assert set(frames) == set(problem.frame_names)
    for fu in unc.frames:
        f = frames[fu.name]
        assert f["std_kind"].startswith("predicted from the stated noise")
        C = np.asarray(f["covariance"], dtype=float)
        assert C.shape == (6, 6)
        # same numbers (YAML floats are repr-exact: only the float round trip)
        np.testing.assert_allclose(C, fu.covariance, rtol=1e-12)
        std_t = np.asarray(f["std_translation_m"], dtype=float)
        std_r = np.asarray(f["std_rotation_deg"], dtype=float)
        assert std_t.shape == (3,) and std_r.shape == (3,)
        # units: metres and degrees from the covariance's m^2 and rad^2 diagonal
        np.testing.assert_allclose(std_t, np.sqrt(np.diag(C)[:3]), rtol=1e-12)
        np.testing.assert_allclose(std_r, np.degrees(np.sqrt(np.diag(C)[3:])), rtol=1e-12)
        # a posteriori: the predicted covariance times the variance factor
        vf = doc["uncertainty"]["variance_factor"]
        np.testing.assert_allclose(np.asarray(f["a_posteriori"]["covariance"]), vf * C,
                                   rtol=1e-12)
        assert f["unobservable"] == {"translation": [], "rotation": []}
    # 1 cm / kappa 200 on 25 pairs per edge: stds of millimetres, not metres (sanity of units)
    assert 1e-4 < max(max(f["std_translation_m"]) for f in doc["frames"]) < 0.05
    assert doc["uncertainty"]["scale_std"] is None  # known scale
    assert "PoseWithCovariance" in doc["uncertainty"]["convention"]


def test_verdict_precision_comes_from_core_uncertainty(good):
    problem, solved, _ = good
    unc = solved.accuracy.uncertainty
    for fu in unc.frames:
        fv = solved.verdict.frames[fu.name]
        t, r = fu.worst_std()
        # the verdict's factor is max(1, s) >= 1 (the fit's noise ratio): its std is t scaled
        ratio = fv.std_translation_m / t
        assert ratio >= 1.0 and fv.std_rotation_deg / r == pytest.approx(ratio, rel=1e-12)
        # worst direction at least the largest axis
        assert t >= fu.std_translation_m.max() * (1 - 1e-12)


def test_cross_validation_in_yaml_matches_core(good):
    problem, solved, doc = good
    cv = doc["cross_validation"]
    assert cv["folds"] == 5 and cv["seed"] == 0
    ref = cross_validate(problem, np.random.default_rng(0), folds=5, result=solved.result)
    assert len(cv["edges"]) == len(problem.edges)
    for e, r in zip(cv["edges"], ref.edges, strict=True):
        assert (e["x"], e["y"]) == (r.x, r.y)
        # same folds (same seed) and the same fast solves: the same residuals
        assert e["held_out"]["rms_translation_mm"] == pytest.approx(
            r.held_out.rms_translation_mm, rel=1e-6)
        assert e["in_sample"]["rms_rotation_deg"] == pytest.approx(
            r.in_sample.rms_rotation_deg, rel=1e-9)


def test_summary_gives_stds_worst_held_out_edge_and_next_motion(good):
    problem, solved, doc = good
    text = summary(solved.result, solved.problem, {}, _naming(problem), solved.verdict,
                   solved.accuracy)
    lines = text.splitlines()
    frame_lines = [ln for ln in lines if "->" in ln and " t=[" in ln]
    assert len(frame_lines) == len(problem.frame_names)
    assert all(" mm, +-" in ln and ln.endswith(" deg") for ln in frame_lines)
    (largest,) = [ln for ln in lines if ln.startswith("largest std: ")]
    assert "predicted from the stated noise" in largest and "a posteriori" in largest
    (cv,) = [ln for ln in lines if ln.startswith("cross-validation (5 folds), worst held-out")]
    worst = max(doc["cross_validation"]["edges"],
                key=lambda e: e["held_out"]["rms_translation_mm"])
    assert f"({worst['x']}, {worst['y']})" in cv
    (motion,) = [ln for ln in lines if ln.startswith("next motion: ")]
    assert motion == "next motion: " + doc["guidance"]["message"]


def test_diagnostics_carry_per_frame_stds_and_the_next_motion(good):
    problem, solved, doc = good
    values = solved.accuracy.diagnostic_values()
    rows = diagnostic_rows([{"x": "x0", "y": "y0", "pairs": 25, "identifiable": True}],
                           {"pairs_kept": 25}, calibration=("good", "GOOD"), accuracy=values)
    session = dict(rows[0]["values"])
    for name in problem.frame_names:
        assert session[f"std {name}"].startswith("+-") and " mm, +-" in session[f"std {name}"]
    assert session["next_motion"] == doc["guidance"]["message"]
    assert rows[0]["message"].endswith("next motion: " + doc["guidance"]["message"])
    assert "worst_held_out_edge" in session and "largest_std" in session


def test_planar_motion_reports_the_height_as_unobservable_not_a_number(planar):
    problem, _, _ = planar
    solved, doc = _document(problem, accuracy=AccuracyOptions(folds=0, guidance=True))
    for f in doc["frames"]:
        # the rig only yaws: every frame's height (z of its parent) is not determined
        assert f["unobservable"]["translation"] == ["z"], f["name"]
        assert f["std_translation_m"][2] is None
        assert all(v is not None for v in f["std_translation_m"][:2])
        C = f["covariance"]
        assert all(C[2][i] is None and C[i][2] is None for i in range(6))
        # the rotations are determined (yaw and two tilts of the frames themselves)
        assert all(v is not None for v in f["std_rotation_deg"])
    assert doc["uncertainty"]["unobservable"]  # in words
    text = summary(solved.result, solved.problem, {}, _naming(problem), solved.verdict,
                   solved.accuracy)
    (line,) = [ln for ln in text.splitlines() if ln.startswith("unobservable (")]
    # problem order: tags (X), then cameras (Y)
    assert line.endswith("tag_0 translation z, tag_1 translation z, cam0 translation z, cam1 "
                         "translation z")
    # and never a huge number anywhere in the frames' stds
    for f in doc["frames"]:
        assert all(v is None or v < 1.0 for v in f["std_translation_m"])
    # the guidance asks for a tilt (rotation about x or y of the rig)
    best = doc["guidance"]["best"]
    assert best["kind"] == "rotate" and best["axis"] in ("x", "y")
    assert doc["cross_validation"] is None
    assert any("cross-validation off" in n for n in doc["accuracy_notes"])


def test_planar_motion_with_a_prior_gives_stds_given_the_prior(planar):
    problem, X, Y = planar
    height = float(Y[0, 2, 3])
    solved, doc = _document(problem, priors=[("cam0", "z", height)],
                            accuracy=AccuracyOptions(folds=0, guidance=False))
    ref = frame_uncertainty(problem, solved.result, UncertaintyOptions(
        gauge=GaugeOptions(priors=(TranslationPrior("cam0", "z", height),))))
    assert doc["uncertainty"]["conditioned_on_priors"] is True
    for f in doc["frames"]:
        assert f["unobservable"]["translation"] == []
        np.testing.assert_allclose(f["std_translation_m"], ref.frame(f["name"]).std_translation_m,
                                   rtol=1e-12)
    assert doc["guidance"] is None


def test_unknown_scale_has_a_scale_std():
    problem, _ = random_instance(np.random.default_rng(4), 2, 2, n_per_edge=30, sigma=0.01,
                                 kappa=200.0, unknown_scale=True)
    solved, doc = _document(problem, accuracy=AccuracyOptions(folds=0, guidance=False))
    s = doc["uncertainty"]["scale_std"]
    ref = frame_uncertainty(problem, solved.result).scale_std
    assert s == pytest.approx(ref, rel=1e-12) and 0 < s < 0.1
    vf = doc["uncertainty"]["variance_factor"]
    assert doc["uncertainty"]["scale_std_a_posteriori"] == pytest.approx(s * np.sqrt(vf))
    text = summary(solved.result, solved.problem, {}, _naming(problem), solved.verdict,
                   solved.accuracy)
    assert f"scale {solved.result.scale:.5f} +-{s:.5f} (1 sigma, predicted)" in text


def test_options_are_validated():
    with pytest.raises(ValueError, match="folds"):
        AccuracyOptions(folds=1)
    with pytest.raises(ValueError, match="moving"):
        AccuracyOptions(moving="z")


def test_reprojection_per_camera_from_a_data_set_with_corners():
    from rwhec_ros.data.corners import corner_data
    from rwhec_ros.data.dataset import Dataset, DatasetEdge
    from rwhec_ros.vision.detection import tag_object_points
    from rwhec_ros.vision.intrinsics import CameraIntrinsics
    from rwhec_ros.vision.reprojection import reprojection_errors

    rng = np.random.default_rng(7)
    problem, truth = random_instance(rng, 2, 2, n_per_edge=15)  # exact B
    intr = {"y0": CameraIntrinsics.pinhole(640, 480, 500.0),
            "y1": CameraIntrinsics.pinhole(800, 600, 650.0)}
    size = 0.2
    edges = []
    for e in Dataset.from_problem(problem).edges:
        # the corners the detector would see: the tag through the measured (exact) B
        c = np.stack([intr[e.y].project_points(tag_object_points(size) @ B[:3, :3].T + B[:3, 3])
                      for B in e.B])
        c[e.B[:, 2, 3] <= 0.5] = np.nan  # tags behind (or at) the camera: no corners
        edges.append(DatasetEdge(e.x, e.y, e.stamps_ns, e.A, e.B, e.sigma, e.kappa,
                                 corners_px=c))
    ds = Dataset(problem.x_names, problem.y_names, edges, intrinsics=intr,
                 tag_sizes_m={"x0": size, "x1": size})
    corners = corner_data(ds)
    assert corners is not None and len(corners[0]) > 10
    # solver.refine false: today's path (the refinement has tests of its own)
    solved, doc = _document(problem, corners=corners, refine=False,
                            accuracy=AccuracyOptions(folds=0, guidance=False))
    assert solved.accuracy.refinement is None and "refinement" not in doc
    ref = reprojection_errors(*corners, solved.result)
    assert set(doc["reprojection"]) == set(ref) == {"y0", "y1"}
    for cam, r in ref.items():
        assert doc["reprojection"][cam] == pytest.approx(r.to_dict())
        # exact data: the calibrated chain reproduces the corners (solver tolerance ~1e-9 m)
        assert doc["reprojection"][cam]["rms_px"] < 1e-3
    text = summary(solved.result, solved.problem, {}, _naming(problem), solved.verdict,
                   solved.accuracy)
    assert "reprojection error of the detected corners through the calibration (RMS): y0 " in text
    assert "reprojection y0" in dict(solved.accuracy.diagnostic_values())
