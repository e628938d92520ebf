"""Reproduce Tables 2-5 of Wise et al. (IJRR 2025), Section 8, and print them as Markdown.

Run from the repository root::

    python benchmarks/paper_tables.py                 # 100 runs per noise level (slow)
    python benchmarks/paper_tables.py --quick         # 5 runs per noise level
    python benchmarks/paper_tables.py --runs 20 --seed 1 --tables 2 4 --output out.md

Every method sees the same runs (scenario data from :mod:`rwhec_ros.simulation.scenarios`, seeded
per table, noise level and run). Weights are the true noise levels (``sigma``, ``kappa``); LOM uses
``sigma_R = 1 / sqrt(kappa)`` as the paper does. "Ours" is
``rwhec_ros.core.solve.solve(problem, SolveOptions(mode="fast"))``; the fraction of runs it
certifies is reported. Each cell shows ``ours-mean +- std / paper-mean +- std (relative
difference of the means)``; differences above 15 % are in bold.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import importlib
import os
import platform
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

# One BLAS thread: the problems are small, and on a loaded 2-core machine threaded BLAS turned
# 0.3 ms SVDs into 250 ms ones. Set before numpy is imported by the package.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rwhec_ros.core.baselines import dornaika1998, run_baseline, wang2022  # noqa: E402
from rwhec_ros.core.lie import make_transform, rotation_distance, so3_exp  # noqa: E402
from rwhec_ros.simulation.scenarios import (  # noqa: E402
    PAPER_NOISE_LEVELS,
    NoiseLevel,
    fixed_cameras_hand_target,
    hand_camera_sphere,
)
from rwhec_ros.simulation.synthetic import GroundTruth  # noqa: E402

COLUMNS = ("t_x", "r_x", "t_y", "r_y", "alpha")
HEADERS = {
    "t_x": "t_x err [mm]",
    "r_x": "r_x err [deg]",
    "t_y": "t_y err [mm]",
    "r_y": "r_y err [deg]",
    "alpha": "alpha err [x1e-3, fraction]",
}
FACTOR = {"t_x": 1e3, "r_x": np.degrees(1.0), "t_y": 1e3, "r_y": np.degrees(1.0), "alpha": 1e3}
TOLERANCE = 0.15  # acceptance: |ours - paper| / paper
TIE = 0.02  # ordering check: relative difference of means treated as a tie


# ----------------------------------------------------------------------------------------------
# published values (copied from the paper's Tables 2-5; "alpha" as printed, see notes)
# ----------------------------------------------------------------------------------------------
def _p(*cells: str) -> tuple[tuple[float, float], ...]:
    out = []
    for c in cells:
        m, s = c.split("+-")
        out.append((float(m), float(s)))
    return tuple(out)


_K125S1, _K125S5, _K12S1, _K12S5 = PAPER_NOISE_LEVELS

PAPER: dict[int, dict[NoiseLevel, dict[str, tuple[tuple[float, float], ...]]]] = {
    2: {
        _K125S1: {
            "Shah": _p("20.6+-10.5", "1.37+-0.55", "9.9+-4.8", "1.34+-0.57"),
            "Wang": _p("20.6+-10.5", "1.37+-0.55", "9.9+-4.8", "1.34+-0.57"),
            "Dornaika (Wang)": _p("19.9+-10.2", "1.25+-0.53", "8.8+-4.3", "1.20+-0.54"),
            "Horn": _p("18.5+-9.4", "1.16+-0.51", "8.4+-4.2", "1.10+-0.51"),
            "LOM (Wang)": _p("11.1+-5.82", "0.78+-0.37", "3.69+-2.12", "0.63+-0.38"),
            "Ours": _p("10.9+-5.6", "0.77+-0.36", "3.71+-2.13", "0.62+-0.36"),
        },
        _K125S5: {
            "Shah": _p("31.2+-15.0", "1.61+-0.64", "21.2+-10.0", "1.57+-0.66"),
            "Wang": _p("31.2+-15.0", "1.61+-0.64", "21.2+-10.0", "1.57+-0.66"),
            "Dornaika (Wang)": _p("30.6+-14.5", "1.49+-0.62", "20.4+-9.7", "1.44+-0.63"),
            "Horn": _p("29.1+-13.6", "1.42+-0.60", "19.9+-9.2", "1.36+-0.59"),
            "LOM (Wang)": _p("28.5+-13.4", "1.45+-0.62", "18.5+-8.8", "1.39+-0.62"),
            "Ours": _p("28.4+-13.0", "1.42+-0.63", "18.5+-8.7", "1.36+-0.61"),
        },
        _K12S1: {
            "Shah": _p("65.5+-38.3", "4.34+-1.95", "31.8+-17.2", "4.41+-1.98"),
            "Wang": _p("65.5+-38.3", "4.34+-1.95", "31.8+-17.2", "4.41+-1.98"),
            "Dornaika (Wang)": _p("63.4+-37.3", "3.92+-1.87", "27.4+-16.2", "3.92+-1.90"),
            "Horn": _p("45.0+-24.8", "3.30+-1.69", "25.8+-14.1", "3.19+-1.55"),
            "LOM (Wang)": _p("15.2+-10.0", "1.84+-0.84", "3.4+-1.8", "0.88+-0.59"),
            "Ours": _p("15.1+-10.0", "1.81+-0.83", "3.4+-1.8", "0.87+-0.59"),
        },
        _K12S5: {
            "Shah": _p("71.9+-44.7", "4.74+-2.13", "37.8+-19.3", "4.63+-2.21"),
            "Wang": _p("71.9+-44.7", "4.74+-2.13", "37.8+-19.3", "4.63+-2.21"),
            "Dornaika (Wang)": _p("69.9+-43.1", "4.33+-2.08", "33.9+-17.9", "4.13+-2.14"),
            "Horn": _p("50.6+-28.4", "3.69+-1.72", "31.0+-16.2", "3.40+-1.72"),
            "LOM (Wang)": _p("48.3+-27.3", "3.18+-1.67", "18.7+-9.04", "2.72+-1.64"),
            "Ours": _p("47.7+-27.0", "3.12+-1.67", "18.8+-9.02", "2.68+-1.65"),
        },
    },
    3: {
        _K125S1: {
            "LOM (close)": _p("4.61+-2.39", "0.51+-0.21", "3.82+-1.93", "0.22+-0.12",
                              "1.78e-3+-1.54e-3"),
            "Ours": _p("4.71+-2.43", "0.51+-0.22", "3.82+-1.91", "0.250+-0.113",
                       "1.76e-3+-1.54e-3"),
        },
        _K125S5: {
            "LOM (close)": _p("23.0+-11.2", "0.94+-0.44", "19.1+-11.4", "0.85+-0.40",
                              "8.45e-3+-7.03e-3"),
            "Ours": _p("23.8+-11.3", "1.11+-0.53", "19.0+-11.4", "1.06+-0.52",
                       "8.41e-3+-7.02e-3"),
        },
        _K12S1: {
            "LOM (close)": _p("4.52+-1.97", "1.57+-0.59", "3.78+-1.89", "0.20+-0.10",
                              "1.88e-3+-1.37e-3"),
            "Ours": _p("4.50+-1.99", "1.54+-0.57", "3.77+-1.88", "0.206+-0.098",
                       "1.87e-3+-1.37e-3"),
        },
        _K12S5: {
            "LOM (close)": _p("23.2+-14.1", "1.90+-0.81", "20.0+-11.0", "1.07+-0.54",
                              "9.24e-3+-7.69e-3"),
            "Ours": _p("24.4+-14.3", "1.99+-0.81", "19.6+-11.0", "1.25+-0.58",
                       "9.16e-3+-7.69e-3"),
        },
    },
    4: {
        _K125S1: {
            "Wang": _p("2.32+-1.56", "0.469+-0.200", "2.71+-1.37", "0.273+-0.120"),
            "Horn": _p("12.11+-6.49", "0.455+-0.191", "5.43+-2.04", "0.165+-0.067"),
            "LOM (Wang)": _p("0.994+-0.416", "0.454+-0.190", "0.572+-0.296", "0.022+-0.010"),
            "Ours": _p("0.992+-0.416", "0.454+-0.189", "0.570+-0.294", "0.021+-0.010"),
        },
        _K125S5: {
            "Wang": _p("4.95+-2.20", "0.470+-0.196", "3.52+-1.57", "0.260+-0.115"),
            "Horn": _p("12.4+-6.4", "4.55+-1.91", "5.42+-2.33", "1.76+-0.69"),
            "LOM (Wang)": _p("4.57+-1.96", "0.460+-0.191", "2.74+-1.34", "0.120+-0.056"),
            "Ours": _p("4.56+-1.96", "0.459+-0.191", "2.69+-1.32", "0.111+-0.051"),
        },
        _K12S1: {
            "Wang": _p("6.05+-4.84", "1.54+-0.63", "7.63+-4.04", "0.812+-0.364"),
            "Horn": _p("69+-121", "24.6+-94.4", "48.5+-82.5", "13.0+-76.8"),
            "LOM (Wang)": _p("0.933+-0.370", "1.52+-0.64", "0.537+-0.262", "0.021+-0.010"),
            "Ours": _p("0.933+-0.370", "1.50+-0.62", "0.537+-0.262", "0.021+-0.010"),
        },
        _K12S5: {
            "Wang": _p("7.85+-4.34", "1.52+-0.70", "9.58+-4.46", "0.868+-0.340"),
            "Horn": _p("77+-146", "26+-106", "57+-110", "14.8+-83.9"),
            "LOM (Wang)": _p("4.57+-1.97", "1.51+-0.682", "2.93+-1.34", "0.104+-0.047"),
            "Ours": _p("4.57+-1.97", "1.48+-0.67", "2.92+-1.32", "0.103+-0.046"),
        },
    },
    5: {
        _K125S1: {
            "LOM (close)": _p("1.05+-0.45", "0.469+-0.185", "0.631+-0.249", "0.030+-0.013",
                              "2.71e-4+-1.98e-4"),
            "Ours": _p("1.05+-0.45", "0.468+-0.185", "0.597+-0.256", "0.026+-0.012",
                       "2.71e-4+-1.98e-4"),
        },
        _K125S5: {
            "LOM (close)": _p("5.25+-2.20", "0.457+-0.195", "3.15+-1.26", "0.179+-0.079",
                              "1.37e-3+-1.03e-3"),
            "Ours": _p("5.21+-2.18", "0.454+-0.194", "3.03+-1.24", "0.159+-0.071",
                       "1.37e-3+-1.03e-3"),
        },
        _K12S1: {
            "LOM (close)": _p("1.02+-0.44", "1.50+-0.62", "0.530+-0.284", "0.021+-0.010",
                              "2.58e-4+-2.02e-4"),
            "Ours": _p("1.02+-0.44", "1.46+-0.61", "0.530+-0.284", "0.021+-0.010",
                       "2.57e-4+-2.02e-4"),
        },
        _K12S5: {
            "LOM (close)": _p("5.20+-2.27", "1.48+-0.64", "3.13+-1.56", "0.156+-0.075",
                              "1.18e-3+-8.63e-4"),
            "Ours": _p("5.18+-2.26", "1.44+-0.626", "3.02+-1.51", "0.144+-0.069",
                       "1.18e-3+-8.62e-4"),
        },
    },
}


# ----------------------------------------------------------------------------------------------
# methods
# ----------------------------------------------------------------------------------------------
@dataclass
class Outcome:
    X: np.ndarray
    Y: np.ndarray
    alpha: float
    status: str = ""


MethodFn = Callable[[object, GroundTruth, np.random.Generator], Outcome]


@dataclass(frozen=True)
class Method:
    label: str  # our row label (matches the paper's where the paper has the row)
    fn: MethodFn
    paper_label: str | None = None  # the paper row to compare with


def _baseline(name: str) -> MethodFn:
    def fn(problem, gt, rng):
        X, Y, a = run_baseline(name, problem)
        return Outcome(X, Y, a)

    return fn


def _dornaika_wang(problem, gt, rng):
    Xw, Yw, _ = wang2022(problem)
    X, Y, a = dornaika1998(problem, Xw, Yw)
    return Outcome(X, Y, a)


def _lom():
    return importlib.import_module("rwhec_ros.core.baselines.lom_solver")


def _lom_wang(problem, gt, rng):
    Xw, Yw, aw = wang2022(problem)
    r = _lom().solve_lom(problem, Xw, Yw, alpha0=aw)
    return Outcome(r.X, r.Y, r.alpha, "converged" if r.converged else "not converged")


def perturb_close(rng: np.random.Generator, T: np.ndarray, angle_deg=10.0, dist=0.10):
    """Each transform (N, 4, 4) rotated by exactly ``angle_deg`` about a uniform axis and shifted
    by exactly ``dist`` [m] in a uniform direction ("10 deg and 10 cm from the ground truth")."""
    n = T.shape[0]
    ax = rng.standard_normal((n, 3))
    ax /= np.linalg.norm(ax, axis=1, keepdims=True)
    d = rng.standard_normal((n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    R = T[:, :3, :3] @ so3_exp(np.radians(angle_deg) * ax)
    return make_transform(R, T[:, :3, 3] + dist * d)


def _lom_close(problem, gt, rng):
    r = _lom().solve_lom(problem, perturb_close(rng, gt.X), perturb_close(rng, gt.Y), alpha0=1.0)
    return Outcome(r.X, r.Y, r.alpha, "converged" if r.converged else "not converged")


def _ours(problem, gt, rng):
    solve_mod = importlib.import_module("rwhec_ros.core.solve")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        r = solve_mod.solve(problem, solve_mod.SolveOptions(mode="fast"))
    fell_back = any("fell back" in n for n in r.notes)
    return Outcome(r.X, r.Y, r.scale, r.certificate.status.value + (" (SDP)" if fell_back else ""))


def _available(module: str) -> bool:
    try:
        importlib.import_module(module)
    except ImportError:
        return False
    return True


@dataclass(frozen=True)
class TableSpec:
    number: int
    title: str
    scenario: Callable[..., tuple]
    monocular: bool
    methods: tuple[Method, ...]


def table_specs(have_lom: bool, have_solve: bool) -> dict[int, TableSpec]:
    lom_wang = (Method("LOM (Wang)", _lom_wang, "LOM (Wang)"),) if have_lom else ()
    lom_close = (Method("LOM (close)", _lom_close, "LOM (close)"),) if have_lom else ()
    ours = (Method("Ours", _ours, "Ours"),) if have_solve else ()
    single = tuple(
        Method(label, _baseline(name), paper)
        for name, label, paper in (
            ("shah", "Shah [OpenCV]", "Shah"),
            ("shah_direct", "Shah [OpenCV, direct]", "Shah"),
            ("li", "Li [OpenCV]", None),
            ("tsai", "Tsai [OpenCV]", None),
            ("park", "Park [OpenCV]", None),
            ("horaud", "Horaud [OpenCV]", None),
            ("andreff", "Andreff [OpenCV]", None),
            ("daniilidis", "Daniilidis [OpenCV]", None),
        )
    )
    wang = Method("Wang", _baseline("wang"), "Wang")
    wang_scale = Method("Wang + linear scale (ext.)", _baseline("wang"), None)
    dornaika = Method("Dornaika (Wang)", _dornaika_wang, "Dornaika (Wang)")
    return {
        2: TableSpec(2, "Section 8.1, known scale (1X1Y, 100 poses on a 1 m sphere)",
                     hand_camera_sphere, False, single + (wang, dornaika) + lom_wang + ours),
        3: TableSpec(3, "Section 8.1, unknown scale (50 poses on each of a 1 m and a 0.3 m "
                     "sphere, alpha = 0.5)", hand_camera_sphere, True,
                     (wang_scale,) + lom_close + ours),
        4: TableSpec(4, "Section 8.2, known scale (4 fixed cameras, hand-mounted target, 108 "
                     "poses)", fixed_cameras_hand_target, False,
                     (wang, dornaika) + lom_wang + ours),
        5: TableSpec(5, "Section 8.2, unknown scale (alpha = 0.5)", fixed_cameras_hand_target,
                     True, (wang_scale,) + lom_close + ours),
    }


# ----------------------------------------------------------------------------------------------
# running
# ----------------------------------------------------------------------------------------------
@dataclass
class Stats:
    """Pooled errors of one method at one noise level (metres, radians, fraction)."""

    errors: dict[str, list[float]] = field(default_factory=lambda: {c: [] for c in COLUMNS})
    times: list[float] = field(default_factory=list)
    statuses: dict[str, int] = field(default_factory=dict)
    failures: list[str] = field(default_factory=list)

    def add(self, out: Outcome, gt: GroundTruth, seconds: float) -> None:
        self.errors["t_x"].extend(np.linalg.norm(out.X[:, :3, 3] - gt.X[:, :3, 3], axis=1))
        self.errors["r_x"].extend(rotation_distance(out.X[:, :3, :3], gt.X[:, :3, :3]))
        self.errors["t_y"].extend(np.linalg.norm(out.Y[:, :3, 3] - gt.Y[:, :3, 3], axis=1))
        self.errors["r_y"].extend(rotation_distance(out.Y[:, :3, :3], gt.Y[:, :3, :3]))
        self.errors["alpha"].append(abs(out.alpha - gt.alpha) / gt.alpha)
        self.times.append(seconds)
        if out.status:
            self.statuses[out.status] = self.statuses.get(out.status, 0) + 1

    def summary(self, col: str) -> tuple[float, float]:
        v = np.asarray(self.errors[col], float) * FACTOR[col]
        if v.size == 0:
            return float("nan"), float("nan")
        return float(np.mean(v)), float(np.std(v))

    @property
    def runs(self) -> int:
        return len(self.times)


def run_table(spec: TableSpec, runs: int, seed: int, progress=None) -> dict:
    """``{level: {label: Stats}}`` for every noise level, all methods on the same runs."""
    results: dict[NoiseLevel, dict[str, Stats]] = {}
    for li, lv in enumerate(PAPER_NOISE_LEVELS):
        per = {m.label: Stats() for m in spec.methods}
        for r in range(runs):
            problem, gt = spec.scenario(
                np.random.default_rng([seed, spec.number, li, r]), lv.sigma, lv.kappa,
                monocular=spec.monocular,
            )
            for mi, m in enumerate(spec.methods):
                rng = np.random.default_rng([seed, spec.number, li, r, 1000 + mi])
                t0 = time.perf_counter()
                try:
                    out = m.fn(problem, gt, rng)
                except Exception as exc:  # noqa: BLE001 - a failed method is a table entry
                    per[m.label].failures.append(f"run {r}: {type(exc).__name__}: {exc}")
                    continue
                per[m.label].add(out, gt, time.perf_counter() - t0)
            if progress is not None:
                progress(spec.number, lv, r + 1, runs)
        results[lv] = per
    return results


# ----------------------------------------------------------------------------------------------
# formatting
# ----------------------------------------------------------------------------------------------
def fmt(x: float) -> str:
    if not np.isfinite(x):
        return "nan"
    if x == 0:
        return "0"
    mag = abs(x)
    if mag >= 100:
        return f"{x:.0f}"
    if mag >= 10:
        return f"{x:.1f}"
    if mag >= 1:
        return f"{x:.2f}"
    return f"{x:.3g}"


def rel(ours: float, paper: float) -> float:
    return (ours - paper) / paper if paper else float("nan")


def cell(ours: tuple[float, float] | None, paper: tuple[float, float] | None) -> str:
    left = "—" if ours is None else f"{fmt(ours[0])} ± {fmt(ours[1])}"
    if paper is None:
        return f"{left} / —"
    right = f"{fmt(paper[0])} ± {fmt(paper[1])}"
    if ours is None:
        return f"— / {right}"
    d = rel(ours[0], paper[0])
    dtxt = f"{100 * d:+.0f} %"
    if abs(d) > TOLERANCE:
        dtxt = f"**{dtxt}**"
    return f"{left} / {right} ({dtxt})"


def paper_alpha(v: tuple[float, float]) -> tuple[float, float]:
    """The paper's alpha column is printed as a fraction (see notes); shown x1e3 here."""
    return v[0] * 1e3, v[1] * 1e3


