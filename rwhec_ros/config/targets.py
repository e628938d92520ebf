"""The named targets of the configuration (``targets.names``, ``targets.<name>.*``): boards and
single tags with their own frame names, checked into :class:`~rwhec_ros.vision.targets.TargetSpec`.

ROS parameters hold no lists of mappings, so a target is a name in ``targets.names`` and its
parameters ``targets.<name>.<key>`` (the scheme of the cameras)::

    targets:
      names: [board]
      board: {type: charuco, squares_x: 7, squares_y: 5, square_size: 0.04,
              marker_size: 0.03, dictionary: DICT_5X5_100}

The target's name is its frame (X variable, published as ``<name><output.frame_suffix>``).
Types (:data:`~rwhec_ros.config.specs.TARGET_TYPES`) and their keys:

* ``aprilgrid``: ``rows``, ``cols``, ``tag_size`` (required), ``spacing`` (0.3), ``first_id``
  (0), ``family`` (tag36h11), ``border_bits`` (2), ``min_corners``;
* ``charuco``: ``squares_x``, ``squares_y``, ``square_size``, ``marker_size`` (required),
  ``dictionary`` (DICT_5X5_100), ``first_id`` (0), ``legacy_pattern`` (false), ``min_corners``;
* ``chessboard``: ``cols``, ``rows`` (inner corners, not equal), ``square_size``
  (required), ``min_corners``;
* ``circles``: ``cols``, ``rows``, ``circle_spacing`` (required), ``origin_circle`` (a larger
  bottom-left circle; false: a plain grid, ``cols != rows``, turn-symmetric),
  ``circle_diameter`` (measured when unset), ``min_corners``;
* ``asymmetric_circles``: ``cols``, ``rows`` (odd), ``circle_spacing`` (OpenCV's square size),
  ``circle_diameter``, ``min_corners``;
* ``tag``: ``tag_id``, ``tag_size`` (required): one tag of ``tags.family``, like ``tags.ids`` but
  with its own frame name.

A layout that looks the same turned by 90 degrees (a square chessboard or plain circle grid)
or that the detector cannot label (an asymmetric grid with an even number of rows) is refused
with the reason and the fix: its point order could flip between views. A chessboard with both
square counts even or both odd, or a plain circle grid (no origin circle), looks the same turned
by 180 degrees and is accepted: the pose stream tells which of its views are turned
(:mod:`rwhec_ros.sync.board_turns`).

A key of another type is refused by name (a typo would otherwise be silently ignored). Marker
ids must be unique per dictionary across ``tags.ids``, the tag targets and every board
(:func:`build_targets` names the two targets and the ids). Frames of the board layouts:
:mod:`rwhec_ros.vision.boards`.
"""

from __future__ import annotations

from typing import Any

from ..vision.boards import AprilGridSpec, CharucoSpec
from ..vision.families import dictionary_key, dictionary_size
from ..vision.grids import ChessboardSpec, CircleGridSpec
from ..vision.targets import TargetSpec, nested_grids
from .specs import TARGET_SPECS, TARGET_TYPES
from .validation import check_choice, check_positive

__all__ = ["build_targets", "target_parameters", "TYPE_KEYS", "DEFAULT_MIN_CORNERS"]

#: Keys each target type takes (besides ``type``), with the default of an unset optional key
#: (``...``: required).
TYPE_KEYS: dict[str, dict[str, Any]] = {
    "tag": {"tag_id": ..., "tag_size": ...},
    "aprilgrid": {"rows": ..., "cols": ..., "tag_size": ..., "spacing": 0.3, "first_id": 0,
                  "family": "tag36h11", "border_bits": 2, "min_corners": None},
    "charuco": {"squares_x": ..., "squares_y": ..., "square_size": ..., "marker_size": ...,
                "dictionary": "DICT_5X5_100", "first_id": 0, "legacy_pattern": False,
                "min_corners": None},
    "chessboard": {"cols": ..., "rows": ..., "square_size": ..., "min_corners": None},
    "circles": {"cols": ..., "rows": ..., "circle_spacing": ..., "origin_circle": False,
                "circle_diameter": None, "min_corners": None},
    "asymmetric_circles": {"cols": ..., "rows": ..., "circle_spacing": ...,
                           "circle_diameter": None, "min_corners": None},
}

