#!/usr/bin/env python3
"""Certificate soundness (issue 10, deliverable 5): is every ``certified_optimal`` true?

Generates seeded adversarial instances (:mod:`soundness_instances`: graph shapes 1X1Y ... 8X4Y,
the paper's / high / extreme noise, known and unknown scale, outliers, near-single-axis and
exactly single-axis motion, tiny rotations, 2-3 pairs per edge), solves each with
``rwhec_ros.core.solve.solve`` and compares every certified result with an independent checker
(:mod:`soundness_checker`: own cost of eq. (33), own variable-projection and joint
``scipy.optimize.least_squares`` solves from >= 20 random starts plus the product's estimate and
the ground truth, costs in extended precision, violations confirmed in exact rational
arithmetic). Prints a Markdown report (definitions, tables per category, status distribution,
worst offenders, crashes, runtimes).

Run from the repository root::

    python benchmarks/certificate_soundness.py --quick                  # 400 instances
    python benchmarks/certificate_soundness.py --n 10000 --jobs 2 \\
        --output benchmarks/certificate_soundness.md                      # the full study
    python benchmarks/certificate_soundness.py --n 800 --categories near_single_axis,few_pairs
    python benchmarks/certificate_soundness.py --select 1200 --select 300:few_pairs:1X1Y \
        --sdp 100 --jobs 2 --save-failures DIR     # balanced + emphasis, SDP subset, npz files
    python benchmarks/certificate_soundness.py --replay DIR   # re-solve and re-check them
    python benchmarks/certificate_soundness.py --quick --mode fast-sparse  # the sparse path

Instances are assigned to the categories round robin by index (``--n`` takes indices 0..N-1,
balanced); ``--categories``/``--shapes`` or repeated ``--select N:CATS:SHAPES`` take the first N
matching indices. The full study takes about 0.7 s per instance with ``--jobs 2`` on the shared
2-core machine (about 2 h for 10,000; the checker dominates, 8X4Y instances take several
seconds).

Every record is appended to a JSON-lines log (``--log``, default ``<output>.jsonl`` or
``certificate_soundness.jsonl`` in the working directory); ``--resume`` skips the instances
already in it. Progress and an ETA go to stderr. The instance ``(seed, index)`` is reproducible
on its own (``soundness_instances.make_instance``).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import platform
import subprocess
import sys
import time
import traceback
import warnings
from collections import Counter, defaultdict
from fractions import Fraction
from pathlib import Path

# One BLAS thread per process: small problems, a shared 2-core machine (see paper_tables.py).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
import scipy  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

from soundness_checker import (  # noqa: E402
    CheckerOptions,
    Pairs,
    Point,
    check_minimum,
    direct_cost_metric,
    exact_cost,
)
from soundness_instances import (  # noqa: E402
    CATEGORIES,
    SHAPES,
    Instance,
    category_of,
    make_instance,
    shape_of,
)

#: A checker point must beat a bound by more than this (relative to the costs involved): the
#: checker's costs are exact to ~1e-18 (extended precision) and confirmed in rational arithmetic,
#: the product's numbers are doubles (~1e-16); 1e-9 leaves seven orders for either.
EVAL_REL_TOL = 1e-9
#: Certified results whose reported primal cost differs from the direct cost at the returned
#: estimate by more than this (relative) are cost mismatches (issue 10 target).
MISMATCH_REL_TOL = 1e-6
#: A returned rotation is feasible when ``max |R^T R - I| <= ROT_TOL`` and ``det R > 0``.
ROT_TOL = 1e-6
CERTIFIED = "certified_optimal"

DEFINITIONS = f"""\
## Definitions

All costs are ``f = 1/2 sum_pairs (|alpha (R_A t_X + t_A - t_Y) - R_Y t_B|^2 / sigma^2 +
kappa |R_A R_X - R_Y R_B|_F^2)`` (eq. (33) with the 1/2 of eq. (42); metric ``t``; ``alpha = 1``
for known scale) -- the same number as ``rwhec_ros.core.model.cost.direct_cost`` (checked in
``test/core/test_certificate_soundness.py``). The feasible set is rotations in SO(3), any
translations and, for unknown scale, ``alpha > 0`` (the checker allows ``alpha = 0`` as the limit
of feasible points). ``p``, ``d``, ``rho_hat``, ``rho_tol`` are the certificate's
``primal_cost``, ``dual_bound``, ``suboptimality_bound``, ``tolerance``. The product claims
(``rwhec_ros/core/certify/dense.py``): ``d`` is a lower bound on the optimum and
``rho_hat = (p - d) / max(d, cost_floor) <= rho_tol``; the denominator is recovered as
``D = max(|d|, (p - d) / rho_hat)`` (``|d|`` when ``rho_hat <= 0``).

