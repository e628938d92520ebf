"""The calibration report: residuals of A X = Y B, and the PNG + HTML files."""

from __future__ import annotations

import numpy as np
import pytest

from rwhec_ros.core.lie import make_transform, so3_exp
from rwhec_ros.core.solve import solve
from rwhec_ros.data.results import FrameNaming, result_document
from rwhec_ros.report import edge_residuals, estimates_from_document, write_report
from rwhec_ros.simulation.synthetic import random_instance


def test_residuals_vanish_at_the_truth_of_exact_data_also_with_a_scale():
    rng = np.random.default_rng(0)
    problem, gt = random_instance(rng, 2, 3, n_per_edge=5, unknown_scale=True, alpha=1.3)
    res = edge_residuals(problem, gt.X, gt.Y, gt.alpha)
    assert [(r.x, r.y) for r in res] == [(e.x, e.y) for e in problem.edges]
    assert all(r.n == 5 for r in res)
    # exact data: rounding only
    assert max(r.translation_m.max() for r in res) < 1e-9
    assert max(r.rotation_rad.max() for r in res) < 1e-7  # arccos near 1 loses half the digits
    # ignoring the scale leaves the (alpha - 1) part of the B translations as residual
    assert max(r.translation_m.max() for r in edge_residuals(problem, gt.X, gt.Y, 1.0)) > 1e-2


def test_residuals_measure_a_known_perturbation():
    rng = np.random.default_rng(1)
    problem, gt = random_instance(rng, 2, 2, n_per_edge=4)
    d = np.array([0.003, -0.004, 0.0])  # 5 mm
    Y = gt.Y.copy()
    Y[0, :3, 3] += d
    X = gt.X.copy()
    X[1] = X[1] @ make_transform(so3_exp(np.array([0.0, 0.01, 0.0])), np.zeros(3))
    for r in edge_residuals(problem, X, Y):
        # a shifted t_Y moves every pair's Y B translation by d; X_1's rotation error is 0.01 rad
        # but leaves t(A X) unchanged (the perturbation is about X_1's own origin)
        t_expected = 0.005 if r.y == "y0" else 0.0
        r_expected = 0.01 if r.x == "x1" else 0.0
        assert np.allclose(r.translation_m, t_expected, atol=1e-9)  # rounding only
        assert np.allclose(r.rotation_rad, r_expected, atol=1e-7)  # arccos rounding


def test_bad_shapes_and_scale_are_rejected():
    problem, gt = random_instance(np.random.default_rng(2), 1, 1, n_per_edge=3)
    with pytest.raises(ValueError, match="X, Y: expected shapes"):
        edge_residuals(problem, gt.X[:0], gt.Y)
    with pytest.raises(ValueError, match="scale: must be finite and > 0"):
        edge_residuals(problem, gt.X, gt.Y, 0.0)


def test_report_png_and_html(tmp_path):
    from matplotlib.image import imread

    rng = np.random.default_rng(3)
    problem, gt = random_instance(rng, 3, 2, n_per_edge=8, sigma=0.01, kappa=400.0)
    result = solve(problem)
    naming = FrameNaming.from_carriers(problem.x_names, problem.y_names,
                                       camera_carrier="rig", tag_carrier="world")
    doc = result_document(result, naming, excluded={"(x9, y9)": "2 pairs < min_pairs=3"})
    X, Y, scale = estimates_from_document(doc, problem)
    assert np.array_equal(X, result.X) and np.array_equal(Y, result.Y) and scale == 1.0
    files = write_report(doc, problem, tmp_path / "r.png", tmp_path / "r.html", title="test")
    img = imread(str(files.png))
    assert img.shape[1] == 1440  # 18 inches at 80 dpi; the height follows the content
    assert img[..., :3].std() > 0.05  # something is drawn
    # no verdict in this document: a grey banner says so (the first rows of the image)
    page = files.html.read_text()
    assert "VERDICT UNKNOWN" in page
    # self-contained: the figure is embedded, no link to a file beside the page
    assert "<img src='data:image/png;base64," in page and "r.png" not in page
    for e in problem.edges:  # one residual row per edge, and the excluded edge with its reason
        assert f"<td>{e.x}</td><td>{e.y}</td><td>{e.n}</td>" in page
    assert "2 pairs &lt; min_pairs=3" in page
    assert "rig -&gt; y0_calibrated" in page
    assert "True" not in page and "None" not in page  # words, not Python values


