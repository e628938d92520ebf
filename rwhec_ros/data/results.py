"""Calibration outputs: frame naming, the result YAML, output paths, writing and reading back.

One module for every entry point: the live session (:class:`rwhec_ros.session.CalibrationSession`)
writes into a new timestamped directory (``result.yaml``, ``static_transforms.launch.py``,
``dataset.yaml``), and the offline CLI, which solves a :class:`~rwhec_ros.core.problem.Problem`
read from files (the paper's CSV layout, a saved data set), writes the same files with the same
keys into such a directory or the one named by ``-o``. Nothing here knows a ROS message.

* :class:`FrameNaming` says under which ``(parent, child)`` each estimated frame is published
  (from a :class:`~rwhec_ros.config.CalibratorConfig` or from two carrier frame names).
* :func:`result_document` is the result YAML mapping (``certified``, ``suboptimality_bound``,
  ``scale``, ``frames`` with ``parent``/``child``, ``timing_s``, ``identifiability``,
  ``excluded_edges``, ``config``, ...).
* :class:`OutputPaths` / :func:`session_output_paths` name the files of one output directory
  (:func:`output_paths`: the older layout beside an explicit ``OUT.yaml``, still read by
  ``rwhec-calibrate report``); :func:`new_output_dir` makes a new timestamped directory like the
  session's; :func:`write_outputs` writes them, refusing to overwrite unless ``force``.
* :func:`load_result` reads a result YAML back (for ``rwhec-calibrate report``).
"""

from __future__ import annotations

import datetime as _dt
import enum
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ..core.result import CalibrationResult
from ..errors import describe_os_error, describe_yaml_error
from .atomic import StagedFiles

__all__ = [
    "FrameNaming",
    "result_document",
    "OutputPaths",
    "output_paths",
    "session_output_paths",
    "new_output_dir",
    "utc_stamp",
    "write_outputs",
    "solved_pairs",
    "load_result",
    "incomplete_result",
    "dump_document",
    "plain",
    "describe_os_error",
    "RESULT_KEYS",
]

#: libyaml's emitter and parser where PyYAML has them (about 4x faster than the pure-Python ones
#: on a result of a few thousand lines; the same YAML).
_Dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
_Loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def dump_document(doc: Mapping[str, Any]) -> str:
    """``doc`` (plain Python types) as YAML text, keys in their order: what
    ``yaml.safe_dump(doc, sort_keys=False)`` writes, with libyaml's emitter where available."""
    return yaml.dump(doc, Dumper=_Dumper, sort_keys=False)


#: Keys every result YAML has (the verdict first, the acceptance keys, identifiability and
#: configuration).
RESULT_KEYS = ("verdict", "reasons", "certified", "suboptimality_bound", "scale", "frames",
               "timing_s", "identifiability", "config")


