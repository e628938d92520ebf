"""What the time offsets of :mod:`rwhec_ros.session.time_offsets` are reported as: the options,
each camera's offset with its status and words, the ``time_offsets`` section of ``result.yaml``,
the ``/diagnostics`` values and the verdict's caution."""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

__all__ = ["TimeOffsetOptions", "CameraOffset", "TimeOffsetReport", "add_offset_reasons",
           "SIGNIFICANT_SIGMAS", "CAUTION_S", "NOT_CERTIFIED", "ms_std"]

#: An offset beyond this many standard deviations is significant (applied) ...
SIGNIFICANT_SIGMAS = 3.0
#: ... and the verdict names one beyond this too [s].
CAUTION_S = 0.002
#: What the offsets are, in the result, the summary and ``/diagnostics``: the certificate proves
#: the extrinsics globally optimal for fixed pairs (those at the applied offsets); the offsets
#: come from Gauss-Newton steps started at a certified solution, which certify nothing.
NOT_CERTIFIED = ("a local estimate (Gauss-Newton steps on top of the certified solve), not "
                 "certified: the certificate covers the extrinsics for the pairs at the applied "
                 "offsets, not the offsets")


def ms_std(std_s: float) -> str:
    """A std [s] in milliseconds with one decimal, or two significant digits below 0.1 ms (a
    std of 0.04 ms is not written as 0.0)."""
    v = 1e3 * float(std_s)
    return f"{v:.1f}" if not math.isfinite(v) or abs(v) >= 0.1 else f"{v:.2g}"


@dataclass(frozen=True)
class TimeOffsetOptions:
    """What to do about time offsets (``sync.*`` of the configuration).

    Attributes
    ----------
    estimate : bool
        ``sync.estimate_time_offset``.
    range_s : float
        ``sync.time_offset_range_s``: the offsets searched lie within +- this [s].
    max_std_s : float
        ``sync.time_offset_max_std_s``: a larger standard deviation is "not determined".
    configured_s : tuple of (str, float)
        The offsets already in the pairs' stamps: ``sync.time_offset.<camera>`` in a session, a
        data set's ``time_offsets_s``.
    parameter_s : tuple of (str, float) or None
        ``sync.time_offset.<camera>`` of the configuration, when it differs from
        ``configured_s`` (a data set whose pairs carry an offset found before): the verdict
        compares the whole offset with it. None: ``configured_s``.
    """

    estimate: bool = True
    range_s: float = 0.1
    max_std_s: float = 0.005
    configured_s: tuple[tuple[str, float], ...] = ()
    parameter_s: tuple[tuple[str, float], ...] | None = None

    @classmethod
    def from_config(cls, config) -> TimeOffsetOptions:
        """From a :class:`~rwhec_ros.config.CalibratorConfig`, or from flat parameters (a
        mapping: the ``sync.*`` keys present, defaults for the others); None: the defaults."""
        if config is None:
            return cls()
        if isinstance(config, Mapping):
            d = cls()
            prefix = "sync.time_offset."
            offsets = tuple((k[len(prefix):], float(v)) for k, v in config.items()
                            if k.startswith(prefix))
            return cls(bool(config.get("sync.estimate_time_offset", d.estimate)),
                       float(config.get("sync.time_offset_range_s", d.range_s)),
                       float(config.get("sync.time_offset_max_std_s", d.max_std_s)), offsets)
        s = config.sync
        return cls(bool(s.estimate_time_offset), float(s.time_offset_range_s),
                   float(s.time_offset_max_std_s), tuple(s.time_offsets))

    def configured(self, camera: str) -> float:
        return float(dict(self.configured_s).get(camera, 0.0))

    def parameter(self, camera: str) -> float:
        table = self.configured_s if self.parameter_s is None else self.parameter_s
        return float(dict(table).get(camera, 0.0))


