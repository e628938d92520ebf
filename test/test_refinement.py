"""The corner-level refinement in the solve step (session.refinement): what is published, what
result.yaml, the summary and the CLI say, and that data without corners keep today's path.

The refinement's numbers are checked in test/core/test_refine.py and benchmarks/refinement.md;
these tests check the wiring, on a small data set whose pairs keep their tags' corners: a
moving rig of two cameras among tags, the pose stream with a rig error per sample, the corners
projected through the true chain with pixel noise, ``B`` the true pose with pose-level noise.
"""

from __future__ import annotations

import io

import numpy as np
import pytest
import yaml

from rwhec_ros.cli import main
from rwhec_ros.core.lie import invert_transform, make_transform, so3_exp
from rwhec_ros.core.refine import SCOPE
from rwhec_ros.data.corners import corner_data
from rwhec_ros.data.dataset import Dataset, DatasetEdge
from rwhec_ros.data.results import FrameNaming, result_document
from rwhec_ros.session import summary
from rwhec_ros.session.accuracy import AccuracyOptions
from rwhec_ros.session.solving import solve_and_assess
from rwhec_ros.vision.detection import tag_object_points
from rwhec_ros.vision.intrinsics import CameraIntrinsics

SIZE = 0.2


def _dataset(seed: int = 0, n: int = 40, with_corners: bool = True) -> Dataset:
    return _scene(seed, n, with_corners)[0]


def _scene(seed: int = 0, n: int = 40, with_corners: bool = True):
    """``(data set, true frames by name)``."""
    rng = np.random.default_rng(seed)
    intr = {"cam0": CameraIntrinsics.pinhole(640, 480, 500.0),
            "cam1": CameraIntrinsics.pinhole(800, 600, 600.0)}
    base = np.array([[0, 0, 1], [-1, 0, 0], [0, -1, 0.0]])  # optical z along the rig's x
    Y = {"cam0": make_transform(base, [0.1, 0, 0]),
         "cam1": make_transform(so3_exp(np.array([0, 0, np.pi])) @ base, [-0.1, 0, 0])}
    X = {}
    for j, ang in enumerate((-0.25, 0.25, np.pi)):
        pos = 1.5 * np.array([np.cos(ang), np.sin(ang), 0.1 * j])
        z = -pos / np.linalg.norm(pos)
        y = np.array([0.0, 0.0, -1.0]) + z[2] * z  # minus its component along z
        y /= np.linalg.norm(y)
        X[f"tag_{j}"] = make_transform(np.c_[np.cross(y, z), y, z], pos)
    edges = {}
    for i in range(n):
        A = invert_transform(make_transform(so3_exp(rng.normal(0, 0.15, 3)),
                                            rng.normal(0, 0.1, 3)))
        E = make_transform(so3_exp(rng.normal(0, 1e-3, 3)), rng.normal(0, 1e-3, 3))
        for cam, Yk in Y.items():
            for tag, Xj in X.items():
                T = invert_transform(Yk) @ E @ A @ Xj
                P = tag_object_points(SIZE) @ T[:3, :3].T + T[:3, 3]
                if np.any(P[:, 2] < 0.3) or T[2, 2] > -0.3:
                    continue
                uv = intr[cam].project_points(P)
                if np.any(uv < 5) or np.any(uv > [intr[cam].width - 5, intr[cam].height - 5]):
                    continue
                B = make_transform(so3_exp(rng.normal(0, 2e-3, 3)) @ T[:3, :3],
                                   T[:3, 3] + rng.normal(0, 2e-3, 3))
                edges.setdefault((tag, cam), []).append(
                    (1_000_000_000 + i, A, B, uv + rng.normal(0, 0.1, uv.shape)))
    out = []
    for (tag, cam), pairs in sorted(edges.items()):
        s, A, B, c = (np.array(v) for v in zip(*pairs, strict=True))
        out.append(DatasetEdge(tag, cam, s, A, B, np.full(len(s), 3e-3), np.full(len(s), 2e4),
                               corners_px=c if with_corners else None))
    return Dataset(tuple(X), tuple(Y), out, intrinsics=intr if with_corners else {},
                   tag_sizes_m={t: SIZE for t in X} if with_corners else {}), {**X, **Y}


def _naming(ds):
    return FrameNaming.from_carriers(ds.x_names, ds.y_names, camera_carrier="rig",
                                     tag_carrier="world")


def _solve(ds, **kw):
    solved = solve_and_assess(ds.to_problem(min_pairs=3), corners=corner_data(ds),
                              accuracy=AccuracyOptions(folds=0, guidance=False), **kw)
    doc = result_document(solved.result, _naming(ds), verdict=solved.verdict,
                          accuracy=solved.accuracy)
    return solved, yaml.safe_load(yaml.safe_dump(doc, sort_keys=False))


@pytest.fixture(scope="module")
def refined():
    ds = _dataset()
    return ds, *_solve(ds)