def test_report_of_a_verdict_shows_the_banner_and_natural_order(tmp_path):
    from rwhec_ros.core.verdict import assess

    rng = np.random.default_rng(6)
    problem, _ = random_instance(rng, 12, 2, n_per_edge=8, sigma=0.01, kappa=400.0)
    names = {f"x{j}": f"tag_{j}" for j in range(12)}  # tag_2 must come before tag_11
    from rwhec_ros.core.problem import Edge, Problem

    problem = Problem([names[n] for n in problem.x_names], problem.y_names,
                      [Edge.build(names[e.x], e.y, e.A, e.B, sigma=e.sigma, kappa=e.kappa)
                       for e in problem.edges])
    result = solve(problem)
    verdict = assess(result, problem, expected_y=["y0", "y1", "cam9"])
    naming = FrameNaming.from_carriers(problem.x_names, (*problem.y_names, "cam9"),
                                       camera_carrier="rig", tag_carrier="world")
    doc = result_document(result, naming, verdict=verdict)
    files = write_report(doc, problem, tmp_path / "r.png", tmp_path / "r.html")
    page = files.html.read_text()
    assert "UNUSABLE: do not use this calibration" in page
    assert "cam9: not calibrated" in page
    rows = [line for line in page.split("<tr>") if line.startswith("<td>tag_")]
    order = [r.split("</td>")[0][4:] for r in rows if "<td>y0</td>" in r]
    assert order == [f"tag_{j}" for j in range(12)]  # natural order in the edge table


def test_document_without_a_frame_of_the_data_is_rejected():
    problem, gt = random_instance(np.random.default_rng(4), 2, 1, n_per_edge=3)
    result = solve(problem)
    naming = FrameNaming.from_carriers(problem.x_names, problem.y_names,
                                       camera_carrier="rig", tag_carrier="world")
    doc = result_document(result, naming)
    doc["frames"] = [f for f in doc["frames"] if f["name"] != "x1"]
    with pytest.raises(ValueError, match=r"no estimate for \['x1'\]"):
        estimates_from_document(doc, problem)


def test_report_shows_the_accuracy_and_grows_by_its_rows(tmp_path):
    from matplotlib.image import imread

    from rwhec_ros.session.accuracy import AccuracyOptions
    from rwhec_ros.session.solving import solve_and_assess

    problem, _ = random_instance(np.random.default_rng(3), 3, 2, n_per_edge=12, sigma=0.01,
                                 kappa=400.0)
    solved = solve_and_assess(problem, accuracy=AccuracyOptions(folds=3))
    naming = FrameNaming.from_carriers(problem.x_names, problem.y_names,
                                       camera_carrier="rig", tag_carrier="world")
    plain_doc = result_document(solved.result, naming, verdict=solved.verdict)
    doc = result_document(solved.result, naming, verdict=solved.verdict,
                          accuracy=solved.accuracy)
    without = write_report(plain_doc, problem, tmp_path / "a.png", tmp_path / "a.html")
    files = write_report(doc, problem, tmp_path / "r.png", tmp_path / "r.html")
    # two more rows (std bars; cross-validation) of at least 3 inches each at 80 dpi
    assert imread(str(files.png)).shape[0] >= imread(str(without.png)).shape[0] + 2 * 3 * 80
    page = files.html.read_text()
    assert "<h2>Uncertainty per frame</h2>" in page
    assert "<h2>Cross-validation (3 folds)</h2>" in page
    assert "<h2>Next motion</h2>" in page
    assert solved.accuracy.guidance.message.split(" (")[0] in page
    best = solved.accuracy.guidance.best
    assert best is not None and ("rotate about " if best.kind == "rotate" else
                                 "translate along ") + "xyz"[best.axis] + " by +-" in page
    # the stds as numbers in the table: the first camera's predicted translation std in mm
    fu = solved.accuracy.uncertainty.frame("y0")
    assert " / ".join(f"{1e3 * v:.2f}" for v in fu.std_translation_m) + " mm" in page
    assert "Uncertainty per frame" not in without.html.read_text()  # older results: no section
    text = page.split("base64,")[0] + page.split("base64,")[1].split("'", 1)[1]  # no figure
    assert "None" not in text and "nan" not in text  # words, not Python values