@dataclass
class CameraOffset:
    """The time offset of one camera.

    Attributes
    ----------
    camera : str
    status : str
        ``estimated`` (determined: ``estimate_s`` +- ``std_s``), ``not_determined`` (the data
        cannot tell: ``why``) or ``not_estimated`` (estimation off, or no recorded stream).
    configured_s : float
        The offset in the pairs' stamps already (``sync.time_offset.<camera>``, or a data
        set's).
    parameter_s : float
        ``sync.time_offset.<camera>`` of the configuration (the verdict compares with it).
    estimate_s : float
        The offset left in the data, on top of the configured one [s] (NaN unless estimated).
    std_s : float
        Its standard deviation [s] (NaN unless estimated).
    applied : bool
        The final pairs are re-interpolated at stamps shifted by ``estimate_s``.
    moving_pairs, pairs : int
        Pairs taken while the stream moved, and all pairs of the camera.
    why : str
        For ``not_determined``/``not_estimated``: why, in words.
    dropped : int
        Pairs left out of the final solve because the recorded stream does not reach their
        corrected stamps.
    lr_sigmas : float
        The likelihood-ratio test of an offset beyond 3 std, in std
        (:mod:`rwhec_ros.session.offset_significance`); NaN when not made. Below 3 the offset
        is not significant.
    """

    camera: str
    status: str
    configured_s: float = 0.0
    parameter_s: float = 0.0
    estimate_s: float = math.nan
    std_s: float = math.nan
    applied: bool = False
    moving_pairs: int = 0
    pairs: int = 0
    why: str = ""
    dropped: int = 0
    lr_sigmas: float = math.nan

    @property
    def determined(self) -> bool:
        return self.status == "estimated"

    @property
    def offset_s(self) -> float:
        """The camera's whole offset (configured + estimated) [s]; NaN unless estimated."""
        return self.configured_s + self.estimate_s if self.determined else math.nan

    @property
    def vetoed(self) -> bool:
        """The likelihood-ratio test was made and found the offset within 3 std."""
        return self.lr_sigmas <= SIGNIFICANT_SIGMAS  # NaN (not made): False

    @property
    def significant(self) -> bool:
        return (self.determined and abs(self.estimate_s) > SIGNIFICANT_SIGMAS * self.std_s
                and not self.vetoed)

    @property
    def caution(self) -> bool:
        """The whole offset differs from ``sync.time_offset.<camera>`` by more than 3 std and
        :data:`CAUTION_S`: the verdict names it."""
        if not self.determined:
            return False
        d = abs(self.offset_s - self.parameter_s)
        return d > SIGNIFICANT_SIGMAS * self.std_s and d > CAUTION_S and not self.vetoed

    def words(self) -> str:
        """``12.3 +- 0.4 ms (applied)`` or ``not determined (why)``."""
        if not self.determined:
            word = "not determined" if self.status == "not_determined" else "not estimated"
            return f"{word} ({self.why})"
        if self.applied:
            tail = "applied"
        elif self.vetoed:
            tail = (f"not significant (beyond 3 std, but a solve without it fits only "
                    f"{self.lr_sigmas:.1f} std worse): not applied")
        else:
            tail = "not significant (within 3 std): not applied"
        conf = (f" ({1e3 * self.configured_s:g} ms of it in the pairs' stamps)"
                if self.configured_s else "")
        return (f"{1e3 * self.offset_s:+.1f} +- {ms_std(self.std_s)} ms{conf}, {tail}"
                + (f"; {self.dropped} pairs beyond the recorded stream left out"
                   if self.dropped else ""))

    def to_dict(self) -> dict:
        def num(v: float) -> float | None:
            return None if not math.isfinite(v) else float(v)
        return {"status": self.status, "offset_s": num(self.offset_s),
                "std_s": num(self.std_s), "configured_s": float(self.configured_s),
                "parameter_s": float(self.parameter_s),
                "estimated_s": num(self.estimate_s), "applied": bool(self.applied),
                "significant": bool(self.significant), "moving_pairs": int(self.moving_pairs),
                "pairs": int(self.pairs), "dropped_pairs": int(self.dropped),
                "likelihood_ratio_sigmas": num(self.lr_sigmas), "why": self.why}


