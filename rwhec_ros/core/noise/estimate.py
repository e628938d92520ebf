"""The noise of each group estimated from the residuals at a solution: :func:`estimate_noise`.

One step of Helmert's / Foerstner's variance-component estimation (:mod:`.redundancy`): for each
noise group ``g`` (:mod:`.groups`) and component ``c`` (translation, rotation), the chi-square
``v^T W v`` of its pairs at the solution over its redundancy ``r_(g, c)`` is the factor by which
the variance of the weights solved with is off: ``s^2 = chi2 / r`` (1 when they fit). The new
weights are ``sigma <- sigma s_t``, ``kappa <- kappa / s_R^2``; :func:`~.reweight.solve_with_noise`
solves again with them until every ``s^2`` is within the tolerance of 1 (Foerstner's iteration;
it converges in a few solves).

Factors are relative to the *given* per-pair ``sigma`` and ``kappa`` (:data:`GIVEN_KINDS`): the
user's statement (``"stated"``), each detection's own precision from its PnP (``"reprojection"``:
the estimate scales it per group, keeping its pair-to-pair shape) or start values only
(``"start"``). A group whose redundancy is below :attr:`NoiseOptions.min_redundancy` is not
estimated alone (a chi-square with ``r`` degrees of freedom gives ``s`` to about ``1 /
sqrt(2 r)``: 22 % at ``r = 10``): it is *pooled* with the other such groups when together they
reach it, else it takes the other groups' estimate (their redundancy-weighted geometric mean),
else its given value. Each component says which (:attr:`ComponentNoise.source`).

An edge whose residuals are far beyond those of the other edges (:attr:`NoiseOptions.outlier_ratio`
times the median edge's noise, std units, significantly: a moved, flipped or wrongly sized target)
is **left out of its group's estimate** (:func:`screen_edges`; its pairs keep the group's weights):
otherwise one bad target would raise its camera's noise and hide itself from the verdict's edge
check, which compares each edge with the noise of its camera. A group whose every edge would be
left out is kept whole (then the whole camera is noisy: :meth:`NoiseEstimate.far_above` names it).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.stats import chi2 as _chi2
from scipy.stats import f as _fdist

from ..model.gauge import GaugeOptions
from ..problem import Problem
from .groups import GROUPINGS, NoiseGroups, noise_groups
from .redundancy import GroupSums, group_sums

__all__ = ["GIVEN_KINDS", "SOURCES", "NoiseOptions", "ComponentNoise", "GroupNoise",
           "NoiseEstimate", "estimate_noise", "std_upper_factor", "components_of",
           "screen_edges"]

#: What the problem's ``sigma``/``kappa`` are (module docstring).
GIVEN_KINDS = ("stated", "reprojection", "start")
#: Where a component's factor comes from: its own estimate, a pool of groups with little
#: redundancy, the other groups' estimate, or the given value.
SOURCES = ("estimated", "pooled", "others", "given")
#: Below this variance factor the residuals are at rounding level (exact data): the given noise
#: is kept (estimating would scale the weights without bound).
_ROUNDING_FACTOR = 1e-12


@dataclass(frozen=True)
class NoiseOptions:
    """How the noise is estimated (module docstring and :func:`~.reweight.solve_with_noise`).

    Attributes
    ----------
    estimate : bool
        Estimate the noise from the data and solve with it (True); False: solve with the given
        noise, as stated.
    groups : str
        The noise groups, one of :data:`~.groups.GROUPINGS` (``"camera"``).
    given : str
        What the problem's ``sigma``/``kappa`` are, one of :data:`GIVEN_KINDS` (``"start"``).
    min_redundancy : float
        A component with less redundancy is pooled (10: ``s`` to about 22 %).
    tolerance : float
        Converged when every variance factor of the last solve is within this of 1 (0.02: ``s``
        within 1 %, well below its statistical error ``1 / sqrt(2 r)`` for ``r < 2500``).
    max_solves : int
        At most this many solves (8); the last weights are used, and the estimate says it did
        not converge.
    information : str
        ``"pairs"`` or ``"edge_blocks"``, as
        :class:`~rwhec_ros.core.analysis.uncertainty.UncertaintyOptions` (the live re-solve's).
    outlier_ratio : float
        An edge this many times the median edge's noise (5.0, std units, the verdict's
        ``edge_ratio``) ...
    outlier_significance : float
        ... significantly so (chi-square p-value below this over the number of edges: 1e-3) is
        left out of its group's estimate (module docstring).
    kinds : tuple of (str, str)
        Target name -> its kind (``"tag"``, ``"chessboard"``, ...): a camera that sees targets
        of several kinds gets one group per kind (:func:`~.groups.noise_groups`); empty: one
        group per camera whatever its targets.
    """

    estimate: bool = True
    groups: str = "camera"
    given: str = "start"
    min_redundancy: float = 10.0
    tolerance: float = 0.02
    max_solves: int = 8
    information: str = "pairs"
    outlier_ratio: float = 5.0
    outlier_significance: float = 1e-3
    kinds: tuple[tuple[str, str], ...] = ()

    def __post_init__(self) -> None:
        if self.groups not in GROUPINGS:
            raise ValueError(f"noise.groups: expected one of {GROUPINGS}, got {self.groups!r}")
        if self.given not in GIVEN_KINDS:
            raise ValueError(f"noise given: expected one of {GIVEN_KINDS}, got {self.given!r}")
        if not (self.outlier_ratio >= 1 and 0 < self.outlier_significance < 1):
            raise ValueError(f"NoiseOptions: outlier_ratio must be >= 1 and outlier_significance "
                             f"in (0, 1), got {self.outlier_ratio!r}, "
                             f"{self.outlier_significance!r}")
        for name in ("min_redundancy", "tolerance"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"NoiseOptions.{name}: must be finite and > 0, got {v!r}")
        if int(self.max_solves) != self.max_solves or self.max_solves < 1:
            raise ValueError(f"NoiseOptions.max_solves: must be an integer >= 1, got "
                             f"{self.max_solves!r}")
        if self.information not in ("pairs", "edge_blocks"):
            raise ValueError(f"NoiseOptions.information: expected 'pairs' or 'edge_blocks', got "
                             f"{self.information!r}")


def std_upper_factor(dof: float, confidence: float = 0.95) -> float:
    """One-sided upper confidence factor of a standard deviation estimated with ``dof`` degrees
    of freedom: ``sqrt(dof / chi2_(1 - confidence)(dof))`` (``r s^2 / sigma^2`` is chi-square with
    ``dof``); 1.04 at 1000, 1.13 at 100, 1.36 at 20, ``inf`` without degrees of freedom."""
    if not (np.isfinite(dof) and dof > 0):
        return float("inf")
    return float(np.sqrt(dof / _chi2.ppf(1.0 - confidence, dof)))


@dataclass(frozen=True)
class ComponentNoise:
    """One group's translation or rotation noise.

    Attributes
    ----------
    redundancy : float
        ``r_(g, c)`` at the last solve.
    chi2 : float
        Its chi-square at the weights of the last solve.
    used : float
        Variance factor on the given noise of the weights of the last solve.
    factor : float
        The estimated variance factor on the given noise: ``used`` times this step's ``s^2``
        (``sigma_hat = sigma s``, ``kappa_hat = kappa / s^2`` with ``s^2 = factor``).
    source : str
        One of :data:`SOURCES`.
    dof : float
        Degrees of freedom of the estimate it takes (its own redundancy, the pool's, the other
        groups'; 0 for ``"given"``).
    """

    redundancy: float
    chi2: float
    used: float
    factor: float
    source: str
    dof: float

    @property
    def ratio(self) -> float:
        """``s = sqrt(factor)``: estimated over given noise (std units)."""
        return float(np.sqrt(self.factor))

    @property
    def change(self) -> float:
        """``|factor / used - 1|``: how far the weights solved with are from the estimate."""
        return abs(self.factor / self.used - 1.0)

    def p_stated(self) -> float:
        """Upper-tail chi-square p-value of the data at the given noise (``chi2 = factor r``
        with ``r`` degrees of freedom): small when the data are significantly noisier."""
        if not (self.dof > 0 and self.source in ("estimated", "pooled")):
            return float("nan")
        return float(_chi2.sf(self.factor * self.dof, self.dof))

    def to_dict(self) -> dict:
        return {"redundancy": float(self.redundancy), "chi2": float(self.chi2),
                "factor": float(self.factor), "used": float(self.used),
                "source": self.source, "dof": float(self.dof)}


@dataclass(frozen=True)
class GroupNoise:
    """The estimated noise of one group.

    Attributes
    ----------
    name : str
        The camera, the edge ``"(x, y)"`` or ``"all"`` (:mod:`.groups`).
    edges : tuple of str
    pairs : int
    sigma_given_m : float
        Median given ``sigma`` over the group's pairs [m] (units of ``B``: nominal for unknown
        scale).
    kappa_given : float
        Median given ``kappa``.
    translation, rotation : ComponentNoise
    camera : str
        The group's camera (``""`` for the global group).
    kind : str
        The kind of its targets (``"tag"``, ``"chessboard"``, ...; ``""`` when not known):
        groups are compared with groups of their kind only (:meth:`NoiseEstimate.far_above`).
    """

    name: str
    edges: tuple[str, ...]
    pairs: int
    sigma_given_m: float
    kappa_given: float
    translation: ComponentNoise
    rotation: ComponentNoise
    camera: str = ""
    kind: str = ""

    @property
    def sigma_m(self) -> float:
        """The estimated translation std [m] (median pair): ``sigma_given s_t``."""
        return self.sigma_given_m * self.translation.ratio

    @property
    def kappa(self) -> float:
        """The estimated Langevin concentration (median pair): ``kappa_given / s_R^2``."""
        return self.kappa_given / self.rotation.factor

    @property
    def rotation_std_deg(self) -> float:
        """Per-axis rotation std [deg] of :attr:`kappa`: ``1 / sqrt(2 kappa)`` rad."""
        return float(np.degrees(1.0 / np.sqrt(2.0 * self.kappa)))

    @property
    def rotation_std_given_deg(self) -> float:
        return float(np.degrees(1.0 / np.sqrt(2.0 * self.kappa_given)))

    def component(self, what: str) -> ComponentNoise:
        return self.translation if what == "translation" else self.rotation

    def to_dict(self) -> dict:
        return {"edges": list(self.edges), "pairs": int(self.pairs),
                "sigma_m": float(self.sigma_m), "sigma_given_m": float(self.sigma_given_m),
                "kappa": float(self.kappa), "kappa_given": float(self.kappa_given),
                "rotation_std_deg": self.rotation_std_deg,
                "rotation_std_given_deg": self.rotation_std_given_deg,
                "translation": self.translation.to_dict(), "rotation": self.rotation.to_dict()}


@dataclass
class NoiseEstimate:
    """The noise per group (module docstring).

    Attributes
    ----------
    grouping : str
    given : str
        What the given noise is (:data:`GIVEN_KINDS`).
    groups : list of GroupNoise
    rank : int
        Directions the data determine.
    solves : int
        Solves made (1 for one step at a solution).
    converged : bool
        The weights of the last solve fit the data (every variance factor within the tolerance).
    min_redundancy : float
    left_out : dict of str to str
        Edges ``"(x, y)"`` left out of their group's estimate, and why (:func:`screen_edges`).
    notes : list of str
    """

    grouping: str
    given: str
    groups: list[GroupNoise]
    rank: int
    solves: int = 1
    converged: bool = False
    min_redundancy: float = 10.0
    left_out: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def group(self, name: str) -> GroupNoise:
        for g in self.groups:
            if g.name == name:
                return g
        raise KeyError(f"no noise group {name!r}; have {[g.name for g in self.groups]}")

    @property
    def estimated(self) -> bool:
        """At least one component was estimated from the data (not all given)."""
        return any(c.source != "given" for g in self.groups
                   for c in (g.translation, g.rotation))

    @property
    def largest_change(self) -> float:
        """Largest ``|factor / used - 1|`` of the last solve (0 when nothing is estimated)."""
        return max((c.change for g in self.groups for c in (g.translation, g.rotation)),
                   default=0.0)

    def factors(self, *, used: bool = False) -> dict[str, tuple[float, float]]:
        """Group name -> ``(translation, rotation)`` variance factors on the given noise: the
        estimate, or with ``used`` those of the last solve's weights."""
        return {g.name: ((g.translation.used, g.rotation.used) if used else
                         (g.translation.factor, g.rotation.factor)) for g in self.groups}

    def frame_dof(self, problem: Problem) -> dict[str, float]:
        """Per frame of ``problem``, the fewest degrees of freedom among the estimates that
        weight its pairs (both components of every group with one of its edges; 0 when one of
        them is given, not estimated)."""
        by_edge = {e: g for g in self.groups for e in g.edges}
        out: dict[str, float] = {}
        for e in problem.edges:
            g = by_edge.get(e.name)
            d = 0.0 if g is None else min(c.dof if c.source != "given" else 0.0
                                          for c in (g.translation, g.rotation))
            for n in (e.x, e.y):
                out[n] = min(out.get(n, np.inf), d)
        return out

    def far_above(self, ratio: float, significance: float = 1e-3
                  ) -> list[tuple[GroupNoise, str, float, float]]:
        """Groups whose estimated noise (std units) is at least ``ratio`` times the median of the
        other groups of their kind (:attr:`GroupNoise.kind`: a board's detector is not a tag's),
        significantly so (F-test of the two variance factors, Bonferroni over the groups):
        ``(group, "translation" or "rotation", ratio to the others, p-value)``, the largest
        ratio first; only components estimated on their own, against others that are."""
        out = []
        for what in ("translation", "rotation"):
            own = [g for g in self.groups if g.component(what).source == "estimated"]
            if len(own) < 2:
                continue
            std = {g.name: (g.sigma_m if what == "translation" else g.rotation_std_deg)
                   for g in own}
            for g in own:
                others = [o for o in own if o is not g and o.kind == g.kind]
                if not others:
                    continue
                med = float(np.median([std[o.name] for o in others]))
                dof_o = float(np.median([o.component(what).dof for o in others]))
                if not med > 0:
                    continue
                q = std[g.name] / med
                p = float(_fdist.sf(q * q, g.component(what).dof, dof_o))
                if q >= ratio and p < significance / len(own):
                    out.append((g, what, q, p))
        return sorted(out, key=lambda item: -item[2])

    def to_dict(self) -> dict:
        return {"estimated": self.estimated, "grouping": self.grouping, "given": self.given,
                "solves": int(self.solves), "converged": bool(self.converged),
                "largest_change": float(self.largest_change),
                "min_redundancy": float(self.min_redundancy), "rank": int(self.rank),
                "groups": {g.name: g.to_dict() for g in self.groups},
                "left_out": dict(self.left_out), "notes": list(self.notes)}


