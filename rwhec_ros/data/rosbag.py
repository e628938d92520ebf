"""rosbag2 recordings without ROS: read messages in log-time order, an offline tf tree, writing.

Reading uses ``rosbags`` (:class:`rosbags.rosbag2.Reader`, sqlite3 or mcap storage) with the
ROS 2 Jazzy type store (``Stores.ROS2_JAZZY``); the messages it returns are dataclasses with the
same field names as rclpy's, so :mod:`rwhec_ros.messages` and
:class:`rwhec_ros.session.handlers.MessageHandlers` take them unchanged.

* :func:`bag_topics` and :func:`read_messages` list the topics and yield
  ``(topic, log_time_ns, msg)`` in log-time order (the order in which the node would have
  received them), for the selected topics only, with an optional progress callback.
* :class:`TfTree` answers ``lookup(parent, child, stamp_ns) = T_parent_child`` from the whole
  recording's ``/tf`` and ``/tf_static``: chains of links, each dynamic link interpolated on
  SE(3) by a :class:`~rwhec_ros.sync.buffer.PoseBuffer` (``max_gap_ns``, ``tolerance_ns``).
* :func:`message_from_fields` and :func:`write_bag` write bags (used by the tests and by
  :mod:`rwhec_ros.simulation.bag`): messages are described by the field dicts of
  :mod:`rwhec_ros.messages` and built as ``rosbags`` messages.

Frames: ``T_parent_child`` maps child coordinates to parent coordinates (tf2's convention, the
transform of a ``TransformStamped`` with ``header.frame_id = parent``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ..core.lie import invert_transform
from ..messages import transform_stamped_to_transform
from ..sync.at_rest import AtRestRule, at_rest_lookup
from ..sync.buffer import PoseBuffer

__all__ = [
    "BagMessage",
    "damaged_bag_words",
    "jazzy_typestore",
    "bag_topics",
    "read_messages",
    "TfTree",
    "message_from_fields",
    "write_bag",
    "POSE_STAMPED",
    "TRANSFORM_STAMPED",
    "TF_MESSAGE",
    "IMAGE",
    "COMPRESSED_IMAGE",
    "CAMERA_INFO",
]

POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
TRANSFORM_STAMPED = "geometry_msgs/msg/TransformStamped"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
IMAGE = "sensor_msgs/msg/Image"
COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
CAMERA_INFO = "sensor_msgs/msg/CameraInfo"

_STORAGES = ("sqlite3", "mcap")


class BagMessage(NamedTuple):
    """One deserialised message: ``topic``, bag log time ``log_time_ns`` [ns], ``msgtype``
    (e.g. ``sensor_msgs/msg/Image``) and the ``rosbags`` message ``msg``."""

    topic: str
    log_time_ns: int
    msgtype: str
    msg: Any


def jazzy_typestore():
    """The ``rosbags`` type store of ROS 2 Jazzy's message definitions."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def _open_reader(path: str | Path):
    from rosbags.rosbag2 import Reader

    path = Path(path)
    if not path.exists():
        raise ValueError(f"bag {str(path)!r}: no such file or directory")
    try:
        reader = Reader(path)
        reader.open()
    except Exception as exc:  # noqa: BLE001 - rosbags raises several types for a bad bag
        raise ValueError(damaged_bag_words(path, exc)) from None
    return reader


#: What rosbags says of a storage file that is cut short or damaged (its own words).
_DAMAGE_WORDS = ("magic", "malformed", "truncated", "not a database", "footer", "summary",
                 "unexpected end", "record length", "could not read", "exceeds")


def damaged_bag_words(path: str | Path, exc: BaseException, read: int | None = None,
                      total: int | None = None) -> str:
    """One line for a recording ``rosbags`` cannot open or read on (``exc``): its reason, what
    could still be read (``read`` of ``total`` messages; rosbags reads nothing of a storage
    file whose end is missing) and how to repair it (``ros2 bag reindex``; a cut-off MCAP file:
    ``mcap recover``; a damaged sqlite3 file: ``sqlite3 ... .recover``)."""
    path = Path(path)
    reason = str(exc).strip().rstrip(".") or type(exc).__name__
    files = [*sorted(path.glob("*.mcap")), *sorted(path.glob("*.db3"))] if path.is_dir() \
        else [path]
    storage = files[0] if files else path
    mcap = storage.suffix == ".mcap"
    damaged = any(w in reason.lower() for w in _DAMAGE_WORDS)
    if read:
        got = f"{read} of {total} messages were read before the damage"
    else:
        got = "nothing could be read from it (rosbags does not read past damage)"
    if not damaged and not read:
        return f"bag {str(path)!r}: cannot open as a rosbag2 recording ({reason})"
    fixed = storage.with_name(storage.stem + "_recovered" + storage.suffix)
    fix = (f"recover the readable part with `mcap recover {storage} -o {fixed}` (mcap CLI)"
           if mcap else
           f"recover the readable part with `sqlite3 {storage} .recover | sqlite3 {fixed}`")
    return (f"bag {str(path)!r}: the recording is cut short or damaged ({reason}); {got}; "
            f"{fix} and rebuild its metadata with `ros2 bag reindex {path}`")


