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
from rwhec_ros.report.accuracy import accuracy_sections, summary_text_lines
from rwhec_ros.report.refinement import REFINEMENT_HEADING
from rwhec_ros.report.words import certificate_words
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
        assert frame["pose_level"]["std_kind"].startswith("predicted from the noise of the weights")
        assert frame["translation"] == pytest.approx(f["refined"]["translation"])
    for cam in ds.y_names:
        c = r["cameras"][cam]
        assert c["rms_px_refined"] < c["rms_px_certified"]
        assert doc["reprojection"][cam]["rms_px"] == pytest.approx(c["rms_px_certified"])
        assert doc["reprojection"][cam]["rms_px_refined"] == pytest.approx(c["rms_px_refined"])
    # the cross-validation scored the pose-level fit on the same held-out corners: the views'
    # A found their pairs in every fold, and the refinement predicts them better
    held = r["held_out_rms_px"]
    assert set(held) == {"pose_noise", "plain", "certified"}, rec.refinement.notes
    assert held[r["model"]] <= held["certified"]
    assert not any("pose-level" in n for n in rec.refinement.notes)


def test_the_pose_level_fit_of_a_fold_leaves_out_its_pose_samples_only():
    """``pose_level_fit`` solves the pairs of every other pose sample; None when a held-out
    ``A`` matches no pair (it would score data it was fitted to) or a frame loses every pair."""
    from rwhec_ros.core.problem import Edge, Problem
    from rwhec_ros.core.solve import SolveOptions, solve
    from rwhec_ros.session.refinement import pose_level_fit

    ds, truth = _scene(n=20)
    problem = ds.to_problem(min_pairs=3)
    fit = pose_level_fit(problem, SolveOptions(mode="fast", fallback_to_sdp=False))
    all_A = np.concatenate([e.A for e in problem.edges])
    held = np.unique(all_A, axis=0)[:3]
    X, Y, alpha = fit(held)
    keys = {A.tobytes() for A in held}
    masks = [np.array([A.tobytes() not in keys for A in e.A]) for e in problem.edges]
    assert 0 < sum((~m).sum() for m in masks) < len(all_A)
    sub = Problem(problem.x_names, problem.y_names,
                  [Edge.build(e.x, e.y, e.A[m], e.B[m], e.sigma[m], e.kappa[m])
                   for e, m in zip(problem.edges, masks, strict=True) if m.any()])
    ref = solve(sub, SolveOptions(mode="fast", fallback_to_sdp=False))
    assert np.allclose(X, ref.X, atol=1e-9) and np.allclose(Y, ref.Y, atol=1e-9)
    assert alpha == pytest.approx(1.0)
    # an A of no pair, or every A held out: no estimate
    assert fit(held + 1e-3) is None
    assert fit(np.unique(all_A, axis=0)) is None


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


def test_the_verdict_s_precision_holds_for_the_published_frames(refined):
    """The first line's and each frame line's ``+-`` are the verdict's precision: with the
    refinement published they are never below the refined frames' own std in the worst
    direction (in this scene the refined tags' rotation std exceeds the certified one's)."""
    from rwhec_ros.session.refinement import published_uncertainty

    _, solved, _ = refined
    rec = solved.accuracy.refinement
    assert rec.published
    widened = 0
    for name, fv in solved.verdict.frames.items():
        C = np.asarray(rec.refinement.frame_covariance(name))
        t = float(np.sqrt(np.linalg.eigvalsh(C[:3, :3])[-1]))
        r = float(np.degrees(np.sqrt(np.linalg.eigvalsh(C[3:, 3:])[-1])))
        assert fv.std_translation_m >= t * (1 - 1e-9), name
        assert fv.std_rotation_deg >= r * (1 - 1e-9), name
        cert_t, cert_r = solved.accuracy.uncertainty.frame(name).worst_std()
        widened += r > cert_r or t > cert_t
    assert widened  # the scene needs the widening, else this test shows nothing
    # never narrowed: a block whose refined std is smaller keeps the certified one
    same = published_uncertainty(solved.accuracy.uncertainty, rec)
    for f, g in zip(solved.accuracy.uncertainty.frames, same.frames, strict=True):
        assert np.all(np.array(g.worst_std()) >= np.array(f.worst_std()) * (1 - 1e-12))
    assert published_uncertainty(solved.accuracy.uncertainty, None) is \
        solved.accuracy.uncertainty


def test_the_launch_file_s_comment_says_the_frames_are_not_certified(refined):
    """The launch file, URDF and frames YAML carry the verdict and the certificate as a
    comment: with the refinement published it says the frames are not the certified ones, and
    each reason is written once."""
    from rwhec_ros.session.outputs import launch_header

    _, solved, _ = refined
    header = launch_header(solved.result, solved.verdict, {}, "created now")
    assert ("certified: True, suboptimality bound" in header and "these frames are its "
            "corner-level refinement, a local estimate, not certified" in header), header
    assert "more reason" not in header
    plain = launch_header(solved.accuracy.refinement.certified, solved.verdict, {}, "now")
    assert "refinement" not in plain


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


