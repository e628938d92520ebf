"""The report figure: verdict banner, identifiability and fit per edge, frames in 3D, residuals.

Matplotlib on the Agg canvas without pyplot (no global state). Layout, top to bottom:

1. the verdict banner (green ``GOOD``, amber ``CAUTION``, red ``UNUSABLE``) with its reasons
   (only in the stand-alone PNG: the HTML page gives them as text);
2. the summary (PNG only) and the identifiability grid of the paper's Fig. 10 (rows cameras,
   columns tags, natural order; "insufficient on its own" in amber, not alarm red, when the graph
   still determines every frame);
3. the fit per edge on the same grid (noise of the edge over that of the median edge; outliers
   framed) and the worst edges ranked, so that 70+ edges stay readable;
4. the estimated frames as axes triads in 3D, labels placed so that they do not overlap;
5. histograms of the residuals of all pairs, then the residuals per edge as boxes (the worst
   edges, :mod:`.edges`) and, when the data set kept the tag corners, the reprojection error per
   camera;
6. with an accuracy in the result (:mod:`.accuracy`): the per-frame std bars (translation,
   rotation), and the held-out vs in-sample residuals per edge of the cross-validation; the next
   motion ends the summary text.
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core.problem import Problem
from ..core.verdict import FitStatistics
from .accuracy import (
    draw_std_bars,
    draw_validation,
    has_accuracy,
    has_validation,
    summary_text_lines,
)
from .edges import (
    draw_edge_boxes,
    draw_reprojection,
    edge_boxes_height,
    edge_rows,
    has_reprojection,
    indented_axes,
    reprojection_height,
)
from .labels import place_labels
from .residuals import EdgeResiduals, natural_key
from .words import BANNER_COLORS, certificate_words

__all__ = ["BANNER_COLORS", "ReportFigure", "build_report_figure", "place_labels"]

_AXIS_COLORS = ("tab:red", "tab:green", "tab:blue")
_STATUS_COLORS = {
    "identifiable": (0.13, 0.36, 0.80),
    "weak": (0.60, 0.74, 0.95),
    "insufficient": (0.84, 0.15, 0.16),
    "insufficient_fixed": (0.98, 0.78, 0.45),
    "rejected": (0.45, 0.45, 0.45),
    "left_out": (0.80, 0.80, 0.80),
    None: (1.0, 1.0, 1.0),
}
_STATUS_LABELS = {
    "identifiable": "identifiable on its own",
    "weak": "identifiable, below comfortable thresholds",
    "insufficient": "not identifiable, and the graph does not fix it",
    "insufficient_fixed": "not identifiable on its own, fixed through the graph",
    "rejected": "rejected (outlier rejection: every pair)",
    "left_out": "left out (too few pairs)",
    None: "not observed",
}


def banner_lines(doc: Mapping[str, Any], width: int = 150, max_lines: int = 9) -> list[str]:
    """The reasons of the verdict wrapped to ``width`` characters, at most ``max_lines``."""
    lines: list[str] = []
    reasons = list(doc.get("reasons") or [])
    for i, reason in enumerate(reasons):
        wrapped = textwrap.wrap(reason, width, subsequent_indent="    ")
        if len(lines) + len(wrapped) > max_lines:
            lines.append(f"... and {len(reasons) - i} more reason(s): see report.html or "
                         "result.yaml")
            break
        lines += wrapped
    return lines


def _banner(ax, doc: Mapping[str, Any]) -> None:
    level = str(doc.get("verdict", "unknown"))
    fg, bg = BANNER_COLORS.get(level, BANNER_COLORS["unknown"])
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_facecolor(bg)
    for spine in ax.spines.values():
        spine.set_edgecolor(fg)
        spine.set_linewidth(3)
    head = {"good": "GOOD: use this calibration", "caution": "CAUTION: usable, read the reasons",
            "unusable": "UNUSABLE: do not use this calibration"}.get(
        level, "VERDICT UNKNOWN: this result was written without a verdict")
    height = ax.get_position().height * ax.figure.get_figheight()  # inches
    ax.text(0.01, 1 - 0.12 / height, head, transform=ax.transAxes, va="top", ha="left",
            fontsize=20, fontweight="bold", color=fg)
    details = doc.get("verdict_details")
    summary = str(details.get("summary", "")) if isinstance(details, Mapping) else ""
    body = banner_lines(doc) or textwrap.wrap(summary, 150)  # the reasons' width: not clipped
    ax.text(0.01, 1 - 0.6 / height, "\n".join(body), transform=ax.transAxes, va="top",
            ha="left", fontsize=11, color="0.1", family="monospace")


def _edge_cells(x_names, y_names, values: Mapping[tuple[str, str], Any]):
    return [[values.get((x, y)) for x in x_names] for y in y_names]


def _color_ticks(ax, levels: Mapping[str, str]) -> None:
    """Tick labels of frames that are not usable in red, of cautions in amber."""
    colors = {"unusable": BANNER_COLORS["unusable"][0], "caution": BANNER_COLORS["caution"][0]}
    for label in [*ax.get_xticklabels(), *ax.get_yticklabels()]:
        level = levels.get(label.get_text())
        if level in colors:
            label.set_color(colors[level])
            label.set_fontweight("bold")


def _grid(ax, x_names, y_names, colors, title: str, *, hatch=None, frame=None) -> None:
    from matplotlib.collections import PatchCollection
    from matplotlib.patches import Rectangle

    M, P = len(x_names), len(y_names)
    # one collection per hatch (and one of the frames): a patch per cell draws far slower
    cells: dict[Any, tuple[list, list]] = {}
    framed = []
    for k in range(P):
        for j in range(M):
            group = cells.setdefault(None if hatch is None else hatch[k][j], ([], []))
            group[0].append(Rectangle((j, k), 1, 1))
            group[1].append(colors[k][j])
            if frame is not None and frame[k][j]:
                framed.append(Rectangle((j + 0.06, k + 0.06), 0.88, 0.88))
    for h, (rects, faces) in cells.items():
        ax.add_collection(PatchCollection(rects, facecolors=faces, edgecolors="0.55",
                                          linewidths=0.5, hatch=h), autolim=False)
    if framed:
        ax.add_collection(PatchCollection(framed, facecolors="none", edgecolors="black",
                                          linewidths=2.2), autolim=False)
    ax.set_xlim(0, M)
    ax.set_ylim(P, 0)
    ax.set_aspect("equal")
    ax.set_xticks(np.arange(M) + 0.5)
    ax.set_xticklabels(x_names, rotation=90, fontsize=8)
    ax.set_yticks(np.arange(P) + 0.5)
    ax.set_yticklabels(y_names, fontsize=8)
    ax.set_xlabel("tags (X)", fontsize=9)
    ax.set_ylabel("cameras (Y)", fontsize=9)
    ax.set_title(title, fontsize=11)


def _identifiability(ax, ident, x_names, y_names,
                     excluded: Mapping[str, str] | None = None) -> None:
    """The identifiability grid; edges the solve left out (the result's ``excluded_edges``)
    are drawn as rejected (outlier rejection) or left out, never as not observed."""
    from matplotlib.patches import Patch

    status = {}
    for name, reason in (excluded or {}).items():
        x, _, y = str(name).strip("()").partition(", ")
        status[(x, y)] = ("rejected" if str(reason).startswith("outlier rejection")
                          else "left_out")
    for e in getattr(ident, "edges", ()):
        s = getattr(e.status, "value", e.status)
        if s == "insufficient" and ident.identifiable:
            s = "insufficient_fixed"
        status[(e.x, e.y)] = s
    cells = _edge_cells(x_names, y_names, status)
    colors = [[_STATUS_COLORS[c] for c in row] for row in cells]
    hatch = [["//" if c == "weak" else None for c in row] for row in cells]
    verdict = str(getattr(ident, "verdict", ""))
    _grid(ax, x_names, y_names, colors, "identifiability per edge (cf. paper Fig. 10): "
          + verdict.split(":")[0], hatch=hatch)
    used = {c for row in cells for c in row}
    handles = [Patch(facecolor=_STATUS_COLORS[k], edgecolor="0.4", label=_STATUS_LABELS[k],
                     hatch="//" if k == "weak" else None) for k in _STATUS_COLORS if k in used]
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8,
              frameon=False, borderaxespad=0.0)


def _fit_grid(fig, ax, fit: FitStatistics, x_names, y_names, edge_ratio: float) -> None:
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import LogNorm

    ratio = {(e.x, e.y): e.ratio for e in fit.edges if np.isfinite(e.ratio) and e.ratio > 0}
    flagged = {(e.x, e.y): True for e in fit.edges if e.flagged}
    top = max([edge_ratio * 2, *ratio.values()])
    norm = LogNorm(vmin=0.5, vmax=top)
    cmap = colormaps["YlOrRd"]
    cells = _edge_cells(x_names, y_names, ratio)
    observed = {(e.x, e.y) for e in fit.edges}
    colors = [[cmap(norm(max(c, 0.5))) if c is not None else
               ((0.85, 0.85, 0.85) if (x, y) in observed else (1.0, 1.0, 1.0))
               for c, x in zip(row, x_names, strict=True)]
              for row, y in zip(cells, y_names, strict=True)]
    frame = _edge_cells(x_names, y_names, flagged)
    _grid(ax, x_names, y_names, colors, "fit per edge: noise of the edge / noise of the median "
          "edge (framed: named as an outlier)", frame=frame)
    bar = fig.colorbar(ScalarMappable(norm, cmap), ax=ax, fraction=0.035, pad=0.02)
    bar.set_label("edge / median edge (grey: too few pairs to compare)", fontsize=8)
    bar.ax.tick_params(labelsize=8)
    bar.ax.axhline(edge_ratio, color="black", linewidth=1.5)


def _ranked(ax, fit: FitStatistics, edge_ratio: float, n: int = 15) -> None:
    edges = [e for e in fit.edges if np.isfinite(e.ratio)]
    edges = sorted(edges, key=lambda e: -e.ratio)[:n][::-1]
    if not edges:
        ax.axis("off")
        ax.text(0.5, 0.5, "too few edges to compare", ha="center", va="center")
        return
    pos = np.arange(len(edges))
    ax.barh(pos + 0.2, [e.ratio_translation for e in edges], height=0.38,
            color="tab:blue", label="translation")
    ax.barh(pos - 0.2, [e.ratio_rotation for e in edges], height=0.38, color="tab:orange",
            label="rotation")
    ax.axvline(edge_ratio, color="black", linestyle="--", linewidth=1,
               label=f"outlier at {edge_ratio:g}x")
    ax.set_yticks(pos)
    labels = ax.set_yticklabels(
        [f"{e.x} / {e.y} ({e.pairs} pairs): {1e3 * e.rms_translation_m:.1f} mm, "
         f"{e.rms_rotation_deg:.2f} deg" for e in edges], fontsize=8)
    for label, e in zip(labels, edges, strict=True):
        if e.flagged:
            label.set_color("#b71c1c")
            label.set_fontweight("bold")
    from matplotlib.ticker import FixedLocator, FuncFormatter, NullLocator

    ax.set_xscale("log")
    values = [v for e in edges for v in (e.ratio_translation, e.ratio_rotation)
              if np.isfinite(v) and v > 0]
    lo, hi = min([*values, edge_ratio]), max([*values, edge_ratio])
    ax.set_xlim(lo / 1.3, hi * 1.3)
    # every tick labelled: 1-2-5 steps within the range (a log axis over less than a decade
    # would label only its power of ten)
    ticks = [m * 10.0 ** k for k in range(int(np.floor(np.log10(lo / 1.3))),
                                          int(np.ceil(np.log10(hi * 1.3))) + 1)
             for m in (1, 2, 5) if lo / 1.3 <= m * 10.0 ** k <= hi * 1.3]
    ax.xaxis.set_major_locator(FixedLocator(ticks))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
    ax.xaxis.set_minor_locator(NullLocator())
    ax.set_xlabel("noise of the edge / noise of the median edge", fontsize=9)
    ax.set_title(f"the {len(edges)} worst-fitting edges (RMS residuals)", fontsize=11)
    ax.legend(loc="lower right", fontsize=8)
    ax.tick_params(axis="x", labelsize=8)
    ax.grid(axis="x", alpha=0.3)


def _triad(ax, T: np.ndarray, length: float, *, lw: float = 1.6) -> None:
    o = T[:3, 3]
    for i, c in enumerate(_AXIS_COLORS):
        tip = o + length * T[:3, i]
        ax.plot([o[0], tip[0]], [o[1], tip[1]], [o[2], tip[2]], color=c, linewidth=lw)


def _frames_3d(ax, frames: Sequence[tuple[str, np.ndarray]], carrier: str,
               what: str) -> list[tuple[str, np.ndarray]]:
    """Axes triads of ``frames`` and of the carrier; returns the labels to place."""
    if not frames:
        ax.set_axis_off()
        ax.text2D(0.5, 0.5, f"{what}: none usable (see the reasons)", transform=ax.transAxes,
                  ha="center", va="center", fontsize=12, color=BANNER_COLORS["unusable"][0])
        return []
    pts = np.array([T[:3, 3] for _, T in frames] + [np.zeros(3)])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    span = float(max(np.max(hi - lo), 0.05))
    length = 0.1 * span
    _triad(ax, np.eye(4), 1.3 * length, lw=2.6)
    for _, T in frames:
        _triad(ax, T, length)
    centre = 0.5 * (lo + hi)
    half = 0.5 * span + length
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1), zoom=1.1)  # 1.2 reached into the title of the row below
    ax.set_xlabel("x [m]", fontsize=8)
    ax.set_ylabel("y [m]", fontsize=8)
    ax.set_zlabel("z [m]", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.set_title(f"{what} in '{carrier}' (x red, y green, z blue)", fontsize=11)
    return [(carrier, np.zeros(3))] + [(n, T[:3, 3]) for n, T in frames]


def _label_3d(fig, ax, labels: list[tuple[str, np.ndarray]]) -> None:
    """Names at 3D points, offset so that no two overlap (call after a draw of the layout)."""
    from mpl_toolkits.mplot3d import proj3d

    M = ax.get_proj()
    xy2 = [proj3d.proj_transform(p[0], p[1], p[2], M)[:2] for _, p in labels]
    xy = np.array([ax.transData.transform(p) for p in xy2])
    dpi = fig.dpi / 72.0
    sizes = np.array([(7 * 0.6 * len(n) * dpi + 4, 7 * 1.3 * dpi) for n, _ in labels])
    offsets = place_labels(xy, sizes, step=6 * dpi)
    for (name, _), p2, off in zip(labels, xy2, offsets, strict=True):
        ax.annotate(name, xy=p2, xycoords="data", xytext=off / dpi, textcoords="offset points",
                    fontsize=7, color="0.1",
                    ha="left" if off[0] > 0 else ("right" if off[0] < 0 else "center"),
                    va="bottom" if off[1] > 0 else ("top" if off[1] < 0 else "center"),
                    arrowprops={"arrowstyle": "-", "color": "0.6", "linewidth": 0.5})


def _summary_lines(doc: Mapping[str, Any], problem: Problem,
                   residuals: Sequence[EdgeResiduals]) -> list[str]:
    t_all = np.concatenate([r.translation_m for r in residuals])
    r_all = np.concatenate([r.rotation_rad for r in residuals])
    total_s = (doc.get("timing_s") or {}).get("total", float("nan"))
    scale = float(doc.get("scale", 1.0))
    lines = textwrap.wrap(certificate_words(doc), 46) + [
        f"mode {doc.get('mode', '?')}, solved in {total_s:.2f} s",
        f"scale alpha = {scale:.5f}" if problem.unknown_scale else "known scale",
        f"{problem.n_measurements} pairs on {len(problem.edges)} edges",
        f"{problem.P} cameras (Y), {problem.M} tags (X)",
        "",
        "residuals of A X = Y B (all pairs):",
        f"  translation RMS {1e3 * np.sqrt(np.mean(t_all ** 2)):.2f} mm, "
        f"median {1e3 * np.median(t_all):.2f} mm",
        f"  rotation RMS {np.degrees(np.sqrt(np.mean(r_all ** 2))):.3f} deg, "
        f"median {np.degrees(np.median(r_all)):.3f} deg",
    ]
    excluded = doc.get("excluded_edges") or {}
    if excluded:
        lines += ["", f"{len(excluded)} edge(s) left out (see report.html)"]
    motion = summary_text_lines(doc)
    if motion:
        lines += ["", *motion]
    return lines


def _fit_lines(fit: FitStatistics) -> list[str]:
    if not fit.testable:
        return ["too few pairs to test the fit"]
    lines = [
        "fit to the stated noise (1 = as stated):",
        f"  translations {fit.noise_ratio_translation:.2f}x:",
        f"    sigma {1e3 * fit.sigma_estimated_m:.2f} mm, stated {1e3 * fit.sigma_stated_m:.2f}",
        f"  rotations {fit.noise_ratio_rotation:.2f}x:",
        f"    kappa {fit.kappa_estimated:.3g}, stated {fit.kappa_stated:.3g}",
    ]
    flagged = fit.flagged_edges()
    if flagged:
        lines += ["", "edges named as outliers:"]
        lines += [f"  {e.x} / {e.y}: {e.ratio:.1f}x" for e in flagged[:8]]
        if len(flagged) > 8:
            lines.append(f"  ... and {len(flagged) - 8} more")
    return lines


def _text(ax, lines: list[str]) -> None:
    ax.axis("off")
    ax.text(0.0, 1.0, "\n".join(lines), va="top", ha="left", fontsize=10, family="monospace",
            transform=ax.transAxes)


@dataclass
class ReportFigure:
    """The report figure, built but not drawn (:func:`build_report_figure`).

    Attributes
    ----------
    figure : matplotlib.figure.Figure
        On an Agg canvas, at the report's dpi.
    rows : list of str
        What each row of the grid holds, top to bottom: ``"banner"``, ``"identifiability"``,
        ``"fit"``, ``"ranked"``, ``"frames"``, ``"histograms"``, then as present ``"edges"``,
        ``"reprojection"``, ``"std"``, ``"validation"``.
    cells : list of (float, float)
        Per row, the top and bottom of its axes (figure fraction, top > bottom).
    text_axes : list of Axes
        The banner and the two summary texts: the stand-alone PNG only (the page gives them as
        text).
    """

    figure: Any
    rows: list[str]
    cells: list[tuple[float, float]]
    text_axes: list[Any]


def build_report_figure(doc: Mapping[str, Any], problem: Problem,
                        residuals: list[EdgeResiduals], fit: FitStatistics, ident, title: str,
                        dpi: int) -> ReportFigure:
    """The whole report figure (module docstring), ready for one draw: the 3D labels are
    placed from the final layout's projections, computed without drawing."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    details = (doc.get("verdict_details") or {}).get("frames") or {}
    missing = {n: d.get("role") for n, d in details.items() if not d.get("calibrated", True)}
    x_names = sorted([*problem.x_names, *(n for n, r in missing.items() if r == "X")],
                     key=natural_key)
    y_names = sorted([*problem.y_names, *(n for n, r in missing.items() if r == "Y")],
                     key=natural_key)
    levels = {n: d.get("level", "good") for n, d in details.items()}
    grid_h = max(3.0, 0.3 * len(y_names) + 2.0)
    banner = banner_lines(doc)
    n_ranked = min(15, sum(np.isfinite(e.ratio) for e in fit.edges))
    text = _summary_lines(doc, problem, residuals)
    fit_text = _fit_lines(fit)
    line_h = 0.18  # inches per line of 10 pt monospace text
    rows = ["banner", "identifiability", "fit", "ranked", "frames", "histograms"]
    heights = [1.0 + 0.2 * max(len(banner), 1),
               max(grid_h, line_h * len(text) + 0.3), max(grid_h, line_h * len(fit_text) + 0.3),
               max(2.5, 0.3 * n_ranked + 1.0), 6.5, 3.2]
    box_rows = edge_rows(residuals)
    if box_rows:
        rows.append("edges")
        heights.append(edge_boxes_height(box_rows))
    rep_rows = len(doc.get("reprojection") or {}) if has_reprojection(doc) else 0
    if rep_rows:
        rows.append("reprojection")
        heights.append(reprojection_height(rep_rows))
    if has_accuracy(doc):  # three bars per frame
        rows.append("std")
        heights.append(max(3.0, 0.33 * len(doc["frames"]) + 1.2))
    if has_validation(doc):
        rows.append("validation")
        heights.append(5.0)
    total = sum(heights) + 0.9 * len(heights) + 1.0
    fig = Figure(figsize=(18, total), dpi=dpi)
    FigureCanvasAgg(fig)
    # the space between rows: 0.9 inch, as a fraction of the mean row height
    gs = fig.add_gridspec(len(heights), 4, height_ratios=heights,
                          hspace=0.9 / (sum(heights) / len(heights)), wspace=0.3, left=0.06,
                          right=0.97, top=1 - 0.8 / total, bottom=0.4 / total)
    cells = []
    for i in range(len(rows)):
        box = gs[i, :].get_position(fig)
        cells.append((float(box.y1), float(box.y0)))
    at = {name: i for i, name in enumerate(rows)}
    edge_ratio = float(((doc.get("verdict_details") or {}).get("options") or {}).get(
        "edge_ratio", 5.0))
    text_axes = [fig.add_subplot(gs[0, :])]
    _banner(text_axes[0], doc)
    text_axes.append(fig.add_subplot(gs[1, 0]))
    _text(text_axes[1], text)
    text_axes.append(fig.add_subplot(gs[2, 0]))
    _text(text_axes[2], fit_text)
    ax = fig.add_subplot(gs[1, 1:3])
    _identifiability(ax, ident, x_names, y_names, doc.get("excluded_edges") or {})
    _color_ticks(ax, levels)
    ax = fig.add_subplot(gs[2, 1:3])
    _fit_grid(fig, ax, fit, x_names, y_names, edge_ratio)
    _color_ticks(ax, levels)
    _ranked(fig.add_subplot(gs[3, 1:]), fit, edge_ratio)
    # only usable frames: a frame that is not calibrated is never shown as a pose
    frames = {f["name"]: f for f in doc["frames"] if f.get("usable", True)}
    views = []
    for col, names, what, default in ((slice(0, 2), y_names, "cameras Y_k", "camera carrier"),
                                      (slice(2, 4), x_names, "tags X_j", "tag carrier")):
        items = [(n, np.asarray(frames[n]["matrix"], dtype=float)) for n in names if n in frames]
        ax = fig.add_subplot(gs[4, col], projection="3d")
        carrier = frames[items[0][0]].get("parent") if items else ""
        views.append((ax, _frames_3d(ax, items, carrier or default, what)))
    t_mm = [1e3 * r.translation_m for r in residuals]
    r_deg = [np.degrees(r.rotation_rad) for r in residuals]
    for col, data, unit, what in ((slice(0, 2), t_mm, "mm", "translation"),
                                  (slice(2, 4), r_deg, "deg", "rotation")):
        ax = fig.add_subplot(gs[5, col])
        pooled = np.concatenate(data)
        ax.hist(pooled, bins=min(60, max(10, pooled.size // 20)), color="tab:blue", alpha=0.8)
        ax.set_xlabel(f"{what} residual [{unit}]", fontsize=9)
        ax.set_ylabel("pairs", fontsize=9)
        log = pooled.size > 200  # a long tail (outliers) stays visible
        if log:
            ax.set_yscale("log")
        ax.set_title(f"{what} residuals of A X = Y B, all {pooled.size} pairs"
                     + (" (log count)" if log else ""), fontsize=11)
        ax.tick_params(labelsize=8)
    if "edges" in at:
        for col, what in ((slice(0, 2), "translation"), (slice(2, 4), "rotation")):
            draw_edge_boxes(indented_axes(fig, gs[at["edges"], col], 1.0), residuals, fit, what)
    if "reprojection" in at:
        draw_reprojection(fig.add_subplot(gs[at["reprojection"], 1:3]), doc)
    if "std" in at:
        draw_std_bars(fig.add_subplot(gs[at["std"], 0:2]), doc, "translation")
        draw_std_bars(fig.add_subplot(gs[at["std"], 2:4]), doc, "rotation")
    if "validation" in at:
        draw_validation(fig.add_subplot(gs[at["validation"], 0:2]), doc, "translation")
        draw_validation(fig.add_subplot(gs[at["validation"], 2:4]), doc, "rotation")
    fig.suptitle(title, fontsize=15, y=1 - 0.25 / total)
    for ax, labels in views:
        # the projection of the final layout, as the draw computes it (the square box first)
        ax.apply_aspect()
        _label_3d(fig, ax, labels)
    return ReportFigure(fig, rows, cells, text_axes)
