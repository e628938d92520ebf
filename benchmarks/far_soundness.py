#!/usr/bin/env python3
"""Certificate soundness far from the origin: the adversarial instances of
``certificate_soundness.py`` moved far away, solved (with ``core/model/recentre.py``'s re-centring)
and every certified result compared with the independent checker (Markdown).

Run from the repository root (a few minutes with ``--jobs 2``)::

    python benchmarks/far_soundness.py [--n 54] [--jobs 2] [--output benchmarks/far_soundness.md]

Each instance ``(seed, index)`` of :mod:`soundness_instances` (round robin over its eight
categories: the paper's, high and extreme noise, outliers, near and exactly single-axis motion,
tiny rotations, 2-3 pairs per edge; known and unknown scale) is moved by ``G`` on the camera
carrier's side (``A' = G A``, ``Y' = G Y``: a random rotation and a translation of the given
distance) or by a translation ``S`` on the tag carrier's side (``A' = A S``,
``X' = S^-1 X``), and solved by ``solve`` in mode ``fast`` as the soundness study does
(``certificate_soundness.evaluate``): the checker (own cost of eq. (33), >= 20 random starts,
the product's estimate and the truth, costs in extended precision, violations confirmed in exact
rational arithmetic) runs on the *moved* data, the data the certificate is about. A false
certificate is a certified result whose dual bound the checker beats, or whose cost is above
the checker's best by more than the certificate allows (the study's definitions). The same
instances at the origin (distance 0) are the reference.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections import defaultdict
from dataclasses import replace
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

from soundness_instances import CATEGORIES, make_instance  # noqa: E402

SEED = 20261124
DISTANCES = (0.0, 1e3, 1e5)
SIDES = ("camera", "tag")


def moved(inst, side: str, distance: float):
    """``inst`` with the camera carrier's (``G A``, ``G Y``) or the tag carrier's (``A S``,
    ``S^-1 X``) origin ``distance`` metres away (same residuals in exact arithmetic)."""
    if distance == 0.0:
        return inst
    direction = np.array([0.6, -0.8, 0.0])
    if side == "camera":
        G = np.eye(4)
        G[:3, :3] = Rotation.random(random_state=inst.index).as_matrix()
        G[:3, 3] = distance * direction
        edges = [(j, k, G @ A, B, s, kp) for j, k, A, B, s, kp in inst.edges]
        return replace(inst, edges=edges, Y_true=G @ inst.Y_true)
    S = np.eye(4)
    S[:3, 3] = distance * direction
    S_inv = np.eye(4)
    S_inv[:3, 3] = -distance * direction
    edges = [(j, k, A @ S, B, s, kp) for j, k, A, B, s, kp in inst.edges]
    return replace(inst, edges=edges, X_true=S_inv @ inst.X_true)


def _task(args):
    import warnings

    from certificate_soundness import evaluate
    from soundness_checker import CheckerOptions

    from rwhec_ros.core.model.recentre import recentring_for

    index, side, distance = args
    inst = moved(make_instance(SEED, index), side, distance)
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            rec = evaluate(inst, "fast", CheckerOptions())
        except Exception as exc:  # a bug of the benchmark or the product: reported
            rec = {"crash": f"{type(exc).__name__}: {exc}", "certified": False,
                   "false_cert": False, "status": "crash"}
    rc = recentring_for(inst.to_problem())
    rec.update(index=index, side=side, distance=distance, category=inst.category,
               unknown_scale=inst.unknown_scale, seconds=time.perf_counter() - t0,
               recentred=(rc.carrier if rc is not None else "no"))
    return rec


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=54, help="instances (round robin over categories)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--output", type=Path, default=None, help="Markdown file (default: print)")
    args = ap.parse_args()
    todo = [(i, side, d) for i in range(args.n) for side in SIDES for d in DISTANCES
            if not (d == 0.0 and side == "tag")]
    t0 = time.monotonic()
    if args.jobs > 1:
        import multiprocessing as mp

        with mp.get_context("spawn").Pool(args.jobs) as pool:
            recs = list(pool.imap_unordered(_task, todo, chunksize=1))
    else:
        recs = [_task(a) for a in todo]
    wall = time.monotonic() - t0
    rows = defaultdict(lambda: defaultdict(int))
    for r in recs:
        key = ("origin" if r["distance"] == 0.0 else r["side"] + " carrier", r["distance"],
               "unknown" if r["unknown_scale"] else "known")
        row = rows[key]
        row["n"] += 1
        row["certified"] += bool(r.get("certified"))
        row["false"] += bool(r.get("false_cert"))
        row["mismatch"] += bool(r.get("mismatch"))
        row["crash"] += bool(r.get("crash"))
        row["recentred"] += r["recentred"] != "no"
        row["checked"] += bool(r.get("checked"))
    lines = [
        "# Certificate soundness far from the origin",
        "",
        f"`python benchmarks/far_soundness.py --n {args.n} --jobs {args.jobs}`: {args.n} "
        f"instances of `soundness_instances` (seed {SEED}, round robin over "
        f"{len(CATEGORIES)} categories), each at the origin and moved "
        f"{', '.join(f'{d:g} m' for d in DISTANCES[1:])} "
        f"on the camera carrier's and on the tag carrier's side; mode `fast`; {len(recs)} "
        f"solves, {wall:.0f} s. See the script's docstring.",
        "",
        "| frame moved | distance [m] | scale | instances | re-centred | certified | "
        "checked | false certificates | p mismatches | crashes |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for key in sorted(rows, key=lambda k: (k[0] != "origin", k[0], k[1], k[2])):
        r = rows[key]
        lines.append(f"| {key[0]} | {key[1]:g} | {key[2]} | {r['n']} | {r['recentred']} | "
                     f"{r['certified']} | {r['checked']} | {r['false']} | {r['mismatch']} | "
                     f"{r['crash']} |")
    total_false = sum(r["false"] for r in rows.values())
    lines += ["", f"False certificates: **{total_false}** of "
              f"{sum(r['certified'] for r in rows.values())} certified results."]
    crashes = [r for r in recs if r.get("crash")]
    for r in crashes[:10]:
        lines.append(f"- crash: instance {r['index']} {r['side']} {r['distance']:g}: "
                     f"{r['crash']}")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.output is not None:
        args.output.write_text(text)
    return 1 if total_false else 0


if __name__ == "__main__":
    sys.exit(main())
