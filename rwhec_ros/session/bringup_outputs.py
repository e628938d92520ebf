"""What a bring-up check says and writes (:mod:`rwhec_ros.session.bringup`): the answer in words,
the ``/diagnostics`` rows, the ``check.yaml`` document and the output files.

The answer's first line is the check (``CHECK CONSISTENT``, ``CHECK MOVED``, ``CHECK NOT ENOUGH
DATA YET``), then the verdict of the final solve (``GOOD: ...``), then one line per camera
(``cam1: MOVED by 5.12 +- 0.25 mm and 0.41 +- 0.02 deg ...``), the targets, and how the test was
made. ``check.yaml`` has the keys of a result (``verdict``, ``certified``, ``frames`` with
``matrix``, ``parent``, ``child`` ...), the frames being the reference with the moved ones
replaced, so that it can be the next check's reference, and a ``check`` section with every
tested frame's change, statistic and decision.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..core.analysis.change import FrameChange
from ..core.lie import transform_to_quat_xyzw
from ..core.verdict.words import deg, mm
from ..data.results import FrameNaming, dump_document, plain
from ..messages import LEVEL_ERROR, LEVEL_OK, LEVEL_WARN
from .bringup import CheckReport
from .outputs import description_texts, static_transforms_launch

__all__ = ["HEADLINES", "frame_line", "check_message", "check_rows", "check_document",
           "check_transforms", "write_check_outputs", "CHECK_FILES"]

#: The first words of an answer, per status.
HEADLINES = {"consistent": "CHECK CONSISTENT", "moved": "CHECK MOVED",
             "undecided": "CHECK NOT ENOUGH DATA YET"}
#: The files a check writes into its directory.
CHECK_FILES = ("check.yaml", "static_transforms.launch.py", "calibration.urdf.xacro",
               "frames.yaml", "dataset.yaml")


def _pm(value: float, std: float, unit) -> str:
    if not np.isfinite(std):
        return unit(value)
    return f"{unit(value).split()[0]} +- {unit(std)}"


def _size(c: FrameChange) -> str:
    return (f"{_pm(c.translation_m, c.translation_std_m, mm)} and "
            f"{_pm(c.rotation_deg, c.rotation_std_deg, deg)}")


def frame_line(name: str, report: CheckReport) -> str:
    """One frame's answer in words (``name: consistent: changed by ...``)."""
    tol = report.options.tolerance
    tol_words = f"{mm(tol.translation_m)}, {deg(tol.rotation_deg)}"
    c = report.changes.get(name)
    if c is None:
        if name in report.unseen:
            return f"{name}: not enough data yet: no pairs of it in these data"
        return f"{name}: not tested"
    lo_t, hi_t = c.translation_bounds_m
    lo_r, hi_r = c.rotation_bounds_deg
    updated = " -> re-estimated" if name in report.updated else ""
    if c.decision == "moved":
        return (f"{name}: MOVED by {_size(c)} (at least {mm(lo_t)} or {deg(lo_r)}, beyond "
                f"the tolerance {tol_words}){updated}")
    if c.decision == "consistent":
        return (f"{name}: consistent: changed by {_size(c)} (at most {mm(hi_t)} and "
                f"{deg(hi_r)}, within {tol_words})")
    if c.dof == 0:
        return f"{name}: not enough data yet: the data do not determine it"
    return (f"{name}: not enough data yet: changed by {_size(c)} (between {mm(lo_t)} and "
            f"{mm(hi_t)}, {deg(lo_r)} and {deg(hi_r)}; tolerance {tol_words}): record more")


def check_message(report: CheckReport) -> str:
    """The whole answer, one item per line (module docstring)."""
    o = report.options
    head = HEADLINES[report.status]
    moved = report.moved
    if report.status == "moved":
        head += ": " + "; ".join(frame_line(n, report).split(" (")[0] for n in moved)
    elif report.status == "consistent":
        head += (f": every camera within {mm(o.tolerance.translation_m)} and "
                 f"{deg(o.tolerance.rotation_deg)} of the reference")
    else:
        waiting = [n for n in report.cameras if report.camera_decision(n) == "undecided"]
        head += ": " + ", ".join(waiting) + " undecided; record more"
    lines = [head]
    if report.verdict is not None:
        lines.append(report.verdict.headline())
    lines += [frame_line(n, report) for n in report.cameras]
    tags = [n for n, c in report.changes.items() if c.role == "X"]
    lines += ["target " + frame_line(n, report) for n in tags]
    if report.unreferenced:
        lines.append("not in the reference (estimated, not tested): "
                     + ", ".join(report.unreferenced))
    held = ("the targets hold the reference" if o.hold == "targets" else
            "nothing held: the pose stream defines the carriers")
    lines.append(
        f"test: {report.n_pairs} pairs against {report.reference.source}; {held}; noise "
        f"{'from the residuals per camera' if o.noise == 'data' else 'as stated'}; "
        f"false-alarm rate {o.false_alarm_rate:g} over the cameras (each decided at "
        f"{report.level:.2g}, look {report.look}"
        f"{', sequential' if o.sequential else ''})")
    if report.updated:
        lines.append(f"re-estimated: {', '.join(report.updated)}; certified for "
                     f"{report.certificate_for}" if report.result.certified else
                     f"re-estimated: {', '.join(report.updated)} (not certified: "
                     f"{report.result.certificate.status.value})")
    lines += [f"note: {n}" for n in report.notes]
    return "\n".join(lines)