def format_table(spec: TableSpec, results: dict) -> tuple[list[str], list[dict]]:
    cols = list(COLUMNS if spec.monocular else COLUMNS[:4])
    lines = [
        f"### Table {spec.number}: {spec.title}",
        "",
        "| Noise level | Method (init.) | " + " | ".join(HEADERS[c] for c in cols)
        + " | ms / run | runs | status (Ours: certified) |",
        "|---|---|" + "---|" * len(cols) + "---|---|---|",
    ]
    flagged: list[dict] = []
    for lv, per in results.items():
        paper = PAPER[spec.number][lv]
        shown_paper: set[str] = set()
        for m in spec.methods:
            st = per[m.label]
            pv = paper.get(m.paper_label) if m.paper_label else None
            if m.paper_label:
                shown_paper.add(m.paper_label)
            cells = []
            for ci, c in enumerate(cols):
                ours = st.summary(c) if st.runs else None
                p = None if pv is None else (paper_alpha(pv[ci]) if c == "alpha" else pv[ci])
                cells.append(cell(ours, p))
                if m.label == "Ours" and ours is not None and p is not None:
                    d = rel(ours[0], p[0])
                    if abs(d) > TOLERANCE:
                        flagged.append({"table": spec.number, "level": lv.label, "col": c,
                                        "ours": ours[0], "paper": p[0], "rel": d})
            ms = f"{1e3 * np.mean(st.times):.1f}" if st.times else "—"
            status = ", ".join(f"{k}: {v}" for k, v in sorted(st.statuses.items()))
            if st.failures:
                first = st.failures[0].strip().splitlines()[-1][-90:]
                status = "; ".join(
                    x for x in (status, f"{len(st.failures)} failed (first: {first})") if x
                )
            lines.append(
                f"| {lv.label} | {m.label} | " + " | ".join(cells) + f" | {ms} | {st.runs} | "
                f"{status} |"
            )
        for plabel, pv in paper.items():
            if plabel in shown_paper:
                continue
            cells = [cell(None, paper_alpha(pv[ci]) if c == "alpha" else pv[ci])
                     for ci, c in enumerate(cols)]
            lines.append(f"| {lv.label} | {plabel} (paper only, not implemented) | "
                         + " | ".join(cells) + " | — | — | |")
    lines.append("")
    return lines, flagged