@pytest.fixture(scope="module")
def assessed():
    """A solved, verdicted and assessed synthetic problem (no corners) and its report files
    (one solve and one report for the tests below: they are the slow part)."""
    import tempfile
    from pathlib import Path

    from rwhec_ros.session.accuracy import AccuracyOptions
    from rwhec_ros.session.solving import solve_and_assess

    problem, _ = random_instance(np.random.default_rng(3), 3, 2, n_per_edge=12, sigma=0.01,
                                 kappa=400.0)
    solved = solve_and_assess(problem, accuracy=AccuracyOptions(folds=3))
    naming = FrameNaming.from_carriers(problem.x_names, problem.y_names,
                                       camera_carrier="rig", tag_carrier="world")
    doc = result_document(solved.result, naming, verdict=solved.verdict,
                          accuracy=solved.accuracy)
    with tempfile.TemporaryDirectory() as tmp:
        files = write_report(doc, problem, Path(tmp) / "r.png", Path(tmp) / "r.html")
        yield problem, doc, files


def _images(page: str) -> dict[str, bytes]:
    """The page's embedded PNGs by their alt text."""
    import base64
    import re

    return {alt: base64.b64decode(data) for data, alt in
            re.findall(r"<img src='data:image/png;base64,([^']*)' alt='([^']*)'>", page)}


def test_report_has_per_edge_residual_boxes_and_no_reprojection_without_corners(assessed):
    from io import BytesIO

    from matplotlib.image import imread

    problem, doc, files = assessed
    assert doc.get("reprojection") is None  # synthetic pairs: no corners, no intrinsics
    page = files.html.read_text()
    images = _images(page)
    assert "residuals per edge, the worst edges first" in images  # in its section
    edges_at = page.index("<h2>Residuals of A X = Y B per edge</h2>")
    assert edges_at < page.index("alt='residuals per edge, the worst edges first'")
    assert page.index("alt='residuals per edge") < page.index("<h2>Uncertainty per frame</h2>")
    img = imread(BytesIO(images["residuals per edge, the worst edges first"]))
    assert img.shape[1] == 1440 and img[..., :3].std() > 0.05
    # no corners: neither a reprojection section nor its chart
    assert "Reprojection error per camera" not in page
    assert "reprojection error per camera" not in images


def test_report_has_the_reprojection_chart_with_corners(assessed, tmp_path):
    import copy

    from matplotlib.image import imread

    problem, plain, without = assessed
    doc = copy.deepcopy(plain)
    # the reprojection mapping as the accuracy step writes it (rwhec_ros.session.accuracy)
    doc["reprojection"] = {cam: {"camera": cam, "n_pairs": 20 + k, "rms_px": 0.4 + 0.3 * k,
                                 "median_px": 0.3 + 0.2 * k, "max_px": 2.0, "n_behind": 0}
                           for k, cam in enumerate(problem.y_names)}
    doc.setdefault("config", {})["detection.max_reprojection_rms_px"] = 1.0
    files = write_report(doc, problem, tmp_path / "r.png", tmp_path / "r.html")
    page = files.html.read_text()
    images = _images(page)
    assert "reprojection error per camera" in images
    heading = page.index("<h2>Reprojection error per camera</h2>")
    assert heading < page.index("alt='reprojection error per camera'") < page.index(
        "<h2>Next motion</h2>")
    assert "<td>y1</td><td>21</td><td>0.70</td>" in page  # the table stays
    # the stand-alone PNG grows by the chart's row (at least 2.2 inches at 80 dpi)
    assert imread(str(files.png)).shape[0] >= imread(str(without.png)).shape[0] + 2.2 * 80


