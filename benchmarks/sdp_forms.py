#!/usr/bin/env python3
"""The exact forms of the SDP (Problem 7): estimated vs. measured cost, and the ``auto`` choice.

Prints Markdown (commit the output as ``benchmarks/sdp_forms.md``):

1. For graphs of several shapes and the paper's real data: the cost per Clarabel iteration that
   :func:`rwhec_ros.core.certify.sparsity.estimate_form_costs` predicts for the ``reduced``,
   ``full`` and ``arrow`` forms, and the measured solve (time, iterations, certificate) of every
   form whose estimate is within ``--max-ratio`` of the cheapest; the form ``auto`` picks is marked.
   All forms run must reach the same dual bound ``d`` (they are exact reformulations).
2. Clarabel's Ruiz equilibration on and off for the arrow form (its default is off).

Everything runs pinned to ONE core (``os.sched_setaffinity``), Clarabel and BLAS single-threaded.
Usage: ``python benchmarks/sdp_forms.py [--max-ratio R] [--random N]``.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rwhec_ros.core.certify.relaxation import SdpOptions  # noqa: E402
from rwhec_ros.core.pipeline.dense import _form_costs  # noqa: E402
from rwhec_ros.core.pipeline.dense import prepare_dense as _prepare  # noqa: E402
from rwhec_ros.core.solve import SolveOptions, solve  # noqa: E402
from rwhec_ros.simulation.synthetic import random_instance  # noqa: E402

SHARED = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "paper_real_world"
FORMS = ("reduced", "full", "arrow")


def _sdp(problem, form: str, **clarabel):
    opts = SdpOptions(form=form)
    opts.clarabel.update({"max_threads": 1, **clarabel})
    t0 = time.perf_counter()
    res = solve(problem, SolveOptions(mode="sdp", sdp=opts))
    iters = next(int(n.split()[1]) for n in res.notes if n.startswith("Clarabel:"))
    return res, time.perf_counter() - t0, iters


def _t(s: float) -> str:
    return f"{s * 1e3:.0f} ms" if s < 1 else f"{s:.2f} s"


def cases(rng):
    out = []
    dense = [(j, k) for j in range(6) for k in range(4)]
    for name, M, P, edges, unk in [
        ("4X1Y", 4, 1, None, False),
        ("10X1Y", 10, 1, None, False),
        ("1X4Y", 1, 4, None, False),
        ("1X10Y", 1, 10, None, False),
        ("3X5Y sparse chain", 3, 5, [(0, 0), (0, 1), (1, 1), (1, 2), (2, 2), (2, 3), (0, 4),
                                     (2, 4)], False),
        ("6X4Y every target in every camera", 6, 4, dense, False),
        ("6X4Y same, unknown scale", 6, 4, dense, True),
        ("40 cameras as X x 1 target", 40, 1, None, False),
        ("1 target x 40 cameras as Y", 1, 40, None, False),
    ]:
        p, _ = random_instance(rng, M, P, edges, n_per_edge=20, sigma=0.01, kappa=125.0,
                               unknown_scale=unk, alpha=0.7 if unk else 1.0)
        out.append((name, p))
    if SHARED.is_dir():
        from rwhec_ros.data.paper_csv import read_paper_csv

        for unk in (False, True):
            p = read_paper_csv(SHARED, sigma=0.1, kappa=125.0, min_pairs=3, unknown_scale=unk)
            out.append((f"paper real data, 16 tags x 8 cameras{', unknown scale' if unk else ''}",
                        p))
    return out


def forms_table(problems, max_ratio: float) -> None:
    print("## Estimated and measured cost of each form\n")
    print("Estimate: relative cost of one interior-point iteration, sum over the cones (after "
          "chordal decomposition) of (n(n+1)/2)^3, divided by the cheapest form's. Forms "
          f"estimated above {max_ratio:g}x the cheapest are not run. `auto` marks the choice.\n")
    print("| problem | form | estimate | time | iterations | status | rho_hat | "
          "(d - d_auto) / d_auto |")
    print("|---|---|---|---|---|---|---|---|")
    for name, problem in problems:
        prep = _prepare(problem, SolveOptions(mode="sdp"))
        auto, costs, _ = _form_costs(prep)
        if not costs:
            costs = {"reduced": 1.0}
        best = min(costs.values())
        runs = {}
        for form in FORMS:
            if form not in costs:
                continue
            if costs[form] > max_ratio * best and form != auto:
                runs[form] = None
                continue
            runs[form] = _sdp(problem, form)
        d_auto = runs[auto][0].certificate.dual_bound
        for form in FORMS:
            if form not in costs:
                continue
            label = f"**{form}** (auto)" if form == auto else form
            est = f"{costs[form] / best:.1f}x"
            if runs[form] is None:
                print(f"| {name} | {label} | {est} | not run | | | | |")
                continue
            res, secs, iters = runs[form]
            c = res.certificate
            rel = (c.dual_bound - d_auto) / abs(d_auto)
            print(f"| {name} | {label} | {est} | {_t(secs)} | {iters} | {c.status.value} | "
                  f"{c.suboptimality_bound:.1e} | {rel:+.1e} |", flush=True)
    print()


def equilibration_table(problems, n_random: int, rng) -> None:
    print("## Arrow form: Clarabel equilibration on vs. off\n")
    rows = [(n, p) for n, p in problems if n.startswith("paper")]
    for i in range(n_random):
        M, P, unk = int(rng.integers(3, 12)), int(rng.integers(2, 6)), bool(i % 2)
        sigma = float(rng.choice([0.001, 0.01, 0.05]))
        kappa = float(rng.choice([10.0, 50.0, 500.0]))
        p, _ = random_instance(rng, M, P, n_per_edge=int(rng.integers(5, 30)), sigma=sigma,
                               kappa=kappa, unknown_scale=unk, alpha=0.6 if unk else 1.0)
        rows.append((f"random {M}X{P}Y, sigma {sigma}, kappa {kappa:g}"
                     f"{', unknown scale' if unk else ''}", p))
    print("| problem | on: time | on: iterations | off: time | off: iterations | both "
          "certified |")
    print("|---|---|---|---|---|---|")
    fewer = 0
    for name, p in rows:
        on, t_on, i_on = _sdp(p, "arrow", equilibrate_enable=True)
        off, t_off, i_off = _sdp(p, "arrow", equilibrate_enable=False)
        fewer += i_off <= i_on
        both = "yes" if on.certified and off.certified else "**NO**"
        print(f"| {name} | {_t(t_on)} | {i_on} | {_t(t_off)} | {i_off} | {both} |", flush=True)
    print(f"\nOff needed the same or fewer iterations in {fewer} of {len(rows)} problems.\n")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--max-ratio", type=float, default=8.0)
    ap.add_argument("--random", type=int, default=14, help="random graphs of the 2nd table")
    args = ap.parse_args(argv)
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
    import cvxpy

    print("# Forms of the SDP\n")
    print(f"Machine: {platform.machine()}, pinned to 1 of {os.cpu_count()} cores, Python "
          f"{platform.python_version()}, cvxpy {cvxpy.__version__}; run "
          f"{time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}.\n")
    rng = np.random.default_rng(7)
    with threadpool_limits(1):
        warm, _ = random_instance(rng, 2, 2, n_per_edge=5, sigma=0.01, kappa=100.0)
        for form in FORMS:
            _sdp(warm, form)
        problems = cases(rng)
        forms_table(problems, args.max_ratio)
        equilibration_table(problems, args.random, rng)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