def ordering_checks(spec: TableSpec, results: dict) -> list[str]:
    """``ours <= LOM (Wang) <= Dornaika (Wang) <= Shah/Wang`` on every column mean; a larger mean
    within ``TIE`` (relative) of the next is reported as a tie, not a violation."""
    chain = [lab for lab in ("Ours", "LOM (Wang)", "Dornaika (Wang)", "Wang")
             if lab in {m.label for m in spec.methods}]
    if spec.monocular or len(chain) < 2:
        return []
    out = []
    for lv, per in results.items():
        bad, ties = [], 0
        for c in COLUMNS[:4]:
            means = [per[lab].summary(c)[0] for lab in chain]
            for a, b, va, vb in zip(chain, chain[1:], means, means[1:], strict=False):
                if va > vb * (1.0 + TIE):
                    bad.append(f"{c}: {a} {fmt(va)} > {b} {fmt(vb)}")
                elif va > vb:
                    ties += 1
        verdict = "holds" if not bad else "violated: " + "; ".join(bad)
        tie_txt = f" ({ties} tie(s) within {100 * TIE:.0f} %)" if ties else ""
        out.append(f"- Table {spec.number}, {lv.label}: {' <= '.join(chain)} {verdict}{tie_txt}")
    return out


def lom_minimum_check(runs: int, seed: int) -> list[str]:
    """Whether LOM (Wang) sits in LOM's own global basin: restart it from the ground truth."""
    lines = []
    for number, scenario in ((2, hand_camera_sphere), (4, fixed_cameras_hand_target)):
        for li, lv in enumerate(PAPER_NOISE_LEVELS):
            same = 0
            for r in range(runs):
                problem, gt = scenario(np.random.default_rng([seed, number, li, r]), lv.sigma,
                                       lv.kappa)
                a = _lom_wang(problem, gt, None)
                b = _lom().solve_lom(problem, gt.X, gt.Y)
                diff = max(np.abs(a.X - b.X).max(), np.abs(a.Y - b.Y).max())
                same += int(diff < 1e-6)
            lines.append(f"Table {number} {lv.label}: {same}/{runs}")
    return lines