@dataclass(frozen=True)
class FrameNaming:
    """Where each estimated frame is published: variable name -> ``(parent, child)``.

    It offers the three members of :class:`~rwhec_ros.config.CalibratorConfig` that the session's
    summary and outputs use (``x_names``, ``y_names``, :meth:`published_frames`).

    Attributes
    ----------
    x_names, y_names : tuple of str
        X frames (tags) and Y frames (cameras).
    frames : dict of str to (str, str)
        ``name -> (parent, child)``: cameras ``(camera carrier, <name><suffix>)``, tags
        ``(tag carrier, <name><suffix>)`` unless configured otherwise.
    """

    x_names: tuple[str, ...]
    y_names: tuple[str, ...]
    frames: dict[str, tuple[str, str]]

    def published_frames(self) -> dict[str, tuple[str, str]]:
        return dict(self.frames)

    @staticmethod
    def from_carriers(
        x_names: Sequence[str],
        y_names: Sequence[str],
        *,
        camera_carrier: str,
        tag_carrier: str,
        suffix: str = "_calibrated",
        carriers: Mapping[str, str] | None = None,
    ) -> FrameNaming:
        """Cameras (Y) published under ``camera_carrier``, tags (X) under ``tag_carrier``, child
        frame ``<name><suffix>``; ``carriers`` (frame -> carrier, e.g.
        :attr:`rwhec_ros.data.dataset.Dataset.carriers`) overrides the parent per frame."""
        carriers = dict(carriers or {})
        frames = {}
        for names, default in ((y_names, camera_carrier), (x_names, tag_carrier)):
            for n in names:
                frames[n] = (carriers.get(n, default), n + suffix)
        return FrameNaming(tuple(x_names), tuple(y_names), frames)

    @staticmethod
    def from_config(config) -> FrameNaming:
        """The naming of a :class:`~rwhec_ros.config.CalibratorConfig`."""
        return FrameNaming(tuple(config.x_names), tuple(config.y_names),
                           dict(config.published_frames()))

    def transforms(self, result: CalibrationResult) -> list[tuple[str, str, np.ndarray]]:
        """``(parent, child, T_parent_child)`` of every estimated frame, cameras first (the order
        of :meth:`~rwhec_ros.session.CalibrationSession.published_transforms`)."""
        out = []
        for names, Ts in ((result.y_names, result.Y), (result.x_names, result.X)):
            for name, T in zip(names, Ts, strict=True):
                parent, child = self.frames.get(name, ("", name))
                out.append((parent, child, np.asarray(T, dtype=float)))
        return out


