"""The report's per-edge residual distributions and the reprojection error per camera.

* :func:`draw_edge_boxes`: one box per edge of the translation [mm] or rotation [deg] residuals
  of ``A_i X_j = Y_k B_i`` (box: quartiles, line: median, whiskers: 1.5 IQR, dots: the pairs
  beyond), the worst edges first (ranked as the fit per edge ranks them: noise of the edge over
  that of the median edge), at most :data:`EDGE_ROWS` edges so that 70+ edges stay readable
  (every edge is in the HTML page's table), and a last grey box of all pairs together.
* :func:`draw_reprojection`: per camera, the RMS reprojection error [px] of the detected tag
  corners through the calibrated chain, the median as a tick, with the per-detection limit
  ``detection.max_reprojection_rms_px`` of the result's configuration as a reference line (the
  verdict uses no reprojection threshold).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ..core.verdict import FitStatistics
from .residuals import EdgeResiduals, natural_key

__all__ = ["EDGE_ROWS", "ranked_edges", "edge_rows", "edge_boxes_height", "draw_edge_boxes",
           "has_reprojection", "reprojection_height", "draw_reprojection", "indented_axes"]

#: Most edges drawn as boxes (the worst ones); the rest are in the page's table.
EDGE_ROWS = 24
_FLAGGED = "#b71c1c"


def ranked_edges(residuals: Sequence[EdgeResiduals], fit: FitStatistics,
                 n: int = EDGE_ROWS) -> list[EdgeResiduals]:
    """The ``n`` worst edges, worst first: by the fit's noise ratio to the median edge (the
    larger of translation and rotation); edges too small to compare come after, by their
    translation RMS."""
    ratio = {(e.x, e.y): e.ratio for e in fit.edges}

    def key(r: EdgeResiduals):
        q = ratio.get((r.x, r.y), float("nan"))
        rms = float(np.sqrt(np.mean(r.translation_m ** 2)))
        return (0, -q, natural_key(r.name)) if np.isfinite(q) else (1, -rms, natural_key(r.name))

    return sorted(residuals, key=key)[:n]


def edge_rows(residuals: Sequence[EdgeResiduals], n: int = EDGE_ROWS) -> int:
    """Rows of :func:`draw_edge_boxes`: the edges shown and the pooled box."""
    return min(len(residuals), n) + 1


def edge_boxes_height(rows: int) -> float:
    """Height [in] of a row of :func:`draw_edge_boxes` with ``rows`` boxes."""
    return max(3.0, 0.26 * rows + 1.3)


def reprojection_height(cameras: int) -> float:
    """Height [in] of :func:`draw_reprojection` with ``cameras`` bars."""
    return max(2.2, 0.32 * cameras + 1.2)


def indented_axes(fig, cell, inches: float):
    """Axes on a grid cell with its left edge moved right by ``inches`` (room for long tick
    labels such as ``tag_15 / cam_6 (16)``)."""
    box = cell.get_position(fig)
    dx = inches / fig.get_figwidth()
    return fig.add_axes((box.x0 + dx, box.y0, box.width - dx, box.height))


def draw_edge_boxes(ax, residuals: Sequence[EdgeResiduals], fit: FitStatistics, what: str,
                    n: int = EDGE_ROWS) -> dict:
    """Box plots of the ``what`` (``"translation"`` [mm] or ``"rotation"`` [deg]) residuals of
    the :func:`ranked_edges` (worst at the top) and of all pairs (the last, grey); returns
    matplotlib's ``boxplot`` artists (``"boxes"``, ``"medians"``, ... in that order)."""
    shown = ranked_edges(residuals, fit, n)
    scale, unit = (1e3, "mm") if what == "translation" else (np.degrees(1.0), "deg")
    get = (lambda r: r.translation_m) if what == "translation" else (lambda r: r.rotation_rad)
    data = [scale * get(r) for r in shown]
    pooled = scale * np.concatenate([get(r) for r in residuals])
    pos = np.arange(len(shown) + 1)
    style = {"markersize": 2.5, "markerfacecolor": "0.3", "markeredgecolor": "none",
             "marker": "o", "alpha": 0.6}
    kwargs = dict(positions=pos, widths=0.6, patch_artist=True, flierprops=style,
                  medianprops={"color": "black", "linewidth": 1.2})
    try:
        boxes = ax.boxplot([*data, pooled], orientation="horizontal", **kwargs)
    except TypeError:  # matplotlib < 3.10 (Ubuntu 24.04's 3.6 and 3.8): no `orientation` yet
        boxes = ax.boxplot([*data, pooled], vert=False, **kwargs)
    flagged = {(e.x, e.y) for e in fit.edges if e.flagged}
    for i, patch in enumerate(boxes["boxes"]):
        last = i == len(shown)
        red = not last and (shown[i].x, shown[i].y) in flagged
        patch.set_facecolor("0.75" if last else ("#f4a6a6" if red else "#a9c6ea"))
        patch.set_edgecolor("0.3")
    ax.axhline(len(shown) - 0.5, color="0.5", linewidth=0.8)
    ax.set_ylim(len(shown) + 0.6, -0.6)  # the worst at the top, all pairs at the bottom
    ax.set_yticks(pos)
    labels = ax.set_yticklabels([f"{r.x} / {r.y} ({r.n})" for r in shown]
                                + [f"all {pooled.size} pairs"], fontsize=8)
    for label, r in zip(labels, shown, strict=False):
        if (r.x, r.y) in flagged:
            label.set_color(_FLAGGED)
            label.set_fontweight("bold")
    labels[-1].set_fontweight("bold")
    ax.set_xlim(left=0)
    ax.set_xlabel(f"{what} residual [{unit}] (box: quartiles and median; whiskers 1.5 IQR; "
                  "dots: pairs beyond)", fontsize=9)
    ax.tick_params(axis="x", labelsize=8)
    ax.grid(axis="x", color="0.88", linewidth=0.6)
    ax.set_axisbelow(True)
    E = len(residuals)
    which = (f"all {E} edges, worst first" if len(shown) == E else
             f"the {len(shown)} worst of {E} edges (all: report.html)")
    ax.set_title(f"{what} residuals per edge (pairs): {which}", fontsize=11)
    return boxes