def bag_topics(path: str | Path) -> dict[str, tuple[str, int]]:
    """Topics of a rosbag2 recording: ``topic -> (msgtype, message count)``.

    Raises ``ValueError`` naming the path when it is not a readable rosbag2 directory/file.
    """
    reader = _open_reader(path)
    try:
        out: dict[str, tuple[str, int]] = {}
        for c in reader.connections:
            msgtype, n = out.get(c.topic, (c.msgtype, 0))
            out[c.topic] = (msgtype, n + int(c.msgcount))
        return out
    finally:
        reader.close()


def read_messages(
    path: str | Path,
    topics: Iterable[str],
    *,
    typestore=None,
    on_progress: Callable[[int, int], None] | None = None,
) -> Iterator[BagMessage]:
    """Yield the messages of ``topics`` in log-time order, deserialised.

    Parameters
    ----------
    path : str or Path
        The rosbag2 directory (or a single ``.mcap``/``.db3`` file, as ``rosbags`` allows).
    topics : iterable of str
        Topics to read; others are skipped without being deserialised. Topics absent from the
        bag are ignored (check with :func:`bag_topics`).
    typestore : rosbags Typestore, optional
        Default :func:`jazzy_typestore`.
    on_progress : callable(done, total), optional
        Called after every message with the number yielded so far and the total of the selected
        connections.

    Raises
    ------
    ValueError
        Unreadable bag, or a message that cannot be deserialised (naming topic and log time).
    """
    wanted = set(topics)
    store = typestore if typestore is not None else jazzy_typestore()
    reader = _open_reader(path)
    try:
        conns = [c for c in reader.connections if c.topic in wanted]
        total = sum(int(c.msgcount) for c in conns)
        done = 0
        if not conns:
            return
        messages = reader.messages(connections=conns)
        while True:
            try:
                conn, log_time, raw = next(messages)
            except StopIteration:
                break
            except Exception as exc:  # noqa: BLE001 - the storage file is damaged part-way
                raise ValueError(damaged_bag_words(path, exc, done, total)) from None
            try:
                msg = store.deserialize_cdr(raw, conn.msgtype)
            except Exception as exc:  # noqa: BLE001 - unknown type or corrupt payload
                raise ValueError(
                    f"bag {str(path)!r}: cannot deserialise a {conn.msgtype} message on "
                    f"{conn.topic} at log time {log_time} ns ({type(exc).__name__}: {exc}); "
                    f"{done} of {total} messages were read before it"
                ) from None
            done += 1
            yield BagMessage(conn.topic, int(log_time), conn.msgtype, msg)
            if on_progress is not None:
                on_progress(done, total)
    finally:
        reader.close()


# ------------------------------------------------------------------------------------------------
# offline tf


