"""The report's HTML page: self-contained (the figure embedded), words rather than Python values,
the summary once."""

from __future__ import annotations

import base64
import html
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..core.problem import Problem
from ..core.verdict import FitStatistics
from .accuracy import REPROJECTION_HEADING, accuracy_sections
from .residuals import EdgeResiduals, natural_key
from .words import BANNER_COLORS, certificate_words

__all__ = ["certificate_words", "render_page"]

_EDGE_WORDS = {"identifiable": "identifiable on its own", "weak": "weakly identifiable",
               "insufficient": "not on its own"}


def _table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> str:
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row) + "</tr>" for row in rows
    )
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def _banner(doc: Mapping[str, Any]) -> str:
    level = str(doc.get("verdict", "unknown"))
    fg, bg = BANNER_COLORS.get(level, BANNER_COLORS["unknown"])
    head = {"good": "GOOD: use this calibration", "caution": "CAUTION: usable, read the reasons",
            "unusable": "UNUSABLE: do not use this calibration"}.get(
        level, "VERDICT UNKNOWN: this result was written without a verdict; solve its data "
               "set again (rwhec-calibrate dataset) to get one")
    reasons = "".join(f"<li>{html.escape(r)}</li>" for r in doc.get("reasons") or [])
    summary = ((doc.get("verdict_details") or {}).get("summary") or "")
    extra = f"<p>{html.escape(summary)}</p>" if summary else ""
    return (f"<div class='banner' style='color:{fg};background:{bg};border-color:{fg}'>"
            f"<div class='head'>{html.escape(head)}</div>"
            + (f"<ul>{reasons}</ul>" if reasons else "") + extra + "</div>")


def _yes_no(value: Any) -> str:
    return "yes" if value else "no"


def _summary_rows(doc, problem: Problem, fit: FitStatistics, ident) -> list[tuple[str, str]]:
    rows = [
        ("certificate", certificate_words(doc)),
        ("scale", f"unknown, estimated alpha = {float(doc.get('scale', 1.0)):.5f}"
         if problem.unknown_scale else "known (alpha = 1)"),
        ("data", f"{problem.n_measurements} pairs on {len(problem.edges)} edges; "
                 f"{problem.P} cameras, {problem.M} tags"),
        ("solver", f"mode {doc.get('mode', '?')}, "
                   f"{(doc.get('timing_s') or {}).get('total', float('nan')):.2f} s"),
        ("identifiability", str(getattr(ident, "verdict", "not analysed"))),
    ]
    if fit.testable:
        rows.append(("fit to the stated noise",
                     f"translations {fit.noise_ratio_translation:.2f}x (sigma "
                     f"{1e3 * fit.sigma_estimated_m:.2f} mm, stated "
                     f"{1e3 * fit.sigma_stated_m:.2f} mm), rotations "
                     f"{fit.noise_ratio_rotation:.2f}x (kappa {fit.kappa_estimated:.3g}, "
                     f"stated {fit.kappa_stated:.3g})"))
    sc = (doc.get("verdict_details") or {}).get("scale_check")
    if sc:
        rows.append(("scale check", f"with a free scale alpha = {sc['alpha']:.4f} +- "
                                    f"{sc['std']:.4f} (1 if tag sizes, focal lengths and pose "
                                    "units agree)"))
    return rows


def _frame_rows(doc: Mapping[str, Any]) -> list[tuple]:
    details = ((doc.get("verdict_details") or {}).get("frames") or {})
    rows = []
    frames = sorted(doc["frames"], key=lambda f: (f["role"] != "Y", natural_key(f["name"])))
    for f in frames:
        d = details.get(f["name"], {})
        usable = f.get("usable")
        use = "unknown" if usable is None else (
            "yes" if usable else "no: " + "; ".join(f.get("why") or []))
        if usable and f.get("why"):
            use += " (caution: " + "; ".join(f["why"]) + ")"
        t = np.asarray(f["matrix"], dtype=float)[:3, 3]
        q = f.get("quaternion_xyzw", [])
        std_t, std_r = d.get("std_translation_m"), d.get("std_rotation_deg")
        prec = (f"+-{1e3 * std_t:.1f} mm, +-{std_r:.2f} deg" if std_t is not None
                and np.isfinite(std_t) else "unknown")
        shown = usable is None or usable
        rows.append((f["name"], "camera" if f["role"] == "Y" else "tag",
                     f"{f.get('parent', '')} -> {f.get('child', '')}", use,
                     " ".join(f"{v:+.4f}" for v in t) if shown else "not calibrated",
                     " ".join(f"{v:+.5f}" for v in q) if shown else "",
                     prec if shown else ""))
    for name, d in details.items():  # asked for, but no estimate at all
        if not d.get("calibrated", True):
            rows.append((name, "", "", "no: " + "; ".join(d.get("why") or []),
                         "not calibrated", "", ""))
    return rows