def screen_edges(sums: GroupSums, groups: NoiseGroups, names: list[str],
                 options: NoiseOptions) -> dict[int, str]:
    """Edges to leave out of their group's estimate (module docstring): edge index -> why.

    Per component, each edge's noise ratio ``sqrt(chi2_e / r_e)`` at the current weights is
    compared with the median of its group's edges (at least 3 edges with ``r_e >= 1``), else of
    the edges of its kind (as many), else of all edges; it is left out when
    ``options.outlier_ratio`` times that or more with a chi-square p-value below
    ``options.outlier_significance / E``. A group keeps all its edges when every one of them
    would be left out."""
    E = groups.edge_group.shape[0]
    kinds = groups.edge_kinds()
    why: dict[int, str] = {}
    for what in ("translation", "rotation"):
        chi = np.asarray(getattr(sums, f"edge_chi2_{what}"), float)
        r = np.asarray(getattr(sums, f"edge_redundancy_{what}"), float)
        valid = r >= 1.0
        if valid.sum() < 3:
            continue
        s = np.sqrt(np.where(valid, chi, 0.0) / np.where(valid, r, 1.0))
        for g in range(groups.size):
            mine = valid & (groups.edge_group == g)
            alike = valid & (kinds == groups.kinds[g])
            ref = mine if mine.sum() >= 3 else alike if alike.sum() >= 3 else valid
            med = float(np.median(s[ref]))
            if not med > 0:
                continue
            for e in np.flatnonzero(mine):
                q = s[e] / med
                if q >= options.outlier_ratio and \
                        _chi2.sf(chi[e] / med**2, r[e]) < options.outlier_significance / E:
                    why.setdefault(int(e), f"its {what} residuals fit {q:.1f}x the median "
                                           f"edge's noise")
    for g in range(groups.size):
        mine = np.flatnonzero(groups.edge_group == g)
        if mine.size and all(int(e) in why for e in mine):
            for e in mine:
                why.pop(int(e))
    return why


