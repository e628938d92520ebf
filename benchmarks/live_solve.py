"""Live re-solve cost vs number of pairs, uncertainty included, on the paper's real data (Markdown).

Run from the repository root (about a minute; it writes ``benchmarks/live_solve.md``)::

    python benchmarks/live_solve.py [--repeats 15] [--output FILE.md]

The paper's real-world data (16 tags x 8 cameras, 73 edges, 3,230 pairs, ``../shared/data/
paper_real_world``) arrive as a session would collect them: the first ``f`` of every edge's pairs
(at least ``solver.min_pairs`` = 3), offered to a real
:class:`~rwhec_ros.sync.accumulator.PairAccumulator` (keyframe thresholds ~0: every pair kept).
Each re-solve is the session's live path, :class:`~rwhec_ros.session.live_solve.LiveSolver`
on its worker thread, end to end: the copy of the kept pairs under the session lock
(``PairAccumulator.edges``, the only time the sensor path could wait), the problem built outside
the lock, the ``fast`` solve without SDP fallback, :func:`~rwhec_ros.core.uncertainty.
frame_uncertainty` and the convergence verdict.

Columns: *lock ms*: the copy under the lock (``PairAccumulator.kept_pairs``); *solve ms* and
*uncertainty ms*: the solver's and the uncertainty's own timers; *re-solve ms*: the whole
re-solve, wall time, median of ``--repeats``; *CPU ms*: the worker thread's CPU time for the
same (``time.thread_time``, less sensitive to other processes on a busy machine); *document
ms*: the ``~/estimate`` mapping, built on first use (by the node's live timer when it publishes;
the CLI never builds it); *largest std*: the convergence verdict's worst
translation / rotation std (predicted from the authors' sigma 0.1 m, kappa 125, or a posteriori,
the larger). Target: under 20 ms per re-solve including the uncertainty on the full data.
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rwhec_ros.config import CalibratorConfig  # noqa: E402
from rwhec_ros.data.paper_csv import read_paper_csv  # noqa: E402
from rwhec_ros.session.live_solve import LiveSolver, PairsSnapshot  # noqa: E402
from rwhec_ros.sync.accumulator import PairAccumulator  # noqa: E402

DATA = ROOT.parent / "shared" / "data" / "paper_real_world"
FRACTIONS = (0.05, 0.1, 0.25, 0.5, 1.0)


def paper_config(problem) -> CalibratorConfig:
    """A configuration naming the paper's frames (tags ``tag_<j>``, cameras ``cam_<k>``) with
    the authors' noise (sigma 0.1 m, kappa 125)."""
    flat = {
        "camera_carrier.frame": "rig", "camera_carrier.moving": True,
        "tag_carrier.frame": "world", "tag_carrier.moving": False,
        "pose_source.topic": "/rig/pose", "pose_source.parent": "world",
        "pose_source.child": "rig", "cameras.names": list(problem.y_names),
        "tags.ids": [int(n.split("_")[1]) for n in problem.x_names],
        "tags.default_size": 0.16, "noise.sigma": 0.1, "noise.kappa": 125.0,
    }
    for cam in problem.y_names:
        flat[f"cameras.{cam}.image_topic"] = f"/{cam}/image_raw"
        flat[f"cameras.{cam}.camera_info_topic"] = f"/{cam}/camera_info"
    return CalibratorConfig.from_parameters(flat)


class PairsHolder:
    """The part of a session the live solver uses: its configuration, the pairs (a real
    accumulator) and the counters; ``bump`` stands for a new pair."""

    def __init__(self, config: CalibratorConfig, problem, fraction: float) -> None:
        self.config = config
        n_max = max(e.n for e in problem.edges)
        self.acc = PairAccumulator(keyframe_rotation_rad=1e-12, keyframe_translation_m=1e-12,
                                   max_pairs_per_edge=n_max, max_edges=len(problem.edges))
        for e in problem.edges:
            k = min(e.n, max(3, int(np.ceil(fraction * e.n))))
            for i in range(k):
                self.acc.offer(e.x, e.y, i, e.A[i], e.B[i], float(e.sigma[i]),
                               float(e.kappa[i]))
        self.version = 0
        self.lock_s: list[float] = []

    def bump(self) -> None:
        self.version += 1

    def pairs_snapshot(self) -> PairsSnapshot:
        t0 = time.perf_counter()
        edges = self.acc.kept_pairs()  # what the session copies under its lock
        self.lock_s.append(time.perf_counter() - t0)
        return PairsSnapshot(self.version, edges, self.acc.rotation_tol)

    def live_counts(self):
        return self.version, 0, 0, False