def _img(png: Path, alt: str) -> str:
    data = base64.b64encode(Path(png).read_bytes()).decode("ascii")
    return f"<p><img src='data:image/png;base64,{data}' alt='{html.escape(alt)}'></p>"


def render_page(doc: Mapping[str, Any], problem: Problem, residuals: list[EdgeResiduals],
                fit: FitStatistics, ident, png: Path, title: str,
                sections: Mapping[str, Path] | None = None) -> str:
    """The HTML page, with the figure ``png`` and the section figures ``sections`` (``"edges"``,
    ``"reprojection"``: :func:`~rwhec_ros.report.images.render_report`) embedded
    (base64)."""
    sections = sections or {}
    by_edge = {(e.x, e.y): e for e in fit.edges}
    rows = []
    for r in residuals:
        e = ident.edge(r.x, r.y) if ident is not None else None
        ef = by_edge.get((r.x, r.y))
        ratio = "" if ef is None or not np.isfinite(ef.ratio) else f"{ef.ratio:.1f}x"
        rows.append((
            r.x, r.y, r.n,
            "" if e is None else _EDGE_WORDS.get(e.status.value, e.status.value),
            f"{1e3 * np.sqrt(np.mean(r.translation_m ** 2)):.2f}",
            f"{1e3 * r.translation_m.max():.2f}",
            f"{np.degrees(np.sqrt(np.mean(r.rotation_rad ** 2))):.3f}",
            f"{np.degrees(r.rotation_rad.max()):.3f}",
            ratio, "OUTLIER" if ef is not None and ef.flagged else "",
        ))
    excluded = sorted((doc.get("excluded_edges") or {}).items(), key=lambda kv: natural_key(kv[0]))
    notes = [html.escape(n) for n in doc.get("notes") or []]
    parts = [
        "<!DOCTYPE html>",
        f"<html><head><meta charset='utf-8'><title>{html.escape(title)}</title>",
        "<style>body{font-family:sans-serif;margin:1.5em;max-width:1500px}"
        "table{border-collapse:collapse;margin:0.5em 0 1.5em}td,th{border:1px solid #bbb;"
        "padding:2px 8px;font-size:13px;text-align:left}th{background:#eee}img{max-width:100%}"
        ".banner{border:3px solid;border-radius:6px;padding:0.6em 1em;margin:1em 0}"
        ".banner .head{font-size:1.5em;font-weight:bold}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        _banner(doc),
        "<h2>Summary</h2>",
        _table(("item", "value"), _summary_rows(doc, problem, fit, ident)),
        "<h2>Estimated frames</h2>",
        "<p>Cameras as T_&lt;camera carrier&gt;_cam, tags as T_&lt;tag carrier&gt;_tag; "
        "translation in metres, rotation as a quaternion (x, y, z, w); precision: predicted "
        "standard deviation, worst direction. A frame that is not usable is never given as a "
        "number and is left off /tf_static.</p>",
        _table(("frame", "kind", "published as", "usable", "translation [m]",
                "quaternion (x, y, z, w)", "precision"), _frame_rows(doc)),
        _img(png, "identifiability and fit per edge, frames in 3D, residual histograms"),
        "<h2>Residuals of A X = Y B per edge</h2>",
        *([_img(sections["edges"], "residuals per edge, the worst edges first"),
           "<p>Above: the residuals of each pair of the worst edges (ranked by their noise over "
           "that of the median edge), one box per edge, and of all pairs together.</p>"]
          if "edges" in sections else []),
        "<p>Below: every edge, tags in natural order. 'vs. median edge': the edge's noise over "
        "that of the median edge (the larger of translation and rotation).</p>",
        _table(("tag (X)", "camera (Y)", "pairs", "identifiability", "translation RMS [mm]",
                "translation max [mm]", "rotation RMS [deg]", "rotation max [deg]",
                "vs. median edge", "outlier"), rows),
        *_accuracy_html(doc, sections),
        "<h2>Edges left out</h2>",
        _table(("edge", "reason"), excluded) if excluded else "<p>none</p>",
    ]
    if notes:
        parts += ["<h2>Notes</h2>", "<ul>" + "".join(f"<li>{n}</li>" for n in notes) + "</ul>"]
    parts.append("</body></html>")
    return "\n".join(parts)


def _accuracy_html(doc: Mapping[str, Any], sections: Mapping[str, Path]) -> list[str]:
    """The uncertainty, cross-validation, reprojection (with its bar chart) and guidance
    sections (:mod:`.accuracy`)."""
    parts = []
    for heading, text, header, rows in accuracy_sections(doc):
        parts += [f"<h2>{html.escape(heading)}</h2>", f"<p>{html.escape(text)}</p>"]
        if heading == REPROJECTION_HEADING and "reprojection" in sections:
            parts.append(_img(sections["reprojection"], "reprojection error per camera"))
        if rows:
            parts.append(_table(header, rows))
    return parts