def components_of(sums: GroupSums, used: np.ndarray, what: str, min_redundancy: float,
                  keep_given: np.ndarray | None = None, kinds=None) -> list[ComponentNoise]:
    """The components (one per group) of ``what`` (``"translation"``/``"rotation"``) from the
    sums at a solution whose weights have the variance factors ``used`` (G,) on the given ones:
    own estimate, pool, the other groups' estimate or the given value (module docstring);
    ``keep_given`` (G,) bool: components held at their given value (:func:`estimate_noise`);
    ``kinds`` (G,) str: the groups' kinds -- a group pools with, or takes the estimate of, the
    groups of its kind first (:attr:`NoiseGroups.kinds`), then of any kind."""
    chi = np.asarray(getattr(sums, f"chi2_{what}"), float)
    r = np.asarray(getattr(sums, f"redundancy_{what}"), float)
    G = chi.shape[0]
    rounding = (chi <= _ROUNDING_FACTOR * np.maximum(r, 1.0))  # exact data: keep as given
    if keep_given is not None:
        rounding = rounding | np.asarray(keep_given, bool)
    own = (r >= min_redundancy) & ~rounding
    factor, source, dof = np.ones(G), ["given"] * G, np.zeros(G)
    factor[own] = used[own] * chi[own] / r[own]
    for i in np.flatnonzero(own):
        source[i], dof[i] = "estimated", r[i]
    kinds = np.array(("",) * G if kinds is None else tuple(kinds), dtype=object)
    todo = ~own & ~rounding
    for alike in [kinds == k for k in dict.fromkeys(kinds[todo])] + [np.ones(G, bool)]:
        low = np.flatnonzero(todo & alike)  # per kind first, then whatever is left together
        if not low.size:
            continue
        R = float(r[low].sum())
        ref = own & alike
        if R >= min_redundancy:
            s2 = float(chi[low].sum()) / R
            factor[low] = used[low] * s2
            for i in low:
                source[i], dof[i] = "pooled", R
        elif ref.any():
            w = r[ref] / r[ref].sum()
            factor[low] = float(np.exp(np.sum(w * np.log(factor[ref]))))
            for i in low:
                source[i], dof[i] = "others", float(r[ref].sum())
        else:
            continue
        todo[low] = False
    return [ComponentNoise(float(r[i]), float(chi[i]), float(used[i]), float(factor[i]),
                           source[i], float(dof[i])) for i in range(G)]


