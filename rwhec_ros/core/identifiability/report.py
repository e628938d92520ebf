"""The identifiability report: components (Theorems 1 and 3), the Fig. 10 grid and :func:`analyze`.

A weakly connected component of the measurement graph is identifiable as soon as one of its edges
is (propagation by Theorems 1 and 3); the numeric check, when it ran, has the final word.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..model.recentre import recentred_frames, recentred_problem, recentring_for
from ..problem import Problem
from .edge import EdgeIdentifiability, EdgeStatistics, analyze_edge
from .numeric import NumericCheck, numeric_check
from .status import (
    IdentifiabilityStatus,
    IdentifiabilityThresholds,
    best_status,
    worst_status,
)

__all__ = ["ComponentIdentifiability", "IdentifiabilityReport", "analyze", "build_report"]


# ----------------------------------------------------------------------------------------------
# Components and the report
# ----------------------------------------------------------------------------------------------
@dataclass
class ComponentIdentifiability:
    """One weakly connected component of the measurement graph (Theorem 1).

    Attributes
    ----------
    x_names, y_names : list of str
    edges : list of (str, str)
    identifiable_edges : list of (str, str)
        Edges identifiable on their own (status ``identifiable`` or ``weak``).
    propagation_status : IdentifiabilityStatus
        Best edge status (Corollaries 2/4 propagated by Theorems 1/3).
    status : IdentifiabilityStatus
        Final verdict: the numeric check's if it ran, else ``propagation_status``.
    reasons : list of str
    """

    x_names: list[str]
    y_names: list[str]
    edges: list[tuple[str, str]]
    identifiable_edges: list[tuple[str, str]]
    propagation_status: IdentifiabilityStatus
    status: IdentifiabilityStatus
    reasons: list[str]

    @property
    def frames(self) -> list[str]:
        return self.x_names + self.y_names

    def to_dict(self) -> dict:
        return {
            "x_names": list(self.x_names),
            "y_names": list(self.y_names),
            "edges": [list(e) for e in self.edges],
            "identifiable_edges": [list(e) for e in self.identifiable_edges],
            "propagation_status": self.propagation_status.value,
            "status": self.status.value,
            "reasons": list(self.reasons),
        }


_GRID_CHARS = {
    IdentifiabilityStatus.IDENTIFIABLE: "#",
    IdentifiabilityStatus.WEAK: "+",
    IdentifiabilityStatus.INSUFFICIENT: "x",
    None: ".",
}
_GRID_COLORS = {
    IdentifiabilityStatus.IDENTIFIABLE: (0.13, 0.36, 0.80),
    IdentifiabilityStatus.WEAK: (0.60, 0.74, 0.95),
    IdentifiabilityStatus.INSUFFICIENT: (0.84, 0.15, 0.16),
    None: (1.0, 1.0, 1.0),
}
_GRID_LABELS = {
    IdentifiabilityStatus.IDENTIFIABLE: "identifiable",
    IdentifiabilityStatus.WEAK: "weak (identifiable, below comfortable thresholds)",
    IdentifiabilityStatus.INSUFFICIENT: "observed, insufficient on its own",
    None: "not observed",
}


@dataclass
class IdentifiabilityReport:
    """Identifiability of a generalized RWHEC problem.

    Attributes
    ----------
    x_names, y_names : tuple of str
        X-frames (tags, grid columns) and Y-frames (cameras, grid rows).
    unknown_scale : bool
    edges : list of EdgeIdentifiability
    components : list of ComponentIdentifiability
    identifiable : bool
        Every component is identifiable (possibly weakly).
    verdict : str
        The overall answer in words.
    numeric : NumericCheck or None
        The whole-problem check, when requested.
    thresholds : IdentifiabilityThresholds
    """

    x_names: tuple[str, ...]
    y_names: tuple[str, ...]
    unknown_scale: bool
    edges: list[EdgeIdentifiability]
    components: list[ComponentIdentifiability]
    identifiable: bool
    verdict: str
    numeric: NumericCheck | None = None
    thresholds: IdentifiabilityThresholds = field(default_factory=IdentifiabilityThresholds)

    @property
    def status(self) -> IdentifiabilityStatus:
        """Worst component status."""
        return worst_status(c.status for c in self.components)

    def edge(self, x: str, y: str) -> EdgeIdentifiability | None:
        """The report of edge ``(x, y)``, or None if it was not observed."""
        for e in self.edges:
            if e.x == x and e.y == y:
                return e
        return None

    def grid(self) -> list[list[IdentifiabilityStatus | None]]:
        """Edge statuses, rows Y-frames, columns X-frames (None: not observed)."""
        cell = {(e.y, e.x): e.status for e in self.edges}
        return [[cell.get((y, x)) for x in self.x_names] for y in self.y_names]

    def grid_text(self) -> str:
        """Text version of the paper's Figure 10: rows cameras (Y), columns tags (X)."""
        grid = self.grid()
        width = max(len(str(max(len(self.x_names) - 1, 0))), 1) + 1
        label = max([len(y) for y in self.y_names] + [1])
        lines = ["Identifiability per edge (cf. paper Fig. 10): rows Y frames (cameras), "
                 "columns X frames (tags)"]
        lines.append("legend: " + "   ".join(f"{_GRID_CHARS[k]} {_GRID_LABELS[k]}"
                                             for k in _GRID_CHARS))
        lines.append("columns: " + " ".join(f"{j}={x}" for j, x in enumerate(self.x_names)))
        lines.append(" " * label + "".join(f"{j:>{width}}" for j in range(len(self.x_names))))
        for y, row in zip(self.y_names, grid, strict=True):
            lines.append(f"{y:<{label}}" + "".join(f"{_GRID_CHARS[c]:>{width}}" for c in row))
        lines.append(self.verdict)
        return "\n".join(lines)

    def save_grid_png(self, path: str | Path, *, dpi: int = 120) -> None:
        """Save the grid as a PNG (blue identifiable, light blue weak, red insufficient -- amber
        when the whole problem is identifiable anyway --, white not observed; cf. paper
        Fig. 10). Uses the Agg canvas, no pyplot state."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
        from matplotlib.patches import Patch, Rectangle

        grid = self.grid()
        M, P = len(self.x_names), len(self.y_names)
        colors, labels = dict(_GRID_COLORS), dict(_GRID_LABELS)
        if self.identifiable:  # the graph fixes such edges: no alarm red
            colors[IdentifiabilityStatus.INSUFFICIENT] = (0.98, 0.78, 0.45)
            labels[IdentifiabilityStatus.INSUFFICIENT] = ("not identifiable on its own, fixed "
                                                          "through the graph")
        fig = Figure(figsize=(max(4.0, 0.45 * M + 2.5), max(3.0, 0.45 * P + 2.5)))
        FigureCanvasAgg(fig)
        ax = fig.add_subplot(1, 1, 1)
        for k, row in enumerate(grid):
            for j, st in enumerate(row):
                ax.add_patch(Rectangle((j, k), 1, 1, facecolor=colors[st],
                                       edgecolor="0.4", linewidth=0.6,
                                       hatch="//" if st is IdentifiabilityStatus.WEAK else None))
        ax.set_xlim(0, M)
        ax.set_ylim(P, 0)
        ax.set_aspect("equal")
        ax.set_xticks(np.arange(M) + 0.5)
        ax.set_xticklabels(self.x_names, rotation=90, fontsize=8)
        ax.set_yticks(np.arange(P) + 0.5)
        ax.set_yticklabels(self.y_names, fontsize=8)
        ax.set_xlabel("X frames (tags)")
        ax.set_ylabel("Y frames (cameras)")
        ax.set_title(self.verdict.split(":")[0], fontsize=10)
        handles = [Patch(facecolor=colors[k], edgecolor="0.4", label=labels[k],
                         hatch="//" if k is IdentifiabilityStatus.WEAK else None)
                   for k in colors]
        fig.legend(handles=handles, loc="lower center", fontsize=7, ncol=2, frameon=False)
        fig.tight_layout(rect=(0, 0.12, 1, 1))
        fig.savefig(str(path), dpi=dpi)

    def to_dict(self) -> dict:
        """Plain, YAML-able mapping."""
        return {
            "identifiable": bool(self.identifiable),
            "status": self.status.value,
            "verdict": self.verdict,
            "unknown_scale": bool(self.unknown_scale),
            "x_names": list(self.x_names),
            "y_names": list(self.y_names),
            "edges": [e.to_dict() for e in self.edges],
            "components": [c.to_dict() for c in self.components],
            "numeric": None if self.numeric is None else self.numeric.to_dict(),
            "thresholds": {k: (int(v) if isinstance(v, int) else float(v))
                           for k, v in asdict(self.thresholds).items()},
        }


def _components(x_names: Sequence[str], y_names: Sequence[str],
                edges: Sequence[tuple[str, str]]) -> list[tuple[list[str], list[str]]]:
    names = list(x_names) + list(y_names)
    index = {n: i for i, n in enumerate(names)}
    parent = list(range(len(names)))

    def find(a: int) -> int:
        while parent[a] != a:
            parent[a] = parent[parent[a]]
            a = parent[a]
        return a

    for x, y in edges:
        ra, rb = find(index[x]), find(index[y])
        if ra != rb:
            parent[ra] = rb
    groups: dict[int, tuple[list[str], list[str]]] = {}
    for i, n in enumerate(names):
        g = groups.setdefault(find(i), ([], []))
        (g[0] if i < len(x_names) else g[1]).append(n)
    return list(groups.values())


def build_report(
    x_names: Sequence[str],
    y_names: Sequence[str],
    unknown_scale: bool,
    edges: list[EdgeIdentifiability],
    thresholds: IdentifiabilityThresholds,
    numeric: NumericCheck | None,
) -> IdentifiabilityReport:
    S = IdentifiabilityStatus
    scale_edges = [e for e in edges if e.identifiable]
    comps = []
    for xs, ys in _components(x_names, y_names, [(e.x, e.y) for e in edges]):
        members = set(xs) | set(ys)
        ce = [e for e in edges if e.x in members]
        ident = [(e.x, e.y) for e in ce if e.identifiable]
        prop = best_status(e.status for e in ce)
        reasons = []
        if prop is not S.INSUFFICIENT:
            best = next(e for e in ce if e.status is prop)
            reasons.append(f"edge {best.name} is {prop.value} on its own; Theorems 1/3 "
                           f"propagate it to all {len(members)} frames of the component")
        elif unknown_scale and scale_edges and any(e.rigid_status is not S.INSUFFICIENT
                                                    for e in ce):
            prop = best_status(e.rigid_status for e in ce)
            best = next(e for e in ce if e.rigid_status is prop)
            reasons.append(f"edge {best.name} determines the rigid part; the shared scale comes "
                           f"from edge {scale_edges[0].name} in another component")
        else:
            reasons.append(f"no edge is identifiable on its own (Corollaries 2/4 do not apply to "
                           f"any of its {len(ce)} edges)")
        status = prop
        if numeric is not None:
            fs = [numeric.frame_status[n] for n in xs + ys if n in numeric.frame_status]
            status = worst_status(fs)
            if numeric.scale_undetermined and any(n in numeric.undetermined_frames
                                                  for n in members):
                status = S.INSUFFICIENT
            if (numeric.scale_rel_std is not None and np.isfinite(numeric.scale_rel_std)
                    and numeric.scale_rel_std > thresholds.full_scale_rel_std):
                status = worst_status([status, S.WEAK])
            bad = [n for n in xs + ys if n in numeric.undetermined_frames]
            if bad:
                reasons.append("numeric check: not determined: " + ", ".join(bad))
            elif prop is S.INSUFFICIENT:
                reasons.append("numeric check: the edges together determine every frame "
                               "(Theorem 1's general case)")
            weak = [n for n in xs + ys if numeric.frame_status.get(n) is S.WEAK]
            if weak:
                reasons.append("numeric check: weakly determined: " + ", ".join(weak))
        comps.append(ComponentIdentifiability(
            x_names=xs, y_names=ys, edges=[(e.x, e.y) for e in ce], identifiable_edges=ident,
            propagation_status=prop, status=status, reasons=reasons))
    identifiable = all(c.status is not S.INSUFFICIENT for c in comps)
    n_frames = len(x_names) + len(y_names)
    n_ident = sum(e.identifiable for e in edges)
    summary = (f"{len(comps)} weakly connected component(s), {n_frames} frames, {n_ident} of "
               f"{len(edges)} edges identifiable on their own"
               + ("" if numeric is None else ", numeric check done"))
    if identifiable:
        worst = worst_status(c.status for c in comps)
        verdict = ("identifiable" if worst is S.IDENTIFIABLE else "identifiable, but weakly") + \
            f": {summary}"
        if len(comps) > 1:
            verdict += "; each component is calibrated on its own (no link between them)"
    else:
        bad = [c for c in comps if c.status is S.INSUFFICIENT]
        verdict = (f"NOT identifiable: {len(bad)} of {len(comps)} component(s) undetermined "
                   f"(frames " + "; ".join(", ".join(c.frames) for c in bad) + f"); {summary}")
    return IdentifiabilityReport(
        x_names=tuple(x_names), y_names=tuple(y_names), unknown_scale=unknown_scale,
        edges=edges, components=comps, identifiable=identifiable, verdict=verdict,
        numeric=numeric, thresholds=thresholds)


def analyze(
    problem: Problem,
    *,
    thresholds: IdentifiabilityThresholds | None = None,
    full: bool = True,
    solution: tuple[np.ndarray, np.ndarray, float] | None = None,
) -> IdentifiabilityReport:
    """Identifiability report of ``problem`` (batch).

    Parameters
    ----------
    problem : Problem
    thresholds : IdentifiabilityThresholds, optional
    full : bool
        Run the whole-problem :func:`numeric_check` (needs all pairs; ~O(pairs + frames^3)).
    solution : (X (M,4,4), Y (P,4,4), alpha), optional
        Linearisation point for the numeric check (e.g. the certified solution); metric.
    """
    thr = thresholds or IdentifiabilityThresholds()
    rc = recentring_for(problem)
    if rc is not None:
        # far from a carrier's origin the rounding of the translations makes determined
        # directions look flat: the same analysis about a point near the data (the
        # identifiability of the problem does not depend on where the origins are)
        problem = recentred_problem(problem, rc)[0]
        if solution is not None:
            solution = (*recentred_frames(solution[0], solution[1], rc), solution[2])
    edges = [analyze_edge(EdgeStatistics.from_edge(e), problem.unknown_scale, thr)
             for e in problem.edges]
    numeric = numeric_check(problem, thresholds=thr, solution=solution) if full else None
    return build_report(problem.x_names, problem.y_names, problem.unknown_scale, edges, thr,
                         numeric)
