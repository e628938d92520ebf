"""A calibration report: a PNG (identifiability grid, residuals, estimated frames) and an HTML page.

The PNG holds

* the identifiability grid of the paper's Fig. 10 (rows cameras, columns tags;
  :meth:`~rwhec_ros.core.identifiability.IdentifiabilityReport.save_grid_png`),
* the residuals of ``A_i X_j = Y_k B_i`` (eq. (7)) at the solution for every pair: translation
  ``|R_A t_X + t_A - R_Y t_B / alpha - t_Y|`` [mm] (camera-carrier frame, ``t_B`` metric) and
  rotation ``angle((R_A R_X)^T R_Y R_B)`` [deg]; pooled histograms, and per edge a box plot
  (median, quartiles, whiskers at 1.5 IQR, outliers as points) so that many edges (73 on the
  paper's data) stay readable,
* two 3D views of the estimated frames as axes triads (x red, y green, z blue): the cameras
  ``Y_k`` in the camera carrier and the tags ``X_j`` in the tag carrier.

The HTML page embeds the PNG (same directory, relative link) and gives the numbers as tables:
summary, frames, per-edge residuals with identifiability status, excluded edges. Matplotlib runs
on the Agg canvas without pyplot (no global state).
"""

from __future__ import annotations

import html
import tempfile
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .core.lie import rotation_distance
from .core.problem import Problem

__all__ = [
    "EdgeResiduals",
    "edge_residuals",
    "estimates_from_document",
    "ReportFiles",
    "write_report",
]


@dataclass(frozen=True)
class EdgeResiduals:
    """Per-pair residuals of ``A_i X = Y B_i`` on one edge.

    Attributes
    ----------
    x, y : str
        Tag (X) and camera (Y) frame names.
    translation_m : ndarray, shape (N,)
        ``|t(A_i X) - t(Y B_i)|`` [m] with the metric ``B`` translation ``t_B / alpha``.
    rotation_rad : ndarray, shape (N,)
        Geodesic angle between ``R_A R_X`` and ``R_Y R_B`` [rad].
    """

    x: str
    y: str
    translation_m: np.ndarray
    rotation_rad: np.ndarray

    @property
    def name(self) -> str:
        return f"({self.x}, {self.y})"

    @property
    def n(self) -> int:
        return int(self.translation_m.shape[0])


def edge_residuals(
    problem: Problem, X: np.ndarray, Y: np.ndarray, scale: float = 1.0
) -> list[EdgeResiduals]:
    """Residuals of every pair of ``problem`` at the estimate (cf. eq. (7) and (22)).

    Parameters
    ----------
    problem : Problem
    X : ndarray, shape (M, 4, 4)
        ``T_<tag carrier>_tag`` in ``problem.x_names`` order (metric).
    Y : ndarray, shape (P, 4, 4)
        ``T_<camera carrier>_cam`` in ``problem.y_names`` order (metric).
    scale : float
        ``alpha``: measured ``B`` translations are ``alpha`` times metric ones (1 for known
        scale).
    """
    X = np.asarray(X, dtype=float)
    Y = np.asarray(Y, dtype=float)
    if X.shape != (problem.M, 4, 4) or Y.shape != (problem.P, 4, 4):
        raise ValueError(f"X, Y: expected shapes ({problem.M}, 4, 4) and ({problem.P}, 4, 4), "
                         f"got {X.shape} and {Y.shape}")
    if not (np.isfinite(scale) and scale > 0):
        raise ValueError(f"scale: must be finite and > 0, got {scale!r}")
    xi = {n: i for i, n in enumerate(problem.x_names)}
    yi = {n: i for i, n in enumerate(problem.y_names)}
    out = []
    for e in problem.edges:
        Xj, Yk = X[xi[e.x]], Y[yi[e.y]]
        RA, tA = e.A[:, :3, :3], e.A[:, :3, 3]
        RB, tB = e.B[:, :3, :3], e.B[:, :3, 3] / scale
        t_ax = RA @ Xj[:3, 3] + tA
        t_yb = tB @ Yk[:3, :3].T + Yk[:3, 3]
        out.append(EdgeResiduals(
            e.x, e.y,
            np.linalg.norm(t_ax - t_yb, axis=1),
            rotation_distance(RA @ Xj[:3, :3], Yk[:3, :3] @ RB),
        ))
    return out


