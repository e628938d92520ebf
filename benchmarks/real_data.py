"""Real third-party hand-eye data through the package, against OpenCV (prints Markdown).

Run from the repository root (the data: ``../shared/data/real/`` beside the repository, or
``--data DIR``; a set that is absent is skipped)::

    python benchmarks/real_data.py > benchmarks/real_data.md

Per set (read by :mod:`rwhec_ros.data.sample_layouts` as ``rwhec-calibrate samples`` reads it,
see ``real_sets.py``; fed image by image with its pose to the
same :class:`~rwhec_ros.session.CalibrationSession` the node and ``rwhec-calibrate bag`` use):

* views offered / accepted by an independent OpenCV detector with its defaults
  (``findChessboardCornersSB``; ``findCirclesGrid``; ``aruco.CharucoDetector``, a view counting
  when it gives at least 8 corners, the package's ``min_corners``) / kept as pairs by the package;
* the verdict (first line) and the reprojection RMS of the corners through the calibration;
* the 5-fold held-out ``A X = Y B`` residual (RMS over the held-out pairs of the translation
  norm and of the rotation angle of ``(A X)^-1 Y B``) of the package's solve and of OpenCV's
  ``calibrateHandEye`` (Tsai, Park, Daniilidis) and ``calibrateRobotWorldHandEye`` (Shah, Li) on
  the same pairs and the same folds (``rwhec_ros.core.baselines.opencv``).

Then the evidence behind the perception defaults: the reprojection gate (fixed vs scaled to the
camera's corner noise), the chessboard corner refinement (real and rendered), the marker corner
refinement on the real ChArUco markers, the circle-centre bias at 45 degrees on renders.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as _dt
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rwhec_ros.config import CalibratorConfig  # noqa: E402
from rwhec_ros.core.analysis.validation import fold_assignment  # noqa: E402
from rwhec_ros.core.baselines.registry import run_baseline  # noqa: E402
from rwhec_ros.core.lie import invert_transform  # noqa: E402
from rwhec_ros.core.noise import solve_with_noise  # noqa: E402
from rwhec_ros.core.problem import Edge, Problem  # noqa: E402
from rwhec_ros.core.solve import SolveOptions, solve  # noqa: E402
from rwhec_ros.session import CalibrationSession  # noqa: E402
from rwhec_ros.session.solving import noise_options  # noqa: E402
from rwhec_ros.vision.boards import CharucoSpec  # noqa: E402
from rwhec_ros.vision.grids import ChessboardSpec, CircleGridSpec  # noqa: E402
from rwhec_ros.vision.intrinsics import CameraIntrinsics  # noqa: E402
from rwhec_ros.vision.target_detector import TargetDetector  # noqa: E402
from rwhec_ros.vision.targets import TargetSpec  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import real_data_defaults  # noqa: E402
from real_sets import CAMERA, TARGET, RealSet, feed_session, load_set  # noqa: E402

DEFAULT_DATA = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "real"
SETS = ("ic_charuco", "ic_circle_10x10", "cct_chessboard_eye_in_hand")
BASELINES = ("tsai", "park", "daniilidis", "shah", "li")
FOLDS = 5


# ------------------------------------------------------------------------- independent detector
def independent_accepts(gray: np.ndarray, target: TargetSpec) -> bool:
    """OpenCV's own detector with its defaults finds the target (module docstring)."""
    b = target.board
    if isinstance(b, ChessboardSpec):
        return bool(cv2.findChessboardCornersSB(gray, b.pattern_size)[0])
    if isinstance(b, CircleGridSpec):
        flags = cv2.CALIB_CB_ASYMMETRIC_GRID if b.asymmetric else cv2.CALIB_CB_SYMMETRIC_GRID
        return bool(cv2.findCirclesGrid(gray, b.pattern_size, flags=flags)[0])
    if isinstance(b, CharucoSpec):
        _, ids, _, _ = cv2.aruco.CharucoDetector(b.cv2_board()).detectBoard(gray)
        return ids is not None and len(ids) >= 8
    raise ValueError(f"no independent detector for {target.kind}")