def test_result_top_says_what_is_published_and_what_the_certificate_covers(refined):
    """``estimate_published`` and ``certificate_scope`` follow the certificate's keys at the
    top of result.yaml; without a refinement they are absent."""
    ds, solved, doc = refined
    keys = list(doc)
    i = keys.index("suboptimality_bound")
    assert keys[i + 1:i + 3] == ["estimate_published", "certificate_scope"]
    assert doc["certified"] is True and doc["estimate_published"] == "refined"
    assert doc["certificate_scope"] == SCOPE
    _, doc_off = _solve(ds, refine=False)
    assert "estimate_published" not in doc_off and "certificate_scope" not in doc_off
    obs, intr = corner_data(ds)
    kept = solve_and_assess(ds.to_problem(min_pairs=3), corners=(obs, {"cam0": intr["cam0"]}),
                            accuracy=AccuracyOptions(folds=0, guidance=False))
    fields = kept.accuracy.certificate_fields()
    assert fields["estimate_published"] == "certified"
    assert fields["certificate_scope"].startswith(
        "the published frames are the pose-level estimate (certified global optimum); the "
        "corner-level refinement is not published: the refinement failed (no corners of ")


def test_report_says_what_is_certified_and_shows_both_rms(refined):
    ds, solved, doc = refined
    words = certificate_words(doc)
    assert words.startswith("certified globally optimal")
    assert words.endswith("it covers the pose-level optimum: the published frames are its "
                          "corner-level refinement (a local estimate, not certified)")
    _, doc_off = _solve(ds, refine=False)
    assert "refinement" not in certificate_words(doc_off)
    assert all(h != REFINEMENT_HEADING for h, *_ in accuracy_sections(doc_off))
    (_, text, _, rows), = [s for s in accuracy_sections(doc) if s[0] == REFINEMENT_HEADING]
    assert text.startswith("Published: the refined estimate (") and SCOPE in text
    cams = doc["refinement"]["cameras"]
    assert [r[0] for r in rows] == list(ds.y_names)
    for cam, n, rms_c, rms_r, _sigma in rows:
        c = cams[cam]
        assert (n, rms_c, rms_r) == (c["n_corners"], f"{c['rms_px_certified']:.2f}",
                                     f"{c['rms_px_refined']:.2f}")
    lines = " ".join(summary_text_lines(doc, width=200)).replace("\u00a0", " ")
    assert "corner-level refinement: the refined estimate published" in lines
    c0 = cams["cam0"]
    assert f"cam0 {c0['rms_px_certified']:.2f} -> {c0['rms_px_refined']:.2f} px" in lines


def test_cli_no_refine(tmp_path, refined):
    ds = refined[0]
    ds.save(tmp_path / "data.yaml")
    docs = {}
    for flag in (["--report"], ["--no-refine"]):
        out = tmp_path / flag[0].strip("-")
        code = main(["dataset", str(tmp_path / "data.yaml"), "-o", str(out), "-q", "--folds",
                     "0", "--no-guidance", *flag], stdout=io.StringIO(), stderr=io.StringIO())
        assert code in (0, 1), code
        docs[flag[0]] = yaml.safe_load((out / "result.yaml").read_text())
    assert docs["--report"]["refinement"]["published"] in ("refined", "certified")
    assert "refinement" not in docs["--no-refine"]
    assert docs["--no-refine"]["config"]["solver.refine"] is False
    assert docs["--report"]["config"]["solver.refine"] is True
    page = (tmp_path / "report" / "report.html").read_text()
    assert f"<h2>{REFINEMENT_HEADING}</h2>" in page
    assert docs["--report"]["certificate_scope"] in page


def test_the_refinement_gets_the_corners_of_the_pairs_solved_only():
    """session.solving._kept_corners: the corners of an edge dropped (excluded, wholly
    rejected) and of the pairs the outlier rejection left out do not reach the refinement and
    the reprojection figures (a flipped tag's views rendered flipped have the flipped pose's
    corners: with them, --robust published cameras 3-5 std off)."""
    from rwhec_ros.core.problem import Edge, Problem
    from rwhec_ros.session.solving import _kept_corners
    from rwhec_ros.vision.reprojection import CornerObservation

    rng = np.random.default_rng(0)
    A = np.array([make_transform(so3_exp(rng.normal(size=3)), rng.normal(size=3))
                  for _ in range(5)])
    B = np.array([make_transform(so3_exp(rng.normal(size=3)), rng.normal(size=3))
                  for _ in range(5)])
    problem = Problem(["t0", "t1"], ["c0"], [Edge.build("t0", "c0", A, B, sigma=0.01, kappa=1e3),
                                             Edge.build("t1", "c0", A, B, sigma=0.01, kappa=1e3)])
    px = np.zeros((4, 2))
    obs = [CornerObservation(x, "c0", a + 1e-12, px, 0.1) for x in ("t0", "t1") for a in A]
    corners = (obs, {})
    assert _kept_corners(corners, problem, {}, {}) is corners
    kept, _ = _kept_corners(corners, problem, {}, {"(t0, c0)": [1, 3]})
    assert [(o.x, i) for o in kept for i, a in enumerate(A) if np.allclose(o.A, a)] == [
        ("t0", 0), ("t0", 2), ("t0", 4), ("t1", 0), ("t1", 1), ("t1", 2), ("t1", 3), ("t1", 4)]
    kept, _ = _kept_corners(corners, problem, {"(t1, c0)": "excluded"}, {"(t0, c0)": [0]})
    assert len(kept) == 4 and all(o.x == "t0" for o in kept)