def estimates_from_document(
    doc: Mapping[str, Any], problem: Problem
) -> tuple[np.ndarray, np.ndarray, float]:
    """``(X (M,4,4), Y (P,4,4), scale)`` of a result mapping, in ``problem``'s frame order.

    Raises ``ValueError`` naming a frame of the problem that the result does not hold.
    """
    frames = {f["name"]: np.asarray(f["matrix"], dtype=float) for f in doc["frames"]}
    missing = [n for n in problem.x_names + problem.y_names if n not in frames]
    if missing:
        raise ValueError(f"frames: the result has no estimate for {missing} of the data")
    X = np.array([frames[n] for n in problem.x_names])
    Y = np.array([frames[n] for n in problem.y_names])
    return X, Y, float(doc.get("scale", 1.0))


@dataclass(frozen=True)
class ReportFiles:
    """Paths written by :func:`write_report`."""

    png: Path
    html: Path


# ------------------------------------------------------------------------------------------------
# figure

_AXIS_COLORS = ("tab:red", "tab:green", "tab:blue")


def _triad(ax, T: np.ndarray, length: float, label: str, *, lw: float = 1.6) -> None:
    o = T[:3, 3]
    for i, c in enumerate(_AXIS_COLORS):
        tip = o + length * T[:3, i]
        ax.plot([o[0], tip[0]], [o[1], tip[1]], [o[2], tip[2]], color=c, linewidth=lw)
    ax.text(o[0], o[1], o[2], " " + label, fontsize=7, color="0.15")