# ------------------------------------------------------------------------------ the session
def session_parameters(samples: RealSet, *, from_reprojection: bool = False,
                       gate_factor: float | None = None) -> dict:
    """The calibrator parameters of a sample set: every view searched (motion gate off) and
    kept (keyframe thresholds at a micro-radian and a micrometre), at least 3 pairs per edge."""
    flat = samples.parameters()
    flat.update({"keyframe.min_rotation_rad": 1e-6, "keyframe.min_translation_m": 1e-6,
                 "detection.motion_gate": False, "solver.min_pairs": 3,
                 "noise.from_reprojection": from_reprojection, "output.directory": ""})
    if gate_factor is not None:
        flat["detection.reprojection_gate_factor"] = gate_factor
    return flat


def run_session(samples: RealSet, flat: dict, out_dir: Path):
    """Feed the set to a session, calibrate; returns (session, outcome, seconds)."""
    session = CalibrationSession(CalibratorConfig.from_parameters(flat), output_root=out_dir)
    t0 = time.perf_counter()
    feed_session(session, samples)
    outcome = session.calibrate(out_dir / "calibration")
    return session, outcome, time.perf_counter() - t0


def kept_pairs_problem(session) -> Problem:
    """The kept pairs of the session's single edge as a known-scale problem."""
    (e,) = session.pairs_snapshot().edges.values()
    return Problem([TARGET], [CAMERA], [Edge(TARGET, CAMERA, e.A, e.B, e.sigma, e.kappa)])


# --------------------------------------------------------------------------- held-out residual
def residuals(A, B, X, Y) -> tuple[np.ndarray, np.ndarray]:
    """Translation norms [m] and rotation angles [rad] of ``(A X)^-1 Y B`` per pair."""
    t, r = [], []
    for a, b in zip(A, B, strict=True):
        D = invert_transform(a @ X) @ Y @ b
        t.append(np.linalg.norm(D[:3, 3]))
        r.append(np.arccos(np.clip(0.5 * (np.trace(D[:3, :3]) - 1.0), -1.0, 1.0)))
    return np.asarray(t), np.asarray(r)


def held_out(problem: Problem, method: str, folds: int = FOLDS, seed: int = 0, noise=None):
    """RMS held-out translation [mm] and rotation [deg] of ``method`` ("ours" or a baseline)
    over ``folds`` folds (the same folds for every method: same seed). ``noise``
    (:class:`~rwhec_ros.core.noise.NoiseOptions`, the session's): "ours" estimates the noise
    from each fold's training pairs as the session does; None: solved with the pairs' noise."""
    (e,) = problem.edges
    (assign,) = fold_assignment(problem, folds, np.random.default_rng(seed), min_pairs=folds)
    ts, rs = [], []
    for f in range(folds):
        train, test = assign != f, assign == f
        if not test.any():
            continue
        sub = Problem(problem.x_names, problem.y_names,
                      [Edge(e.x, e.y, e.A[train], e.B[train], e.sigma[train], e.kappa[train])])
        if method == "ours" and noise is not None:
            res = solve_with_noise(sub, SolveOptions(mode="fast"), noise).result
            X, Y = res.X[0], res.Y[0]
        elif method == "ours":
            res = solve(sub, SolveOptions(mode="fast"))
            X, Y = res.X[0], res.Y[0]
        else:
            X, Y, _ = run_baseline(method, sub)
            X, Y = X[0], Y[0]
        t, r = residuals(e.A[test], e.B[test], X, Y)
        ts.append(t)
        rs.append(r)
    t, r = np.concatenate(ts), np.concatenate(rs)
    return (1e3 * float(np.sqrt(np.mean(t**2))), float(np.degrees(np.sqrt(np.mean(r**2)))),
            t, r)


def ratio_interval(ours: np.ndarray, other: np.ndarray, draws: int = 2000) -> tuple[float, float]:
    """95 % interval of the held-out RMS ratio ours / other from a paired bootstrap over the
    held-out pairs (both arrays in the same pair order: the same folds; seed 0)."""
    idx = np.random.default_rng(0).integers(0, len(ours), size=(draws, len(ours)))
    boot = np.sqrt(np.mean(ours[idx] ** 2, axis=1) / np.mean(other[idx] ** 2, axis=1))
    lo, hi = np.percentile(boot, [2.5, 97.5])
    return float(lo), float(hi)


