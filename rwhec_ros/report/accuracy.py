"""The report's accuracy part: per-frame std bars, held-out vs in-sample residuals, the
reprojection error per camera, the guidance.

Everything is read from the result YAML mapping (keys of
:func:`rwhec_ros.data.results.result_document` with an accuracy: each frame's
``std_translation_m``/``std_rotation_deg``/``unobservable``/``a_posteriori``, and
``cross_validation``, ``reprojection``, ``guidance``); a result written before these keys
existed simply has no accuracy part (:func:`has_accuracy`).
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping
from typing import Any

import numpy as np

from .labels import label_points
from .refinement import refinement_section, refinement_text_lines
from .residuals import natural_key

__all__ = ["REPROJECTION_HEADING", "has_accuracy", "has_validation", "draw_std_bars",
           "draw_validation", "summary_text_lines", "accuracy_sections"]

#: The heading of the reprojection section (the page puts its bar chart under it).
REPROJECTION_HEADING = "Reprojection error per camera"
_AXES = ("x", "y", "z")
_AXIS_COLORS = ("tab:red", "tab:green", "tab:blue")


def has_accuracy(doc: Mapping[str, Any]) -> bool:
    """Some frame of ``doc`` has its per-axis stds."""
    return any("std_translation_m" in f for f in doc.get("frames") or [])


def has_validation(doc: Mapping[str, Any]) -> bool:
    """``doc`` holds a cross-validation with at least one held-out edge."""
    cv = doc.get("cross_validation") or {}
    return any(e.get("held_out") for e in cv.get("edges") or [])


def _frames(doc: Mapping[str, Any]) -> list[Mapping[str, Any]]:
    """Frames with stds, cameras first, natural order."""
    return sorted((f for f in doc.get("frames") or [] if "std_translation_m" in f),
                  key=lambda f: (f["role"] != "Y", natural_key(f["name"])))


def _values(seq) -> np.ndarray:
    return np.array([np.nan if v is None else float(v) for v in seq], dtype=float)


def draw_std_bars(ax, doc: Mapping[str, Any], what: str) -> None:
    """Horizontal bars per frame (rows) and axis (colours x, y, z of the parent) of the
    predicted std of the ``what`` (``"translation"`` [mm] or ``"rotation"`` [deg]); a black tick
    marks the a-posteriori std, ``unobservable`` is written where an axis is not determined."""
    frames = _frames(doc)
    key, scale, unit = (("std_translation_m", 1e3, "mm") if what == "translation" else
                        ("std_rotation_deg", 1.0, "deg"))
    n = len(frames)
    h = 0.26
    pred = scale * np.array([_values(f[key]) for f in frames]).reshape(n, 3)
    post = scale * np.array([_values((f.get("a_posteriori") or {}).get(key, [None] * 3))
                             for f in frames]).reshape(n, 3)
    post[~np.isfinite(pred)] = np.nan  # a tick only on a bar
    y = np.arange(n)[:, None] + (np.arange(3)[None, :] - 1) * h  # rows: frames, columns: axes
    for a in range(3):  # one bar container per axis colour
        bar = np.isfinite(pred[:, a])
        if bar.any():
            ax.barh(y[bar, a], pred[bar, a], height=h, color=_AXIS_COLORS[a])
    tick = np.isfinite(post)
    if tick.any():  # the a-posteriori ticks as one line, NaN between the ticks
        xs = np.repeat(post[tick], 3)
        ys = np.stack([y[tick] - h / 2, y[tick] + h / 2, np.full(tick.sum(), np.nan)], axis=1)
        xs[2::3] = np.nan
        ax.plot(xs, ys.ravel(), color="black", lw=1.5)
    finite_max = float(np.max(np.concatenate([pred[np.isfinite(pred)], post[tick]]),
                              initial=0.0))
    xmax = 1.4 * finite_max if finite_max > 0 else 1.0  # the right part: the legend
    for i, f in enumerate(frames):
        pred = _values(f[key])
        for a in range(3):
            if not np.isfinite(pred[a]):
                ax.text(0.01 * xmax, i + (a - 1) * h, f"{_AXES[a]}: unobservable", va="center",
                        ha="left", fontsize=8, color="#b71c1c", fontweight="bold")
    ax.set_xlim(0, xmax)
    ax.set_ylim(n - 0.5, -0.5)
    ax.set_yticks(np.arange(n))
    ax.set_yticklabels([f["name"] for f in frames], fontsize=8)
    ax.set_xlabel(f"{what} std [{unit}] per axis of the frame's parent", fontsize=9)
    ax.tick_params(axis="x", labelsize=8)
    ax.grid(axis="x", color="0.85", lw=0.6)
    ax.set_axisbelow(True)
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles = [Patch(color=_AXIS_COLORS[a], label=f"{_AXES[a]} axis") for a in range(3)]
    handles.append(Line2D([], [], color="black", lw=1.5, label="a posteriori"))
    ax.legend(handles=handles, fontsize=8, loc="upper right", framealpha=0.9)
    ax.set_title(f"{what} uncertainty per frame: bars predicted from the weights' noise "
                 "(1 sigma), ticks a posteriori", fontsize=11)


def draw_validation(ax, doc: Mapping[str, Any], what: str, label: int = 4) -> None:
    """Per edge, the held-out RMS residual against the in-sample one (``what``:
    ``"translation"`` [mm] or ``"rotation"`` [deg]) with the line held-out = in-sample; the
    ``label`` edges with the largest held-out residual are named, and (up to 4 more) those
    held out at more than 1.5 times their in-sample residual; the names never overlap each
    other or a point (:func:`~rwhec_ros.report.labels.label_points`)."""
    cv = doc.get("cross_validation") or {}
    key, unit = (("rms_translation_mm", "mm") if what == "translation" else
                 ("rms_rotation_deg", "deg"))
    edges = [e for e in cv.get("edges") or [] if e.get("held_out")]
    x = np.array([float(e["in_sample"][key]) for e in edges])
    y = np.array([float(e["held_out"][key]) for e in edges])
    ax.scatter(x, y, s=18, color="tab:blue", alpha=0.8, zorder=3)
    hi = 1.08 * max(float(np.max(x, initial=0.0)), float(np.max(y, initial=0.0)), 1e-9)
    ax.plot([0, hi], [0, hi], color="0.5", lw=1, ls="--", label="held-out = in-sample")
    ax.set_xlim(0, hi)
    ax.set_ylim(0, hi)
    worst = [int(i) for i in np.argsort(-y)[:label]]
    ratio = np.where(x > 0, y / np.where(x > 0, x, 1.0), np.inf)
    worst += [int(i) for i in np.argsort(-ratio) if ratio[i] > 1.5 and i not in worst][:4]
    label_points(ax, x[worst], y[worst], [f"{edges[i]['x']} / {edges[i]['y']}" for i in worst],
                 others=(x, y))
    ax.set_xlabel(f"in-sample RMS {what} residual [{unit}]", fontsize=9)
    ax.set_ylabel(f"held-out RMS [{unit}]", fontsize=9)
    ax.tick_params(labelsize=8)
    ax.legend(fontsize=8, loc="upper left")
    total = cv.get("held_out") or {}
    ins = cv.get("in_sample") or {}
    ax.set_title(f"{cv.get('folds', '?')}-fold cross-validation, {what} per edge (all: held-out "
                 f"{float(total.get(key, np.nan)):.3g} {unit}, in-sample "
                 f"{float(ins.get(key, np.nan)):.3g} {unit})", fontsize=11)


def _px(value) -> str:
    return f"{value:.2f}" if isinstance(value, (int, float)) and np.isfinite(value) else "-"


def _focal_words(r: Mapping[str, Any]) -> str:
    """``x0.953 +-0.001`` (``-`` when not determined or not computed)."""
    s, std = r.get("focal_scale"), r.get("focal_scale_std")
    if not (isinstance(s, (int, float)) and np.isfinite(s)):
        return "-"
    return f"x{s:.3f} +-{std:.3f}"


def summary_text_lines(doc: Mapping[str, Any], width: int = 40) -> list[str]:
    """The reprojection RMS per camera, the corner-level refinement (which estimate is
    published, the corner RMS of both) and the next motion (or why none is needed), wrapped to
    ``width``; empty without them."""
    lines = []
    rep = doc.get("reprojection")
    if rep:
        lines += ["reprojection RMS per camera:"] + textwrap.wrap(
            # no-break spaces: a camera, its RMS and "px" stay on one line
            ", ".join(f"{cam}\u00a0{r['rms_px']:.2f}\u00a0px" for cam, r in
                      sorted(rep.items(), key=lambda kv: natural_key(kv[0]))),
            width, initial_indent="  ", subsequent_indent="  ") + [""]
    lines += refinement_text_lines(doc, width)
    g = doc.get("guidance")
    if g:
        lines += ["next motion:"] + textwrap.wrap(str(g.get("message", "")), width,
                                                  initial_indent="  ", subsequent_indent="  ")
    return lines


def _std_text(values, scale: float, unit: str, digits: int) -> str:
    return " / ".join("unobservable" if v is None else f"{scale * float(v):.{digits}f}"
                      for v in values) + f" {unit}"


def _motion_words(c: Mapping[str, Any]) -> str:
    """``rotate about x by +-30 deg``, ``translate along y by +-0.2 m`` (``, new view`` when the
    camera has not seen the tag yet) for a guidance candidate's mapping."""
    amount = float(c.get("amount", float("nan")))
    how = (f"rotate about {c.get('axis')} by +-{amount:.0f} deg" if c.get("kind") == "rotate"
           else f"translate along {c.get('axis')} by +-{amount:.2g} m")
    return how + (", new view" if c.get("new_edge") else "")


