"""A :class:`~rwhec_ros.core.problem.Problem` from kept pairs per edge, :func:`problem_from_edges`.

What :meth:`PairAccumulator.to_problem <rwhec_ros.sync.accumulator.PairAccumulator.to_problem>`
and the live re-solve (from a snapshot taken under the session's lock,
:meth:`~rwhec_ros.sync.accumulator.PairAccumulator.kept_pairs`) build: the edges with at least
``min_pairs`` pairs among the requested frames, ordered by frame, and the reason each other edge
was left out.
"""

from __future__ import annotations

import numbers
from collections.abc import Sequence

from ..core.problem import DEFAULT_ROTATION_TOL, Edge, Problem
from .edge_pairs import DatasetEdge
from .edge_store import KeptPairs

__all__ = ["problem_from_edges"]


def _is_int(value: object) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)



def problem_from_edges(
    data: dict[tuple[str, str], DatasetEdge | KeptPairs],
    x_names: Sequence[str] | None = None,
    y_names: Sequence[str] | None = None,
    unknown_scale: bool = False,
    min_pairs: int = 3,
    rotation_tol: float = DEFAULT_ROTATION_TOL,
    *,
    validate: bool = True,
) -> tuple[Problem, dict[tuple[str, str], str]]:
    """:meth:`PairAccumulator.to_problem` of ``data`` (its :meth:`~PairAccumulator.edges` or
    :meth:`~PairAccumulator.kept_pairs`, e.g. copied under a lock and built outside it); same
    parameters, returns and errors. ``validate=False`` skips re-checking the transforms and
    precisions of :meth:`~PairAccumulator.kept_pairs` (checked when offered)."""
    if not _is_int(min_pairs) or min_pairs < 1:
        raise ValueError(f"min_pairs: expected an integer >= 1, got {min_pairs!r}")
    xs = sorted({x for x, _ in data}) if x_names is None else [str(n) for n in x_names]
    ys = sorted({y for _, y in data}) if y_names is None else [str(n) for n in y_names]
    x_index = {n: i for i, n in enumerate(xs)}
    y_index = {n: i for i, n in enumerate(ys)}
    excluded: dict[tuple[str, str], str] = {}
    kept: list[DatasetEdge] = []
    for (x, y), e in data.items():
        if x not in x_index:
            excluded[(x, y)] = f"X frame {x!r} not in x_names"
        elif y not in y_index:
            excluded[(x, y)] = f"Y frame {y!r} not in y_names"
        elif e.n < min_pairs:
            excluded[(x, y)] = f"{e.n} pairs < min_pairs={min_pairs}"
        else:
            kept.append(e)
    if not kept:
        raise ValueError(
            f"to_problem: no edge has at least min_pairs={min_pairs} pairs among the "
            f"requested frames; excluded: {excluded}"
        )
    kept.sort(key=lambda e: (x_index[e.x], y_index[e.y]))
    if validate:
        edges = [Edge.build(e.x, e.y, e.A, e.B, sigma=e.sigma, kappa=e.kappa,
                            rotation_tol=rotation_tol) for e in kept]
    else:
        edges = [Edge._of(e.x, e.y, e.A, e.B, e.sigma, e.kappa) for e in kept]
    touched = {e.x for e in kept} | {e.y for e in kept}
    problem = Problem(
        [n for n in xs if n in touched],
        [n for n in ys if n in touched],
        edges,
        unknown_scale=unknown_scale,
    )
    return problem, excluded