_LEVELS = {"consistent": LEVEL_OK, "moved": LEVEL_ERROR, "undecided": LEVEL_WARN}


def check_rows(report: CheckReport | None, prefix: str, *, waiting: str = "") -> list[dict]:
    """``/diagnostics`` rows as :func:`rwhec_ros.messages.diagnostic_rows` makes them: one
    ``<prefix>: check`` row (the status), then one ``<prefix>: check <camera>`` row per camera
    (OK consistent, ERROR moved, WARN not enough data). Without a report: the summary row only,
    WARN, with ``waiting`` (why not)."""
    if report is None:
        return [{"name": f"{prefix}: check", "level": LEVEL_WARN,
                 "message": waiting or "no check yet (call ~/check)", "hardware_id": "",
                 "values": []}]
    level = _LEVELS[report.status]
    if report.verdict is not None and not report.verdict.usable:
        level = max(level, LEVEL_WARN)
    rows = [{"name": f"{prefix}: check", "level": level,
             "message": check_message(report).splitlines()[0], "hardware_id": "",
             "values": [("status", report.status), ("pairs", str(report.n_pairs)),
                        ("look", str(report.look)),
                        ("verdict", "" if report.verdict is None else report.verdict.level),
                        ("reference", report.reference.source)]}]
    for name in report.cameras:
        c = report.changes.get(name)
        values = [("decision", report.camera_decision(name))]
        if c is not None:
            values += [("translation_mm", f"{1e3 * c.translation_m:.4g}"),
                       ("translation_std_mm", f"{1e3 * c.translation_std_m:.4g}"),
                       ("rotation_deg", f"{c.rotation_deg:.4g}"),
                       ("rotation_std_deg", f"{c.rotation_std_deg:.4g}"),
                       ("p_value", f"{c.p_value:.3g}"), ("pairs", str(c.n_pairs))]
        rows.append({"name": f"{prefix}: check {name}",
                     "level": _LEVELS[report.camera_decision(name)],
                     "message": frame_line(name, report).split(": ", 1)[1],
                     "hardware_id": name, "values": values})
    return rows


def check_transforms(report: CheckReport, naming: FrameNaming
                     ) -> tuple[list[tuple[str, str, np.ndarray]], dict[str, str]]:
    """``(parent, child, T)`` of every output frame the naming knows (cameras first), and the
    re-estimated frames the verdict finds unusable (left out, with why)."""
    names = [n for n in naming.y_names if n in report.frames]
    names += [n for n in naming.x_names if n in report.frames]
    items = [(*naming.frames[n], report.frames[n]) for n in names]
    verdict = report.verdict
    if verdict is None:
        return items, {}
    keep, left_out = [], {}
    for name, item in zip(names, items, strict=True):
        fv = verdict.frames.get(name)
        if name in report.updated and fv is not None and not fv.usable:
            left_out[name] = "; ".join(fv.why) or fv.level
            continue
        keep.append(item)
    return keep, left_out


def _covariances(report: CheckReport) -> dict[str, Any]:
    """Covariance (a posteriori) of the re-estimated frames from the final solve."""
    if not report.updated or report.solved is None:
        return {}
    from ..core.analysis.uncertainty import frame_uncertainty

    try:
        unc = frame_uncertainty(report.solved_problem, report.solved)
    except (ValueError, ArithmeticError, np.linalg.LinAlgError):
        return {}
    return {f.name: f.to_dict() for f in unc.frames if f.name in report.updated}


