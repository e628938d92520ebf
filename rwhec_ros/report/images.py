"""The report's pictures from one draw of one figure (:func:`render_report`).

The stand-alone PNG, the HTML page's figure and the page's section figures show the same plots:
the figure of :func:`~rwhec_ros.report.figure.build_report_figure` is drawn once, without the
banner and the summary texts; that picture is cut between its rows into the page's figure (the
grids, the 3D frames, the histograms and the accuracy rows) and its sections (the per-edge boxes,
the reprojection per camera); then the banner and the texts are drawn onto the same canvas for
the stand-alone PNG. Matplotlib draws text slowly: one draw instead of two per picture (the
first one for the 3D labels' layout, now computed without drawing) and one per section makes the
report about three times faster (paper data: ~20 s -> ~7 s CPU on a busy 2-core machine).

A cut lies in the space between two rows, on a pixel row with nothing drawn on it (the middle
of the longest such run), so that no title, tick label or axis label is cut through.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core.problem import Problem
from ..core.verdict import FitStatistics
from .figure import build_report_figure
from .residuals import EdgeResiduals

__all__ = ["ReportImages", "render_report", "row_cuts", "save_png", "PAGE_ROWS", "SECTIONS"]

#: Rows of the report figure that make the HTML page's figure (the page gives the banner and
#: the summary as text, and the per-edge boxes and the reprojection in their own sections).
PAGE_ROWS = ("identifiability", "fit", "ranked", "frames", "histograms", "std", "validation")
#: Rows of the report figure that are sections of their own on the page.
SECTIONS = ("edges", "reprojection")


@dataclass(frozen=True)
class ReportImages:
    """The report's pictures, RGBA ``(height, width, 4)`` uint8 arrays, all 18 inches wide.

    Attributes
    ----------
    png : ndarray
        The stand-alone PNG: banner, summary, every plot.
    page : ndarray
        The page's figure: the rows :data:`PAGE_ROWS` present.
    sections : dict of str to ndarray
        ``"edges"`` and, with a reprojection error in the result, ``"reprojection"``.
    dpi : int
    """

    png: np.ndarray
    page: np.ndarray
    sections: dict[str, np.ndarray]
    dpi: int


def row_cuts(image: np.ndarray, cells: Sequence[tuple[float, float]],
             background: Sequence[int] = (255, 255, 255, 255)) -> list[int]:
    """Pixel rows that separate the rows of ``image`` (RGBA, top row first): ``0``, one cut
    between each two consecutive rows of ``cells`` (``(top, bottom)`` of each row's axes as
    figure fractions, top to bottom), and the image height. A cut is the middle of the longest
    run of ``background`` pixel rows between the two axes; without one (something drawn across
    the whole space) the middle of the space."""
    h = image.shape[0]
    blank = np.all(image.reshape(h, -1) == np.tile(np.asarray(background, dtype=image.dtype),
                                                   image.shape[1]), axis=1)
    cuts = [0]
    for (_, bottom), (top, _) in zip(cells[:-1], cells[1:], strict=True):
        lo = min(h, max(0, int(np.ceil((1.0 - bottom) * h))))  # below the upper row's axes
        hi = min(h, max(lo, int(np.floor((1.0 - top) * h))))  # above the lower row's axes
        best, run_start, best_len = (lo + hi) // 2, None, 0
        for y in range(lo, hi + 1):
            if y < hi and blank[y]:
                run_start = y if run_start is None else run_start
                continue
            if run_start is not None and y - run_start > best_len:
                best, best_len = (run_start + y) // 2, y - run_start
            run_start = None
        cuts.append(best)
    cuts.append(h)
    return cuts


def render_report(doc: Mapping[str, Any], problem: Problem, residuals: list[EdgeResiduals],
                  fit: FitStatistics, ident, title: str, dpi: int) -> ReportImages:
    """Build the report figure, draw it once and cut it into the report's pictures (module
    docstring)."""
    report = build_report_figure(doc, problem, residuals, fit, ident, title, dpi)
    fig = report.figure
    for ax in report.text_axes:
        ax.set_visible(False)
    fig.canvas.draw()
    plots = np.asarray(fig.canvas.buffer_rgba()).copy()  # without banner and texts
    cuts = row_cuts(plots, report.cells)
    spans = {name: plots[cuts[i]:cuts[i + 1]] for i, name in enumerate(report.rows)}
    page = np.concatenate([spans[name] for name in PAGE_ROWS if name in spans])
    sections = {name: spans[name] for name in SECTIONS if name in spans}
    for ax in report.text_axes:  # onto the drawn canvas: the stand-alone PNG
        ax.set_visible(True)
        fig.draw_artist(ax)
    png = np.asarray(fig.canvas.buffer_rgba()).copy()
    return ReportImages(png, page, sections, dpi)


def save_png(path: str | Path, image: np.ndarray, dpi: int) -> Path:
    """Write the RGBA ``image`` as a PNG (``dpi`` recorded in the file); returns ``path``."""
    from matplotlib.image import imsave

    imsave(str(path), image, format="png", dpi=dpi)
    return Path(path)