# ------------------------------------------------------------------------------------ tables
def set_rows(name: str, samples: RealSet, tmp: Path, label: str = "") -> tuple[list, dict]:
    """The per-set rows: counts, verdict, reprojection; and the held-out residuals."""
    grays = [v.gray() for v in samples.views]
    independent = sum(independent_accepts(g, samples.target) for g in grays)
    flat = session_parameters(samples)
    session, outcome, seconds = run_session(samples, flat, tmp / (name + label))
    counters = session.counters()
    kept = counters.get("pairs_kept", 0)
    verdict = outcome.message.splitlines()[0] if outcome.success else outcome.message
    reproj = "-"
    if outcome.accuracy is not None and outcome.accuracy.reprojection:
        reproj = f"{outcome.accuracy.reprojection[CAMERA].rms_px:.2f}"
    no_pair = {k: v for k, v in counters.items()
               if k.startswith(("images_targets_rejected", "images_without_tags"))}
    row = dict(name=name + label, kind=samples.target.kind, offered=len(grays),
               independent=independent, kept=kept, verdict=verdict, reproj=reproj,
               no_pair=no_pair, seconds=seconds, intrinsics=samples.intrinsics_source)
    problem = kept_pairs_problem(session)
    held = {"ours": held_out(problem, "ours", noise=noise_options(session.config.noise))}
    for m in BASELINES:
        try:
            held[m] = held_out(problem, m)
        except Exception as exc:  # noqa: BLE001 - a method failing is a result
            held[m] = f"failed: {type(exc).__name__}"
    # with noise.from_reprojection (the detector's per-pair precisions)
    s2, _, _ = run_session(samples, session_parameters(samples, from_reprojection=True),
                           tmp / (name + label + "_rep"))
    held["ours, noise.from_reprojection"] = held_out(kept_pairs_problem(s2), "ours",
                                                     noise=noise_options(s2.config.noise))
    return row, held


