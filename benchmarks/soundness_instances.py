"""Seeded adversarial instance generators for the certificate-soundness benchmark (issue 10).

Independent of the product: everything here uses numpy and :mod:`scipy.spatial.transform` only;
``rwhec_ros`` is touched solely by :meth:`Instance.to_problem`, which builds the solver's input
with :meth:`rwhec_ros.core.problem.Edge.build` and :class:`rwhec_ros.core.problem.Problem`.

Model (paper eq. (7), (20)): ``A_i X_j = Y_k B_i`` with ``A`` the noise-free pose stream and
``B`` the measurement. Exact ``B = Y^-1 A X``; then ``t_B <- alpha t_B + N(0, sigma^2 I)`` and
``R_B <- R_B R_n`` with ``R_n ~ Lang(I, kappa)`` (right perturbation, Section 8.1). Outliers
replace ``B`` by a random transform. The weights given to the solver are the inlier ``sigma``,
``kappa``.

Every instance is reproducible from ``(seed, index)``: its generator is
``np.random.default_rng(np.random.SeedSequence([seed, index]))`` and its category is a function of
``index`` (see :func:`category_of`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = [
    "CATEGORIES",
    "SHAPES",
    "Instance",
    "category_of",
    "make_instance",
    "sample_langevin_angle",
    "shape_of",
]

#: Graph shapes (M targets X, P cameras Y, edge list (j, k)).
SHAPES: dict[str, tuple[int, int, list[tuple[int, int]]]] = {
    "1X1Y": (1, 1, [(0, 0)]),
    "1X3Y": (1, 3, [(0, k) for k in range(3)]),
    "3X1Y": (3, 1, [(j, 0) for j in range(3)]),
    "3X3Y": (3, 3, [(j, k) for j in range(3) for k in range(3)]),
    # sparse: a ring, every target seen by two cameras, every camera sees two targets
    "4X4Y": (4, 4, [(j, k) for j in range(4) for k in (j, (j + 1) % 4)]),
    # sparse: every target seen by two neighbouring cameras (a ring over the 4 cameras)
    "8X4Y": (8, 4, [(j, k) for j in range(8) for k in (j % 4, (j + 1) % 4)]),
}

#: The paper's noise levels (Section 8.1): sigma in {1, 5} cm x kappa in {125, 12}.
PAPER_LEVELS = ((0.01, 125.0), (0.05, 125.0), (0.01, 12.0), (0.05, 12.0))

#: Categories (rows of the main table). Round-robin over this tuple by instance index.
CATEGORIES = (
    "well_posed_paper",  # general 3-axis motion, 8-25 pairs per edge, the paper's noise
    "high_noise",  # general motion, sigma 0.1-0.5 m, kappa 2-10
    "extreme_noise",  # general motion, sigma 1-3 m, kappa 0.5-1
    "outliers",  # general motion, 10-40 % of the pairs replaced by random transforms
    "near_single_axis",  # all A rotations about one axis, jittered by 1e-8..1e-3 rad
    "single_axis",  # exactly single-axis A rotations
    "tiny_rotation",  # A rotations below 5 degrees
    "few_pairs",  # 2-3 pairs per edge
)


@dataclass
class Instance:
    """One generated problem with its ground truth and how it was made.

    Attributes
    ----------
    seed, index : int
        ``(seed, index)`` reproduce the instance with :func:`make_instance`.
    category : str
    params : dict
        Generation parameters (shape, noise level, scale, motion, jitter, outliers, pairs).
    M, P : int
    edges : list of (j, k, A (N,4,4), B (N,4,4), sigma (N,), kappa (N,))
    unknown_scale : bool
    X_true (M,4,4), Y_true (P,4,4), alpha_true : ground truth.
    """

    seed: int
    index: int
    category: str
    params: dict
    M: int
    P: int
    edges: list
    unknown_scale: bool
    X_true: np.ndarray
    Y_true: np.ndarray
    alpha_true: float = 1.0

    @property
    def key(self) -> str:
        return f"{self.category}_s{self.seed}_i{self.index}"

    def to_problem(self):
        """The solver input: :class:`rwhec_ros.core.problem.Problem` built with ``Edge.build``."""
        from rwhec_ros.core.problem import Edge, Problem

        edges = [Edge.build(f"x{j}", f"y{k}", A, B, sigma=s, kappa=kp)
                 for j, k, A, B, s, kp in self.edges]
        return Problem([f"x{j}" for j in range(self.M)], [f"y{k}" for k in range(self.P)],
                       edges, unknown_scale=self.unknown_scale)

    def save(self, path: Path, result_info: dict | None = None,
             extra: dict[str, np.ndarray] | None = None) -> None:
        """Write the instance to an ``.npz`` file, optionally with what the solver reported
        (``result_info``, JSON-able) and extra arrays (e.g. a witness point), stored as
        ``extra_<name>``."""
        arrays = {"X_true": self.X_true, "Y_true": self.Y_true}
        for name, value in (extra or {}).items():
            arrays[f"extra_{name}"] = np.asarray(value)
        for e, (j, k, A, B, s, kp) in enumerate(self.edges):
            arrays[f"e{e}_jk"] = np.array([j, k])
            arrays[f"e{e}_A"] = A
            arrays[f"e{e}_B"] = B
            arrays[f"e{e}_sigma"] = s
            arrays[f"e{e}_kappa"] = kp
        meta = {"seed": self.seed, "index": self.index, "category": self.category,
                "params": self.params, "M": self.M, "P": self.P, "n_edges": len(self.edges),
                "unknown_scale": self.unknown_scale, "alpha_true": self.alpha_true,
                "result": result_info or {}}
        arrays["meta_json"] = np.array(json.dumps(meta, default=float))
        np.savez_compressed(path, **arrays)

    @staticmethod
    def load(path: Path) -> tuple[Instance, dict, dict[str, np.ndarray]]:
        """Read an instance written by :meth:`save`; returns it, the stored result info and the
        extra arrays."""
        with np.load(path, allow_pickle=False) as z:
            meta = json.loads(str(z["meta_json"]))
            edges = []
            for e in range(meta["n_edges"]):
                j, k = (int(v) for v in z[f"e{e}_jk"])
                edges.append((j, k, z[f"e{e}_A"], z[f"e{e}_B"], z[f"e{e}_sigma"],
                              z[f"e{e}_kappa"]))
            inst = Instance(meta["seed"], meta["index"], meta["category"], meta["params"],
                            meta["M"], meta["P"], edges, meta["unknown_scale"], z["X_true"],
                            z["Y_true"], meta["alpha_true"])
            extra = {k[len("extra_"):]: z[k] for k in z.files if k.startswith("extra_")}
        return inst, meta.get("result", {}), extra


# --- random helpers (own code, numpy/scipy only) ---------------------------------------------

def _transforms(R: np.ndarray, t: np.ndarray) -> np.ndarray:
    T = np.zeros((R.shape[0], 4, 4))
    T[:, :3, :3] = R
    T[:, :3, 3] = t
    T[:, 3, 3] = 1.0
    return T


def _random_rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    return Rotation.random(n, random_state=rng).as_matrix().reshape(n, 3, 3)


def _unit(rng: np.random.Generator, n: int) -> np.ndarray:
    v = rng.standard_normal((n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def sample_langevin_angle(rng: np.random.Generator, kappa: float, n: int) -> np.ndarray:
    """Rotation angles of ``Lang(I, kappa)``: density ``exp(2 kappa cos th) (1 - cos th)`` on
    ``[0, pi]`` (Haar measure of SO(3)), drawn by inverse transform on a fine grid."""
    th = np.linspace(0.0, np.pi, 8193)
    logp = 2.0 * kappa * (np.cos(th) - 1.0) + np.log(np.maximum(1.0 - np.cos(th), 1e-300))
    pdf = np.exp(logp - logp.max())
    cdf = np.concatenate([[0.0], np.cumsum(0.5 * (pdf[1:] + pdf[:-1]) * np.diff(th))])
    cdf /= cdf[-1]
    return np.interp(rng.random(n), cdf, th)


def _langevin(rng: np.random.Generator, kappa: float, n: int) -> np.ndarray:
    """``n`` samples of the isotropic Langevin distribution ``Lang(I, kappa)`` (n, 3, 3)."""
    th = sample_langevin_angle(rng, kappa, n)
    return Rotation.from_rotvec(_unit(rng, n) * th[:, None]).as_matrix().reshape(n, 3, 3)


def category_of(index: int) -> str:
    """Category of instance ``index`` (round robin, so every prefix of a run is balanced)."""
    return CATEGORIES[index % len(CATEGORIES)]


def _noise(rng: np.random.Generator, level: str) -> tuple[float, float]:
    if level == "paper":
        return PAPER_LEVELS[rng.integers(len(PAPER_LEVELS))]
    if level == "high":
        return float(rng.uniform(0.1, 0.5)), float(rng.uniform(2.0, 10.0))
    if level == "extreme":
        return float(rng.uniform(1.0, 3.0)), float(rng.uniform(0.5, 1.0))
    raise ValueError(f"noise level: unknown {level!r}")


def _motion_rotations(rng: np.random.Generator, motion: str, n: int, axis: np.ndarray,
                      jitter: float) -> np.ndarray:
    """Rotations of the pose stream ``A`` for one edge (n, 3, 3)."""
    if motion == "general":
        return _random_rotations(rng, n)
    if motion == "tiny":
        th = rng.uniform(0.0, np.radians(5.0), n)
        return Rotation.from_rotvec(_unit(rng, n) * th[:, None]).as_matrix().reshape(n, 3, 3)
    if motion == "axis":
        # each rotation about the common axis tilted by ``jitter`` rad in a random direction
        perp = _unit(rng, n)
        perp -= np.outer(perp @ axis, axis)
        perp /= np.linalg.norm(perp, axis=1, keepdims=True)
        axes = np.cos(jitter) * axis[None, :] + np.sin(jitter) * perp
        th = rng.uniform(-np.pi, np.pi, n)
        return Rotation.from_rotvec(axes * th[:, None]).as_matrix().reshape(n, 3, 3)
    raise ValueError(f"motion: unknown {motion!r}")


def _rng(seed: int, index: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([int(seed), int(index)]))


def _draw_shape(rng: np.random.Generator) -> str:
    return list(SHAPES)[int(rng.integers(len(SHAPES)))]


def shape_of(seed: int, index: int) -> str:
    """Graph shape of instance ``(seed, index)`` without generating it (its first draw)."""
    return _draw_shape(_rng(seed, index))


def _category_params(rng: np.random.Generator, category: str) -> dict:
    """Draw the generation parameters of one instance of ``category``."""
    shape = _draw_shape(rng)
    p = {"shape": shape, "motion": "general", "jitter": 0.0, "outlier_fraction": 0.0,
         "planar_translation": False, "unknown_scale": bool(rng.random() < 0.4)}
    if category == "well_posed_paper":
        p.update(noise="paper", pairs=(8, 25))
    elif category == "high_noise":
        p.update(noise="high", pairs=(5, 25))
    elif category == "extreme_noise":
        p.update(noise="extreme", pairs=(5, 25))
    elif category == "outliers":
        p.update(noise=str(rng.choice(["paper", "high"])), pairs=(5, 25),
                 outlier_fraction=float(rng.uniform(0.1, 0.4)))
    elif category in ("near_single_axis", "single_axis"):
        p.update(noise=str(rng.choice(["paper", "paper", "high", "extreme"])), pairs=(3, 25),
                 motion="axis", planar_translation=bool(rng.random() < 0.5),
                 jitter=0.0 if category == "single_axis" else float(10 ** rng.uniform(-8, -3)))
    elif category == "tiny_rotation":
        p.update(noise=str(rng.choice(["paper", "paper", "high"])), pairs=(3, 25),
                 motion="tiny")
    elif category == "few_pairs":
        p.update(noise=str(rng.choice(["paper", "high", "extreme"])), pairs=(2, 3))
    else:
        raise ValueError(f"category: unknown {category!r}")
    return p


def make_instance(seed: int, index: int, category: str | None = None) -> Instance:
    """The instance ``(seed, index)``; ``category`` overrides :func:`category_of` (tests)."""
    category = category or category_of(index)
    rng = _rng(seed, index)
    p = _category_params(rng, category)
    sigma, kappa = _noise(rng, p["noise"])
    p.update(sigma=sigma, kappa=kappa)
    M, P, edge_list = SHAPES[p["shape"]]
    scene = 1.0  # metres: spread of X, Y and A translations
    X = _transforms(_random_rotations(rng, M), scene * rng.standard_normal((M, 3)))
    Y = _transforms(_random_rotations(rng, P), scene * rng.standard_normal((P, 3)))
    alpha = float(np.exp(rng.uniform(np.log(0.3), np.log(3.0)))) if p["unknown_scale"] else 1.0
    axis = _unit(rng, 1)[0]
    edges = []
    lo, hi = p["pairs"]
    n_pairs = []
    for j, k in edge_list:
        n = int(rng.integers(lo, hi + 1))
        n_pairs.append(n)
        RA = _motion_rotations(rng, p["motion"], n, axis, p["jitter"])
        tA = scene * rng.standard_normal((n, 3))
        if p["planar_translation"]:
            tA -= np.outer(tA @ axis, axis)
        A = _transforms(RA, tA)
        Yinv = np.linalg.inv(Y[k])
        B = Yinv[None] @ A @ X[j][None]
        B[:, :3, 3] = alpha * B[:, :3, 3] + sigma * rng.standard_normal((n, 3))
        B[:, :3, :3] = B[:, :3, :3] @ _langevin(rng, kappa, n)
        n_out = int(round(p["outlier_fraction"] * n))
        if n_out:
            idx = rng.choice(n, size=n_out, replace=False)
            B[idx] = _transforms(_random_rotations(rng, n_out),
                                 alpha * scene * 2.0 * rng.standard_normal((n_out, 3)))
        # re-orthonormalise (products of rotations drift by ~1e-16; Edge.build checks 1e-6)
        U, _, Vt = np.linalg.svd(B[:, :3, :3])
        B[:, :3, :3] = U @ Vt
        edges.append((j, k, A, B, np.full(n, sigma), np.full(n, kappa)))
    p["pairs"] = [int(min(n_pairs)), int(max(n_pairs))]
    return Instance(int(seed), int(index), category, p, M, P, edges, p["unknown_scale"], X, Y,
                    alpha)
