"""Identifiability of one edge on its own (paper Corollaries 2 and 4), O(1) per pair.

Per-edge quantities
-------------------
The A transforms are noise-free (Section 4.2, assumption 1), so the conditions of Corollaries 2
and 4 are evaluated on A alone; B enters only the rotation system of eq. (60), reported for
reference. With ``S = sum_i R_A_i`` (3x3, singular values ``s_1 >= s_2 >= s_3``):

* ``rotation_spread_deg = arccos(s_3 / N)`` and ``second_axis_spread_deg = arccos(s_1 / N)``.
  ``N - s_1 = min_{|u|=|v|=1} 1/2 sum_i |R_A_i u - v|^2 = sum_i (1 - cos phi_i)``, where
  ``phi_i`` is the angle by which pair ``i`` moves the best-preserved direction ``u``
  (``dominant_axis``, in the tag-carrier frame that A maps from). All pairs rotating about one
  axis give ``second_axis_spread = 0``; no rotation at all gives ``rotation_spread = 0``.
  Unlike relative rotations to a first pair, these need no reference pair and are exact sums.
* ``rotation_std_deg``: linearising ``R_A R_X = R_Y R_B`` at the solution, the Fisher information
  of the rotation measurements on ``(R_X, R_Y)`` is ``sum_i 2 kappa_i [[I, -R_A^T], [-R_A, I]]``
  (Langevin ``exp(kappa tr R)`` has per-axis variance ``1 / (2 kappa)``); its smallest
  eigenvalue is ``2 (sum kappa_i - s_1(sum kappa_i R_A_i))``, and the reported value is the
  predicted standard deviation along that least-determined direction (rotation terms only, so
  conservative). Note that this matrix is also ``M_e^T M_e`` of eq. (64) (weighted).
* The rotation system of eq. (60), ``Q_e r = 0`` with 18 columns, has Gram matrix
  ``[[N I, -K], [-K^T, N I]]`` with ``K = sum_i R_B^T (x) R_A^T`` (9x9), so its singular values
  are ``sqrt(N +- s_k(K))``: ``rotation_sv_ratio = sigma_17 / sigma_1`` (kernel one-dimensional
  iff > 0) and ``rotation_residual_ratio = sigma_18 / sigma_1`` (0 for exact data, the noise
  otherwise); ``rotation_gap = sigma_17 / sigma_18`` compares them (noise-aware, reference only).
* Translation system. ``M_e`` and ``Mbar_e = [M_e, t_e]`` of eqs. (64) and (67) need ``R_Y``
  through ``t_e = R_Y t_B``, unknown before solving. For exact data
  ``t_e = alpha (t_A - M_e [t_X; t_Y])``, so ``range([M_e, t_e]) = range([M_e, t_A])``: we use the
  R_Y-free 7-column system ``[R_A, -I, t_A]`` (Andreff/Shah form, unknowns ``t_X, t_Y`` and the
  scale / homogenising ``s``). Its Gram matrix is a sum of per-pair terms. The Schur complement
  of the ``t_A`` column gives ``translation_excitation_m``, the RMS distance of the A translations
  from a pure rotation about a fixed point (``t_A = R_A u - v``): zero means a single sphere
  around the target (paper Section 8.1), where the scale of a monocular camera is not
  identifiable and, with known scale, eq. (63) fails (unique solution, but the unconstrained
  minimiser is not unique, so the a-priori tightness guarantee does not apply). With weights
  ``1 / sigma_i^2`` the same complement predicts ``scale_rel_std``, the relative standard
  deviation of ``alpha`` (assuming ``alpha ~ 1``) given the rotations.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..problem import Edge
from .status import IdentifiabilityStatus, IdentifiabilityThresholds

__all__ = ["EdgeStatistics", "EdgeIdentifiability", "analyze_edge"]


# ----------------------------------------------------------------------------------------------
# Per-edge sufficient statistics
# ----------------------------------------------------------------------------------------------
@dataclass
class EdgeStatistics:
    """Sufficient statistics of edge ``(x, y)``: sums of per-pair terms, O(1) to update.

    Attributes
    ----------
    x, y : str
    n : int
        Number of pairs.
    sum_RA : ndarray (3, 3)
        ``sum_i R_A_i``.
    sum_kappa : float
    sum_kappa_RA : ndarray (3, 3)
        ``sum_i kappa_i R_A_i``.
    K : ndarray (9, 9)
        ``sum_i R_B_i^T (x) R_A_i^T`` (off-diagonal block of the Gram matrix of eq. (60)).
    G, Gw : ndarray (7, 7)
        ``sum_i C_i^T C_i`` and ``sum_i C_i^T C_i / sigma_i^2`` with ``C_i = [R_A_i, -I, t_A_i]``.
    """

    x: str
    y: str
    n: int = 0
    sum_RA: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    sum_kappa: float = 0.0
    sum_kappa_RA: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    K: np.ndarray = field(default_factory=lambda: np.zeros((9, 9)))
    G: np.ndarray = field(default_factory=lambda: np.zeros((7, 7)))
    Gw: np.ndarray = field(default_factory=lambda: np.zeros((7, 7)))

    def add(self, A: np.ndarray, B: np.ndarray, sigma: np.ndarray, kappa: np.ndarray) -> None:
        """Add validated pairs ``A, B`` (N, 4, 4) with ``sigma, kappa`` (N,), vectorised."""
        RA, tA = A[:, :3, :3], A[:, :3, 3]
        RB = B[:, :3, :3]
        N = A.shape[0]
        C = np.zeros((N, 3, 7))
        C[:, :, 0:3] = RA
        C[:, :, 3:6] = -np.eye(3)
        C[:, :, 6] = tA
        self.n += N
        self.sum_RA += RA.sum(axis=0)
        self.sum_kappa += float(kappa.sum())
        self.sum_kappa_RA += np.einsum("n,nij->ij", kappa, RA)
        self.K += np.einsum("nba,nji->aibj", RB, RA).reshape(9, 9)
        self.G += np.einsum("nki,nkj->ij", C, C)
        self.Gw += np.einsum("n,nki,nkj->ij", 1.0 / sigma**2, C, C)

    @staticmethod
    def from_pairs(
        x: str,
        y: str,
        A: np.ndarray,
        B: np.ndarray,
        sigma: float | np.ndarray = 0.01,
        kappa: float | np.ndarray = 125.0,
    ) -> EdgeStatistics:
        """Statistics of pairs ``A, B`` (N, 4, 4) (validated here)."""
        return EdgeStatistics.from_edge(Edge.build(x, y, A, B, sigma=sigma, kappa=kappa))

    @staticmethod
    def from_edge(edge: Edge) -> EdgeStatistics:
        """Statistics of a validated :class:`~rwhec_ros.core.problem.Edge`."""
        stats = EdgeStatistics(x=edge.x, y=edge.y)
        stats.add(edge.A, edge.B, edge.sigma, edge.kappa)
        return stats


# ----------------------------------------------------------------------------------------------
# Per-edge verdict
# ----------------------------------------------------------------------------------------------
@dataclass
class EdgeIdentifiability:
    """Graded identifiability of one edge on its own (Corollaries 2 and 4).

    Attributes
    ----------
    x, y : str
    n_pairs : int
    status : IdentifiabilityStatus
    reasons : list of str
        Why the edge is weak or insufficient (empty when identifiable).
    rigid_status : IdentifiabilityStatus
        The verdict ignoring the scale criteria (differs from ``status`` only for unknown scale):
        what the edge gives once ``alpha`` is known from elsewhere.
    rotation_spread_deg, second_axis_spread_deg : float
        See the module docstring [deg].
    dominant_axis : ndarray (3,)
        Best-preserved direction of the A rotations (tag-carrier frame).
    rotation_std_deg : float
        Predicted std of the least-determined rotation direction [deg]; ``inf`` exactly when a
        reason says the rotation is not determined (the same decision).
    rotation_sv_ratio, rotation_residual_ratio, rotation_gap : float
        ``sigma_17 / sigma_1``, ``sigma_18 / sigma_1`` and ``sigma_17 / sigma_18`` of eq. (60).
    translation_excitation_m : float
        RMS distance of the A translations from a rotation about a fixed point [m].
    translation_sv_ratio : float
        ``sigma_min / sigma_max`` of the column-normalised system ``[R_A, -I, t_A]``.
    scale_rel_std : float
        Predicted relative std of ``alpha`` (or of the homogenising ``s``) given the rotations;
        ``inf`` exactly when the edge does not determine the scale (the translation direction is
        degenerate: the decision behind that reason).
    """

    x: str
    y: str
    n_pairs: int
    status: IdentifiabilityStatus
    reasons: list[str]
    rigid_status: IdentifiabilityStatus
    rotation_spread_deg: float
    second_axis_spread_deg: float
    dominant_axis: np.ndarray
    rotation_std_deg: float
    rotation_sv_ratio: float
    rotation_residual_ratio: float
    rotation_gap: float
    translation_excitation_m: float
    translation_sv_ratio: float
    scale_rel_std: float

    @property
    def identifiable(self) -> bool:
        """True unless ``status`` is ``insufficient``."""
        return self.status is not IdentifiabilityStatus.INSUFFICIENT

    @property
    def name(self) -> str:
        return f"({self.x}, {self.y})"

    def to_dict(self) -> dict:
        return {
            "x": self.x,
            "y": self.y,
            "n_pairs": int(self.n_pairs),
            "status": self.status.value,
            "rigid_status": self.rigid_status.value,
            "reasons": list(self.reasons),
            "rotation_spread_deg": float(self.rotation_spread_deg),
            "second_axis_spread_deg": float(self.second_axis_spread_deg),
            "dominant_axis": [float(v) for v in self.dominant_axis],
            "rotation_std_deg": float(self.rotation_std_deg),
            "rotation_sv_ratio": float(self.rotation_sv_ratio),
            "rotation_residual_ratio": float(self.rotation_residual_ratio),
            "rotation_gap": float(self.rotation_gap),
            "translation_excitation_m": float(self.translation_excitation_m),
            "translation_sv_ratio": float(self.translation_sv_ratio),
            "scale_rel_std": float(self.scale_rel_std),
        }


def _schur_last(G: np.ndarray) -> float:
    """``G_ss - g^T pinv(G_uu) g`` for the last column ``s`` of a PSD Gram matrix ``G``."""
    Guu, gus, gss = G[:-1, :-1], G[:-1, -1], G[-1, -1]
    w, V = np.linalg.eigh(Guu)
    keep = w > 1e-9 * max(float(w.max()), 1e-300)
    proj = V[:, keep].T @ gus
    return max(float(gss - np.sum(proj**2 / w[keep])), 0.0)


def _fmt_axis(u: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:+.2f}" for v in u) + "]"


def analyze_edge(
    stats: EdgeStatistics,
    unknown_scale: bool = False,
    thresholds: IdentifiabilityThresholds | None = None,
) -> EdgeIdentifiability:
    """Graded verdict of one edge from its statistics; O(1). See the module docstring."""
    thr = thresholds or IdentifiabilityThresholds()
    N = stats.n
    if N < 1:
        raise ValueError(f"edge ({stats.x}, {stats.y}): no pairs")
    # --- A rotations: spreads and best-preserved direction
    _, s, Vt = np.linalg.svd(stats.sum_RA)
    second_axis = float(np.degrees(np.arccos(np.clip(s[0] / N, -1.0, 1.0))))
    spread = float(np.degrees(np.arccos(np.clip(s[2] / N, -1.0, 1.0))))
    axis = Vt[0] * np.sign(Vt[0][np.argmax(np.abs(Vt[0]))])
    # --- predicted rotation std (rotation terms only)
    sk1 = np.linalg.svd(stats.sum_kappa_RA, compute_uv=False)[0]
    info = 2.0 * (stats.sum_kappa - sk1)
    info_positive = info > 1e-12 * 2.0 * stats.sum_kappa  # rounding of s_1: ~eps N kappa
    # --- rotation system of eq. (60)
    k = np.linalg.svd(stats.K, compute_uv=False)
    s_max = np.sqrt(N + k[0])
    s18 = np.sqrt(max(N - k[0], 0.0))
    s17 = np.sqrt(max(N - k[1], 0.0))
    sv_ratio = float(s17 / s_max)
    res_ratio = float(s18 / s_max)
    gap = float(s17 / s18) if s18 > 0 else float("inf")
    # --- translation system [R_A, -I, t_A]
    excitation = float(np.sqrt(_schur_last(stats.G) / N))
    d = np.sqrt(np.maximum(np.diag(stats.G), 1e-300))
    lam = np.linalg.eigvalsh(stats.G / np.outer(d, d))
    t_ratio = float(np.sqrt(max(lam[0], 0.0) / lam[-1])) if lam[-1] > 0 else 0.0
    # One decision whether this edge determines the scale (``scale_determined``), from which
    # both the reason and ``scale_rel_std`` follow, so that a scale reported undetermined never
    # carries a finite std: the translation excitation against its threshold (the reported
    # reason), and the weighted Schur complement numerically positive (rounding of the sums is
    # ~eps times its diagonal; 1e-12 of it leaves a 4-digit margin).
    schur_w = _schur_last(stats.Gw)
    scale_determined = (excitation >= thr.min_translation_excitation_m
                        and schur_w > 1e-12 * max(float(stats.Gw[-1, -1]), 1e-300))
    scale_std = float(1.0 / np.sqrt(schur_w)) if scale_determined else float("inf")

    hard: list[str] = []
    weak: list[str] = []
    scale_hard: list[str] = []
    scale_weak: list[str] = []
    if N < thr.min_pairs:
        hard.append(f"fewer than {thr.min_pairs} pairs (has {N})")
    rotation_ok = True
    if spread < thr.min_rotation_deg:
        hard.append(f"no rotation (pure translations): the A rotations differ by "
                    f"{spread:.2f} deg (need >= {thr.min_rotation_deg:g} deg about two axes)")
        rotation_ok = False
    elif second_axis < thr.min_second_axis_deg:
        hard.append(f"rotations only about one axis ({_fmt_axis(axis)} in the tag-carrier "
                    f"frame): {second_axis:.2f} deg about any other axis (need >= "
                    f"{thr.min_second_axis_deg:g}, comfortable {thr.good_second_axis_deg:g})")
        rotation_ok = False
    elif second_axis < thr.good_second_axis_deg:
        weak.append(f"little rotation about a second axis: {second_axis:.1f} deg away from "
                    f"{_fmt_axis(axis)} (comfortable >= {thr.good_second_axis_deg:g} deg)")
    if rotation_ok and N >= 2 and sv_ratio < thr.kernel_rtol:
        hard.append(f"the rotation system of eq. (60) has a kernel of dimension > 1 "
                    f"(sigma_17/sigma_1 = {sv_ratio:.1e})")
        rotation_ok = False
    if rotation_ok and not info_positive:
        hard.append("rotation not determined: the rotation information of this edge is "
                    "numerically zero")
        rotation_ok = False
    # the std follows the same decision as the reasons: a rotation reported undetermined (any of
    # the hard rotation reasons above) has no finite std, on any machine's rounding
    rot_std = float(np.degrees(1.0 / np.sqrt(info))) if rotation_ok else float("inf")
    if rotation_ok and rot_std > thr.max_rotation_std_deg:
        weak.append(f"rotation weakly determined for the noise level: predicted "
                    f"+-{rot_std:.2f} deg (rotation terms only; comfortable <= "
                    f"{thr.max_rotation_std_deg:g} deg)")
    if rotation_ok:
        if not scale_determined:
            text = (f"translation direction degenerate: the A motion is a rotation about a fixed "
                    f"point (RMS deviation {1e3 * excitation:.3g} mm, e.g. a single sphere "
                    f"around the target)")
            if unknown_scale:
                scale_hard.append(text + ", so the scale is not identifiable")
            else:
                weak.append(text + "; the solution is unique, but eq. (63) fails, so the "
                            "SDP relaxation may not be tight")
        elif unknown_scale and scale_std > thr.max_scale_rel_std:
            scale_weak.append(f"scale weakly determined: predicted +-{100 * scale_std:.2g}% "
                              f"(comfortable <= {100 * thr.max_scale_rel_std:g}%)")

    def grade(h, w):
        if h:
            return IdentifiabilityStatus.INSUFFICIENT
        if w:
            return IdentifiabilityStatus.WEAK
        return IdentifiabilityStatus.IDENTIFIABLE

    return EdgeIdentifiability(
        x=stats.x,
        y=stats.y,
        n_pairs=N,
        status=grade(hard + scale_hard, weak + scale_weak),
        reasons=hard + scale_hard + weak + scale_weak,
        rigid_status=grade(hard, weak),
        rotation_spread_deg=spread,
        second_axis_spread_deg=second_axis,
        dominant_axis=axis,
        rotation_std_deg=rot_std,
        rotation_sv_ratio=sv_ratio,
        rotation_residual_ratio=res_ratio,
        rotation_gap=gap,
        translation_excitation_m=excitation,
        translation_sv_ratio=t_ratio,
        scale_rel_std=scale_std,
    )

