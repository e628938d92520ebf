"""The baselines behind one interface: :data:`BASELINES` by name, :func:`run_baseline`, and the
adapter of the paper's LOM (Appendix A, :mod:`rwhec_ros.core.baselines.lom_solver`)."""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np

from ..problem import Problem
from .dornaika import dornaika1998
from .opencv import BaselineOutput, opencv_hand_eye, opencv_robot_world_hand_eye
from .wang2022 import wang2022

__all__ = ["BaselineInfo", "BASELINES", "BaselineOutput", "baseline_names", "run_baseline", "lom"]


# --------------------------------------------------------------------------------------------
# LOM (paper Appendix A), implemented in rwhec_ros.core.baselines.lom_solver
# --------------------------------------------------------------------------------------------
def lom(
    problem: Problem,
    X0: np.ndarray | None = None,
    Y0: np.ndarray | None = None,
    alpha0: float = 1.0,
    **kw,
) -> BaselineOutput:
    """LOM of the paper's Appendix A via ``rwhec_ros.core.baselines.lom_solver.solve_lom`` (imported
    lazily).

    Defaults to the :func:`wang2022` initialisation (Tables 2 and 4) when ``X0``/``Y0`` are
    omitted. Extra keywords go to ``solve_lom``.
    """
    mod = importlib.import_module("rwhec_ros.core.baselines.lom_solver")
    if X0 is None or Y0 is None:
        Xw, Yw, aw = wang2022(problem)
        X0 = Xw if X0 is None else X0
        Y0 = Yw if Y0 is None else Y0
    out = mod.solve_lom(problem, X0, Y0, alpha0=alpha0, **kw)
    if hasattr(out, "X") and hasattr(out, "Y"):
        alpha = getattr(out, "scale", getattr(out, "alpha", 1.0))
        return np.asarray(out.X), np.asarray(out.Y), float(alpha)
    X, Y, alpha = out[:3]
    return np.asarray(X), np.asarray(Y), float(alpha)


# --------------------------------------------------------------------------------------------
# registry
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class BaselineInfo:
    """One registered baseline.

    Attributes
    ----------
    name : str
        Registry key.
    label : str
        Row label used in the paper's tables.
    reference : str
        The paper that defines the method.
    single_edge_only : bool
        Only defined for 1X1Y problems.
    unknown_scale : bool
        Handles ``problem.unknown_scale``.
    function : callable
        ``function(problem, **kw) -> (X, Y, alpha)``.
    """

    name: str
    label: str
    reference: str
    single_edge_only: bool
    unknown_scale: bool
    function: Callable[..., BaselineOutput]


def _rwhe(method: str, mapping: str = "frames") -> Callable[..., BaselineOutput]:
    return lambda problem, **kw: opencv_robot_world_hand_eye(
        problem, method, **{"mapping": mapping, **kw}
    )


def _he(method: str) -> Callable[..., BaselineOutput]:
    return lambda problem, **kw: opencv_hand_eye(problem, method, **kw)


_OPENCV = "via OpenCV"
_DIRECT = "via OpenCV, direct A X = Y B mapping"

BASELINES: Mapping[str, BaselineInfo] = MappingProxyType(
    {
        info.name: info
        for info in (
            BaselineInfo("shah", "Shah", f"Shah (2013), {_OPENCV}", True, False, _rwhe("shah")),
            BaselineInfo(
                "shah_direct", "Shah (direct)", f"Shah (2013), {_DIRECT}", True, False,
                _rwhe("shah", "direct"),
            ),
            BaselineInfo("li", "Li", f"Li et al. (2010), {_OPENCV}", True, False, _rwhe("li")),
            BaselineInfo(
                "li_direct", "Li (direct)", f"Li et al. (2010), {_DIRECT}", True, False,
                _rwhe("li", "direct"),
            ),
            BaselineInfo(
                "tsai", "Tsai", f"Tsai and Lenz (1989), {_OPENCV}", True, False, _he("tsai")
            ),
            BaselineInfo(
                "park", "Park", f"Park and Martin (1994), {_OPENCV}", True, False, _he("park")
            ),
            BaselineInfo(
                "horaud", "Horaud", f"Horaud and Dornaika (1995), {_OPENCV}", True, False,
                _he("horaud"),
            ),
            BaselineInfo(
                "andreff", "Andreff", f"Andreff et al. (1999), {_OPENCV}", True, False,
                _he("andreff"),
            ),
            BaselineInfo(
                "daniilidis", "Daniilidis", f"Daniilidis (1999), {_OPENCV}", True, False,
                _he("daniilidis"),
            ),
            BaselineInfo("wang", "Wang", "Wang et al. (2022)", False, True, wang2022),
            BaselineInfo(
                "dornaika", "Dornaika", "Dornaika and Horaud (1998)", False, False, dornaika1998
            ),
            BaselineInfo("lom", "LOM", "Wise et al. (2025), Appendix A", False, True, lom),
        )
    }
)


def baseline_names() -> tuple[str, ...]:
    """Registered baseline names, in table order."""
    return tuple(BASELINES)


def run_baseline(name: str, problem: Problem, **kw) -> BaselineOutput:
    """Run the baseline called ``name`` (see :data:`BASELINES`) on ``problem``.

    Returns
    -------
    X : ndarray, shape (M, 4, 4)
    Y : ndarray, shape (P, 4, 4)
    alpha : float
        The estimated scale (1.0 for known-scale methods).
    """
    key = str(name).lower()
    if key not in BASELINES:
        raise ValueError(f"name: unknown baseline {name!r}, expected one of {baseline_names()}")
    X, Y, alpha = BASELINES[key].function(problem, **kw)
    return np.asarray(X, float), np.asarray(Y, float), float(alpha)
