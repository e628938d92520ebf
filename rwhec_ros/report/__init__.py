"""A calibration report that answers "can I use this?" at a glance: a PNG and an HTML page.

The verdict first (a coloured banner: green ``GOOD``, amber ``CAUTION``, red ``UNUSABLE``, with
its reasons), then the summary, the identifiability grid of the paper's Fig. 10, the fit per edge
on the same grid with the worst edges ranked (readable with 70+ edges), the estimated frames in
3D, the residual histograms, the residuals per edge as boxes (the worst edges) and, when the
data set kept the tag corners, the reprojection error per camera. The HTML page is
self-contained (its figures embedded as base64) and gives the banner, the summary and the tables
as text (frames with usability and precision, edges in natural order, edges left out, notes),
the per-edge boxes and the reprojection bars in their own sections.

Modules: :mod:`.residuals` (the numbers), :mod:`.figure` (the PNG), :mod:`.edges` (per-edge
boxes, reprojection per camera), :mod:`.accuracy` (stds, cross-validation, guidance),
:mod:`.labels` (labels that do not overlap), :mod:`.images` (one draw of the figure, cut into
the PNG's, the page's and the sections' pictures), :mod:`.page` (the HTML).
"""

from __future__ import annotations

import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..core.problem import Problem
from ..data.atomic import StagedFiles
from .images import render_report, save_png
from .page import render_page
from .residuals import (
    EdgeResiduals,
    edge_residuals,
    estimates_from_document,
    fit_of_document,
    natural_key,
)

__all__ = [
    "EdgeResiduals",
    "edge_residuals",
    "estimates_from_document",
    "fit_of_document",
    "natural_key",
    "ReportFiles",
    "weighted_from_document",
    "write_report",
]


def weighted_from_document(doc: Mapping[str, Any], problem: Problem) -> Problem:
    """``problem`` with the weights the result ``doc`` was solved with: the noise per group
    estimated from the data (its ``noise`` section's ``used`` factors) when
    ``certificate.weights`` is ``estimated``, else ``problem`` as it is."""
    noise = doc.get("noise") or {}
    if (doc.get("certificate") or {}).get("weights") != "estimated" or not noise.get("groups"):
        return problem
    from ..core.noise import weighted_as

    factors = {name: (float(g["translation"]["used"]), float(g["rotation"]["used"]))
               for name, g in noise["groups"].items()}
    edges = {name: [str(e) for e in g["edges"]] for name, g in noise["groups"].items()
             if isinstance(g.get("edges"), list)}
    return weighted_as(problem, str(noise.get("grouping", "camera")), factors,
                       edges if len(edges) == len(factors) else None)


@dataclass(frozen=True)
class ReportFiles:
    """Paths written by :func:`write_report`."""

    png: Path
    html: Path


def write_report(
    doc: Mapping[str, Any],
    problem: Problem,
    png_path: str | Path,
    html_path: str | Path,
    *,
    identifiability=None,
    title: str = "rwhec_ros calibration report",
    dpi: int = 80,
) -> ReportFiles:
    """Write the report PNG and the self-contained HTML page of one calibration.

    Parameters
    ----------
    doc : mapping
        The result YAML mapping (:func:`rwhec_ros.data.results.result_document`, the session's
        result YAML, or :func:`rwhec_ros.data.results.load_result`); its ``verdict``,
        ``reasons`` and ``verdict_details`` make the banner (a result without them gets a grey
        "verdict unknown" banner).
    problem : Problem
        The measurement pairs that were solved (residuals, fit, identifiability), with their
        given noise: when the solve estimated it (``certificate.weights: estimated``), the
        weights of the result's ``noise`` section are applied here
        (:func:`weighted_from_document`).
    png_path, html_path : str or Path
        Output files (the page embeds its figure: it can be moved alone).
    identifiability : IdentifiabilityReport, optional
        Default: :func:`rwhec_ros.core.identifiability.analyze` of ``problem`` at the estimate.
    title : str
    dpi : int
        Resolution of the PNG (18 inches wide).
    """
    png_path, html_path = Path(png_path), Path(html_path)
    problem = weighted_from_document(doc, problem)
    X, Y, scale = estimates_from_document(doc, problem)
    residuals = edge_residuals(problem, X, Y, scale)
    fit = fit_of_document(doc, problem)
    if identifiability is None:
        from ..core.identifiability import analyze

        identifiability = analyze(problem, solution=(X, Y, scale))
    images = render_report(doc, problem, residuals, fit, identifiability, title, dpi)
    with tempfile.TemporaryDirectory() as tmp:
        png = save_png(Path(tmp) / "report.png", images.png, dpi)
        figure = save_png(Path(tmp) / "figure.png", images.page, dpi)
        sections = {name: save_png(Path(tmp) / f"{name}.png", image, dpi)
                    for name, image in images.sections.items()}
        page = render_page(doc, problem, residuals, fit, identifiability, figure, title,
                           sections=sections)
        # both files whole or absent, the page (which embeds the figure) last
        with StagedFiles() as staged:
            staged.stage(png_path, png.read_bytes())
            staged.stage(html_path, page)
            staged.commit()
    return ReportFiles(png_path, html_path)