class TfTree:
    """tf over a whole recording: ``T_parent_child`` at any stamp, through chains of links.

    Each frame has one parent (the latest one declared wins, as in tf2). A static link
    (``/tf_static``) holds at every stamp; a dynamic link (``/tf``) is held in a
    :class:`~rwhec_ros.sync.buffer.PoseBuffer` and interpolated on SE(3) between samples at
    most ``max_gap_ns`` apart, or served from a sample within ``tolerance_ns`` (zero-order
    hold; no extrapolation of motion).

    Parameters
    ----------
    max_gap_ns : int
        Largest gap [ns] between two samples of a link that is interpolated
        (``sync.max_gap_s`` of the configuration).
    tolerance_ns : int
        A stamp this close [ns] to a sample it cannot be interpolated around gets that sample
        (``sync.extrapolation_tolerance_s``).
    at_rest : AtRestRule, optional
        Stop-and-go (``sync.at_rest_*``): a stamp between two samples of a link further apart
        than ``max_gap_ns`` that agree gets the link at rest (:mod:`rwhec_ros.sync.at_rest`).
    """

    def __init__(self, *, max_gap_ns: int, tolerance_ns: int = 0,
                 at_rest: AtRestRule | None = None) -> None:
        self.max_gap_ns = int(max_gap_ns)
        self.tolerance_ns = int(tolerance_ns)
        self.at_rest = at_rest
        if self.max_gap_ns < 1:
            raise ValueError(f"max_gap_ns: must be >= 1, got {max_gap_ns!r}")
        if self.tolerance_ns < 0:
            raise ValueError(f"tolerance_ns: must be >= 0, got {tolerance_ns!r}")
        self._parent: dict[str, str] = {}
        self._static: dict[str, np.ndarray] = {}
        self._dynamic: dict[str, PoseBuffer] = {}
        self.rejected = 0

    def add(self, parent: str, child: str, stamp_ns: int, T_parent_child: np.ndarray,
            *, static: bool) -> bool:
        """Add one link sample; returns False (counted in ``rejected``) for an invalid one."""
        if not parent or not child or parent == child:
            self.rejected += 1
            return False
        if self._parent.get(child) != parent:  # new or re-parented frame: start afresh
            self._static.pop(child, None)
            self._dynamic.pop(child, None)
            self._parent[child] = parent
        if static:
            T = np.asarray(T_parent_child, dtype=float)
            if T.shape != (4, 4) or not np.all(np.isfinite(T)):
                self.rejected += 1
                return False
            self._static[child] = T.copy()
            self._dynamic.pop(child, None)
            return True
        buf = self._dynamic.get(child)
        if buf is None:
            buf = self._dynamic[child] = PoseBuffer(
                capacity=2**62, max_gap_ns=self.max_gap_ns,
                extrapolation_tol_ns=self.tolerance_ns, backwards_jump_ns=2**62,
            )
        ok = buf.add(int(stamp_ns), T_parent_child)
        self.rejected += not ok
        return bool(ok)

    def add_message(self, msg: Any, *, static: bool) -> int:
        """Add every ``TransformStamped`` of a ``tf2_msgs/TFMessage``; returns how many were
        stored (bad ones are counted in ``rejected``, never raised)."""
        n = 0
        for tfm in msg.transforms:
            try:
                stamp, parent, child, T = transform_stamped_to_transform(tfm)
            except (ValueError, TypeError, AttributeError):
                self.rejected += 1
                continue
            n += self.add(parent, child, stamp, T, static=static)
        return n

    @property
    def frames(self) -> set[str]:
        """Every frame that appears as a parent or a child."""
        return set(self._parent) | set(self._parent.values())

    def _to_root(self, frame: str, stamp_ns: int) -> tuple[str, np.ndarray]:
        """``(root, T_root_frame)`` at ``stamp_ns``; ``LookupError`` naming the failing link."""
        T = np.eye(4)
        seen = {frame}
        while frame in self._parent:
            parent = self._parent[frame]
            if frame in self._static:
                link = self._static[frame]
            else:
                buf = self._dynamic[frame]
                link = buf.lookup(stamp_ns)
                if link is None:
                    link = at_rest_lookup(buf, stamp_ns, self.at_rest)
                if link is None:
                    status = buf.lookup_status(stamp_ns).value
                    raise LookupError(
                        f"no transform {parent} -> {frame} at {stamp_ns} ns ({status}; "
                        f"{len(buf)} samples)"
                    )
            T = link @ T
            frame = parent
            if frame in seen:
                raise LookupError(f"tf loop through frame {frame!r}")
            seen.add(frame)
        return frame, T

    def chain_stamps(self, parent: str, child: str) -> np.ndarray:
        """The stamps [ns] (sorted, unique) of the samples of every dynamic link between
        ``parent`` and ``child`` (both up to their common root): where ``T_parent_child``
        changes, the pose stream of a tf pose source (:meth:`lookup` at each gives it)."""
        links, stamps = set(), []
        for frame in (parent, child):
            seen = {frame}
            while frame in self._parent:
                if frame in self._dynamic:
                    links.add(frame)
                frame = self._parent[frame]
                if frame in seen:
                    break
                seen.add(frame)
        for frame in links:
            stamps.append(self._dynamic[frame].stamps())
        return np.unique(np.concatenate(stamps)) if stamps else np.zeros(0, dtype=np.int64)

    def lookup(self, parent: str, child: str, stamp_ns: int) -> np.ndarray:
        """``T_parent_child`` (4, 4) at ``stamp_ns``.

        Raises ``LookupError`` when a frame is unknown, the two frames are not connected, or a
        dynamic link has no sample close enough to the stamp.
        """
        for f in (parent, child):
            if f not in self.frames:
                raise LookupError(f"frame {f!r} does not appear on /tf or /tf_static")
        root_p, T_root_parent = self._to_root(parent, stamp_ns)
        root_c, T_root_child = self._to_root(child, stamp_ns)
        if root_p != root_c:
            raise LookupError(
                f"frames {parent!r} and {child!r} are not connected (trees rooted at "
                f"{root_p!r} and {root_c!r})"
            )
        return invert_transform(T_root_parent) @ T_root_child