def refit_circle_intrinsics(samples: RealSet) -> RealSet:
    """The set with intrinsics refitted by ``cv2.calibrateCamera`` from the package's labelled
    grid points of the same views (plumb_bob)."""
    det = TargetDetector([samples.target])
    obj, img = [], []
    for v in samples.views:
        res = det.detect(v.gray(), samples.intrinsics)
        for o in res.observations:
            obj.append(o.object_points.astype(np.float32))
            img.append(o.image_points.astype(np.float32).reshape(-1, 1, 2))
    w, h = samples.intrinsics.width, samples.intrinsics.height
    rms, K, D, _, _ = cv2.calibrateCamera(obj, img, (w, h), samples.intrinsics.K.copy(), None,
                                          flags=cv2.CALIB_USE_INTRINSIC_GUESS)
    intr = CameraIntrinsics(w, h, K, np.asarray(D, dtype=float).reshape(-1)[:5], "plumb_bob")
    return dataclasses.replace(
        samples, intrinsics=intr,
        intrinsics_source=f"refitted by cv2.calibrateCamera from the package's grid points of "
                          f"the {len(obj)} views (RMS {rms:.2f} px)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--sets", nargs="+", choices=SETS, default=list(SETS),
                    help="only these sets (default: all)")
    ap.add_argument("--no-defaults", action="store_true",
                    help="only the per-set table (skip the evidence of the defaults)")
    args = ap.parse_args(argv)
    t_start = time.time()
    print("# Real hand-eye data: views kept, verdict, held-out residual vs OpenCV\n")
    print(f"- date: {_dt.date.today().isoformat()}")
    print(f"- machine: {os.cpu_count()} cores ({platform.machine()}, {platform.system()}), "
          f"Python {platform.python_version()}, OpenCV {cv2.__version__}, numpy "
          f"{np.__version__}")
    print("- generated by `python benchmarks/real_data.py > benchmarks/real_data.md`")
    print("- data: `../shared/data/real/` (third-party sets, see their READMEs); read by "
          "`rwhec_ros.data.sample_layouts` (as `rwhec-calibrate samples`), fed to "
          "`CalibrationSession` (motion gate off, every view a keyframe, `solver.min_pairs: 3`, "
          "the configuration's defaults otherwise: "
          "the noise estimated from the data (`noise.estimate`, the default; the held-out "
          "solves estimate it from their training pairs))\n")
    rows, helds = [], []
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        for name in args.sets:
            folder = args.data / name
            if not folder.is_dir():
                print(f"_{name}: absent, skipped._\n")
                continue
            samples = load_set(folder)
            row, held = set_rows(name, samples, tmp)
            rows.append(row)
            helds.append(held)
            if isinstance(samples.target.board, CircleGridSpec):
                row, held = set_rows(name, refit_circle_intrinsics(samples), tmp,
                                     label=" (refitted intrinsics)")
                rows.append(row)
                helds.append(held)
    if rows:
        print("## Views and verdict per set\n")
        print("| set | target | views offered | OpenCV detector (defaults) | kept by the package | "
              "kept / OpenCV | images without a pair, why | verdict | reprojection RMS "
              "through the calibration (px) | session time (s) |")
        print("|---|---|---|---|---|---|---|---|---|---|")
        for r in rows:
            why = ", ".join(f"{k}={v}" for k, v in sorted(r["no_pair"].items())) or "-"
            share = 100.0 * r["kept"] / max(r["independent"], 1)
            print(f"| {r['name']} | {r['kind']} | {r['offered']} | {r['independent']} | "
                  f"{r['kept']} | {share:.0f} % | {why} | {r['verdict']} | {r['reproj']} | "
                  f"{r['seconds']:.1f} |")
        print("\nIntrinsics: " + "; ".join(f"{r['name']}: {r['intrinsics']}" for r in rows)
              + ".\n")
        print(f"## {FOLDS}-fold held-out `A X = Y B` residual (RMS over held-out pairs: "
              "translation mm / rotation deg)\n")
        methods = ["ours", "ours, noise.from_reprojection", *BASELINES]
        print("| set | " + " | ".join(methods) + " | best OpenCV | ours vs best OpenCV |")
        print("|---|" + "---|" * (len(methods) + 2))
        for r, h in zip(rows, helds, strict=True):
            cells = [f"{h[m][0]:.2f} / {h[m][1]:.3f}" if isinstance(h[m], tuple) else h[m]
                     for m in methods]
            ok = {m: h[m] for m in BASELINES if isinstance(h[m], tuple)}
            best_t = min(ok, key=lambda m: ok[m][0])
            best_r = min(ok, key=lambda m: ok[m][1])
            lo_t, hi_t = ratio_interval(h["ours"][2], ok[best_t][2])
            lo_r, hi_r = ratio_interval(h["ours"][3], ok[best_r][3])
            verdict = (f"t {h['ours'][0] / ok[best_t][0]:.2f}x of {best_t} [{lo_t:.2f}, "
                       f"{hi_t:.2f}], R {h['ours'][1] / ok[best_r][1]:.2f}x of {best_r} "
                       f"[{lo_r:.2f}, {hi_r:.2f}]")
            print(f"| {r['name']} | " + " | ".join(cells)
                  + f" | t: {best_t}, R: {best_r} | {verdict} |")
        print("\nOpenCV's methods and ours see the same pairs (the package's detections and "
              "poses) and the same folds (`fold_assignment`, seed 0); `ours` is the fast "
              "certifiable solve of the session with the noise estimated from the training pairs "
              "(defaults), the second column with the detector's per-pair precisions scaled by "
              "the estimated factor. Below 1x: ours lower; in brackets the 95 % interval of the "
              "ratio from a paired bootstrap over the held-out pairs (what so few pairs can tell "
              "apart).\n")
    if not args.no_defaults:
        real_data_defaults.print_all(args.data)
    load = os.getloadavg()
    print(f"_Total benchmark time: {time.time() - t_start:.0f} s; load average at the end "
          f"{load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} on {os.cpu_count()} cores (other jobs "
          f"share this machine: times are upper bounds)._")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