#: Layout field names of the vision specs -> parameter keys (in error messages).
_FIELD_KEYS = {"tag_spacing": "spacing", "spacing": "circle_spacing",
               "diameter": "circle_diameter"}

#: ``min_corners`` of a board when unset (capped at the board's corner count).
DEFAULT_MIN_CORNERS = 8

_SIZES = ("tag_size", "square_size", "marker_size", "spacing", "circle_spacing",
          "circle_diameter")
_COUNTS = {"rows": 1, "cols": 1, "squares_x": 2, "squares_y": 2, "border_bits": 1}


def _values(v: dict[str, Any], name: str, kind: str) -> dict[str, Any]:
    """The keys of target ``name`` of type ``kind``: given ones checked, defaults filled."""
    p = f"targets.{name}."
    keys = TYPE_KEYS[kind]
    for spec in TARGET_SPECS:
        if spec.name != "type" and spec.name not in keys and v[p + spec.name] is not None:
            takes = ", ".join(sorted(keys))
            raise ValueError(f"{p}{spec.name}: not a parameter of a {kind!r} target (it takes "
                             f"{takes}), got {v[p + spec.name]!r}")
    out: dict[str, Any] = {}
    for key, default in keys.items():
        value = v[p + key]
        if value is None:
            if default is ...:
                raise ValueError(f"{p}{key}: missing, required for a {kind!r} target")
            out[key] = default
            continue
        if key in _SIZES:
            value = check_positive(v, p + key)
        elif key in _COUNTS and value < _COUNTS[key]:
            raise ValueError(f"{p}{key}: must be >= {_COUNTS[key]}, got {value!r}")
        elif key in ("first_id", "tag_id") and value < 0:
            raise ValueError(f"{p}{key}: ids are >= 0, got {value!r}")
        elif key in ("family", "dictionary"):
            try:
                value = dictionary_key(value)
            except ValueError as exc:
                raise ValueError(f"{p}{key}: unknown {key} {value!r} ({exc})") from None
        out[key] = value
    return out


def _board(name: str, kind: str, k: dict[str, Any]
           ) -> AprilGridSpec | CharucoSpec | ChessboardSpec | CircleGridSpec:
    """The layout, its own checks (spacing range, marker size, ids within the dictionary)
    reported under ``targets.<name>``."""
    try:
        if kind == "aprilgrid":
            return AprilGridSpec(k["rows"], k["cols"], tag_size=k["tag_size"],
                                 tag_spacing=k["spacing"], first_id=k["first_id"],
                                 family=k["family"], border_bits=k["border_bits"])
        if kind == "charuco":
            return CharucoSpec(k["squares_x"], k["squares_y"], square_size=k["square_size"],
                               marker_size=k["marker_size"], dictionary=k["dictionary"],
                               first_id=k["first_id"], legacy_pattern=k["legacy_pattern"])
        if kind == "chessboard":
            return ChessboardSpec(k["cols"], k["rows"], square_size=k["square_size"])
        return CircleGridSpec(k["cols"], k["rows"], k["circle_spacing"],
                              asymmetric=kind == "asymmetric_circles",
                              origin_circle=bool(k.get("origin_circle", False)),
                              diameter=k["circle_diameter"])
    except ValueError as exc:
        # "aprilgrid: tag_spacing must be ..." -> the parameter's name
        words = str(exc).split(": ", 1)[-1]
        key = words.split(" ", 1)[0]
        if key in _FIELD_KEYS and _FIELD_KEYS[key] in TYPE_KEYS[kind]:
            words = _FIELD_KEYS[key] + words[len(key):]
            key = _FIELD_KEYS[key]
        key = key if key in TYPE_KEYS[kind] else "type"
        raise ValueError(f"targets.{name}.{key}: invalid {kind} layout: {words}") from None