def certified_summary(results_all: dict) -> list[str]:
    out = []
    for number, results in results_all.items():
        n = cert = 0
        kinds: dict[str, int] = {}
        for per in results.values():
            st = per.get("Ours")
            if st is None:
                continue
            n += st.runs
            for k, v in st.statuses.items():
                kinds[k] = kinds.get(k, 0) + v
                if k.startswith("certified_optimal"):
                    cert += v
        if n:
            detail = ", ".join(f"{k}: {v}" for k, v in sorted(kinds.items()))
            out.append(f"- Table {number}: {cert}/{n} runs certified ({100 * cert / n:.0f} %); "
                       f"{detail}")
    return out


def oracle_lines() -> list[str]:
    """Error magnitudes of an efficient estimator that knows ``Y`` exactly (Section 8.2)."""
    c = np.sqrt(8.0 / np.pi)  # mean norm of a 3D standard Gaussian vector
    n = 108
    lines = []
    for lv in PAPER_NOISE_LEVELS:
        t = 1e3 * c * lv.sigma / np.sqrt(n)
        r = np.degrees(c / np.sqrt(2.0 * lv.kappa * n))
        p4 = PAPER[4][lv]["Ours"]
        lines.append(
            f"| {lv.label} | {fmt(t)} | {fmt(p4[0][0])} ({100 * rel(p4[0][0], t):+.0f} %) | "
            f"{fmt(r)} | {fmt(p4[1][0])} ({100 * rel(p4[1][0], r):+.0f} %) |"
        )
    return lines