@dataclass
class TimeOffsetReport:
    """Every camera's time offset (:func:`estimate_offsets`).

    Attributes
    ----------
    cameras : dict of str to CameraOffset
    iterations : int
        Newton steps taken.
    solves : int
        Solves made for the estimate (the final certified solve not counted).
    elapsed_s : float
    range_s : float
    notes : list of str
    """

    cameras: dict[str, CameraOffset] = field(default_factory=dict)
    iterations: int = 0
    solves: int = 0
    elapsed_s: float = 0.0
    range_s: float = 0.1
    notes: list[str] = field(default_factory=list)

    @property
    def applied(self) -> dict[str, float]:
        """Camera -> the estimate applied to its pairs [s]."""
        return {c: o.estimate_s for c, o in self.cameras.items() if o.applied}

    def to_dict(self) -> dict:
        """The ``time_offsets`` section of ``result.yaml``."""
        return {"convention": "t_pose = t_image + offset_s",
                "certified": False, "method": NOT_CERTIFIED,
                "range_s": float(self.range_s), "iterations": int(self.iterations),
                "solves": int(self.solves), "elapsed_s": float(self.elapsed_s),
                "cameras": {c: o.to_dict() for c, o in self.cameras.items()},
                "notes": list(self.notes)}

    def into(self, doc: dict) -> dict:
        """``doc`` (a result mapping) with this ``time_offsets`` section placed before
        ``excluded_edges`` (at the end without it), not last: a ``result.yaml`` cut short inside
        or before the section then lacks the keys after it that every result has, and is refused
        as incomplete (:func:`~rwhec_ros.data.results.incomplete_result`)."""
        out: dict = {}
        for key, value in doc.items():
            if key == "excluded_edges":
                out["time_offsets"] = self.to_dict()
            if key != "time_offsets":
                out[key] = value
        if "time_offsets" not in out:
            out["time_offsets"] = self.to_dict()
        return out

    def lines(self) -> list[str]:
        """Summary lines: ``time offset cam1: +20.3 +- 0.4 ms, applied``, then, when a number
        is shown, ``time offsets: a local estimate ..., not certified`` (:data:`NOT_CERTIFIED`);
        one line when no camera's was estimated for one reason."""
        whys = {(o.status, o.why) for o in self.cameras.values()}
        if len(whys) == 1 and next(iter(whys))[0] == "not_estimated":
            return [f"time offsets: not estimated ({next(iter(whys))[1]})"]
        lines = [f"time offset {c}: {o.words()}" for c, o in self.cameras.items()]
        if any(o.determined for o in self.cameras.values()):
            lines.append(f"time offsets: {NOT_CERTIFIED}")
        return lines

    def diagnostic_values(self, prefix: str = "time_offset") -> list[tuple[str, str]]:
        """``(key, value)`` pairs for ``/diagnostics``: ``time_offset <camera>`` ->
        ``+20.3 +- 0.4 ms`` or ``not determined (...)``; with a number, ``time_offsets`` ->
        ``local estimate, not certified``."""
        out = []
        for c, o in self.cameras.items():
            value = (f"{1e3 * o.offset_s:+.1f} +- {ms_std(o.std_s)} ms" if o.determined
                     else o.words())
            out.append((f"{prefix} {c}", value))
        if any(o.determined for o in self.cameras.values()):
            out.append((f"{prefix}s", "local estimate, not certified"))
        return out


def add_offset_reasons(verdict, report: TimeOffsetReport | None) -> None:
    """Add a caution to ``verdict`` (in place) for each camera whose offset is significant and
    beyond :data:`CAUTION_S`, naming the fix, and raise its level to caution if it was good."""
    if verdict is None or report is None:
        return
    from ..core.verdict.model import PRIORITY, Reason
    from ..core.verdict.options import level_rank, worst_level

    added = False
    for cam, o in report.cameras.items():
        if not o.caution:
            continue
        late = "late" if o.offset_s < 0 else "early"
        param = (f" (sync.time_offset.{cam} is {o.parameter_s:g})" if o.parameter_s else "")
        verdict.reasons.append(Reason(
            "caution", "time_offset",
            f"camera {cam}'s images are stamped {1e3 * abs(o.offset_s):.1f} +- "
            f"{ms_std(o.std_s)} ms {late} against the pose stream (t_pose = t_image "
            f"{'+' if o.offset_s >= 0 else '-'} {1e3 * abs(o.offset_s):.1f} ms): "
            + ("estimated and applied here" if o.applied else
               "in the data's stamps already, nothing left to apply")
            + f"{param}; set sync.time_offset.{cam}: {o.offset_s:.4f} (or fix the camera "
            "driver's stamps) so that live pairing and keyframes use it from the start",
            frames=(cam,)))
        fv = verdict.frames.get(cam)
        if fv is not None and "time offset" not in fv.why:
            fv.why.append("time offset")
            if level_rank("caution") > level_rank(fv.level):
                fv.level = "caution"
        added = True
    if added:
        order = {code: i for i, code in enumerate(PRIORITY)}
        verdict.reasons.sort(key=lambda r: (-level_rank(r.level), order.get(r.code, len(order))))
        verdict.level = worst_level([verdict.level, "caution"])