def estimate_noise(
    problem: Problem,
    result,
    options: NoiseOptions | None = None,
    *,
    gauge: GaugeOptions | None = None,
    given: Problem | None = None,
    used: dict[str, tuple[float, float]] | None = None,
    groups: NoiseGroups | None = None,
    keep_given: dict[str, tuple[bool, bool]] | None = None,
) -> NoiseEstimate:
    """The noise of every group of ``problem`` at its solution ``result`` (one step, module
    docstring).

    Parameters
    ----------
    problem : Problem
        The pairs and the weights that ``result`` solves.
    result : CalibrationResult
        ``X``, ``Y`` (metric), ``scale`` in ``problem``'s frame order.
    options : NoiseOptions, optional
        ``groups``, ``given``, ``min_redundancy``, ``information``.
    gauge : GaugeOptions, optional
        The solve's (priors), for the redundancies.
    given : Problem, optional
        The same edges with the given ``sigma``/``kappa`` (default ``problem``: its weights are
        the given ones).
    used : dict of str to (float, float), optional
        Per group the variance factors of ``problem``'s weights on ``given``'s (default 1).
    groups : NoiseGroups, optional
        Default ``noise_groups(problem, options.groups)``.
    keep_given : dict of str to (bool, bool), optional
        Per group, whether its translation / rotation component stays at its given value
        whatever its redundancy now (:func:`~.reweight.solve_with_noise`: a component found
        below the redundancy bound once).

    Returns
    -------
    NoiseEstimate
        Per group the given and estimated ``sigma``/``kappa``, redundancies, degrees of freedom
        and where each factor comes from. A one-step estimate (``solves`` 1); ``converged`` when
        the weights solved with already fit (within ``options.tolerance``).
    """
    opts = options or NoiseOptions()
    groups = groups or noise_groups(problem, opts.groups, dict(opts.kinds))
    given = given or problem
    sums = group_sums(problem, result, groups, gauge=gauge, information=opts.information)
    edge_names = [e.name for e in problem.edges]
    left = screen_edges(sums, groups, edge_names, opts)
    if left:
        mask = np.zeros(len(edge_names), bool)
        mask[list(left)] = True
        sums = sums.without(groups.edge_group, mask)
    u_t = np.array([(used or {}).get(n, (1.0, 1.0))[0] for n in groups.names])
    u_r = np.array([(used or {}).get(n, (1.0, 1.0))[1] for n in groups.names])
    k_t = np.array([(keep_given or {}).get(n, (False, False))[0] for n in groups.names])
    k_r = np.array([(keep_given or {}).get(n, (False, False))[1] for n in groups.names])
    comp_t = components_of(sums, u_t, "translation", opts.min_redundancy, k_t, groups.kinds)
    comp_r = components_of(sums, u_r, "rotation", opts.min_redundancy, k_r, groups.kinds)
    st = given.stacked()
    pg = groups.pair_group(given)
    out = []
    for g, name in enumerate(groups.names):
        sel = pg == g
        out.append(GroupNoise(
            name=name, edges=tuple(groups.edges_of(problem, g)), pairs=int(sums.pairs[g]),
            sigma_given_m=float(np.median(st["sigma"][sel])),
            kappa_given=float(np.median(st["kappa"][sel])),
            translation=comp_t[g], rotation=comp_r[g], camera=groups.cameras[g],
            kind=groups.kinds[g]))
    est = NoiseEstimate(grouping=groups.grouping, given=opts.given, groups=out, rank=sums.rank,
                        min_redundancy=opts.min_redundancy,
                        left_out={edge_names[e]: w for e, w in sorted(left.items())})
    est.converged = est.largest_change <= opts.tolerance
    rounding = [g.name for g in out if "given" in (g.translation.source, g.rotation.source)
                and min(g.translation.chi2, g.rotation.chi2) <= _ROUNDING_FACTOR * 3 * g.pairs]
    if rounding:
        est.notes.append(f"residuals at rounding level (exact data) for {', '.join(rounding)}: "
                         "their given noise is kept")
    return est