def build_targets(v: dict[str, Any], tag_family: str, single_tag_ids: tuple[int, ...]
                  ) -> tuple[TargetSpec, ...]:
    """The named targets of typed values ``v`` (every schema name present, see
    :func:`~rwhec_ros.config.validation.typed_parameters`), in ``targets.names`` order.

    Parameters
    ----------
    v : dict
        Typed parameter values.
    tag_family : str
        ``tags.family`` (the family of ``tags.ids`` and of ``type: tag`` targets).
    single_tag_ids : tuple of int
        ``tags.ids``.

    Raises
    ------
    ValueError
        Naming the parameter and the value: unknown type, a key of another type, a missing
        key, a bad layout, an unknown family or dictionary, a marker id used twice.
    """
    try:
        family = dictionary_key(tag_family)
    except ValueError as exc:
        raise ValueError(f"tags.family: {exc}") from None
    owners: dict[tuple[str, int], str] = {(family, i): "tags.ids" for i in single_tag_ids}
    out = []
    for name in v["targets.names"]:
        p = f"targets.{name}."
        kind = check_choice(v, p + "type", TARGET_TYPES)
        k = _values(v, name, kind)
        if kind == "tag":
            spec = TargetSpec(name, tag_id=k["tag_id"], tag_size=k["tag_size"])
            dictionary = family
        else:
            board = _board(name, kind, k)
            mc = k["min_corners"]
            mc = min(DEFAULT_MIN_CORNERS, board.n_corners) if mc is None else mc
            try:
                spec = TargetSpec(name, board=board, min_corners=mc)
            except ValueError as exc:
                raise ValueError(f"{p}min_corners: {str(exc).split(': ', 1)[-1]}") from None
            dictionary = board.dictionary
        id_key = p + ("tag_id" if kind == "tag" else "first_id")  # no ids for grids
        for marker in spec.marker_ids():
            other = owners.get((dictionary, marker))
            if other is not None:
                ids = sorted(m for m in spec.marker_ids() if owners.get((dictionary, m)) == other)
                raise ValueError(
                    f"{id_key}: marker ids {ids} of {dictionary} are used by {other} too; a "
                    f"marker id must belong to one target (target {name!r} has ids "
                    f"{spec.marker_ids()[0]}..{spec.marker_ids()[-1]})")
        owners.update({(dictionary, m): f"target {name!r}" for m in spec.marker_ids()})
        if kind == "tag" and spec.tag_id >= dictionary_size(family):
            raise ValueError(f"{p}tag_id: {spec.tag_id} is not in {family} "
                             f"({dictionary_size(family)} tags)")
        for other in out:
            why = nested_grids(other, spec)
            if why is not None:
                raise ValueError(f"targets.names: {why}")
        out.append(spec)
    return tuple(out)


def target_parameters(spec: TargetSpec) -> dict[str, Any]:
    """The flat parameters ``targets.<name>.<key>`` that :func:`build_targets` turns back into
    ``spec`` (add ``spec.name`` to ``targets.names``)."""
    p = f"targets.{spec.name}."
    if spec.board is None:
        return {p + "type": "tag", p + "tag_id": spec.tag_id, p + "tag_size": spec.tag_size}
    b = spec.board
    if isinstance(b, AprilGridSpec):
        keys = {"rows": b.rows, "cols": b.cols, "tag_size": b.tag_size, "spacing": b.tag_spacing,
                "first_id": b.first_id, "family": b.family, "border_bits": b.border_bits}
    elif isinstance(b, ChessboardSpec):
        keys = {"cols": b.cols, "rows": b.rows, "square_size": b.square_size}
    elif isinstance(b, CircleGridSpec):
        keys = {"cols": b.cols, "rows": b.rows, "circle_spacing": b.spacing}
        if b.diameter is not None:
            keys["circle_diameter"] = b.diameter
        if not b.asymmetric:
            keys["origin_circle"] = b.origin_circle
    else:
        keys = {"squares_x": b.squares_x, "squares_y": b.squares_y,
                "square_size": b.square_size, "marker_size": b.marker_size,
                "dictionary": b.dictionary, "first_id": b.first_id,
                "legacy_pattern": b.legacy_pattern}
    keys["min_corners"] = spec.min_corners
    return {p + "type": b.kind, **{p + k: v for k, v in keys.items()}}