def run(fraction: float, problem, config: CalibratorConfig, repeats: int) -> dict:
    holder = PairsHolder(config, problem, fraction)
    live = LiveSolver(holder)
    walls, cpus, solves, uncs, docs = [], [], [], [], []
    est = None
    try:
        for _ in range(repeats + 1):  # the first one warms up (imports, caches)
            holder.bump()
            t0 = time.perf_counter()
            est = live.solve_now(120.0)
            walls.append(time.perf_counter() - t0)
            assert est is not None and est.version == holder.version, live.status().line()
            cpus.append(est.cpu_s)
            t1 = time.perf_counter()
            _ = est.document  # built on first use: the node's live timer does it
            docs.append(time.perf_counter() - t1)
            solves.append(est.result.timing_s.get("total", float("nan")))
            uncs.append(est.uncertainty.timing_s)
    finally:
        live.stop()
    med = lambda v: 1e3 * statistics.median(v[1:])  # noqa: E731 - ms, warm-up left out
    c = est.convergence
    return {"pairs": est.n_pairs, "edges": est.n_edges, "lock": med(holder.lock_s),
            "solve": med(solves), "unc": med(uncs), "wall": med(walls), "cpu": med(cpus),
            "doc": med(docs),
            "certified": est.result.certified, "t": 1e3 * c.worst_translation_m,
            "r": c.worst_rotation_deg}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--output", type=Path, default=ROOT / "benchmarks" / "live_solve.md")
    args = ap.parse_args()
    if not DATA.is_dir():
        print(f"no data at {DATA}", file=sys.stderr)
        return 1
    problem = read_paper_csv(DATA)
    config = paper_config(problem)
    load0 = os.getloadavg()
    t0 = time.monotonic()
    rows = [run(f, problem, config, args.repeats) for f in FRACTIONS]
    load1 = os.getloadavg()
    full = rows[-1]
    lines = [
        "# Live re-solve cost vs number of pairs (paper real data, 16 tags x 8 cameras)",
        "",
        f"`python benchmarks/live_solve.py --repeats {args.repeats}`; {platform.machine()}, "
        f"{os.cpu_count()} cores, Python {platform.python_version()}; load average "
        f"{load0[0]:.1f} at the start, {load1[0]:.1f} at the end (measured under load: other "
        "jobs shared the 2 cores), total {:.0f} s.".format(time.monotonic() - t0),
        "",
        "Each row: the first fraction of every edge's pairs, re-solved by the session's "
        "`LiveSolver` end to end (copy under the lock, problem, `fast` solve without SDP "
        "fallback, `frame_uncertainty`, convergence); medians of "
        f"{args.repeats} re-solves. See the script's docstring for the columns.",
        "",
        "| share of pairs | pairs | edges | lock ms | solve ms | uncertainty ms | re-solve ms "
        "| CPU ms | document ms | certified | largest std |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for f, r in zip(FRACTIONS, rows, strict=True):
        lines.append(
            f"| {100 * f:g} % | {r['pairs']} | {r['edges']} | {r['lock']:.2f} | "
            f"{r['solve']:.1f} | {r['unc']:.1f} | {r['wall']:.1f} | {r['cpu']:.1f} | "
            f"{r['doc']:.1f} | "
            f"{'yes' if r['certified'] else 'no'} | {r['t']:.1f} mm / {r['r']:.2f} deg |")
    verdict = "met" if full["wall"] < 20.0 else "not met"
    cpu_verdict = "met" if full["cpu"] < 20.0 else "not met"
    ratio = full["wall"] / full["solve"]
    lines += [
        "",
        f"Target < 20 ms per re-solve including the uncertainty on all {full['pairs']} pairs, "
        f"as measured here under load: {verdict} in wall time ({full['wall']:.1f} ms), "
        f"{cpu_verdict} in CPU time ({full['cpu']:.1f} ms). The `fast` solve alone took "
        f"{full['solve']:.1f} ms in this run against 10.1 ms on the quiet machine of "
        "`benchmarks/solver_speed.md`; the whole re-solve costs "
        f"{ratio:.2f}x the solve, so about {ratio * 10.1:.0f} ms there (an extrapolation, not "
        "a measurement). The sensor path waits at most for the copy under the lock "
        f"({full['lock']:.2f} ms on all pairs); everything else runs on the live solver's "
        "thread. With the default `solver.live_period_s` of 2 s the re-solves take about "
        f"{100 * full['cpu'] / 2000:.1f} % of one core on the full data (CPU time).",
        "",
    ]
    text = "\n".join(lines)
    args.output.write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