# ------------------------------------------------------------------------------------------------
# writing

_BASE_DTYPES = {
    "bool": np.bool_, "byte": np.uint8, "char": np.uint8, "octet": np.uint8,
    "int8": np.int8, "uint8": np.uint8, "int16": np.int16, "uint16": np.uint16,
    "int32": np.int32, "uint32": np.uint32, "int64": np.int64, "uint64": np.uint64,
    "float32": np.float32, "float64": np.float64,
}


def _field_value(store, kind: int, spec: Any, value: Any, where: str) -> Any:
    from rosbags.interfaces import Nodetype

    if kind == Nodetype.NAME:
        if value is not None and not isinstance(value, Mapping):
            return value  # already a message object
        return message_from_fields(spec, value or {}, typestore=store, where=where)
    if kind == Nodetype.BASE:
        name = spec[0]
        if name in ("string", "wstring"):
            return "" if value is None else str(value)
        dtype = _BASE_DTYPES[name]
        if value is None:
            value = 0
        return bool(value) if name == "bool" else dtype(value).item()
    # ARRAY (fixed length) or SEQUENCE
    (sub_kind, sub_spec), length = spec
    if sub_kind == Nodetype.BASE and sub_spec[0] in _BASE_DTYPES:
        dtype = _BASE_DTYPES[sub_spec[0]]
        if value is None:
            arr = np.zeros(length if kind == Nodetype.ARRAY else 0, dtype=dtype)
        elif isinstance(value, (bytes, bytearray, memoryview)):
            arr = np.frombuffer(bytes(value), dtype=dtype).copy()
        else:
            arr = np.asarray(value, dtype=dtype).reshape(-1)
        if kind == Nodetype.ARRAY and arr.shape[0] != length:
            raise ValueError(f"{where}: expected {length} elements, got {arr.shape[0]}")
        return arr
    items = list(value or [])
    return [_field_value(store, sub_kind, sub_spec, v, f"{where}[{i}]")
            for i, v in enumerate(items)]


def message_from_fields(msgtype: str, fields: Mapping[str, Any], *, typestore=None,
                        where: str | None = None) -> Any:
    """A ``rosbags`` message of type ``msgtype`` from a nested field dict.

    The dicts are those of :mod:`rwhec_ros.messages` (``*_fields`` functions); missing
    fields take ROS defaults (zero, empty string, zero-filled fixed arrays, empty sequences),
    ``bytes`` become ``uint8`` arrays. Raises ``ValueError`` for an unknown field or type.
    """
    store = typestore if typestore is not None else jazzy_typestore()
    where = where or msgtype
    if msgtype not in store.fielddefs:
        raise ValueError(f"{where}: unknown message type {msgtype!r}")
    _, defs = store.fielddefs[msgtype]
    names = {name for name, _ in defs}
    extra = sorted(set(fields) - names)
    if extra:
        raise ValueError(f"{where}: unknown fields {extra} for {msgtype} (fields {sorted(names)})")
    kwargs = {
        name: _field_value(store, kind, spec, fields.get(name), f"{where}.{name}")
        for name, (kind, spec) in defs
    }
    return store.types[msgtype](**kwargs)


def write_bag(
    path: str | Path,
    messages: Iterable[tuple[str, str, int, Any]],
    *,
    storage: str = "sqlite3",
    typestore=None,
) -> Path:
    """Write a rosbag2 recording (``rosbags.rosbag2.Writer``, bag version 9).

    Parameters
    ----------
    path : str or Path
        The bag directory to create (must not exist).
    messages : iterable of (topic, msgtype, log_time_ns, msg)
        ``msg`` a ``rosbags`` message (see :func:`message_from_fields`); one connection per
        topic, its type fixed by the first message.
    storage : {"sqlite3", "mcap"}

    Returns
    -------
    Path
        The bag directory.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer

    if storage not in _STORAGES:
        raise ValueError(f"storage: expected one of {list(_STORAGES)}, got {storage!r}")
    path = Path(path)
    if path.exists():
        raise ValueError(f"bag {str(path)!r}: already exists (a recording is never "
                         "overwritten): give another path, or remove it first")
    store = typestore if typestore is not None else jazzy_typestore()
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    conns: dict[str, Any] = {}
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        for topic, msgtype, log_time_ns, msg in messages:
            conn = conns.get(topic)
            if conn is None:
                conn = conns[topic] = writer.add_connection(topic, msgtype, typestore=store)
            elif conn.msgtype != msgtype:
                raise ValueError(f"topic {topic}: {msgtype} after {conn.msgtype}")
            writer.write(conn, int(log_time_ns), store.serialize_cdr(msg, msgtype))
    return path