def has_reprojection(doc: Mapping[str, Any]) -> bool:
    """``doc`` holds a reprojection error of at least one camera."""
    return any(np.isfinite(float(r.get("rms_px", np.nan)))
               for r in (doc.get("reprojection") or {}).values())


def draw_reprojection(ax, doc: Mapping[str, Any]) -> None:
    """Per camera (natural order, top to bottom) the RMS reprojection error [px] as a bar, the
    median as a black tick, and ``<rms> px (<pairs> pairs)`` beside it."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    rep = sorted((doc.get("reprojection") or {}).items(), key=lambda kv: natural_key(kv[0]))
    names = [cam for cam, _ in rep]
    rms = np.array([float(r.get("rms_px", np.nan)) for _, r in rep])
    med = np.array([float(r.get("median_px", np.nan)) for _, r in rep])
    pos = np.arange(len(names))
    limit = (doc.get("config") or {}).get("detection.max_reprojection_rms_px")
    top = float(np.nanmax(np.r_[rms, med, 0.0]))
    if limit is not None:
        top = max(top, float(limit))
    xmax = 1.45 * top if top > 0 else 1.0  # room for the numbers and the legend
    ok = np.isfinite(rms)
    ax.barh(pos[ok], rms[ok], height=0.6, color="tab:blue")
    for i, (_, r) in enumerate(rep):
        if np.isfinite(med[i]):
            ax.plot([med[i]] * 2, [i - 0.3, i + 0.3], color="black", linewidth=1.5)
        words = (f"{rms[i]:.2f} px ({r.get('n_pairs', '?')} pairs)" if ok[i] else
                 "no corners through the calibration")
        if r.get("n_behind"):
            words += f", {r['n_behind']} behind the camera"
        ax.text((rms[i] if ok[i] else 0.0) + 0.01 * xmax, i, words, va="center", ha="left",
                fontsize=8)
    handles = [Patch(color="tab:blue", label="RMS"),
               Line2D([], [], color="black", linewidth=1.5, label="median")]
    if limit is not None:
        ax.axvline(float(limit), color="0.4", linestyle=":", linewidth=1.2)
        handles.append(Line2D([], [], color="0.4", linestyle=":", linewidth=1.2,
                              label=f"per-detection limit {float(limit):g} px (not a verdict "
                                    "threshold)"))
    ax.set_xlim(0, xmax)
    ax.set_ylim(len(names) - 0.4, -0.6)
    ax.set_yticks(pos)
    ax.set_yticklabels(names, fontsize=8)
    ax.set_xlabel("reprojection error of the detected corners (tags, boards) [px]", fontsize=9)
    ax.tick_params(axis="x", labelsize=8)
    ax.grid(axis="x", color="0.88", linewidth=0.6)
    ax.set_axisbelow(True)
    ax.legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0),
              frameon=False, borderaxespad=0.0)  # beside the bars: never over them
    ax.set_title("reprojection error per camera: corners through camera <- carrier <- pose "
                 "<- target carrier <- target", fontsize=11)
