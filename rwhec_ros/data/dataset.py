"""The package's own self-describing data set format (synchronised measurement pairs per edge).

A data set is what a calibration session collected: for each edge (X-frame ``x`` = tag,
Y-frame ``y`` = camera) the image stamps and the pairs ``(A_i, B_i)`` with ``A_i X = Y B_i``
(paper eq. (7)), ``A = T_<camera carrier>_<tag carrier>`` (pose stream) and ``B = T_cam_tag``
(detector), with the per-pair precisions ``sigma`` [m] and ``kappa`` (paper eq. (32)).

File layout: one YAML file with the header ``format: rwhec_ros.dataset`` and ``version: 1``,
the frame names, ``unknown_scale``, ``carriers`` (optional frame -> carrier frame names),
``metadata`` (configuration, creation time, package version) and ``edges``. Arrays are written
inline (floats with ``repr`` precision, so the round trip is bit-exact) or, for large data sets,
in an ``.npz`` file beside the YAML named in its ``arrays`` key together with its SHA-256.
Measured on this project's 2-core machine (libyaml): inline YAML for 100k pairs is 61 MB and
takes 20 s to write and 28 s to read with libyaml alone (49 s / 145 s through :meth:`save` /
:meth:`load` on the busy shared machine), the ``.npz`` path 28 MB in 0.07 s / 0.15 s; hence
``arrays="auto"`` writes inline up to ``inline_max_pairs`` pairs (default 2000) and ``.npz``
above.

Optional keys (:mod:`rwhec_ros.data.corners`; files without them load as before): per edge
``corners_px`` (each pair's detected corners [px], ``.nan`` for a pair without: a tag's four;
a board's, as many as were seen) with, for boards only, ``corner_points_m`` (the same corners in
the board frame [m]), and at the top ``intrinsics`` (per camera) and ``tag_sizes_m`` (per tag),
which give the reprojection error per camera. Files written before boards kept corners (tag
edges with four corners per pair, board edges with none) have no ``corner_points_m`` and load
as before.

Inline edge layout (``A``/``B``: one 4x4 matrix per pair, rows as flow lists)::

    edges:
    - x: tag_0
      y: cam_0
      n: 2
      stamps_ns: [1000000000, 1033000000]
      sigma: [0.01, 0.01]
      kappa: [125.0, 125.0]
      A:
      - - [1.0, 0.0, 0.0, 0.5]
        ...
"""

from __future__ import annotations

import datetime
import hashlib
import io
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import yaml

from ..core.problem import Edge, Problem
from ..errors import describe_os_error, describe_yaml_error
from ..sync.edge_pairs import DatasetEdge, check_name
from .atomic import atomic_write_bytes, atomic_write_text

if TYPE_CHECKING:
    from ..sync.accumulator import PairAccumulator

__all__ = ["DATASET_FORMAT", "DATASET_VERSION", "DatasetEdge", "Dataset", "default_metadata"]

DATASET_FORMAT = "rwhec_ros.dataset"
DATASET_VERSION = 1

_ARRAY_KEYS = ("stamps_ns", "sigma", "kappa", "A", "B")
_CORNER_KEYS = ("corners_px", "corner_points_m")
_Dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
_Loader = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def default_metadata(config: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """``{"created": <UTC ISO 8601>, "package_version": ..., "config": config or {}}``."""
    from .. import __version__

    return {
        "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "package_version": __version__,
        "config": _plain(dict(config or {}), "config"),
    }


def _plain(value: Any, where: str) -> Any:
    """``value`` as plain YAML-safe Python data (numpy scalars/arrays and tuples converted)."""
    if isinstance(value, np.ndarray):
        return _plain(value.tolist(), where)
    if isinstance(value, np.generic):
        return value.item()
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, Mapping):
        out = {}
        for k, v in value.items():
            if not isinstance(k, str):
                raise ValueError(f"{where}: keys must be strings, got {k!r}")
            out[k] = _plain(v, f"{where}.{k}")
        return out
    if isinstance(value, (list, tuple)):
        return [_plain(v, f"{where}[{i}]") for i, v in enumerate(value)]
    raise ValueError(f"{where}: cannot store a {type(value).__name__} in a data set: {value!r}")


