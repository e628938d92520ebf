"""The generalized RWHEC problem model: a bipartite graph of X and Y frames (paper Section 4.5).

Each edge ``e = (j, k)`` joins X-frame ``j`` and Y-frame ``k`` and holds ``N_e >= 1`` measurement
pairs ``(A_i, B_i)`` with ``A_i X_j = Y_k B_i`` (eq. (7)), where ``A`` is the noise-free pose-stream
transform and ``B`` the noisy camera-target measurement, together with per-pair precisions
``sigma_i`` (translation standard deviation, metres) and ``kappa_i`` (Langevin rotation
concentration), cf. eq. (32) and footnote 7.

With ``unknown_scale=True`` (monocular, Section 4.3, Problem 3) the translations of ``B`` are
``alpha`` times their metric values for an unknown common scale ``alpha`` (eq. (20): e.g. tags of
nominal size); the residual of eq. (22) then carries ``alpha t_A`` and the scaled unknowns
``alpha t_X``, ``alpha t_Y``. Otherwise ``alpha = 1`` (Problem 4).

Frame ordering in every state vector of the package: X-frames ``0..M-1`` first, then Y-frames
``0..P-1`` (global index ``M + k``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Edge", "Problem", "check_transforms", "check_precisions"]

#: Default tolerance on ``max|R^T R - I|`` and ``|det R - 1|`` for measurement rotations.
DEFAULT_ROTATION_TOL = 1e-6


def check_transforms(
    T: np.ndarray, *, what: str, rotation_tol: float = DEFAULT_ROTATION_TOL
) -> np.ndarray:
    """Validate a stack of rigid transforms (N, 4, 4) and return it as a float array.

    Raises ``ValueError`` naming ``what``, the index and the offending value when a number is not
    finite, the last row is not ``[0 0 0 1]``, or the rotation block is not orthonormal with
    ``det = +1`` within ``rotation_tol``.
    """
    T = np.asarray(T, dtype=float)
    if T.ndim == 2:
        T = T[None]
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        raise ValueError(f"{what}: expected shape (N, 4, 4), got {T.shape}")
    finite = np.isfinite(T).all(axis=(1, 2))
    if not finite.all():
        i = int(np.argmin(finite))
        raise ValueError(f"{what}[{i}]: non-finite value in {T[i].tolist()}")
    last = np.abs(T[:, 3, :] - np.array([0.0, 0.0, 0.0, 1.0])).max(axis=1)
    if (last > rotation_tol).any():
        i = int(np.argmax(last))
        raise ValueError(f"{what}[{i}]: last row must be [0, 0, 0, 1], got {T[i, 3].tolist()}")
    R = T[:, :3, :3]
    orth = np.abs(np.swapaxes(R, 1, 2) @ R - np.eye(3)).max(axis=(1, 2))
    if (orth > rotation_tol).any():
        i = int(np.argmax(orth))
        raise ValueError(
            f"{what}[{i}]: rotation block not orthonormal (max |R^T R - I| = {orth[i]:.3g} > "
            f"{rotation_tol:g}): {R[i].tolist()}"
        )
    det = np.linalg.det(R)
    bad = np.abs(det - 1.0) > rotation_tol
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"{what}[{i}]: rotation block has det {det[i]:.6g}, expected +1")
    return T


def check_precisions(values, n: int, *, what: str) -> np.ndarray:
    """Broadcast a scalar or validate an (n,) array of precisions: finite and > 0, else
    ``ValueError`` naming ``what``, the index and the value."""
    arr = np.asarray(values, dtype=float)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise ValueError(f"{what}: expected a scalar or shape ({n},), got shape {arr.shape}")
    bad = ~np.isfinite(arr) | (arr <= 0)
    if bad.any():
        i = int(np.argmax(bad))
        raise ValueError(f"{what}[{i}]: must be finite and > 0, got {arr[i]!r}")
    return arr


@dataclass(frozen=True)
class Edge:
    """Measurements between X-frame ``x`` and Y-frame ``y`` (names).

    Attributes
    ----------
    x, y : str
        Names of the X- and Y-frame.
    A, B : ndarray, shape (N, 4, 4)
        Pose-stream transforms (noise-free) and camera-target measurements (noisy), row ``i`` of
        each forming one pair with ``A_i X = Y B_i``.
    sigma : ndarray, shape (N,)
        Translation standard deviation of each ``B_i`` [m].
    kappa : ndarray, shape (N,)
        Langevin rotation concentration of each ``B_i``.
    """

    x: str
    y: str
    A: np.ndarray
    B: np.ndarray
    sigma: np.ndarray = field(default=None)  # type: ignore[assignment]
    kappa: np.ndarray = field(default=None)  # type: ignore[assignment]

    @property
    def n(self) -> int:
        return int(self.A.shape[0])

    @property
    def name(self) -> str:
        return f"({self.x}, {self.y})"

    @classmethod
    def _of(cls, x: str, y: str, A: np.ndarray, B: np.ndarray, sigma: np.ndarray,
            kappa: np.ndarray) -> Edge:
        """``Edge(x, y, A, B, sigma, kappa)`` (no validation, as that call), its fields set at
        once (the frozen dataclass's ``__init__`` sets them one by one through
        ``object.__setattr__``, twice the time: the live re-solve makes one per edge)."""
        obj = object.__new__(cls)
        obj.__dict__.update(x=x, y=y, A=A, B=B, sigma=sigma, kappa=kappa)
        return obj

    @staticmethod
    def build(
        x: str,
        y: str,
        A: np.ndarray,
        B: np.ndarray,
        sigma: float | np.ndarray = 0.01,
        kappa: float | np.ndarray = 125.0,
        *,
        rotation_tol: float = DEFAULT_ROTATION_TOL,
    ) -> Edge:
        """Validated constructor; scalars ``sigma``/``kappa`` are broadcast to every pair."""
        name = f"edge ({x}, {y})"
        A = check_transforms(A, what=f"{name} A", rotation_tol=rotation_tol)
        B = check_transforms(B, what=f"{name} B", rotation_tol=rotation_tol)
        if A.shape[0] != B.shape[0]:
            raise ValueError(f"{name}: {A.shape[0]} A transforms but {B.shape[0]} B transforms")
        if A.shape[0] < 1:
            raise ValueError(f"{name}: needs at least one measurement pair, got 0")
        n = A.shape[0]
        return Edge(
            x=x,
            y=y,
            A=A,
            B=B,
            sigma=check_precisions(sigma, n, what=f"{name} sigma"),
            kappa=check_precisions(kappa, n, what=f"{name} kappa"),
        )


class Problem:
    """A validated generalized RWHEC instance (Problem 3 / Problem 4 of the paper).

    Parameters
    ----------
    x_names, y_names : sequence of str
        Names of the M X-frames and P Y-frames (unique across both lists).
    edges : sequence of Edge
        Use :meth:`Edge.build` (validated). Every frame must be touched by an edge; at most one
        edge per (x, y) pair.
    unknown_scale : bool
        Estimate a common scale ``alpha`` of the B translations (monocular, Problem 3).
    """

    def __init__(
        self,
        x_names: Sequence[str],
        y_names: Sequence[str],
        edges: Sequence[Edge],
        *,
        unknown_scale: bool = False,
    ) -> None:
        self.x_names: tuple[str, ...] = tuple(str(n) for n in x_names)
        self.y_names: tuple[str, ...] = tuple(str(n) for n in y_names)
        self.unknown_scale = bool(unknown_scale)
        names = self.x_names + self.y_names
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise ValueError(f"frame names must be unique across X and Y, duplicated: {dup}")
        if not self.x_names or not self.y_names:
            raise ValueError(
                f"need at least one X and one Y frame, got {len(self.x_names)} and "
                f"{len(self.y_names)}"
            )
        x_index = {n: i for i, n in enumerate(self.x_names)}
        y_index = {n: i for i, n in enumerate(self.y_names)}
        edges = tuple(edges)
        seen: set[tuple[str, str]] = set()
        xi, yi = [], []
        for e_idx, e in enumerate(edges):
            if not isinstance(e, Edge):
                raise ValueError(f"edges[{e_idx}]: expected Edge, got {type(e).__name__}")
            i, j = x_index.get(e.x), y_index.get(e.y)
            if i is None:
                raise ValueError(f"edges[{e_idx}] {e.name}: unknown X frame {e.x!r}")
            if j is None:
                raise ValueError(f"edges[{e_idx}] {e.name}: unknown Y frame {e.y!r}")
            if (e.x, e.y) in seen:
                raise ValueError(f"edges[{e_idx}] {e.name}: duplicate edge")
            seen.add((e.x, e.y))
            if e.sigma is None or e.kappa is None:
                raise ValueError(f"edges[{e_idx}] {e.name}: build edges with Edge.build")
            xi.append(i)
            yi.append(j)
        self.edges: tuple[Edge, ...] = edges
        touched = {x for x, _ in seen} | {y for _, y in seen}
        untouched = [n for n in names if n not in touched]
        if untouched:
            raise ValueError(f"frames not touched by any edge: {untouched}")
        self.edge_x = np.array(xi, dtype=int)
        self.edge_y = np.array(yi, dtype=int)
        #: The cost's edge blocks ``(full, rot, idx)`` of these edges when computed ahead
        #: (:class:`~rwhec_ros.core.model.edge_cache.EdgeBlockCache`, the live re-solve's), used by
        #: :func:`~rwhec_ros.core.model.cost.edge_blocks` instead of assembling them; ``None``:
        # built  when needed. Only valid while the edges' arrays are not changed in place.
        self.precomputed_blocks: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    # --- sizes -------------------------------------------------------------------------------
    @property
    def M(self) -> int:
        """Number of X-frames."""
        return len(self.x_names)

    @property
    def P(self) -> int:
        """Number of Y-frames."""
        return len(self.y_names)

    @property
    def n_frames(self) -> int:
        return self.M + self.P

    @property
    def n_measurements(self) -> int:
        """Number of pairs (counted once per ``edges`` tuple)."""
        counted = self.__dict__.get("_n_measurements")
        if counted is None or counted[0] is not self.edges:
            counted = (self.edges, int(sum(e.n for e in self.edges)))
            self.__dict__["_n_measurements"] = counted
        return counted[1]

    @property
    def frame_names(self) -> tuple[str, ...]:
        """All names in state order: X-frames then Y-frames."""
        return self.x_names + self.y_names

    def stacked(self) -> dict[str, np.ndarray]:
        """All pairs concatenated: ``A, B`` (N, 4, 4), ``sigma, kappa`` (N,), frame indices
        ``xi`` (N,) in ``0..M-1`` and ``yi`` (N,) in ``0..P-1``, and ``edge`` (N,)."""
        counts = [e.n for e in self.edges]
        return {
            "A": np.concatenate([e.A for e in self.edges]),
            "B": np.concatenate([e.B for e in self.edges]),
            "sigma": np.concatenate([e.sigma for e in self.edges]),
            "kappa": np.concatenate([e.kappa for e in self.edges]),
            "xi": np.repeat(self.edge_x, counts),
            "yi": np.repeat(self.edge_y, counts),
            "edge": np.repeat(np.arange(len(self.edges)), counts),
        }

    def components(self) -> list[list[str]]:
        """Weakly connected components of the graph, as lists of frame names."""
        parent = list(range(self.n_frames))

        def find(a: int) -> int:
            while parent[a] != a:
                parent[a] = parent[parent[a]]
                a = parent[a]
            return a

        for j, k in zip(self.edge_x, self.edge_y, strict=False):
            ra, rb = find(int(j)), find(self.M + int(k))
            if ra != rb:
                parent[ra] = rb
        groups: dict[int, list[str]] = {}
        for i, name in enumerate(self.frame_names):
            groups.setdefault(find(i), []).append(name)
        return list(groups.values())

    def with_edges(self, edges: Sequence[Edge], *, unknown_scale: bool | None = None) -> Problem:
        """A new problem on a subset/replacement of edges; frames no edge touches are dropped."""
        touched = {e.x for e in edges} | {e.y for e in edges}
        return Problem(
            [n for n in self.x_names if n in touched],
            [n for n in self.y_names if n in touched],
            edges,
            unknown_scale=self.unknown_scale if unknown_scale is None else unknown_scale,
        )

    def __repr__(self) -> str:
        return (
            f"Problem(M={self.M}, P={self.P}, edges={len(self.edges)}, "
            f"pairs={self.n_measurements}, unknown_scale={self.unknown_scale})"
        )