def noise_free_check(specs: dict[int, TableSpec], seed: int) -> list[str]:
    """Largest error of every method on one exact (noise-free) instance of each scenario."""
    lines = [
        "| Table | Method | max abs error of X, Y entries | alpha error |",
        "|---|---|---|---|",
    ]
    for number, spec in specs.items():
        problem, gt = spec.scenario(np.random.default_rng([seed, number, 99]), 0.0, np.inf,
                                    monocular=spec.monocular)
        for mi, m in enumerate(spec.methods):
            try:
                out = m.fn(problem, gt, np.random.default_rng([seed, number, 99, mi]))
            except Exception as exc:  # noqa: BLE001
                lines.append(f"| {number} | {m.label} | failed: {type(exc).__name__}: "
                             f"{str(exc).strip().splitlines()[-1][-90:]} | |")
                continue
            err = max(np.abs(out.X - gt.X).max(), np.abs(out.Y - gt.Y).max())
            lines.append(f"| {number} | {m.label} | {err:.1e} | "
                         f"{abs(out.alpha - gt.alpha):.1e} |")
    return lines + [""]


def trajectory_sensitivity(runs: int, seed: int) -> list[str]:
    """Ours on Section 8.1 (known scale, kappa 125, sigma 1 cm) for several sphere readings."""
    lv = PAPER_NOISE_LEVELS[0]
    designs = (
        ("band, latitudes +45..-45 (used)", (45.0, 135.0)),
        ("nearly whole sphere, polar 5..175", (5.0, 175.0)),
        ("polar cap, polar 5..60", (5.0, 60.0)),
        ("polar cap, polar 5..30", (5.0, 30.0)),
    )
    p = PAPER[2][lv]["Ours"]
    lines = [
        f"| 8.1 trajectory ({runs} runs, {lv.label}) | t_x [mm] | r_x [deg] | t_y [mm] | "
        "r_y [deg] |",
        "|---|---|---|---|---|",
        f"| paper (Ours) | {fmt(p[0][0])} | {fmt(p[1][0])} | {fmt(p[2][0])} | {fmt(p[3][0])} |",
    ]
    for di, (name, rng_deg) in enumerate(designs):
        st = Stats()
        for r in range(runs):
            problem, gt = hand_camera_sphere(
                np.random.default_rng([seed, 81, di, r]), lv.sigma, lv.kappa,
                polar_range_deg=rng_deg,
            )
            t0 = time.perf_counter()
            st.add(_ours(problem, gt, None), gt, time.perf_counter() - t0)
        cells = " | ".join(fmt(st.summary(c)[0]) for c in COLUMNS[:4])
        lines.append(f"| {name} | {cells} |")
    return lines + [""]