@dataclass(eq=False)
class Dataset:
    """A collected data set: frames, measurement pairs per edge, and where they came from.

    Attributes
    ----------
    x_names, y_names : tuple of str
        X-frames (tags) and Y-frames (cameras); frames without an edge are allowed (dropped by
        :meth:`to_problem`).
    edges : tuple of DatasetEdge
        At most one per (x, y); every edge's frames must be listed.
    unknown_scale : bool
        Monocular data with an unknown common scale of the ``A`` translations (paper Problem 3).
    metadata : dict
        Plain YAML-safe data: the configuration that produced the data set, creation time,
        package version (see :func:`default_metadata`).
    carriers : dict[str, str]
        Optional: for a frame name, the frame it is rigidly attached to (camera -> camera
        carrier, tag -> tag carrier), e.g. ``{"cam_0": "base_link", "tag_0": "world"}``.
    intrinsics : dict[str, CameraIntrinsics]
        Optional: camera (Y frame) -> its intrinsics (for the reprojection error).
    tag_sizes_m : dict[str, float]
        Optional: tag (X frame) -> edge length [m] (nominal for unknown scale).
    """

    x_names: tuple[str, ...]
    y_names: tuple[str, ...]
    edges: tuple[DatasetEdge, ...]
    unknown_scale: bool = False
    metadata: dict[str, Any] = field(default_factory=dict)
    carriers: dict[str, str] = field(default_factory=dict)
    intrinsics: dict[str, Any] = field(default_factory=dict)
    tag_sizes_m: dict[str, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.x_names = tuple(check_name(n, f"x_names[{i}]") for i, n in enumerate(self.x_names))
        self.y_names = tuple(check_name(n, f"y_names[{i}]") for i, n in enumerate(self.y_names))
        names = self.x_names + self.y_names
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise ValueError(f"x_names/y_names: frame names must be unique, duplicated: {dup}")
        self.edges = tuple(self.edges)
        seen: set[tuple[str, str]] = set()
        for i, e in enumerate(self.edges):
            if not isinstance(e, DatasetEdge):
                raise ValueError(f"edges[{i}]: expected DatasetEdge, got {type(e).__name__}")
            if e.x not in self.x_names:
                raise ValueError(f"edges[{i}] ({e.x}, {e.y}): x {e.x!r} is not in x_names")
            if e.y not in self.y_names:
                raise ValueError(f"edges[{i}] ({e.x}, {e.y}): y {e.y!r} is not in y_names")
            if (e.x, e.y) in seen:
                raise ValueError(f"edges[{i}] ({e.x}, {e.y}): duplicate edge")
            seen.add((e.x, e.y))
        if not isinstance(self.unknown_scale, (bool, np.bool_)):
            raise ValueError(f"unknown_scale: expected a bool, got {self.unknown_scale!r}")
        self.unknown_scale = bool(self.unknown_scale)
        if not isinstance(self.metadata, Mapping):
            raise ValueError(f"metadata: expected a mapping, got {self.metadata!r}")
        self.metadata = _plain(self.metadata, "metadata")
        if not isinstance(self.carriers, Mapping):
            raise ValueError(f"carriers: expected a mapping, got {self.carriers!r}")
        for frame, carrier in self.carriers.items():
            if frame not in names:
                raise ValueError(f"carriers: {frame!r} is not a frame of the data set")
            check_name(carrier, f"carriers[{frame!r}]")
        self.carriers = dict(self.carriers)
        self._check_corner_data()

    def _check_corner_data(self) -> None:
        """``intrinsics`` of cameras of the data set (mappings converted), ``tag_sizes_m`` of its
        tags (:mod:`rwhec_ros.data.corners`)."""
        if not self.intrinsics and not self.tag_sizes_m:
            self.intrinsics, self.tag_sizes_m = {}, {}
            return
        from .corners import check_tag_sizes, intrinsics_from_dict

        if not isinstance(self.intrinsics, Mapping):
            raise ValueError(f"intrinsics: expected a mapping camera -> intrinsics, got "
                             f"{self.intrinsics!r}")
        out = {}
        for cam, value in self.intrinsics.items():
            if cam not in self.y_names:
                raise ValueError(f"intrinsics: {cam!r} is not a camera (Y frame) of the data set")
            out[cam] = intrinsics_from_dict(value, f"intrinsics[{cam!r}]")
        self.intrinsics = out
        self.tag_sizes_m = check_tag_sizes(self.tag_sizes_m, self.x_names)

    # --- sizes -------------------------------------------------------------------------------
    @property
    def n_pairs(self) -> int:
        return sum(e.n for e in self.edges)

    def edge(self, x: str, y: str) -> DatasetEdge:
        """The edge ``(x, y)``; ``KeyError`` when absent."""
        for e in self.edges:
            if e.x == x and e.y == y:
                return e
        raise KeyError((x, y))

    # --- conversions -------------------------------------------------------------------------
    def to_problem(self, min_pairs: int = 1) -> Problem:
        """The data as a validated :class:`Problem` (edges via :meth:`Edge.build`).

        Edges with fewer than ``min_pairs`` pairs are left out and frames without an edge are
        dropped; ``ValueError`` if no edge is left.
        """
        if isinstance(min_pairs, bool) or not isinstance(min_pairs, numbers.Integral) or (
            min_pairs < 1
        ):
            raise ValueError(f"min_pairs: expected an integer >= 1, got {min_pairs!r}")
        kept = [e for e in self.edges if e.n >= min_pairs]
        if not kept:
            counts = {f"({e.x}, {e.y})": e.n for e in self.edges}
            raise ValueError(f"to_problem: no edge has at least min_pairs={min_pairs}: {counts}")
        touched = {e.x for e in kept} | {e.y for e in kept}
        return Problem(
            [n for n in self.x_names if n in touched],
            [n for n in self.y_names if n in touched],
            [Edge.build(e.x, e.y, e.A, e.B, sigma=e.sigma, kappa=e.kappa) for e in kept],
            unknown_scale=self.unknown_scale,
        )

    @staticmethod
    def from_problem(
        problem: Problem,
        stamps: Sequence[np.ndarray] | None = None,
        metadata: Mapping[str, Any] | None = None,
        *,
        carriers: Mapping[str, str] | None = None,
    ) -> Dataset:
        """A data set holding ``problem``'s pairs.

        ``stamps``: one int array (N_e,) per edge in ``problem.edges`` order; ``0..N_e-1`` when
        omitted. ``metadata`` entries are added to :func:`default_metadata`.
        """
        if stamps is not None and len(stamps) != len(problem.edges):
            raise ValueError(
                f"stamps: expected one array per edge ({len(problem.edges)}), got {len(stamps)}"
            )
        edges = []
        for i, e in enumerate(problem.edges):
            st = np.arange(e.n, dtype=np.int64) if stamps is None else np.asarray(stamps[i])
            edges.append(DatasetEdge(e.x, e.y, st, e.A, e.B, e.sigma, e.kappa))
        return Dataset(
            x_names=problem.x_names,
            y_names=problem.y_names,
            edges=tuple(edges),
            unknown_scale=problem.unknown_scale,
            metadata={**default_metadata(), **dict(metadata or {})},
            carriers=dict(carriers or {}),
        )

    @staticmethod
    def from_accumulator(
        acc: PairAccumulator,
        *,
        x_names: Sequence[str] | None = None,
        y_names: Sequence[str] | None = None,
        unknown_scale: bool = False,
        metadata: Mapping[str, Any] | None = None,
        carriers: Mapping[str, str] | None = None,
        intrinsics: Mapping[str, Any] | None = None,
        tag_sizes_m: Mapping[str, float] | None = None,
    ) -> Dataset:
        """Every kept pair of a :class:`~rwhec_ros.sync.accumulator.PairAccumulator` (with their
        corners when the accumulator kept them; ``intrinsics`` and ``tag_sizes_m`` of the frames
        listed, for the reprojection error).

        No ``min_pairs`` filter (a data set keeps the raw collection). Frame lists default to
        the sorted names of the edges; when given, they must contain every edge's frames (frames
        without an edge are kept). Edges are ordered by (X index, Y index), pairs by stamp.
        """
        data = acc.edges()
        xs = sorted({x for x, _ in data}) if x_names is None else list(x_names)
        ys = sorted({y for _, y in data}) if y_names is None else list(y_names)
        x_index = {n: i for i, n in enumerate(xs)}
        y_index = {n: i for i, n in enumerate(ys)}
        for x, y in data:
            if x not in x_index or y not in y_index:
                raise ValueError(
                    f"x_names/y_names: edge ({x}, {y}) of the accumulator has a frame not listed"
                )
        ordered = sorted(data.values(), key=lambda e: (x_index[e.x], y_index[e.y]))
        return Dataset(
            x_names=tuple(xs),
            y_names=tuple(ys),
            edges=tuple(ordered),
            unknown_scale=unknown_scale,
            metadata={**default_metadata(), **dict(metadata or {})},
            carriers=dict(carriers or {}),
            intrinsics={k: v for k, v in dict(intrinsics or {}).items() if k in ys},
            tag_sizes_m={k: v for k, v in dict(tag_sizes_m or {}).items() if k in xs},
        )

    # --- files -------------------------------------------------------------------------------
    def writes_npz(self, arrays: str = "auto", inline_max_pairs: int = 2000) -> bool:
        """Whether :meth:`save` with these arguments writes the arrays to ``<stem>.npz``."""
        if arrays not in ("auto", "inline", "npz"):
            raise ValueError(f"arrays: expected 'auto', 'inline' or 'npz', got {arrays!r}")
        if arrays == "auto":
            return self.n_pairs > inline_max_pairs
        return arrays == "npz"

    def save(self, path: str | Path, *, arrays: str = "auto", inline_max_pairs: int = 2000) -> Path:
        """Write the data set to the YAML file ``path`` (and ``<stem>.npz`` beside it).

        Parameters
        ----------
        path : str or Path
            The YAML file to write.
        arrays : {"auto", "inline", "npz"}
            Where the arrays go; ``"auto"`` is ``"inline"`` up to ``inline_max_pairs`` pairs.
        inline_max_pairs : int
            Threshold of ``"auto"``.

        Returns
        -------
        Path
            The YAML file written.
        """
        path = Path(path)
        arrays = "npz" if self.writes_npz(arrays, inline_max_pairs) else "inline"
        doc: dict[str, Any] = {
            "format": DATASET_FORMAT,
            "version": DATASET_VERSION,
            "unknown_scale": self.unknown_scale,
            "x_names": list(self.x_names),
            "y_names": list(self.y_names),
            "carriers": dict(self.carriers),
            "metadata": self.metadata,
        }
        if self.intrinsics:
            from .corners import intrinsics_to_dict

            doc["intrinsics"] = {k: intrinsics_to_dict(v) for k, v in self.intrinsics.items()}
        if self.tag_sizes_m:
            doc["tag_sizes_m"] = dict(self.tag_sizes_m)
        edges_doc = []
        if arrays == "npz":
            npz_path = path.with_suffix(".npz")
            buffer = io.BytesIO()
            named = {
                f"e{i}_{k}": getattr(e, k) for i, e in enumerate(self.edges) for k in _ARRAY_KEYS
            }
            for i, e in enumerate(self.edges):
                named.update({f"e{i}_{k}": getattr(e, k) for k in _CORNER_KEYS
                              if getattr(e, k) is not None})
            np.savez(buffer, **named)
            payload = buffer.getvalue()
            atomic_write_bytes(npz_path, payload)  # whole or absent (module atomic)
            doc["arrays"] = {"file": npz_path.name, "sha256": hashlib.sha256(payload).hexdigest()}
            for e in self.edges:
                edges_doc.append({"x": e.x, "y": e.y, "n": e.n})
        else:
            for e in self.edges:
                edges_doc.append(
                    {
                        "x": e.x,
                        "y": e.y,
                        "n": e.n,
                        "stamps_ns": e.stamps_ns.tolist(),
                        "sigma": e.sigma.tolist(),
                        "kappa": e.kappa.tolist(),
                        "A": e.A.tolist(),
                        "B": e.B.tolist(),
                    }
                )
                edges_doc[-1].update({k: getattr(e, k).tolist() for k in _CORNER_KEYS
                                      if getattr(e, k) is not None})
        doc["edges"] = edges_doc
        text = yaml.dump(doc, Dumper=_Dumper, sort_keys=False, default_flow_style=None, width=100)
        atomic_write_text(path, text)
        return path

    @staticmethod
    def load(path: str | Path) -> Dataset:
        """Read a data set written by :meth:`save`.

        Raises ``ValueError`` naming the file, the key or edge and the offending value for a
        file that is not a valid data set (wrong header, missing key, bad array, bad transform,
        missing or modified ``.npz``).
        """
        path = Path(path)
        try:
            doc = yaml.load(path.read_text(encoding="utf-8"), Loader=_Loader)
        except OSError as exc:
            raise ValueError(f"cannot read the data set: {describe_os_error(exc)}") from None
        except yaml.YAMLError as exc:
            raise ValueError(describe_yaml_error(path, exc)) from None
        except UnicodeDecodeError as exc:
            raise ValueError(f"{path}: not a UTF-8 text file: {exc}") from None
        if not isinstance(doc, dict):
            raise ValueError(f"{path}: expected a YAML mapping, got {type(doc).__name__}")
        if doc.get("format") != DATASET_FORMAT:
            raise ValueError(
                f"{path}: key 'format': expected {DATASET_FORMAT!r}, got {doc.get('format')!r}"
            )
        if doc.get("version") != DATASET_VERSION:
            raise ValueError(
                f"{path}: key 'version': expected {DATASET_VERSION}, got {doc.get('version')!r}"
            )
        for key in ("x_names", "y_names", "edges"):
            if not isinstance(doc.get(key), list):
                raise ValueError(f"{path}: key {key!r}: expected a list, got {doc.get(key)!r}")
        npz = _read_npz(path, doc["arrays"]) if "arrays" in doc else None
        edges = []
        for i, ed in enumerate(doc["edges"]):
            if not isinstance(ed, dict):
                raise ValueError(f"{path}: edges[{i}]: expected a mapping, got {ed!r}")
            label = f"{path}: edges[{i}] ({ed.get('x')}, {ed.get('y')})"
            for key in ("x", "y", "n"):
                if key not in ed:
                    raise ValueError(f"{label}: missing key {key!r}")
            values = {}
            for key in _ARRAY_KEYS:
                if npz is not None:
                    npz_key = f"e{i}_{key}"
                    if npz_key not in npz:
                        raise ValueError(f"{label}: array {npz_key!r} missing from the .npz file")
                    values[key] = npz[npz_key]
                else:
                    if key not in ed:
                        raise ValueError(f"{label}: missing key {key!r}")
                    values[key] = _array_from_yaml(ed[key], key, label)
            for key in _CORNER_KEYS:  # optional (module docstring)
                if npz is not None and f"e{i}_{key}" in npz:
                    values[key] = npz[f"e{i}_{key}"]
                elif npz is None and ed.get(key) is not None:
                    values[key] = _array_from_yaml(ed[key], key, label)
            n = ed["n"]
            if values["stamps_ns"].ndim != 1 or values["stamps_ns"].shape[0] != n:
                raise ValueError(
                    f"{label}: key 'n' is {n!r} but 'stamps_ns' has shape "
                    f"{values['stamps_ns'].shape}"
                )
            try:
                edges.append(DatasetEdge(ed["x"], ed["y"], **values))
            except ValueError as exc:
                raise ValueError(f"{label}: {exc}") from None
        try:
            return Dataset(
                x_names=tuple(doc["x_names"]),
                y_names=tuple(doc["y_names"]),
                edges=tuple(edges),
                unknown_scale=doc.get("unknown_scale", False),
                metadata=doc.get("metadata") or {},
                carriers=doc.get("carriers") or {},
                intrinsics=doc.get("intrinsics") or {},
                tag_sizes_m=doc.get("tag_sizes_m") or {},
            )
        except ValueError as exc:
            raise ValueError(f"{path}: {exc}") from None


def _array_from_yaml(value: Any, key: str, label: str) -> np.ndarray:
    """Convert an inline YAML list, rejecting non-numbers (and non-integers for stamps)."""
    try:
        if key == "stamps_ns":
            flat = np.asarray(value, dtype=object).ravel()
            bad = [v for v in flat if isinstance(v, bool) or not isinstance(v, int)]
            if bad:
                raise ValueError(f"expected integer nanoseconds, got {bad[0]!r}")
            return np.asarray(value, dtype=np.int64)
        arr = np.asarray(value, dtype=object)
        flat = arr.ravel()
        bad = [v for v in flat if isinstance(v, bool) or not isinstance(v, (int, float))]
        if bad:
            raise ValueError(f"expected numbers, got {bad[0]!r}")
        return arr.astype(float)
    except (ValueError, TypeError, OverflowError) as exc:
        raise ValueError(f"{label}: key {key!r}: {exc}") from None


def _read_npz(path: Path, arrays: Any) -> dict[str, np.ndarray]:
    """Load and verify the ``.npz`` file named in the header's ``arrays`` key."""
    if not isinstance(arrays, dict) or not isinstance(arrays.get("file"), str):
        raise ValueError(f"{path}: key 'arrays': expected {{file: <name>.npz, sha256: ...}}, "
                         f"got {arrays!r}")
    npz_path = path.parent / arrays["file"]
    try:
        payload = npz_path.read_bytes()
    except OSError as exc:
        raise ValueError(f"{path}: key 'arrays.file': cannot read {npz_path.name} beside it "
                         f"({describe_os_error(exc).rsplit(': ', 1)[-1]}); the arrays of a data "
                         "set above 2,000 pairs are in that file: copy it with the YAML file"
                         ) from None
    digest = hashlib.sha256(payload).hexdigest()
    if arrays.get("sha256") != digest:
        raise ValueError(
            f"{path}: key 'arrays.sha256': {npz_path.name} has SHA-256 {digest}, header says "
            f"{arrays.get('sha256')!r} (file replaced or modified)"
        )
    try:
        with np.load(io.BytesIO(payload), allow_pickle=False) as npz:
            return {k: npz[k] for k in npz.files}
    except (ValueError, OSError) as exc:
        raise ValueError(f"{path}: key 'arrays.file': {npz_path.name} is not a valid .npz: "
                         f"{exc}") from None
