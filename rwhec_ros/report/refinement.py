"""The report's corner-level refinement part: which estimate is published, what the certificate
covers, and the corner reprojection RMS per camera of both estimates.

Read from the result YAML mapping's ``refinement`` section
(:meth:`rwhec_ros.session.refinement.CornerRefinement.to_dict`) and ``estimate_published`` /
``certificate_scope``; a result without a refinement (``solver.refine: false``, data without
corners, a result written before it existed) has no refinement part.
"""

from __future__ import annotations

import textwrap
from collections.abc import Mapping
from typing import Any

from .residuals import natural_key

__all__ = ["REFINEMENT_HEADING", "refinement_published", "scope_words", "refinement_text_lines",
           "refinement_section"]

#: The heading of the refinement section of the HTML page.
REFINEMENT_HEADING = "Corner-level refinement"

_MODEL_WORDS = {"pose_noise": "corners with the pose stream's noise",
                "plain": "plain reprojection error"}


def refinement_published(doc: Mapping[str, Any]) -> bool:
    """The published frames of ``doc`` are the corner-level refinement, not the certified
    pose-level estimate."""
    ref = doc.get("refinement") or {}
    return doc.get("estimate_published", ref.get("published")) == "refined"


def scope_words(doc: Mapping[str, Any]) -> str:
    """What the certificate covers, in words, when the published frames are the refinement
    (``""`` otherwise): appended to the certificate words of the PNG and the page."""
    if not refinement_published(doc):
        return ""
    return ("; it covers the pose-level optimum: the published frames are its corner-level "
            "refinement (a local estimate, not certified)")


def _cameras(ref: Mapping[str, Any]) -> list[tuple[str, Mapping[str, Any]]]:
    return sorted((ref.get("cameras") or {}).items(), key=lambda kv: natural_key(kv[0]))


def refinement_text_lines(doc: Mapping[str, Any], width: int = 40) -> list[str]:
    """For the PNG's summary: which estimate is published and the corner RMS per camera,
    certified -> refined, wrapped to ``width``; empty without a refinement."""
    ref = doc.get("refinement")
    if not ref:
        return []
    which = "refined" if refinement_published(doc) else "certified"
    lines = textwrap.wrap(f"corner-level refinement: the {which} estimate published",
                          width) + [""]
    cams = _cameras(ref)
    if cams:
        lines += ["corner RMS, certified -> refined:"] + textwrap.wrap(
            ", ".join(f"{cam}\u00a0{c['rms_px_certified']:.2f}\u00a0->\u00a0"
                      f"{c['rms_px_refined']:.2f}\u00a0px" for cam, c in cams),
            width, initial_indent="  ", subsequent_indent="  ") + [""]
    return lines


def refinement_section(doc: Mapping[str, Any]) -> tuple[str, str, tuple, list[tuple]] | None:
    """The HTML page's refinement section as ``(heading, paragraph, table header, rows)``, one
    row per camera; None without a refinement."""
    ref = doc.get("refinement")
    if not ref:
        return None
    which = "refined" if refinement_published(doc) else "certified"
    scope = doc.get("certificate_scope") or ref.get("certificate_scope", "")
    text = (f"Published: the {which} estimate ({ref.get('reason', '')}). Certificate: "
            f"{scope}.")
    if ref.get("model"):
        text += (f" Fit kept: {_MODEL_WORDS.get(ref['model'], ref['model'])}. The corners are "
                 "reprojected through each estimate (camera <- carrier <- pose stream <- target "
                 "carrier <- target) with the camera's intrinsics and distortion; the "
                 "verdict judges the data and the certified solve.")
    sigma = (ref.get("noise") or {}).get("sigma_px") or {}
    rows = [(cam, c.get("n_corners", ""), f"{c['rms_px_certified']:.2f}",
             f"{c['rms_px_refined']:.2f}",
             "" if cam not in sigma else f"{float(sigma[cam]):.2f}") for cam, c in _cameras(ref)]
    return (REFINEMENT_HEADING, text,
            ("camera", "corners", "RMS certified [px]", "RMS refined [px]",
             "corner noise estimated [px]"), rows)