def axis_magnitude_noise(rng: np.random.Generator, B: np.ndarray, sigma: float, kappa: float):
    """The hypothesised noise of the paper's simulation (NOT ``Lang(I, kappa)``): a von Mises
    angle of concentration ``kappa`` and a ``N(0, sigma^2)`` length, each along its own uniform
    axis, i.e. per-axis variances ``1 / (3 kappa)`` and ``sigma^2 / 3``."""
    n = B.shape[0]
    u = rng.standard_normal((n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = rng.standard_normal((n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    out = np.array(B, float)
    out[:, :3, 3] += u * (sigma * rng.standard_normal(n))[:, None]
    out[:, :3, :3] = out[:, :3, :3] @ so3_exp(v * rng.vonmises(0.0, kappa, n)[:, None])
    return out


def hypothesis_check(runs: int, seed: int) -> list[str]:
    """Ours on Tables 2 and 4 data whose noise follows :func:`axis_magnitude_noise`."""
    edge_mod = importlib.import_module("rwhec_ros.core.problem")
    lines = [
        f"| Table | Noise level | Ours with axis-magnitude noise ({runs} runs) vs paper: "
        "t_x | r_x | t_y | r_y |",
        "|---|---|---|---|---|---|",
    ]
    for number, scenario in ((2, hand_camera_sphere), (4, fixed_cameras_hand_target)):
        for li, lv in enumerate(PAPER_NOISE_LEVELS):
            st = Stats()
            for r in range(runs):
                rng = np.random.default_rng([seed, 77, number, li, r])
                exact, gt = scenario(rng, 0.0, np.inf)
                edges = [
                    edge_mod.Edge.build(e.x, e.y, e.A, axis_magnitude_noise(rng, e.B, lv.sigma,
                                                                            lv.kappa),
                                        sigma=lv.sigma, kappa=lv.kappa)
                    for e in exact.edges
                ]
                problem = exact.with_edges(edges)
                t0 = time.perf_counter()
                st.add(_ours(problem, gt, None), gt, time.perf_counter() - t0)
            p = PAPER[number][lv]["Ours"]
            cells = " | ".join(cell(st.summary(c), p[ci]) for ci, c in enumerate(COLUMNS[:4]))
            lines.append(f"| {number} | {lv.label} | {cells} |")
    return lines + [""]


def notes(flagged: list[dict], sensitivity: list[str], exact: list[str],
          hypothesis: list[str], lom_check: list[str]) -> list[str]:
    out = ["## Notes", ""]
    out += [
        "- **Noise-free check** (one exact instance per table; round-off level means the "
        "method recovers the ground truth):",
        "",
        *exact,
        "  On the 8.1 data the camera always looks at the sphere centre, so the hand-camera "
        "translation is tied to the rotations (`t_X + r R_X e_z` is a fixed pivot). OpenCV's "
        "joint linear methods (Li, Andreff) solve one homogeneous system for rotations and "
        "translations together, and this structure makes it rank-deficient: they are wrong "
        "even without noise (or throw), independently of our frame mapping (they are exact "
        "on generic data, see `test/core/test_baselines.py`). It is the same degeneracy that "
        "makes the single-sphere monocular problem unidentifiable (paper Section 8.1, tested in "
        "`test/core/test_scenarios.py`).",
        "- **Weights.** The MLE (Ours) gets the true noise levels (`sigma`, `kappa`; for "
        "monocular data the noise was scaled with the translations, so `alpha * sigma`). LOM "
        "uses `sigma_t = sigma` and `sigma_R = 1 / sqrt(kappa)` as in the paper (Appendix A). "
        "With the Langevin density proportional to `exp(kappa tr R)` the small-angle rotation "
        "vector is approximately `N(0, I / (2 kappa))`, so the matched Gaussian would be "
        "`sigma_R = 1 / sqrt(2 kappa)`: relative to the MLE, LOM weights rotations by half. "
        "Where LOM (Wang) is less accurate than Ours (Table 2, kappa = 12, sigma = 5 cm) this is "
        "mostly its objective, not local minima: restarted from the ground truth LOM returns "
        "the same solution as from Wang in " + (", ".join(lom_check) if lom_check else
                                                  "(not run)") + " runs.",
        "- **Dornaika** is our implementation of Dornaika & Horaud (1998): joint "
        "Levenberg-Marquardt on `sum |R_A R_X - R_Y R_B|_F^2 + |R_A t_X + t_A - R_Y t_B - "
        "t_Y|^2` (unit weights, metres), started from Wang; the paper has no Dornaika row in "
        "Tables 4/5. **Wang** is the unweighted Kronecker null-vector + linear translation "
        "closed form of Wang et al. (2022); `Wang + linear scale (ext.)` adds `alpha` to its "
        "translation stage (our extension, not in the paper).",
        "- **OpenCV rows.** `[OpenCV]` passes the data in OpenCV's documented frames "
        "(`world2cam = B^-1`, `base2gripper = A^-1`), which puts the translation residual in "
        "the camera frame; `[OpenCV, direct]` feeds its `A X = Z B` with our `A, B` directly, "
        "which makes Shah identical to Wang (as in the paper's Table 2, where the two rows "
        "coincide). Tsai ... Daniilidis estimate `X` only; `Y` is the chordal mean of "
        "`A X B^-1`.",
        "- **LOM (close)** starts exactly 10 deg (uniform axis) and 10 cm (uniform direction) "
        "from the true `X` and `Y`, with `alpha = 1`, as in the paper.",
        "- **alpha column.** Ours is the relative error `|alpha_hat - alpha| / alpha` as a "
        "fraction x1e-3. The paper's column is labelled [%] but its values (e.g. 1.76e-3 at "
        "sigma = 1 cm) only make sense as fractions: 100 measurements with 1 cm noise at "
        "0.3-1 m cannot fix the scale to 1.8e-5. We therefore compare against the printed "
        "numbers read as fractions.",
        "- **Monocular noise.** Section 8 says the *noisy* B translations are scaled by alpha "
        "(`alpha (t + eps)`), which is what we simulate; eq. (20) and "
        "`synthetic.perturb_measurements` add the noise after scaling (`alpha t + eps`), i.e. "
        "twice the metric noise for alpha = 0.5.",
        "- **Ordering** is checked on column means; a larger mean within "
        f"{100 * TIE:.0f} % of the next method's is counted as a tie (Ours and LOM (Wang) "
        "often agree to three digits).",
        "- **Runtime** is wall-clock per run with one BLAS thread on a shared 2-core machine "
        "(other jobs were running); only the orders of magnitude mean anything.",
        "",
        "## Why some rows differ from the paper",
        "",
        "**Trajectories (all tables).** The paper does not give its trajectories or "
        "ground-truth distributions, and the error statistics depend strongly on the trajectory "
        "(not on the ground truth: the MLE, Wang, Dornaika and OpenCV-direct Shah are "
        "equivariant under a change of base or hand frame, tested in "
        "`test/core/test_baselines.py`). Our readings are documented in "
        "`rwhec_ros/simulation/scenarios.py`: 8.1 is a spiral over latitudes +45..-45 deg (one "
        "azimuth turn) on the sphere, camera looking at the centre with `y` to the south pole; "
        "8.2 uses uniformly random target orientations in an 80 x 80 x 60 cm box kept only when "
        "the target is in front of and within 60 deg of every optical axis of four cameras 1.5 m "
        "away. We tried other 8.1 readings (table below, measured by this script): the whole "
        "sphere or a polar cap give much smaller t_x and r_y than the paper, and a cap makes "
        "t_y as large as t_x, whereas the paper has t_y about a third of t_x; an equatorial "
        "band reproduces that pattern (its weak direction is a rotation of Y about the polar "
        "axis traded against t_X), so we kept it. Nothing was tuned beyond choosing this family "
        "and the +-45 deg band; with it the sigma = 1 cm rows of Table 2 come out close to the "
        "paper and the sigma = 5 cm rows lower (the paper's trajectory is evidently less "
        "informative about translations).",
        "",
        *sensitivity,
        "**Section 8.2 (Tables 4/5) is below what the stated noise model allows.** Camera j's "
        "rotation `R_Xj` appears only in the rotation residuals and its position only in edge "
        "j's translation residuals, so even an estimator that knew `Y` exactly would average "
        "108 Langevin / Gaussian samples per camera; its mean error magnitudes are "
        "`sqrt(8/pi) sigma / sqrt(108)` and `sqrt(8/pi) / sqrt(2 kappa 108)`:",
        "",
        "| Noise level | oracle t_x [mm] | paper Ours t_x [mm] | oracle r_x [deg] | "
        "paper Ours r_x [deg] |",
        "|---|---|---|---|---|",
        *oracle_lines(),
        "",
        "The paper's r_x is about 0.82 = sqrt(2/3) of the oracle at both kappas and its t_x "
        "about 0.6 of it. Both would follow if the simulation drew a 1-D Gaussian "
        "(or von Mises) magnitude along a uniformly random axis (per-axis variance 1/3 of the "
        "magnitude variance: `1/(3 kappa)` instead of `1/(2 kappa)` for rotations, `sigma^2/3` "
        "for translations); that is a hypothesis about the authors' code, not something the "
        "paper states, so the tables above do not use it. Our sampler follows `Lang(I, kappa)` "
        "exactly (Kolmogorov-Smirnov test against `p(theta) ~ exp(2 kappa cos theta)(1 - cos "
        "theta)` in `test/core/test_scenarios.py`), so our Table 4/5 r_x and t_x cannot go "
        "below the oracle. For reference only, the same scenarios with the hypothesised noise "
        "(with it our Table 4 moves onto the paper's numbers, while Table 2 drops well below "
        "them, so with our 8.1 trajectory it does not explain both tables):",
        "",
        *hypothesis,
        "**Monocular scale (Tables 3/5).** In 8.2 the scale is observed only through the "
        "spread of the hand positions (the mean hand position is absorbed by `t_X`), so its "
        "error scales like `alpha sigma / (sqrt(3 N) spread)`; the paper's 2.7e-4 at 1 cm needs "
        "a hand workspace several times larger than our 80 x 80 x 60 cm box (a 30 x 40 x 30 "
        "cm box doubled our alpha error), and Table 5's t_x inherits `alpha error x camera "
        "distance` on top of Table 4's. In 8.1 the scale comes from the two sphere radii, and "
        "ours is within about +50 % of the paper.",
        "",
    ]
    if flagged:
        out += ["### Ours cells more than 15 % from the paper", "",
                "| Table | Noise level | column | ours | paper | difference |",
                "|---|---|---|---|---|---|"]
        for f in flagged:
            out.append(f"| {f['table']} | {f['level']} | {f['col']} | {fmt(f['ours'])} | "
                       f"{fmt(f['paper'])} | {100 * f['rel']:+.0f} % |")
        out.append("")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="5 runs per noise level")
    ap.add_argument("--runs", type=int, default=None, help="runs per noise level (default 100)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--tables", type=int, nargs="+", default=[2, 3, 4, 5], choices=[2, 3, 4, 5])
    ap.add_argument("--output", type=Path, default=None, help="also write the Markdown here")
    ap.add_argument("--progress", action="store_true", help="progress on stderr")
    ap.add_argument("--sensitivity-runs", type=int, default=None,
                    help="runs per 8.1 trajectory reading in the notes (default 20, quick 3)")
    ap.add_argument("--hypothesis-runs", type=int, default=None,
                    help="runs per level of the noise-hypothesis check (default 30, quick 3)")
    args = ap.parse_args(argv)
    runs = args.runs if args.runs is not None else (5 if args.quick else 100)
    if runs < 1:
        ap.error(f"--runs must be >= 1, got {runs}")

    have_lom = _available("rwhec_ros.core.baselines.lom_solver")
    have_solve = _available("rwhec_ros.core.solve")
    specs = table_specs(have_lom, have_solve)

    def progress(t, lv, r, n):
        if args.progress:
            print(f"table {t} {lv.label}: {r}/{n}", file=sys.stderr, flush=True)

    t_start = time.perf_counter()
    results_all, flagged, body, order = {}, [], [], []
    for number in args.tables:
        spec = specs[number]
        results = run_table(spec, runs, args.seed, progress)
        results_all[number] = results
        lines, fl = format_table(spec, results)
        body += lines
        flagged += fl
        order += ordering_checks(spec, results)
    exact = noise_free_check({n: specs[n] for n in args.tables}, args.seed)
    sens_runs = args.sensitivity_runs
    if sens_runs is None:
        sens_runs = 3 if args.quick else 20
    sensitivity = trajectory_sensitivity(sens_runs, args.seed) if have_solve and sens_runs else []
    hyp_runs = args.hypothesis_runs
    if hyp_runs is None:
        hyp_runs = 3 if args.quick else 30
    hypothesis = hypothesis_check(hyp_runs, args.seed) if have_solve and hyp_runs else []
    lom_check = lom_minimum_check(3 if args.quick else 10, args.seed) if have_lom else []
    elapsed = time.perf_counter() - t_start

    head = [
        "# Reproduction of Tables 2-5 (Wise et al., IJRR 2025, Section 8)",
        "",
        f"Generated by `benchmarks/paper_tables.py --runs {runs} --seed {args.seed}` on "
        f"{_dt.date.today().isoformat()} ({platform.machine()}, Python "
        f"{platform.python_version()}, numpy {np.__version__}); {runs} runs per noise level, "
        f"every method on the same runs; total {elapsed / 60:.1f} min.",
        "",
        "\"Ours\" is `solve(problem, SolveOptions(mode=\"fast\"))` of the working tree at that "
        "date.",
        "",
        "Each cell: **ours mean ± std / paper mean ± std (relative difference of the means)**; "
        f"differences above {100 * TOLERANCE:.0f} % in bold. X errors pool all X's "
        "(Tables 4/5: four cameras). Weights: true `sigma`, `kappa` for Ours; LOM uses "
        "`sigma_R = 1/sqrt(kappa)` (the paper's choice; the Langevin small-angle equivalent is "
        "`1/sqrt(2 kappa)`, see notes).",
        "",
    ]
    if not have_lom:
        head += ["**LOM rows skipped: `rwhec_ros.core.baselines.lom_solver` is not available.**",
                 ""]
    if not have_solve:
        head += ["**Ours rows skipped: `rwhec_ros.core.solve` is not available.**", ""]
    summary = ["## Acceptance summary", "", "Certification (Ours):", ""]
    summary += certified_summary(results_all) or ["- (no Ours rows)"]
    n_cells = sum(
        len(PAPER[n][lv]["Ours"]) for n in args.tables for lv in PAPER_NOISE_LEVELS
    ) if have_solve else 0
    summary += ["", f"Ours means within {100 * TOLERANCE:.0f} % of the paper: "
                f"{n_cells - len(flagged)} of {n_cells} cells; the {len(flagged)} outside are "
                "listed at the end.", "",
                "Ordering of column means (known scale):", ""]
    summary += order or ["- (not applicable)"]
    summary.append("")
    tail = notes(flagged, sensitivity, exact, hypothesis, lom_check)
    text = "\n".join(head + body + summary + tail) + "\n"
    sys.stdout.write(text)
    if args.output is not None:
        args.output.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