def _frames_3d(ax, frames: Sequence[tuple[str, np.ndarray]], carrier: str, what: str) -> None:
    pts = np.array([T[:3, 3] for _, T in frames] + [np.zeros(3)])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    span = float(max(np.max(hi - lo), 0.05))
    length = 0.1 * span
    _triad(ax, np.eye(4), 1.3 * length, carrier, lw=2.6)
    for name, T in frames:
        _triad(ax, T, length, name)
    centre = 0.5 * (lo + hi)
    half = 0.5 * span + length
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1), zoom=1.25)
    ax.set_xlabel("x [m]", fontsize=8)
    ax.set_ylabel("y [m]", fontsize=8)
    ax.set_zlabel("z [m]", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.set_title(f"{what} in '{carrier}' (x red, y green, z blue)", fontsize=10)


def _summary_lines(doc: Mapping[str, Any], problem: Problem,
                   residuals: Sequence[EdgeResiduals]) -> list[str]:
    t_all = np.concatenate([r.translation_m for r in residuals])
    r_all = np.concatenate([r.rotation_rad for r in residuals])
    rho = doc.get("suboptimality_bound", float("nan"))
    total_s = (doc.get("timing_s") or {}).get("total", float("nan"))
    lines = [
        "CERTIFIED globally optimal" if doc.get("certified") else
        f"NOT certified ({doc.get('status', '?')})",
        f"suboptimality bound rho_hat = {rho:.2e}",
        f"mode {doc.get('mode', '?')}, solve {total_s:.2f} s",
        f"scale alpha = {float(doc.get('scale', 1.0)):.5f}"
        + ("" if problem.unknown_scale else " (known scale)"),
        f"{problem.n_measurements} pairs, {len(problem.edges)} edges",
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
        lines += ["", f"{len(excluded)} edge(s) excluded (see HTML)"]
    return lines


def _box(ax, data: list[np.ndarray], labels: list[str], ylabel: str, title: str) -> None:
    ax.boxplot(data, whis=1.5, widths=0.6, flierprops={"markersize": 2, "alpha": 0.5},
               medianprops={"color": "tab:orange"})
    ax.set_xticks(np.arange(1, len(labels) + 1))
    fs = 8 if len(labels) <= 30 else 6
    ax.set_xticklabels(labels, rotation=90, fontsize=fs)
    ax.set_ylabel(ylabel, fontsize=9)
    ax.set_title(title, fontsize=10)
    ax.set_xlim(0.3, len(labels) + 0.7)
    ax.grid(axis="y", alpha=0.3)
    ax.tick_params(axis="y", labelsize=8)


def _draw_png(path: Path, doc: Mapping[str, Any], problem: Problem,
              residuals: list[EdgeResiduals], ident, title: str, dpi: int) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.image import imread

    fig = Figure(figsize=(18, 26))
    FigureCanvasAgg(fig)
    gs = fig.add_gridspec(5, 4, height_ratios=(1.5, 1.2, 0.7, 0.9, 0.9), hspace=0.4,
                          wspace=0.25)

    ax = fig.add_subplot(gs[0, 0])
    ax.axis("off")
    ax.text(0.0, 1.0, "\n".join(_summary_lines(doc, problem, residuals)), va="top",
            ha="left", fontsize=11, family="monospace", transform=ax.transAxes)

    ax = fig.add_subplot(gs[0, 1:])
    ax.axis("off")
    with tempfile.TemporaryDirectory() as tmp:
        grid_png = Path(tmp) / "grid.png"
        ident.save_grid_png(grid_png, dpi=dpi)  # shown at about its own size
        ax.imshow(imread(str(grid_png)), interpolation="antialiased")
    ax.set_title("identifiability per edge (cf. paper Fig. 10)", fontsize=11)

    frames = {f["name"]: f for f in doc["frames"]}
    cams = [(n, np.asarray(frames[n]["matrix"], dtype=float)) for n in problem.y_names]
    tags = [(n, np.asarray(frames[n]["matrix"], dtype=float)) for n in problem.x_names]
    cam_carrier = frames[problem.y_names[0]].get("parent") or "camera carrier"
    tag_carrier = frames[problem.x_names[0]].get("parent") or "tag carrier"
    _frames_3d(fig.add_subplot(gs[1, :2], projection="3d"), cams, cam_carrier, "cameras Y_k")
    _frames_3d(fig.add_subplot(gs[1, 2:], projection="3d"), tags, tag_carrier, "tags X_j")

    t_mm = [1e3 * r.translation_m for r in residuals]
    r_deg = [np.degrees(r.rotation_rad) for r in residuals]
    for col, data, unit, what in ((slice(0, 2), t_mm, "mm", "translation"),
                                  (slice(2, 4), r_deg, "deg", "rotation")):
        ax = fig.add_subplot(gs[2, col])
        pooled = np.concatenate(data)
        ax.hist(pooled, bins=min(60, max(10, pooled.size // 20)), color="tab:blue", alpha=0.8)
        ax.set_xlabel(f"{what} residual [{unit}]", fontsize=9)
        ax.set_ylabel("pairs", fontsize=9)
        ax.set_title(f"{what} residuals of A X = Y B, all {pooled.size} pairs", fontsize=10)
        ax.tick_params(labelsize=8)

    labels = [f"{r.x}/{r.y} ({r.n})" for r in residuals]
    _box(fig.add_subplot(gs[3, :]), t_mm, labels, "translation [mm]",
         "translation residual per edge (tag/camera (pairs)); box: quartiles, whiskers 1.5 IQR")
    _box(fig.add_subplot(gs[4, :]), r_deg, labels, "rotation [deg]",
         "rotation residual per edge (tag/camera (pairs))")
    fig.suptitle(title, fontsize=14)
    fig.subplots_adjust(left=0.05, right=0.98, top=0.96, bottom=0.06)
    fig.savefig(str(path), dpi=dpi)


# ------------------------------------------------------------------------------------------------
# html


def _table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row) + "</tr>" for row in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _html(doc: Mapping[str, Any], problem: Problem, residuals: list[EdgeResiduals], ident,
          png_name: str, title: str) -> str:
    summary = [
        ("certified", doc.get("certified")),
        ("status", doc.get("status", "")),
        ("suboptimality bound rho_hat", f"{doc.get('suboptimality_bound', float('nan')):.3e}"),
        ("scale alpha", f"{float(doc.get('scale', 1.0)):.6f}"),
        ("mode", doc.get("mode", "")),
        ("pairs / edges", f"{problem.n_measurements} / {len(problem.edges)}"),
        ("identifiability", ident.verdict),
    ] + [(f"time {k} [s]", f"{v:.3f}") for k, v in (doc.get("timing_s") or {}).items()]
    frames = []
    for f in doc["frames"]:
        t = np.asarray(f["matrix"], dtype=float)[:3, 3]
        q = f.get("quaternion_xyzw", [])
        frames.append((f["name"], f["role"], f"{f.get('parent', '')} -> {f.get('child', '')}",
                       " ".join(f"{v:+.4f}" for v in t), " ".join(f"{v:+.5f}" for v in q)))
    rows = []
    for r in residuals:
        e = ident.edge(r.x, r.y)
        rows.append((
            r.x, r.y, r.n, "" if e is None else e.status.value,
            f"{1e3 * np.sqrt(np.mean(r.translation_m ** 2)):.2f}",
            f"{1e3 * r.translation_m.max():.2f}",
            f"{np.degrees(np.sqrt(np.mean(r.rotation_rad ** 2))):.3f}",
            f"{np.degrees(r.rotation_rad.max()):.3f}",
        ))
    excluded = list((doc.get("excluded_edges") or {}).items())
    parts = [
        "<!DOCTYPE html>",
        f"<html><head><meta charset='utf-8'><title>{html.escape(title)}</title>",
        "<style>body{font-family:sans-serif;margin:1.5em}table{border-collapse:collapse;"
        "margin:0.5em 0 1.5em}td,th{border:1px solid #bbb;padding:2px 8px;font-size:13px;"
        "text-align:left}th{background:#eee}img{max-width:100%}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        "<h2>Summary</h2>", _table(("item", "value"), summary),
        f"<p><img src='{html.escape(png_name)}' alt='calibration report figure'></p>",
        "<h2>Estimated frames</h2>",
        "<p>Cameras (Y) as T_&lt;camera carrier&gt;_cam, tags (X) as T_&lt;tag carrier&gt;_tag; "
        "translation [m], quaternion (x, y, z, w).</p>",
        _table(("name", "role", "published as", "translation [m]", "quaternion xyzw"), frames),
        "<h2>Residuals of A X = Y B per edge</h2>",
        _table(("tag (X)", "camera (Y)", "pairs", "identifiability", "t RMS [mm]",
                "t max [mm]", "r RMS [deg]", "r max [deg]"), rows),
        "<h2>Excluded edges</h2>",
        _table(("edge", "reason"), excluded) if excluded else "<p>none</p>",
        "</body></html>",
    ]
    return "\n".join(parts)


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
    """Write the report PNG and HTML page of one calibration.

    Parameters
    ----------
    doc : mapping
        The result YAML mapping (:func:`rwhec_ros.data.results.result_document`, the session's
        result YAML, or :func:`rwhec_ros.data.results.load_result`).
    problem : Problem
        The measurement pairs that were solved (residuals, identifiability).
    png_path, html_path : str or Path
        Output files; the page links the PNG by file name (keep them in one directory).
    identifiability : IdentifiabilityReport, optional
        Default: :func:`rwhec_ros.core.identifiability.analyze` of ``problem`` at the estimate.
    title : str
    dpi : int
        Resolution of the PNG (the figure is 18 x 26 inches).
    """
    png_path, html_path = Path(png_path), Path(html_path)
    X, Y, scale = estimates_from_document(doc, problem)
    residuals = edge_residuals(problem, X, Y, scale)
    if identifiability is None:
        from .core.identifiability import analyze

        identifiability = analyze(problem, solution=(X, Y, scale))
    _draw_png(png_path, doc, problem, residuals, identifiability, title, dpi)
    html_path.write_text(_html(doc, problem, residuals, identifiability, png_path.name, title),
                         encoding="utf-8")
    return ReportFiles(png_path, html_path)