def check_document(report: CheckReport, naming: FrameNaming, *,
                   source: dict[str, Any] | None = None, config: dict | None = None) -> dict:
    """The ``check.yaml`` mapping (module docstring)."""
    v = report.verdict
    res = report.result
    cov = _covariances(report)
    frames = []
    for role, names in (("Y", naming.y_names), ("X", naming.x_names)):
        for name in names:
            if name not in report.frames:
                continue
            T = report.frames[name]
            q, t = transform_to_quat_xyzw(T)
            parent, child = naming.frames[name]
            entry = {"name": name, "role": role, "matrix": T.tolist(), "translation": t.tolist(),
                     "quaternion_xyzw": q.tolist(), "parent": parent, "child": child,
                     "updated": name in report.updated,
                     "decision": report.camera_decision(name) if role == "Y" else
                     (report.changes[name].decision if name in report.changes else "not tested")}
            fv = None if v is None else v.frames.get(name)
            if name in report.updated:
                entry.update(cov.get(name, {}))
                if fv is not None:
                    entry.update(usable=fv.usable, verdict=fv.level, why=list(fv.why))
            else:
                C = report.reference.covariance.get(name)
                if C is not None:
                    entry["covariance"] = [[None if not np.isfinite(x) else float(x)
                                            for x in row] for row in C]
            frames.append(entry)
    doc = {
        "verdict": "unknown" if v is None else v.level,
        "reasons": [] if v is None else v.messages(),
        "certified": bool(res.certified),
        "status": res.certificate.status.value,
        "suboptimality_bound": float(res.certificate.suboptimality_bound),
        "scale": float(res.scale),
        "frames": frames,
        "check": {
            "status": report.status,
            "message": check_message(report),
            "reference": report.reference.source,
            "tolerance": {"translation_m": report.options.tolerance.translation_m,
                          "rotation_deg": report.options.tolerance.rotation_deg},
            "false_alarm_rate": report.options.false_alarm_rate,
            "level_per_camera": report.level, "look": report.look,
            "sequential": report.options.sequential, "hold": report.options.hold,
            "noise": report.options.noise, "pairs": report.n_pairs,
            "certificate_for": report.certificate_for,
            "cameras": {n: report.camera_decision(n) for n in report.cameras},
            "updated": list(report.updated), "unseen": list(report.unseen),
            "not_in_reference": list(report.unreferenced),
            "frames": {n: c.to_dict() for n, c in report.changes.items()},
            "variance_factors": {k: list(f) for k, f in report.variance_factors.items()},
            "notes": list(report.notes),
        },
        "verdict_details": None if v is None else v.to_dict(),
        "timing_s": {k: float(x) for k, x in res.timing_s.items()},
        "identifiability": None,  # the check's own per-frame tests are under ``check``
        "config": dict(config or {}),
        "source": dict(source or {}),
    }
    return plain(doc)


def write_check_outputs(out: Path, report: CheckReport, naming: FrameNaming, *,
                        force: bool = False, source: dict | None = None,
                        config: dict | None = None) -> dict[str, str]:
    """Write ``check.yaml`` and the reference frames with the moved ones replaced as a launch
    file, a URDF/xacro snippet and a frames YAML into ``out`` (:data:`CHECK_FILES` but the data
    set, which the caller saves). Existing files are refused (``FileExistsError``) unless
    ``force``. The set is staged whole (:class:`~rwhec_ros.data.atomic.StagedFiles`),
    ``check.yaml`` renamed last: an error or an interrupt leaves the earlier files as they were.
    Returns what -> path."""
    from ..data.atomic import StagedFiles

    out = Path(out)
    transforms, left_out = check_transforms(report, naming)
    head = check_message(report).splitlines()
    header = "\n".join(head[:2] + [f"re-estimated (others as in {report.reference.source}): "
                                   + (", ".join(report.updated) or "none")]
                       + ([f"left out (not usable): {left_out}"] if left_out else []))
    texts = {"check": ("check.yaml", dump_document(check_document(report, naming, source=source,
                                                                 config=config))),
             "launch": ("static_transforms.launch.py",
                        static_transforms_launch(transforms, header=header))}
    urdf, frames = description_texts(transforms, header)
    texts["urdf"] = ("calibration.urdf.xacro", urdf)
    texts["frames"] = ("frames.yaml", frames)
    targets = [out / name for name, _ in texts.values()]
    existing = [str(p) for p in targets if p.exists()]
    if existing and not force:
        raise FileExistsError(f"refusing to overwrite existing file(s) {existing} (use --force "
                              "to overwrite)")
    out.mkdir(parents=True, exist_ok=True)
    files = {}
    with StagedFiles() as staged:
        for key in ("launch", "urdf", "frames", "check"):  # check.yaml (complete) last
            name, text = texts[key]
            staged.stage(out / name, text)
            files[key] = str(out / name)
        staged.commit()
    return {k: files[k] for k in texts}