def test_reprojection_bars_are_the_rms_per_camera_with_the_detection_limit():
    from matplotlib.figure import Figure

    from rwhec_ros.report.edges import draw_reprojection

    doc = {"reprojection": {"cam10": {"rms_px": 0.9, "median_px": 0.5, "n_pairs": 3},
                            "cam2": {"rms_px": 0.25, "median_px": 0.2, "n_pairs": 40,
                                     "n_behind": 2}},
           "config": {"detection.max_reprojection_rms_px": 1.5}}
    ax = Figure().add_subplot()
    draw_reprojection(ax, doc)
    assert [t.get_text() for t in ax.get_yticklabels()] == ["cam2", "cam10"]  # natural order
    widths = [p.get_width() for p in ax.patches]
    assert widths == [0.25, 0.9]
    assert ax.get_xlim()[1] >= 1.5  # the per-detection limit is on the chart
    texts = [t.get_text() for t in ax.texts]
    assert "0.25 px (40 pairs), 2 behind the camera" in texts and "0.90 px (3 pairs)" in texts
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert any("per-detection limit 1.5 px" in t for t in legend)


def test_edge_boxes_show_the_worst_edges_of_many_in_rank_order():
    from matplotlib.figure import Figure

    from rwhec_ros.report import edge_residuals, fit_of_document
    from rwhec_ros.report.edges import EDGE_ROWS, draw_edge_boxes, ranked_edges

    # 6 tags x 5 cameras = 30 edges: more than EDGE_ROWS, so only the worst are drawn
    problem, gt = random_instance(np.random.default_rng(8), 6, 5, n_per_edge=6, sigma=0.01,
                                  kappa=400.0)
    result = solve(problem)
    naming = FrameNaming.from_carriers(problem.x_names, problem.y_names,
                                       camera_carrier="rig", tag_carrier="world")
    doc = result_document(result, naming)
    residuals = edge_residuals(problem, result.X, result.Y, result.scale)
    fit = fit_of_document(doc, problem)
    shown = ranked_edges(residuals, fit)
    assert len(residuals) == 30 and len(shown) == EDGE_ROWS
    ratio = {(e.x, e.y): e.ratio for e in fit.edges}
    ranks = [ratio[(r.x, r.y)] for r in shown]
    assert ranks == sorted(ranks, reverse=True)  # worst first
    left_out = [ratio[(r.x, r.y)] for r in residuals if r not in shown]
    assert max(left_out) <= min(ranks)  # none left out is worse than one shown
    ax = Figure().add_subplot()
    boxes = draw_edge_boxes(ax, residuals, fit, "translation")
    labels = [t.get_text() for t in ax.get_yticklabels()]
    assert labels == [f"{r.x} / {r.y} ({r.n})" for r in shown] + ["all 180 pairs"]
    assert f"the {EDGE_ROWS} worst of 30 edges" in ax.get_title()
    # the boxes are of the residuals in mm: the pooled median is the median of all pairs
    pooled = 1e3 * np.concatenate([r.translation_m for r in residuals])
    assert boxes["medians"][-1].get_xdata()[0] == pytest.approx(np.median(pooled))
    worst = 1e3 * shown[0].translation_m
    assert boxes["medians"][0].get_xdata()[0] == pytest.approx(np.median(worst))


def test_cross_validation_labels_never_overlap():
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from rwhec_ros.report.accuracy import draw_validation

    # a crowded corner: eight edges within 2 % of each other, all named (held out at 1.6x)
    rng = np.random.default_rng(2)
    edges = [{"x": f"tag_{j}", "y": f"cam_{j % 3}", "n_pairs": 10,
              "in_sample": {"rms_translation_mm": v, "rms_rotation_deg": v},
              "held_out": {"rms_translation_mm": 1.6 * v, "rms_rotation_deg": 1.6 * v}}
             for j, v in enumerate(4.0 + 0.08 * rng.random(8))]
    edges += [{"x": "tag_20", "y": "cam_0", "n_pairs": 10,
               "in_sample": {"rms_translation_mm": 1.0, "rms_rotation_deg": 1.0},
               "held_out": {"rms_translation_mm": 1.0, "rms_rotation_deg": 1.0}}]
    doc = {"cross_validation": {"folds": 5, "edges": edges, "held_out": {}, "in_sample": {}}}
    fig = Figure(figsize=(9, 5))
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    draw_validation(ax, doc, "translation")
    canvas.draw()
    renderer = canvas.get_renderer()
    from matplotlib.text import Text

    boxes = [Text.get_window_extent(t, renderer) for t in ax.texts]  # the text, not its line
    assert len(boxes) == 8  # 4 largest held-out + up to 4 more held out at > 1.5x
    for i, a in enumerate(boxes):
        for b in boxes[i + 1:]:
            assert not a.overlaps(b), (a, b)
    frame = ax.get_window_extent(renderer)
    assert all(frame.x0 <= b.x0 and b.x1 <= frame.x1 + 1 for b in boxes)  # inside the axes