* **checker**: best cost ``c*`` (extended precision) over >= 20 random-start local solves of an
  independent implementation plus starts at the product's estimate and the ground truth.
* **false certificate**: status ``{CERTIFIED}`` and at least one of
  - *below bound*: ``c* < d - eps`` (a feasible point beats the dual bound);
  - *suboptimal*: ``p_direct - c* > rho_tol * D + eps`` (the returned estimate is worse than the
    certificate claims; ``p_direct`` = direct cost at the returned ``X, Y, scale``);
  - *scale<=0*: unknown scale and ``scale <= 0`` (or not finite);
  - *infeasible*: non-finite estimate or a rotation with ``max|R^T R - I| > {ROT_TOL:g}`` or
    ``det <= 0``;

  with ``eps = {EVAL_REL_TOL:g} * max(|d|, c*, p_direct)``. *below bound* and *suboptimal* are
  confirmed by the exact rational cost of the checker's point with exactly orthogonal (rational
  quaternion) rotations; only confirmed ones count.
* **cost mismatch**: certified and ``|p - p_direct| > {MISMATCH_REL_TOL:g} * p_direct``
  (``p_direct`` in extended precision; "rounding" is its float64 vs. extended-precision gap).
* **crash**: any exception escaping ``solve()`` on valid input.
"""


# --- one instance -------------------------------------------------------------------------------

def _product_estimate(res) -> tuple[np.ndarray, np.ndarray, float]:
    T = np.concatenate([np.asarray(res.X, float), np.asarray(res.Y, float)])
    return T[:, :3, :3], T[:, :3, 3], float(res.scale)


def _feasible_rotations(R: np.ndarray) -> bool:
    if not np.all(np.isfinite(R)):
        return False
    orth = np.abs(np.swapaxes(R, 1, 2) @ R - np.eye(3)).max()
    return bool(orth <= ROT_TOL and np.all(np.linalg.det(R) > 0))


def _status_value(status) -> str:
    return str(getattr(status, "value", status))


def _base_record(inst: Instance, mode: str) -> dict:
    p = inst.params
    return {"key": inst.key, "seed": inst.seed, "index": inst.index, "category": inst.category,
            "mode": mode, "shape": p["shape"], "noise": p["noise"], "sigma": p["sigma"],
            "kappa": p["kappa"], "unknown_scale": inst.unknown_scale, "motion": p["motion"],
            "jitter": p["jitter"], "outlier_fraction": p["outlier_fraction"],
            "pairs": p["pairs"], "n_pairs": int(sum(e[2].shape[0] for e in inst.edges))}


#: ``--mode`` values and their solver options: ``fast-sparse`` forces the sparse unreduced path of
#: ``fast`` (issue 14) with no dense/SDP fallback, so that every certificate is the sparse one;
#: ``sdp-cvxpy`` and ``sdp-structured`` force the SDP's backend (``sdp`` takes the default).
MODE_OPTIONS = {"fast": {"mode": "fast"}, "sdp": {"mode": "sdp"},
                "sdp-cvxpy": {"mode": "sdp", "sdp_backend": "cvxpy"},
                "sdp-structured": {"mode": "sdp", "sdp_backend": "structured"},
                "fast-sparse": {"mode": "fast", "fast_form": "sparse", "fallback_to_sdp": False}}


def _solve(inst: Instance, mode: str, rec: dict):
    """Run the product; fills status fields or the crash. Returns the result or None."""
    from rwhec_ros.core.relaxation import SdpOptions
    from rwhec_ros.core.solve import SolveOptions, solve

    try:
        problem = inst.to_problem()
    except Exception as exc:  # the generator made invalid input: not the solver's fault
        rec.update(status="input_error", certified=False, crash=None,
                   input_error=f"{type(exc).__name__}: {exc}"[:300])
        return None
    t0 = time.perf_counter()
    try:
        opts = dict(MODE_OPTIONS[mode])
        backend = opts.pop("sdp_backend", None)
        if backend is not None:
            opts["sdp"] = SdpOptions(backend=backend)
        res = solve(problem, SolveOptions(**opts))
    except Exception as exc:
        rec.update(status="crash", certified=False, solve_s=time.perf_counter() - t0,
                   crash=f"{type(exc).__name__}: {exc}"[:300],
                   traceback=traceback.format_exc(limit=-3)[-800:])
        return None
    rec["solve_s"] = time.perf_counter() - t0
    c = res.certificate
    status = _status_value(c.status)
    rec.update(status=status, certified=status == CERTIFIED, crash=None,
               message=str(c.message)[:300], p_rep=float(c.primal_cost),
               d=float(c.dual_bound), rho_hat=float(c.suboptimality_bound),
               rho_tol=float(c.tolerance), scale=float(res.scale),
               retry="tighten" in (getattr(res, "timing_s", None) or {}))
    return res


def _verdict(rec: dict, pairs: Pairs, check, witness: Point | None) -> None:
    """Fill ``false_cert``, ``reasons``, gaps and the exact confirmation for a certified result."""
    d, p_rep, rho, tol = rec["d"], rec["p_rep"], rec["rho_hat"], rec["rho_tol"]
    p_dir, c_best = rec["p_direct"], rec.get("c_best", float("nan"))
    reasons = []
    if not np.isfinite(d):
        reasons.append("no finite bound")
    if rec["unknown_scale"] and not (np.isfinite(rec["scale"]) and rec["scale"] > 0):
        reasons.append("scale<=0")
    if not rec["estimate_feasible"]:
        reasons.append("infeasible")
    denom = abs(d)
    if np.isfinite(rho) and rho > 0 and p_rep > d:
        denom = max(denom, (p_rep - d) / rho)
    allowance = tol * denom if np.isfinite(tol) else 0.0
    eps = EVAL_REL_TOL * max(abs(d) if np.isfinite(d) else 0.0, abs(c_best), abs(p_dir), 1e-300)
    scale_ref = max(abs(d), 1e-300) if np.isfinite(d) else 1.0
    rec["bound_excess_rel"] = float((d - c_best) / scale_ref)
    rec["subopt_found_rel"] = float((p_dir - c_best) / max(abs(c_best), 1e-300))
    below = bool(np.isfinite(d) and c_best < d - eps)
    subopt = bool(rec["estimate_feasible"] and p_dir - c_best > allowance + eps)
    if (below or subopt) and witness is not None:
        t0 = time.perf_counter()
        exact, _ = exact_cost(pairs, witness)
        rec["exact_s"] = time.perf_counter() - t0
        rec["exact_cost"] = float(exact)
        F = Fraction
        below = below and exact < F(d) - F(eps)
        subopt = subopt and F(p_dir) - exact > F(allowance) + F(eps)
        rec["exact_confirmed"] = bool(below or subopt)
    if below:
        reasons.append("below bound")
    if subopt:
        reasons.append("suboptimal")
    rec["reasons"] = reasons
    rec["false_cert"] = bool(reasons)


def evaluate(inst: Instance, mode: str, checker: CheckerOptions, check_all: bool = False,
             save_dir: Path | None = None, witness_start: Point | None = None) -> dict:
    """Solve ``inst`` with the product in ``mode``, check it, and return a flat record."""
    rec = _base_record(inst, mode)
    res = _solve(inst, mode, rec)
    pairs = Pairs.from_edges(inst.M, inst.P, inst.edges, inst.unknown_scale)
    check = None
    if res is not None:
        R, t, alpha = _product_estimate(res)
        finite = bool(np.all(np.isfinite(R)) and np.all(np.isfinite(t)) and np.isfinite(alpha))
        rec["estimate_feasible"] = finite and _feasible_rotations(R)
        if finite:
            rec["p_direct"] = direct_cost_metric(pairs, R, t, alpha)
            p64 = direct_cost_metric(pairs, R, t, alpha, dtype=float)
            rec["rounding_rel"] = abs(p64 - rec["p_direct"]) / max(abs(rec["p_direct"]), 1e-300)
        else:
            rec["p_direct"] = float("nan")
        rec["mismatch_rel"] = abs(rec["p_rep"] - rec["p_direct"]) / max(abs(rec["p_direct"]),
                                                                        1e-300)
        rec["mismatch"] = bool(rec["certified"] and not rec["mismatch_rel"] <= MISMATCH_REL_TOL)
        if rec["certified"] or check_all:
            gt = np.concatenate([inst.X_true, inst.Y_true])
            starts = {"truth": Point(gt[:, :3, :3], inst.alpha_true * gt[:, :3, 3],
                                     inst.alpha_true)}
            if finite:
                starts["product"] = Point(R, alpha * t, max(alpha, 0.0))
            if witness_start is not None:
                starts["saved witness"] = witness_start
            rng = np.random.default_rng(np.random.SeedSequence([inst.seed, inst.index, 7]))
            check = check_minimum(pairs, rng, starts, checker)
            b = check.best
            rec.update(checked=True, c_best=check.best_cost, best_origin=check.best_origin,
                       best_alpha=b.alpha, check_s=check.seconds, n_starts=check.n_starts,
                       best_tmax=float(np.abs(b.t).max()) if b.alpha > 0 else float("inf"))
            if not rec["certified"]:
                rec["subopt_found_rel"] = float((rec["p_direct"] - check.best_cost)
                                                / max(abs(check.best_cost), 1e-300))
        if rec["certified"]:
            _verdict(rec, pairs, check, check.best if check else None)
    rec.setdefault("false_cert", False)
    rec.setdefault("mismatch", False)
    failed = rec["false_cert"] or rec["mismatch"] or rec.get("crash")
    if failed and save_dir is not None:
        extra = {}
        if check is not None:
            extra.update(witness_R=check.best.R, witness_u=check.best.u,
                         witness_alpha=np.array(check.best.alpha))
        if res is not None:
            extra.update(product_X=res.X, product_Y=res.Y, product_scale=np.array(res.scale))
        info = {k: rec.get(k) for k in ("mode", "status", "p_rep", "d", "rho_hat", "scale",
                                        "p_direct", "c_best", "reasons", "mismatch_rel",
                                        "crash")}
        path = Path(save_dir) / f"{inst.key}_{mode}.npz"
        inst.save(path, info, extra)
        rec["saved"] = str(path)
    return rec


def _task(args: tuple) -> dict:
    """Worker entry (picklable): ``(source, mode, checker_kwargs, check_all, save_dir)`` with
    ``source`` either ``(seed, index)`` or the path of a saved ``.npz`` instance."""
    source, mode, ck, check_all, save_dir = args
    witness = None
    prev = None
    if isinstance(source, str):
        inst, prev, extra = Instance.load(Path(source))
        if "witness_R" in extra:
            witness = Point(extra["witness_R"], extra["witness_u"],
                            float(extra["witness_alpha"]))
    else:
        inst = make_instance(*source)
    try:
        with warnings.catch_warnings():  # Clarabel/cvxpy accuracy warnings: the status says it
            warnings.simplefilter("ignore")
            rec = evaluate(inst, mode, CheckerOptions(**ck), check_all, save_dir, witness)
    except Exception as exc:  # a bug of the benchmark itself: report, do not stop the run
        rec = _base_record(inst, mode)
        rec.update(status="benchmark_error", certified=False, false_cert=False, mismatch=False,
                   benchmark_error=f"{type(exc).__name__}: {exc}"[:300],
                   traceback=traceback.format_exc()[-1500:])
    if prev is not None:
        rec["replay_of"] = Path(source).name
        rec["previous"] = prev
    return rec


# --- report -------------------------------------------------------------------------------------

def _median(v) -> float:
    v = [x for x in v if x is not None and np.isfinite(x)]
    return float(np.median(v)) if v else float("nan")


def _pct(v, q) -> float:
    v = [x for x in v if x is not None and np.isfinite(x)]
    return float(np.percentile(v, q)) if v else float("nan")


def _fmt(x: float, spec: str = ".3g") -> str:
    return "–" if x is None or not np.isfinite(x) else format(x, spec)


def _group_table(records: list[dict], key, title: str) -> list[str]:
    groups: dict[str, list[dict]] = defaultdict(list)
    for r in records:
        groups[key(r)].append(r)
    out = [f"| {title} | instances | certified | cert. rate | **false cert.** | below bound | "
           "suboptimal | scale<=0 | infeasible | cost mismatch | crashes | median solve [ms] | "
           "median check [s] |", "|" + "---|" * 13]
    for g in sorted(groups, key=lambda s: (str(s))):
        rs = groups[g]
        cert = [r for r in rs if r.get("certified")]
        fc = [r for r in cert if r.get("false_cert")]
        cnt = Counter(x for r in fc for x in r.get("reasons", []))
        out.append(
            f"| {g} | {len(rs)} | {len(cert)} | {100 * len(cert) / len(rs):.1f} % | "
            f"**{len(fc)}** | {cnt['below bound']} | {cnt['suboptimal']} | {cnt['scale<=0']} | "
            f"{cnt['infeasible'] + cnt['no finite bound']} | "
            f"{sum(1 for r in cert if r.get('mismatch'))} | "
            f"{sum(1 for r in rs if r.get('crash'))} | "
            f"{_fmt(1e3 * _median([r.get('solve_s') for r in rs]), '.1f')} | "
            f"{_fmt(_median([r.get('check_s') for r in rs]), '.2f')} |")
    return out


def _status_table(records: list[dict], key, title: str) -> list[str]:
    statuses = sorted({r["status"] for r in records}, key=lambda s: (s != CERTIFIED, s))
    groups: dict[str, Counter] = defaultdict(Counter)
    for r in records:
        groups[key(r)][r["status"]] += 1
    out = [f"| {title} | " + " | ".join(statuses) + " |", "|" + "---|" * (len(statuses) + 1)]
    for g in sorted(groups):
        out.append(f"| {g} | " + " | ".join(str(groups[g][s]) for s in statuses) + " |")
    return out


def _jitter_bin(r: dict) -> str:
    j = r["jitter"]
    if r["category"] == "single_axis" or j == 0:
        return "0 (exact)"
    e = int(np.floor(np.log10(j)))
    return f"[1e{e}, 1e{e + 1})"


def _gap_table(records: list[dict]) -> list[str]:
    """False certificates by the size of the violation (relative), per reason."""
    bins = [(0.0, 1e-6), (1e-6, 1e-3), (1e-3, 1e-1), (1e-1, np.inf)]
    names = ["<= 1e-6", "(1e-6, 1e-3]", "(1e-3, 0.1]", "> 0.1"]
    out = ["| reason | measure | " + " | ".join(names) + " |", "|" + "---|" * 6]
    fc = [r for r in records if r.get("false_cert")]
    for reason, field, label in (("below bound", "bound_excess_rel", "(d - c*)/d"),
                                 ("suboptimal", "subopt_found_rel", "(p_direct - c*)/c*")):
        v = [r[field] for r in fc if reason in r.get("reasons", [])]
        out.append(f"| {reason} | {label} | " + " | ".join(
            str(sum(1 for x in v if lo < x <= hi)) for lo, hi in bins) + " |")
    v = [r["scale"] for r in fc if "scale<=0" in r.get("reasons", [])]
    out.append(f"| scale<=0 | reported scale | {len(v)} in total; range "
               f"[{_fmt(min(v, default=np.nan))}, {_fmt(max(v, default=np.nan))}] | | | |")
    return out


def _offenders(records: list[dict], limit: int) -> list[str]:
    fc = [r for r in records if r.get("false_cert")]
    fc.sort(key=lambda r: (-max(r.get("bound_excess_rel", 0.0) or 0.0,
                                r.get("subopt_found_rel", 0.0) or 0.0),
                           r.get("scale", 0.0)))
    out = ["| seed | index | category | shape | scale | noise (sigma, kappa) | jitter [rad] | "
           "rho_hat | reasons | gap found (p_direct - c*)/c* | (d - c*)/d | reported scale | "
           "max abs t of better point [m] | exact |", "|" + "---|" * 14]
    if not fc:
        return ["None."]
    for r in fc[:limit]:
        out.append(
            f"| {r['seed']} | {r['index']} | {r['category']} | {r['shape']} | "
            f"{'unknown' if r['unknown_scale'] else 'known'} | {r['noise']} "
            f"({r['sigma']:.3g}, {r['kappa']:.3g}) | {_fmt(r['jitter'], '.1e')} | "
            f"{_fmt(r['rho_hat'], '.2e')} | {', '.join(r['reasons'])} | "
            f"{_fmt(r.get('subopt_found_rel'), '.2e')} | {_fmt(r.get('bound_excess_rel'), '.2e')}"
            f" | {_fmt(r['scale'], '.3g')} | {_fmt(r.get('best_tmax'), '.3g')} | "
            f"{'yes' if r.get('exact_confirmed') else '–'} |")
    if len(fc) > limit:
        out.append(f"\n({len(fc) - limit} more in the log.)")
    return out


def _retry_line(records: list[dict]) -> str:
    """How often the certificate's extended-precision retry fired (``"tighten"`` in the result's
    ``timing_s``: the reduction's residual bound recomputed, :func:`rwhec_ros.core.pipeline.
    dense._tighten_reduction`) and what came of it."""
    fired = [r for r in records if r.get("retry")]
    if not any("retry" in r for r in records):
        return "Extended-precision certificate retry: not recorded (log from an older harness)."
    cert = [r for r in fired if r.get("certified")]
    return (f"Extended-precision certificate retry fired on {len(fired)} instances "
            f"({len(cert)} certified after it, "
            f"{sum(1 for r in cert if r.get('false_cert'))} of them false certificates).")


def report(records: list[dict], header: list[str], limit: int = 30) -> str:
    """The Markdown report of ``records`` (one per instance and mode)."""
    out = list(header) + ["", DEFINITIONS]
    modes = sorted({r["mode"] for r in records}, key=lambda m: (m != "fast", m))
    for mode in modes:
        rs = [r for r in records if r["mode"] == mode]
        cert = [r for r in rs if r.get("certified")]
        n_fc = sum(1 for r in cert if r.get("false_cert"))
        n_mm = sum(1 for r in cert if r.get("mismatch"))
        n_cr = sum(1 for r in rs if r.get("crash"))
        n_be = sum(1 for r in rs if r.get("status") == "benchmark_error")
        out += [f"## Mode `{mode}`: {len(rs)} instances", "",
                f"**{n_fc} false certificates, {n_mm} cost mismatches, {n_cr} crashes** "
                f"among {len(cert)} certified results ({100 * len(cert) / max(len(rs), 1):.1f} "
                f"%)." + (f" {n_be} benchmark errors (see log)." if n_be else ""), "",
                _retry_line(rs), "", "### Per category", ""]
        out += _group_table(rs, lambda r: r["category"], "category")
        wp = [r for r in rs if r["category"] == "well_posed_paper"]
        if wp:
            rate = 100 * sum(1 for r in wp if r.get("certified")) / len(wp)
            out += ["", f"Certified rate on well-posed instances at the paper's noise levels: "
                        f"{rate:.2f} % (target >= 99.5 %)."]
        out += ["", "### Status distribution per category", ""]
        out += _status_table(rs, lambda r: r["category"], "category")
        axis = [r for r in rs if r["motion"] == "axis"]
        if axis:
            out += ["", "### Single-axis motion by axis jitter", ""]
            out += _group_table(axis, _jitter_bin, "jitter")
        for title, key in (("graph shape", lambda r: r["shape"]),
                           ("noise level", lambda r: r["noise"]),
                           ("scale", lambda r: "unknown" if r["unknown_scale"] else "known")):
            out += ["", f"### By {title}", ""]
            out += _group_table(rs, key, title)
        out += ["", "### Size of the violations (confirmed false certificates by reason)", ""]
        out += _gap_table(rs)
        out += ["", "### Worst offenders", ""] + _offenders(rs, limit)
        crashes = [r for r in rs if r.get("crash")]
        if crashes:
            out += ["", "### Crashes", "", "| seed | index | category | shape | pairs | scale | "
                    "exception |", "|---|---|---|---|---|---|---|"]
            for r in crashes[:limit]:
                out.append(f"| {r['seed']} | {r['index']} | {r['category']} | {r['shape']} | "
                           f"{r['pairs']} | {'unknown' if r['unknown_scale'] else 'known'} | "
                           f"`{r['crash'][:160]}` |")
        mism = sorted((r for r in cert if r.get("mismatch")), key=lambda r: -r["mismatch_rel"])
        if mism:
            out += ["", "### Cost mismatches (largest first)", "",
                    "| seed | index | category | shape | reported p | direct p | relative | "
                    "rounding (float64 vs extended) |", "|---|---|---|---|---|---|---|---|"]
            for r in mism[:limit]:
                out.append(f"| {r['seed']} | {r['index']} | {r['category']} | {r['shape']} | "
                           f"{r['p_rep']:.10g} | {r['p_direct']:.10g} | "
                           f"{r['mismatch_rel']:.2e} | {_fmt(r.get('rounding_rel'), '.1e')} |")
        out += ["", "### Runtime per instance (seconds; measured under load)", "",
                "| category | solve median | solve p90 | solve max | check median | check p90 | "
                "check max |", "|---|---|---|---|---|---|---|"]
        by_cat: dict[str, list[dict]] = defaultdict(list)
        for r in rs:
            by_cat[r["category"]].append(r)
        for g in sorted(by_cat):
            s = [r.get("solve_s") for r in by_cat[g]]
            c = [r.get("check_s") for r in by_cat[g]]
            out.append(f"| {g} | {_fmt(_median(s), '.3f')} | {_fmt(_pct(s, 90), '.3f')} | "
                       f"{_fmt(max([x for x in s if x] or [float('nan')]), '.2f')} | "
                       f"{_fmt(_median(c), '.2f')} | {_fmt(_pct(c, 90), '.2f')} | "
                       f"{_fmt(max([x for x in c if x] or [float('nan')]), '.2f')} |")
        replays = [r for r in rs if r.get("replay_of")]
        if replays:
            out += ["", "### Replayed instances", "", "| file | before | now | false cert. now | "
                    "mismatch now | crash now |", "|---|---|---|---|---|---|"]
            for r in sorted(replays, key=lambda r: r["replay_of"]):
                prev = r["previous"]
                before = prev.get("status", "?") + (
                    f" ({', '.join(prev.get('reasons') or [])})" if prev.get("reasons") else "")
                fc = "**yes**: " + ", ".join(r["reasons"]) if r.get("false_cert") else "no"
                out.append(f"| {r['replay_of']} | {before} | {r['status']} | {fc} | "
                           f"{'**yes**' if r.get('mismatch') else 'no'} | "
                           f"{'**yes**' if r.get('crash') else 'no'} |")
        out.append("")
    return "\n".join(out)


# --- driver -------------------------------------------------------------------------------------

def _git_head() -> str:
    """The last commit that changed ``rwhec_ros/`` (the solver under test), and whether the
    working tree modifies it."""
    try:
        root = HERE.parent
        head = subprocess.run(["git", "-C", str(root), "log", "-1", "--format=%h", "--",
                               "rwhec_ros"],
                              capture_output=True, text=True, check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "rwhec_ros"],
                               capture_output=True, text=True, check=True).stdout.strip()
        return head + (" (rwhec_ros modified)" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def _parse_select(spec: str) -> tuple[int, list[str] | None, list[str] | None]:
    """``N[:categories[:shapes]]`` (comma-separated lists, empty = all)."""
    parts = spec.split(":")
    if not 1 <= len(parts) <= 3 or not parts[0].isdigit():
        raise SystemExit(f"--select: expected N[:categories[:shapes]], got {spec!r}")
    cats = parts[1].split(",") if len(parts) > 1 and parts[1] else None
    shapes = parts[2].split(",") if len(parts) > 2 and parts[2] else None
    bad = [c for c in cats or [] if c not in CATEGORIES] + \
        [s for s in shapes or [] if s not in SHAPES]
    if bad:
        raise SystemExit(f"--select {spec!r}: unknown {bad}; categories {list(CATEGORIES)}, "
                         f"shapes {list(SHAPES)}")
    return int(parts[0]), cats, shapes


def _select(seed: int, specs: list[str], start: int) -> list[int]:
    """Instance indices: for each spec the first N indices from ``start`` that match its
    categories and shapes and are not selected yet."""
    chosen: list[int] = []
    taken: set[int] = set()
    for spec in specs:
        n, cats, shapes = _parse_select(spec)
        i, got = start, 0
        while got < n:
            if (i not in taken and (not cats or category_of(i) in cats)
                    and (not shapes or shape_of(seed, i) in shapes)):
                chosen.append(i)
                taken.add(i)
                got += 1
            i += 1
    return chosen


def _parse(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, default=10000, help="instances (default 10000)")
    ap.add_argument("--quick", action="store_true", help="400 instances")
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--start", type=int, default=0, help="first instance index")
    ap.add_argument("--categories", default="",
                    help=f"comma-separated subset of {','.join(CATEGORIES)}")
    ap.add_argument("--shapes", default="", help=f"comma-separated subset of {','.join(SHAPES)}")
    ap.add_argument("--select", action="append", default=None, metavar="N[:CATS[:SHAPES]]",
                    help="a selection of instances (repeatable; replaces --n/--categories/"
                         "--shapes), e.g. --select 800 --select 300:few_pairs:1X1Y")
    ap.add_argument("--mode", default=None, choices=tuple(MODE_OPTIONS),
                    help="solver mode (default fast; with --replay, each file's saved mode); "
                         "fast-sparse: fast on the sparse unreduced path, no fallback")
    ap.add_argument("--sdp", type=int, default=0,
                    help="also solve the first N selected instances in mode sdp")
    ap.add_argument("--jobs", type=int, default=1, help="worker processes (default 1)")
    ap.add_argument("--starts", type=int, default=20, help="random starts (>= 20)")
    ap.add_argument("--check-all", action="store_true",
                    help="also run the checker on uncertified results")
    ap.add_argument("--output", type=Path, default=None, help="Markdown report (else stdout)")
    ap.add_argument("--log", type=Path, default=None, help="JSON-lines record log")
    ap.add_argument("--resume", action="store_true", help="skip instances already in --log")
    ap.add_argument("--save-failures", type=Path, default=None, metavar="DIR",
                    help="write failing instances (npz) to DIR")
    ap.add_argument("--replay", type=Path, default=None, metavar="DIR",
                    help="solve and check the saved instances in DIR instead of generating")
    ap.add_argument("--offenders", type=int, default=30, help="rows of the offender list")
    args = ap.parse_args(argv)
    if args.quick:
        args.n = 400
    if not args.select:
        args.select = [f"{args.n}:{args.categories}:{args.shapes}"]
    if args.starts < 20:
        print("warning: fewer than 20 random starts is below the issue's requirement",
              file=sys.stderr)
    return args


def main(argv: list[str] | None = None) -> int:
    args = _parse(argv)
    ck = {"n_random": args.starts}
    if args.save_failures:
        args.save_failures.mkdir(parents=True, exist_ok=True)
    if args.replay:
        files = sorted(str(p) for p in args.replay.glob("*.npz"))
        tasks = [(f, args.mode or Instance.load(Path(f))[1].get("mode", "fast"), ck,
                  args.check_all, None) for f in files]
        what = f"replay of {len(files)} saved instances from `{args.replay}`"
    else:
        idx = _select(args.seed, args.select, args.start)
        mode = args.mode or "fast"
        tasks = [((args.seed, i), mode, ck, args.check_all, args.save_failures) for i in idx]
        tasks += [((args.seed, i), "sdp", ck, args.check_all, args.save_failures)
                  for i in idx[: args.sdp] if mode != "sdp"]
        what = (f"{len(idx)} instances (seed {args.seed}, indices from {args.start}, "
                f"selections {' + '.join(args.select)})"
                + (f" + {min(args.sdp, len(idx))} in mode sdp" if args.sdp else ""))
    log = args.log or (args.output.with_suffix(".jsonl") if args.output
                       else Path("certificate_soundness.jsonl"))
    done: dict[tuple, dict] = {}
    if args.resume and log.exists():
        for line in log.read_text().splitlines():
            r = json.loads(line)
            done[(r.get("replay_of") or (r["seed"], r["index"]), r["mode"])] = r
    elif log.exists():
        log.unlink()

    def task_id(t):
        return (Path(t[0]).name if isinstance(t[0], str) else tuple(t[0]), t[1])

    todo = [t for t in tasks if task_id(t) not in done]
    records = [done[task_id(t)] for t in tasks if task_id(t) in done]
    print(f"{len(tasks)} tasks, {len(records)} already in {log}, {len(todo)} to run, "
          f"{args.jobs} job(s)", file=sys.stderr)
    t0 = time.perf_counter()
    with open(log, "a") as fh:
        if args.jobs > 1:
            import multiprocessing as mp

            pool = mp.get_context("spawn").Pool(args.jobs)
            it = pool.imap_unordered(_task, todo, chunksize=1)
        else:
            pool, it = None, map(_task, todo)
        for k, rec in enumerate(it, 1):
            records.append(rec)
            fh.write(json.dumps(rec, default=float) + "\n")
            fh.flush()
            flag = " ".join(x for x, on in (("FALSE-CERT", rec.get("false_cert")),
                                            ("MISMATCH", rec.get("mismatch")),
                                            ("CRASH", rec.get("crash")),
                                            ("BENCHMARK-ERROR",
                                             rec.get("status") == "benchmark_error")) if on)
            if flag or k % 25 == 0 or k == len(todo):
                el = time.perf_counter() - t0
                print(f"[{k}/{len(todo)}] {rec['key']} {rec['mode']} {rec['status']} "
                      f"solve {rec.get('solve_s', 0):.2f}s check {rec.get('check_s', 0):.2f}s "
                      f"{flag} | {el / k:.2f} s/instance, ETA {el / k * (len(todo) - k):.0f} s",
                      file=sys.stderr)
        if pool is not None:
            pool.close()
            pool.join()
    wall = time.perf_counter() - t0
    cmd = "python benchmarks/certificate_soundness.py " + " ".join(
        argv if argv is not None else sys.argv[1:])
    header = [
        "# Certificate soundness (issue 10)", "",
        f"Generated {_dt.date.today().isoformat()} by `{cmd}`: {what}; solver commit "
        f"{_git_head()}; {args.starts} random starts per check; {args.jobs} job(s), "
        f"{wall:.0f} s wall for the {len(todo)} tasks run now ({platform.machine()}, "
        f"Python {platform.python_version()}, numpy {np.__version__}, scipy "
        f"{scipy.__version__}). Times are measured on a shared, loaded 2-core machine.",
    ]
    text = report(records, header, args.offenders)
    if args.output:
        args.output.write_text(text)
        print(f"wrote {args.output}", file=sys.stderr)
    else:
        print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