def accuracy_sections(doc: Mapping[str, Any]) -> list[tuple[str, str, tuple, list[tuple]]]:
    """The HTML page's accuracy sections as ``(heading, paragraph, table header, rows)``: the
    per-frame stds (predicted and a posteriori), the cross-validation per edge, the reprojection
    per camera, the corner-level refinement (:mod:`.refinement`), the guidance."""
    out = []
    if has_accuracy(doc):
        rows = []
        for f in _frames(doc):
            post = f.get("a_posteriori") or {}
            rows.append((f["name"], _std_text(f["std_translation_m"], 1e3, "mm", 2),
                         _std_text(f["std_rotation_deg"], 1.0, "deg", 3),
                         _std_text(post.get("std_translation_m", [None] * 3), 1e3, "mm", 2),
                         _std_text(post.get("std_rotation_deg", [None] * 3), 1.0, "deg", 3)))
        unc = doc.get("uncertainty") or {}
        vf = unc.get("variance_factor")
        vf = "undefined" if vf is None else f"{vf:.3g}"
        text = ("One standard deviation along / about the x / y / z axes of each frame's "
                "parent. Predicted: from the noise of the weights (estimated or stated); a "
                "posteriori: times "
                f"the variance factor of the residuals ({vf}). 'unobservable': the data do not "
                "determine that axis (give a prior or add motion).")
        if unc.get("scale_std") is not None:
            text += f" Scale: +-{float(unc['scale_std']):.2g} (predicted)."
        out.append(("Uncertainty per frame", text,
                    ("frame", "translation std (predicted)", "rotation std (predicted)",
                     "translation std (a posteriori)", "rotation std (a posteriori)"), rows))
    cv = doc.get("cross_validation")
    if cv:
        rows = []
        for e in sorted(cv.get("edges") or [], key=lambda e: natural_key(f"{e['x']} {e['y']}")):
            held = e.get("held_out")
            ins = e["in_sample"]
            rows.append((e["x"], e["y"], e["n_pairs"], f"{ins['rms_translation_mm']:.2f}",
                         "" if not held else f"{held['rms_translation_mm']:.2f}",
                         f"{ins['rms_rotation_deg']:.3f}",
                         "" if not held else f"{held['rms_rotation_deg']:.3f}",
                         e.get("note", "")))
        out.append((f"Cross-validation ({cv.get('folds')} folds)",
                    "Each edge's pairs are split into folds; each fold is solved without its "
                    "pairs and scored on them (held-out), next to the residuals of the solution "
                    "on all pairs (in-sample). Held-out much larger than in-sample: the "
                    "calibration does not predict new data (outliers, time offsets, a flexing "
                    "rig, too few motions).",
                    ("tag (X)", "camera (Y)", "pairs", "in-sample RMS [mm]", "held-out RMS [mm]",
                     "in-sample RMS [deg]", "held-out RMS [deg]", "note"), rows))
    rep = doc.get("reprojection")
    if rep:
        rows = [(cam, r["n_pairs"], f"{r['rms_px']:.2f}", f"{r['median_px']:.2f}",
                 f"{r['max_px']:.1f}", r.get("n_behind", 0), _px(r.get("image_fit_rms_px")),
                 _focal_words(r)) for cam, r in
                sorted(rep.items(), key=lambda kv: natural_key(kv[0]))]
        out.append((REPROJECTION_HEADING,
                    "The detected corners (tags, boards) against the target placed by the "
                    "calibrated chain (camera <- carrier <- pose stream <- target carrier <- "
                    "target) and projected "
                    "with the camera's intrinsics, in pixels: the residual of the whole "
                    "calibration, to compare with the detector's noise (a few tenths of a "
                    "pixel for sharp tags). Per image: the same corners through each image's "
                    "own best pose; focal length: the factor on the configured focal length "
                    "that the corners fit best (1: as configured; the verdict's focal check).",
                    ("camera", "pairs", "RMS [px]", "median [px]", "max [px]",
                     "pairs behind the camera", "per image [px]", "focal length fits"), rows))
    ref = refinement_section(doc)
    if ref is not None:
        out.append(ref)
    g = doc.get("guidance")
    if g:
        rows = [(c.get("x"), c.get("y"), _motion_words(c), c.get("worst", ""))
                for c in g.get("candidates") or []]
        out.append(("Next motion", str(g.get("message", "")),
                    ("tag", "camera", "motion", "largest std predicted after it"), rows))
    return out