def plain(obj: Any) -> Any:
    """Plain YAML-safe Python of nested dicts/lists/tuples/numpy values/enums."""
    if isinstance(obj, Mapping):
        return {str(k): plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return plain(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, enum.Enum):
        return obj.value
    return obj


def result_document(
    result: CalibrationResult,
    naming: FrameNaming,
    *,
    excluded: Mapping[str, str] | None = None,
    identifiability: Mapping[str, Any] | None = None,
    config: Mapping[str, Any] | None = None,
    source: Mapping[str, Any] | None = None,
    verdict=None,
    accuracy=None,
    rejected_pairs: Mapping[str, Sequence[int]] | None = None,
    fingerprint: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """The result YAML mapping, with the keys of the session's
    :meth:`~rwhec_ros.session.CalibrationSession.result_document`.

    First the ``verdict`` (``good``, ``caution`` or ``unusable``; ``unknown`` without one) and
    its ``reasons`` (sentences, worst first), then ``CalibrationResult.to_dict()``
    (``certified``, ``suboptimality_bound``, ``scale``, ``mode``,
    ``frames`` (name, role, matrix, translation, quaternion_xyzw), ``timing_s``, certificate
    details), each frame's published ``parent``/``child``, ``excluded_edges`` (``"(x, y)"`` ->
    reason), ``rejected_pairs`` (outlier rejection: ``"(x, y)"`` -> indices of the edge's pairs
    in the data set that the solve left out; empty without), ``identifiability``
    (``IdentifiabilityReport.to_dict()``), ``config`` (flat dotted calibrator parameters, as
    far as they apply) and ``source`` (where the data came from).
    With a :class:`~rwhec_ros.core.verdict.Verdict`, each frame also says whether it is
    ``usable`` (and its ``verdict`` and ``why``), and ``verdict_details`` holds the fit
    statistics, the scale check and the per-frame verdicts.

    With an :class:`~rwhec_ros.session.accuracy.Accuracy`, each frame also has its uncertainty
    (:meth:`~rwhec_ros.session.accuracy.Accuracy.frame_fields`: ``std_kind``, predicted
    ``std_translation_m`` [x, y, z] and ``std_rotation_deg`` [x, y, z] about the parent's axes,
    the 6x6 ``covariance`` of ``[dt (m), phi (rad)]``, the same under ``a_posteriori``, the
    ``unobservable`` axes, whose entries are ``null``), and the document has ``uncertainty``
    (convention, variance factor, ``scale_std``), ``cross_validation`` (per edge held-out and
    in-sample residuals in mm and deg) and ``guidance`` (the next motion), each ``null`` when not
    computed, with ``accuracy_notes`` saying why.

    ``fingerprint`` (:func:`rwhec_ros.data.fingerprint.dataset_fingerprint` of the data set
    written beside the result) is stored as ``dataset_fingerprint``: ``report`` and ``dataset``
    refuse a result beside another data set.
    """
    doc = {"verdict": "unknown" if verdict is None else verdict.level,
           "reasons": [] if verdict is None else verdict.messages()}
    doc.update(result.to_dict())
    frames = naming.published_frames()
    for f in doc["frames"]:
        f["parent"], f["child"] = frames.get(f["name"], ("", f["name"]))
        fv = None if verdict is None else verdict.frames.get(f["name"])
        if fv is not None:
            f["usable"], f["verdict"], f["why"] = fv.usable, fv.level, list(fv.why)
        if accuracy is not None:
            f.update(accuracy.frame_fields(f["name"]))
    doc["excluded_edges"] = dict(excluded or {})
    doc["rejected_pairs"] = {k: [int(i) for i in v] for k, v in (rejected_pairs or {}).items()}
    doc["identifiability"] = None if identifiability is None else dict(identifiability)
    doc["config"] = dict(config or {})
    doc["source"] = dict(source or {})
    if fingerprint is not None:
        doc["dataset_fingerprint"] = dict(fingerprint)
    if verdict is not None:
        doc["verdict_details"] = verdict.to_dict()
    if accuracy is not None:
        doc.update(accuracy.to_dict())
    return plain(doc)


@dataclass(frozen=True)
class OutputPaths:
    """The files of one calibration run (all in one directory)."""

    result: Path
    launch: Path
    dataset: Path
    report_png: Path
    report_html: Path
    urdf: Path
    frames: Path

    def all(self) -> tuple[Path, ...]:
        return (self.result, self.launch, self.dataset, self.report_png, self.report_html,
                self.urdf, self.frames)


def output_paths(result_path: str | Path) -> OutputPaths:
    """Files beside an explicit result path ``OUT.yaml``: ``OUT.launch.py``,
    ``OUT.dataset.yaml``, ``OUT.report.png``, ``OUT.report.html``, ``OUT.urdf.xacro`` and
    ``OUT.frames.yaml`` (same stem)."""
    p = Path(result_path)
    stem = p.with_suffix("") if p.suffix in (".yaml", ".yml") else p
    base = stem.name
    return OutputPaths(
        result=p,
        launch=p.with_name(base + ".launch.py"),
        dataset=p.with_name(base + ".dataset.yaml"),
        report_png=p.with_name(base + ".report.png"),
        report_html=p.with_name(base + ".report.html"),
        urdf=p.with_name(base + ".urdf.xacro"),
        frames=p.with_name(base + ".frames.yaml"),
    )


def session_output_paths(directory: str | Path) -> OutputPaths:
    """The files of a session output directory (``result.yaml``,
    ``static_transforms.launch.py``, ``calibration.urdf.xacro``, ``frames.yaml``,
    ``dataset.yaml``) plus ``report.png``/``report.html``."""
    d = Path(directory)
    return OutputPaths(d / "result.yaml", d / "static_transforms.launch.py", d / "dataset.yaml",
                       d / "report.png", d / "report.html", d / "calibration.urdf.xacro",
                       d / "frames.yaml")


def utc_stamp(now: _dt.datetime | None = None) -> str:
    """``now`` (default: the current time) as the UTC stamp of output directory names,
    e.g. ``20261121T061241_560269Z``."""
    now = now if now is not None else _dt.datetime.now(_dt.timezone.utc)
    return now.astimezone(_dt.timezone.utc).strftime("%Y%m%dT%H%M%S_%fZ")


def new_output_dir(root: str | Path, kind: str = "calibration",
                   now: _dt.datetime | None = None) -> Path:
    """A new directory ``<root>/<kind>_<UTC stamp>[_n]`` (never reused), named like the
    session's output directories."""
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    base = f"{kind}_{utc_stamp(now)}"
    for i in range(1000):
        path = root / (base if i == 0 else f"{base}_{i}")
        try:
            path.mkdir()
        except FileExistsError:
            continue
        return path
    raise OSError(f"{root}: could not create a new directory for {base!r}")


def write_outputs(
    paths: OutputPaths,
    *,
    result_yaml: str,
    launch_text: str,
    dataset=None,
    force: bool = False,
    urdf_text: str | None = None,
    frames_text: str | None = None,
) -> dict[str, str]:
    """Write the result YAML, the launch file and (optionally) the data set, the URDF/xacro
    snippet and the frames YAML (:mod:`rwhec_ros.data.export`).

    Nothing is written when any target exists and ``force`` is False: ``FileExistsError``
    naming the existing files. Returns ``{"result", "launch"[, "urdf"][, "frames"][,
    "dataset"[, "dataset_arrays"]]}`` -> path (``"dataset_arrays"``: the ``.npz`` file of a
    large data set).
    """
    texts = [(paths.result, "result", result_yaml), (paths.launch, "launch", launch_text)]
    if urdf_text is not None:
        texts.append((paths.urdf, "urdf", urdf_text))
    if frames_text is not None:
        texts.append((paths.frames, "frames", frames_text))
    targets = [path for path, _, _ in texts]
    if dataset is not None:  # Dataset.save writes its arrays to <stem>.npz when large
        targets += [paths.dataset, paths.dataset.with_suffix(".npz")]
    existing = [str(p) for p in targets if p.exists()]
    if existing and not force:
        raise FileExistsError(
            f"refusing to overwrite existing file(s) {existing} (use --force to overwrite)"
        )
    paths.result.parent.mkdir(parents=True, exist_ok=True)
    files = {}
    # every file whole or absent (rwhec_ros.data.atomic): the texts staged first, so that a full
    # disk leaves the directory as it was; the data set next; result.yaml, which says the set is
    # complete, renamed last
    with StagedFiles() as staged:
        for path, kind, text in [*texts[1:], texts[0]]:
            staged.stage(path, text)
            files[kind] = str(path)
        if dataset is not None:
            files["dataset"] = str(dataset.save(paths.dataset))
            npz = paths.dataset.with_suffix(".npz")
            if dataset.writes_npz():
                files["dataset_arrays"] = str(npz)
            elif npz.exists():  # an earlier, larger data set's arrays (force): never left stale
                npz.unlink()
        staged.commit()
    return {k: files[k] for k in ("result", "launch", "urdf", "frames", "dataset",
                                  "dataset_arrays") if k in files}


def solved_pairs(doc: Mapping[str, Any], problem):
    """The pairs of ``problem`` (a :class:`~rwhec_ros.core.problem.Problem` of the result's data
    set) that the result ``doc`` was solved on: without the edges of its ``excluded_edges`` and
    the pairs of its ``rejected_pairs`` (outlier rejection), so that a report made later from
    the data set shows the fit the solve had. A result without ``rejected_pairs`` (written
    before it existed) only loses its excluded edges.

    Raises ``ValueError`` naming the edge and the index when ``rejected_pairs`` does not fit
    the data set (an index outside the edge's pairs, or an edge it does not have), e.g. a
    result beside another run's data set.
    """
    from ..core.outliers.pairs import restrict_problem

    excluded = set((doc.get("excluded_edges") or {}).keys())
    rejected = dict(doc.get("rejected_pairs") or {})
    edges = {e.name: e for e in problem.edges}
    for name, indices in rejected.items():
        if name not in edges:
            raise ValueError(f"rejected_pairs: edge {name} is not in the data set")
        for i in indices:
            if not 0 <= int(i) < edges[name].n:
                raise ValueError(f"rejected_pairs[{name}]: pair index {i} outside the edge's "
                                 f"{edges[name].n} pairs in the data set")
    if not excluded.intersection(edges) and not rejected:
        return problem
    masks = {}
    for name, e in edges.items():
        mask = np.full(e.n, name not in excluded)
        mask[[int(i) for i in rejected.get(name, ())]] = False
        masks[name] = mask
    return restrict_problem(problem, masks, what="solved_pairs")


def load_result(path: str | Path) -> dict[str, Any]:
    """Read a result YAML written by the session or the CLI.

    Raises ``ValueError`` naming the file and the missing or malformed key.
    """
    path = Path(path)
    try:
        doc = yaml.load(path.read_text(encoding="utf-8"), Loader=_Loader)  # noqa: S506 - safe
    except OSError as exc:
        raise ValueError(f"{path}: cannot read ({describe_os_error(exc)})") from None
    except yaml.YAMLError as exc:
        raise ValueError(describe_yaml_error(path, exc)) from None
    if not isinstance(doc, dict):
        raise ValueError(f"{path}: expected a YAML mapping, got {type(doc).__name__}")
    for key in ("certified", "suboptimality_bound", "scale", "frames"):
        if key not in doc:
            raise ValueError(f"{path}: missing key {key!r} (not a calibration result)")
    if not isinstance(doc["frames"], list):
        raise ValueError(f"{path}: key 'frames': expected a list, got {doc['frames']!r}")
    for i, f in enumerate(doc["frames"]):
        if not isinstance(f, dict) or not {"name", "role", "matrix"} <= set(f):
            raise ValueError(f"{path}: frames[{i}]: expected name, role and matrix, got {f!r}")
        T = np.asarray(f["matrix"], dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise ValueError(f"{path}: frames[{i}] ({f['name']}): matrix must be a finite 4x4, "
                             f"got {f['matrix']!r}")
        if f["role"] not in ("X", "Y"):
            raise ValueError(f"{path}: frames[{i}] ({f['name']}): role must be 'X' or 'Y', "
                             f"got {f['role']!r}")
    missing = incomplete_result(doc)
    if missing:
        raise ValueError(f"{path}: incomplete result: {missing} (the file was cut short, e.g. "
                         "written on a full disk); solve its data set again with "
                         "rwhec-calibrate dataset")
    return doc


#: Keys a complete result YAML has whatever wrote it (older versions included).
_COMPLETE_KEYS = ("certified", "suboptimality_bound", "scale", "frames", "timing_s",
                  "identifiability", "config")


def incomplete_result(doc: Mapping[str, Any]) -> str:
    """What shows a result mapping cut short, in words (``""`` when nothing does): a key every
    result has, missing, or the last entry of a list of mappings lacking keys that the entry
    before it has (a YAML file truncated inside a list still parses)."""
    for key in _COMPLETE_KEYS:
        if key not in doc:
            return f"key {key!r} is missing"
    # keys written after others by the same version (result_document): the later ones absent
    if doc.get("verdict") in ("good", "caution", "unusable") and "verdict_details" not in doc:
        return "key 'verdict_details' is missing (the verdict is there)"
    frames = doc["frames"] if isinstance(doc["frames"], list) else []
    if any(isinstance(f, Mapping) and "std_kind" in f for f in frames):
        for key in ("uncertainty", "cross_validation", "guidance", "accuracy_notes"):
            if key not in doc:
                return f"key {key!r} is missing (the frames have their uncertainty)"

    def walk(node: Any, where: str) -> str:
        if isinstance(node, Mapping):
            for k, v in node.items():
                found = walk(v, f"{where}.{k}" if where else str(k))
                if found:
                    return found
        elif isinstance(node, list) and node:
            if len(node) >= 2 and all(isinstance(v, Mapping) for v in node[-2:]):
                lost = [k for k in node[-2] if k not in node[-1]]
                if lost:
                    return (f"{where}[{len(node) - 1}] has no {', '.join(map(repr, lost))}, "
                            f"which {where}[{len(node) - 2}] has")
            return walk(node[-1], f"{where}[{len(node) - 1}]")
        return ""

    return walk(doc, "")