def test_the_refined_estimate_is_published_with_both_in_the_result(refined):
    ds, solved, doc = refined
    rec = solved.accuracy.refinement
    assert rec.published, rec.reason
    cert = rec.certified
    # the published result holds the refined frames, the certificate stays the pose-level one
    assert np.array_equal(solved.result.X, rec.refinement.X)
    assert np.array_equal(solved.result.Y, rec.refinement.Y)
    assert solved.result.certificate is cert.certificate and cert.certified
    assert not np.allclose(cert.X, solved.result.X, atol=1e-9)
    assert any(SCOPE in n for n in solved.result.notes)
    r = doc["refinement"]
    assert r["published"] == "refined" and r["certificate_scope"] == SCOPE
    assert "lowers the corner residual" in r["reason"]
    for name in ds.x_names + ds.y_names:
        f = r["frames"][name]
        assert f["certified"]["translation"] == pytest.approx(
            list(cert.transform(name)[:3, 3]), abs=1e-12)
        assert f["refined"]["translation"] == pytest.approx(
            list(solved.result.transform(name)[:3, 3]), abs=1e-12)
        assert len(f["refined"]["std_translation_m"]) == 3
        frame = next(x for x in doc["frames"] if x["name"] == name)
        # the published frame's uncertainty is the refinement's, the certified one's beside it
        assert frame["std_kind"].startswith("corner-level model")
        assert frame["std_translation_m"] == pytest.approx(f["refined"]["std_translation_m"])
        assert frame["pose_level"]["std_kind"].startswith("predicted from the stated noise")
        assert frame["translation"] == pytest.approx(f["refined"]["translation"])
    for cam in ds.y_names:
        c = r["cameras"][cam]
        assert c["rms_px_refined"] < c["rms_px_certified"]
        assert doc["reprojection"][cam]["rms_px"] == pytest.approx(c["rms_px_certified"])
        assert doc["reprojection"][cam]["rms_px_refined"] == pytest.approx(c["rms_px_refined"])


def test_the_truth_is_nearer_after_the_refinement(refined):
    """The pose-level noise (2 mm, 2 mrad) is larger than what the corners (0.1 px) and the
    rig's pose error (1 mm, 1 mrad) leave: the refined frames are closer to the truth."""
    ds, solved, _ = refined
    truth = _scene()[1]
    cert = solved.accuracy.refinement.certified
    err = {"c": [], "r": []}
    for name, T in truth.items():
        err["c"].append(np.linalg.norm(cert.transform(name)[:3, 3] - T[:3, 3]))
        err["r"].append(np.linalg.norm(solved.result.transform(name)[:3, 3] - T[:3, 3]))
    assert np.mean(err["r"]) < np.mean(err["c"]), err


def test_summary_says_what_is_published_and_what_is_certified(refined):
    ds, solved, _ = refined
    text = summary(solved.result, solved.problem, {}, _naming(ds), solved.verdict,
                   solved.accuracy)
    assert "CERTIFIED globally optimal" in text
    assert "the pose-level optimum; the frames below are its corner-level refinement" in text
    assert "the refined estimate published" in text
    r = solved.accuracy.refinement.refinement
    assert ("corner reprojection RMS per camera, certified -> refined: cam0 "
            f"{r.rms_start_px['cam0']:.2f} -> {r.rms_px['cam0']:.2f} px") in text


def test_refine_false_and_data_without_corners_keep_todays_path(refined):
    ds, solved, doc = refined
    off, doc_off = _solve(ds, refine=False)
    assert off.accuracy.refinement is None and "refinement" not in doc_off
    assert np.array_equal(off.result.X, solved.accuracy.refinement.certified.X)
    bare = _dataset(with_corners=False)
    assert corner_data(bare) is None
    plain, doc_plain = _solve(bare)
    assert plain.accuracy.refinement is None and "refinement" not in doc_plain
    assert np.array_equal(plain.result.X, off.result.X)


def test_a_refinement_that_cannot_run_says_why(refined):
    ds, _, _ = refined
    obs, intr = corner_data(ds)
    # no corners of cam1 (its intrinsics missing): the refinement refuses, the certified is kept
    solved = solve_and_assess(ds.to_problem(min_pairs=3), corners=(obs, {"cam0": intr["cam0"]}),
                              accuracy=AccuracyOptions(folds=0, guidance=False))
    rec = solved.accuracy.refinement
    assert not rec.published and rec.skipped.startswith("the refinement failed (no corners of ")
    assert "cam1" in rec.skipped
    assert rec.to_dict()["published"] == "certified"
    assert np.array_equal(solved.result.X, rec.certified.X)


def test_cli_no_refine(tmp_path, refined):
    ds = refined[0]
    ds.save(tmp_path / "data.yaml")
    docs = {}
    for flag in ([], ["--no-refine"]):
        out = tmp_path / f"out{len(flag)}"
        code = main(["dataset", str(tmp_path / "data.yaml"), "-o", str(out), "-q", "--folds",
                     "0", "--no-guidance", *flag], stdout=io.StringIO(), stderr=io.StringIO())
        assert code in (0, 1), code
        docs[bool(flag)] = yaml.safe_load((out / "result.yaml").read_text())
    assert docs[False]["refinement"]["published"] in ("refined", "certified")
    assert "refinement" not in docs[True]