def test_row_cuts_fall_in_the_blank_space_between_rows():
    from rwhec_ros.report.images import row_cuts

    # 100 rows, white; rows 10-29 and 60-89 drawn (the axes 12-27 and 62-87, their titles and
    # labels reaching 2 rows further); a drawn line across the space at row 40
    img = np.full((100, 8, 4), 255, dtype=np.uint8)
    img[10:30, 2:6] = 0
    img[60:90, 1:7] = 0
    img[40] = 0
    cells = [(1 - 12 / 100, 1 - 28 / 100), (1 - 62 / 100, 1 - 88 / 100)]  # (top, bottom)
    cuts = row_cuts(img, cells)
    # the middle of the longer blank run between the rows (41-59, not 30-39)
    assert cuts == [0, 50, 100]
    # nothing blank between the axes: the middle of the space
    img[28:62] = 0
    assert row_cuts(img, cells) == [0, 45, 100]


def test_one_draw_gives_the_png_the_page_figure_and_the_sections(assessed):
    from rwhec_ros.report import edge_residuals, fit_of_document
    from rwhec_ros.report.figure import BANNER_COLORS
    from rwhec_ros.report.images import render_report

    problem, doc, _ = assessed
    X, Y, scale = estimates_from_document(doc, problem)
    images = render_report(doc, problem, edge_residuals(problem, X, Y, scale),
                           fit_of_document(doc, problem), None, "t", 80)
    assert set(images.sections) == {"edges"}  # no corners: no reprojection section
    pictures = [images.png, images.page, images.sections["edges"]]
    assert all(p.shape[1] == 1440 and p.shape[2] == 4 for p in pictures)  # 18 inches at 80 dpi
    # the page's figure and the section are parts of the PNG: together not taller than it
    assert images.page.shape[0] + images.sections["edges"].shape[0] < images.png.shape[0]
    # the banner (its background colour) is in the PNG only; the page gives it as text
    bg = np.array([int(BANNER_COLORS[doc["verdict"]][1][i:i + 2], 16) for i in (1, 3, 5)])
    has_banner = [bool(np.all(p[..., :3] == bg, axis=-1).sum() > 1440 * 20) for p in pictures]
    assert has_banner == [True, False, False]
    # the page's rows are the PNG's, pixel for pixel (cut from the same draw): its last row (the
    # cross-validation) ends the PNG too
    tail = images.page[-200:]
    assert np.array_equal(tail, images.png[-200:])


def test_report_applies_the_estimated_noise_of_the_result():
    """A report made from the data set (the given noise) shows the fit the solve had: the
    weights of the result's ``noise`` section (``certificate.weights: estimated``)."""
    from rwhec_ros.core.noise import solve_with_noise
    from rwhec_ros.core.problem import Edge, Problem
    from rwhec_ros.report import weighted_from_document
    from rwhec_ros.simulation.synthetic import random_instance

    problem, _ = random_instance(np.random.default_rng(31), 2, 2, n_per_edge=30, sigma=0.002,
                                 kappa=3000.0)
    given = Problem(problem.x_names, problem.y_names,
                    [Edge.build(e.x, e.y, e.A, e.B, 0.01, 125.0) for e in problem.edges])
    ns = solve_with_noise(given)
    doc = {"certificate": {"weights": ns.result.certificate.weights},
           "noise": ns.estimate.to_dict()}
    weighted = weighted_from_document(doc, given)
    for a, b in zip(weighted.edges, ns.problem.edges, strict=True):
        np.testing.assert_allclose(a.sigma, b.sigma, rtol=1e-12)
        np.testing.assert_allclose(a.kappa, b.kappa, rtol=1e-12)
    doc["certificate"]["weights"] = "given"
    assert weighted_from_document(doc, given) is given
