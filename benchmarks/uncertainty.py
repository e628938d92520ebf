#!/usr/bin/env python3
"""Uncertainty of the calibration (issue 11): predicted stds against Monte-Carlo, and costs.

Prints Markdown tables (commit the output as ``benchmarks/uncertainty.md``):

1. Monte-Carlo per scenario: the paper's Section 8 scenarios (``rwhec_ros.simulation.scenarios``:
   8.1 hand camera on a sphere, 8.2 four fixed cameras and a hand-held target; known and unknown
   scale; two noise levels) and the demo rig (``rwhec_ros.simulation.rig``: 3 cameras, 6 tags,
   geometry only, no rendering). For each scenario ONE design (trajectory and ground truth) is
   drawn and then ``--runs`` independent noise draws of ``B`` (the paper's noise model, the stated
   ``sigma``/``kappa`` equal to the true ones); every run is solved (``fast``) and only
   certified estimates count. Per frame and axis the predicted std (root mean predicted
   variance, :func:`~rwhec_ros.core.analysis.uncertainty.frame_uncertainty`) is compared with the
   empirical std of the estimates' errors in the same convention (``t = t_true + dt``,
   ``R = exp(phi^) R_true``, in the frame's parent); the coverage is the fraction of
   frame-runs whose error lies in the predicted 95 % ellipsoid (``e^T C^-1 e <= chi2_6(0.95)``).
   Targets (issue 11): every ratio predicted / empirical within 20 % of 1, coverage 90-98 %.
2. Cost on the paper's real data (16 tags x 8 cameras, 3,230 pairs): the uncertainty from the
   pairs, from a cost matrix a solve has built (the live path), cross-validation and guidance.

Usage: ``python benchmarks/uncertainty.py [--runs 200] [--seed 0] [--quick]``.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from rwhec_ros.core.analysis.guidance import GuidanceOptions, suggest_next_motion  # noqa: E402
from rwhec_ros.core.analysis.information import information_from_cost_matrix  # noqa: E402
from rwhec_ros.core.analysis.uncertainty import (  # noqa: E402
    frame_uncertainty,
    uncertainty_from_information,
)
from rwhec_ros.core.analysis.validation import cross_validate  # noqa: E402
from rwhec_ros.core.lie import invert_transform, so3_log  # noqa: E402
from rwhec_ros.core.model.cost import build_cost_matrices  # noqa: E402
from rwhec_ros.core.problem import Edge, Problem  # noqa: E402
from rwhec_ros.core.solve import SolveOptions, solve  # noqa: E402
from rwhec_ros.simulation.rig import demo_rig  # noqa: E402
from rwhec_ros.simulation.scenarios import (  # noqa: E402
    fixed_cameras_hand_target,
    hand_camera_sphere,
    noisy_measurements,
)
from rwhec_ros.simulation.synthetic import GroundTruth  # noqa: E402

REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "paper_real_world"
CHI2_6_95 = 12.591587243743977  # scipy.stats.chi2.ppf(0.95, 6)
AXES = ("t_x", "t_y", "t_z", "r_x", "r_y", "r_z")


def _demo_design(sigma: float, kappa: float):
    """The demo rig's geometry: exact pairs every 0.5 s over two yaw turns (48 s)."""
    rig = demo_rig()
    pairs: dict[tuple[str, str], list] = {}
    for t in np.arange(0.0, 48.0, 0.5):
        T_world_rig = rig.T_world_rig(t)
        A = invert_transform(T_world_rig)  # T_rig_world
        for cam in rig.cameras:
            for seen in rig.visible_tags(cam, T_world_rig):
                pairs.setdefault((f"tag_{seen.tag_id}", cam), []).append((A, seen.T_cam_tag))
    edges = [Edge.build(x, y, np.array([p[0] for p in v]), np.array([p[1] for p in v]),
                        sigma, kappa) for (x, y), v in pairs.items() if len(v) >= 3]
    xs = [f"tag_{j}" for j in rig.tag_ids if any(e.x == f"tag_{j}" for e in edges)]
    problem = Problem(xs, list(rig.cameras), edges)
    truth = GroundTruth(X=np.array([rig.T_world_tag[int(n[4:])] for n in xs]),
                        Y=np.array([rig.T_rig_cam[c] for c in rig.cameras]))
    return problem, truth


def scenarios(seed: int):
    """(name, noise label, exact problem, truth, sigma, kappa, alpha) per scenario."""
    out = []
    for name, fn, mono in (("8.1 hand camera, sphere", hand_camera_sphere, False),
                           ("8.1 monocular, two spheres", hand_camera_sphere, True),
                           ("8.2 four fixed cameras", fixed_cameras_hand_target, False),
                           ("8.2 monocular", fixed_cameras_hand_target, True)):
        for kappa, sigma in ((125.0, 0.01), (12.0, 0.05)):
            problem, truth = fn(np.random.default_rng(seed), 0.0, np.inf, monocular=mono)
            out.append((name, f"kappa {kappa:g}, sigma {100 * sigma:g} cm", problem, truth,
                        sigma, kappa, truth.alpha))
    for kappa, sigma in ((2000.0, 0.005), (200.0, 0.02)):
        problem, truth = _demo_design(sigma, kappa)
        out.append(("demo rig (3 cameras, 6 tags)", f"kappa {kappa:g}, sigma {100 * sigma:g} cm",
                    problem, truth, sigma, kappa, 1.0))
    return out


def _noisy(rng, exact: Problem, sigma: float, kappa: float, alpha: float) -> Problem:
    """The exact design with the paper's noise (monocular: t <- alpha (t + eps), Section 8)."""
    edges = []
    for e in exact.edges:
        B = e.B.copy()
        B[:, :3, 3] /= alpha  # the exact design's B carry alpha already
        Bn = noisy_measurements(rng, B, sigma, kappa, alpha, scale_after_noise=True)
        edges.append(Edge.build(e.x, e.y, e.A, Bn, alpha * sigma, kappa))
    return Problem(exact.x_names, exact.y_names, edges, unknown_scale=exact.unknown_scale)


def _errors(res, truth: GroundTruth) -> np.ndarray:
    T_hat = np.concatenate([res.X, res.Y])
    T = np.concatenate([truth.X, truth.Y])
    dt = T_hat[:, :3, 3] - T[:, :3, 3]
    phi = so3_log(T_hat[:, :3, :3] @ np.swapaxes(T[:, :3, :3], 1, 2))
    return np.concatenate([dt, phi], axis=1)


def monte_carlo(runs: int, seed: int):
    print("## Predicted std vs Monte-Carlo spread\n")
    print(f"{runs} noise draws per scenario on one fixed design; only certified estimates "
          "count. *pred/emp*: predicted over empirical std, the range over all frames and "
          "axes (target 0.80-1.20); *worst*: the frame axis farthest from 1; *coverage*: "
          "share of frame-runs inside the predicted 95 % ellipsoid (6-D, target 90-98 %); "
          "*scale*: pred/emp of alpha (monocular); *s0^2*: mean a-posteriori variance factor "
          "(1 when the stated noise is right); *ms*: median time of `frame_uncertainty`.\n")
    print("| scenario | noise | pairs | certified | pred/emp | worst | coverage | scale | "
          "s0^2 | ms | targets |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    rng = np.random.default_rng(seed + 1)
    all_ok = True
    for name, noise, exact, truth, sigma, kappa, alpha in scenarios(seed):
        errs, covs, scales, s_pred, s0, ms = [], [], [], [], [], []
        for _ in range(runs):
            problem = _noisy(rng, exact, sigma, kappa, alpha)
            res = solve(problem, SolveOptions(mode="fast"))
            if not res.certified:
                continue
            t0 = time.perf_counter()
            unc = frame_uncertainty(problem, res)
            ms.append(1e3 * (time.perf_counter() - t0))
            errs.append(_errors(res, truth))
            covs.append(np.stack([f.covariance for f in unc.frames]))
            s0.append(unc.variance_factor)
            if problem.unknown_scale:
                scales.append(res.scale - truth.alpha)
                s_pred.append(unc.scale_std)
        e, C = np.array(errs), np.array(covs)
        emp = np.sqrt(np.mean(e**2, axis=0))  # (frames, 6); the MLE is unbiased to first order
        pred = np.sqrt(np.mean(np.diagonal(C, axis1=2, axis2=3), axis=0))
        ratio = pred / emp
        f, i = np.unravel_index(int(np.nanargmax(np.abs(ratio - 1.0))), ratio.shape)
        names = exact.frame_names
        d2 = np.einsum("rfi,rfij,rfj->rf", e, np.linalg.inv(C), e)
        cov = float(np.mean(d2 <= CHI2_6_95))
        sc = "–"
        sc_ok = True
        if scales:
            sr = float(np.sqrt(np.mean(np.square(s_pred))) / np.sqrt(np.mean(np.square(scales))))
            sc = f"{sr:.2f}"
            sc_ok = abs(sr - 1.0) <= 0.2
        ok = bool(np.all(np.abs(ratio - 1.0) <= 0.2) and 0.90 <= cov <= 0.98 and sc_ok)
        all_ok &= ok
        print(f"| {name} | {noise} | {exact.n_measurements} | {len(errs)}/{runs} | "
              f"{np.nanmin(ratio):.2f}-{np.nanmax(ratio):.2f} | {names[f]} {AXES[i]} "
              f"{ratio[f, i]:.2f} | {100 * cov:.1f} % | {sc} | {np.mean(s0):.2f} | "
              f"{np.median(ms):.1f} | {'met' if ok else '**missed**'} |", flush=True)
    print()
    return all_ok


# ------------------------------------------------------------------------------------------------
# with the noise estimated from the data (issue 34)

#: Per-camera noise of the rig whose cameras differ 5x (std units, both components).
CAMERA_FACTORS = (1.0, 2.2, 5.0)


def _noisy_per_camera(rng, exact: Problem, noise: dict, stated: dict | None) -> Problem:
    """``exact`` with camera ``y``'s noise ``noise[y] = (sigma, kappa)``, the pairs stating
    ``stated[y]`` (None: the true noise)."""
    edges = []
    for e in exact.edges:
        s, k = noise[e.y]
        ws, wk = (stated or noise)[e.y]
        Bn = noisy_measurements(rng, e.B, s, k, 1.0, scale_after_noise=True)
        edges.append(Edge.build(e.x, e.y, e.A, Bn, ws, wk))
    return Problem(exact.x_names, exact.y_names, edges, unknown_scale=exact.unknown_scale)


def _estimated_cases(seed: int):
    """(name, true noise label, stated label, exact, truth, noise per camera, stated per camera or
    None)."""
    out = []
    fixed, fixed_truth = fixed_cameras_hand_target(np.random.default_rng(seed), 0.0, np.inf)
    demo, demo_truth = _demo_design(0.005, 2000.0)
    for name, exact, truth, sigma, kappa in (
            ("8.2 four fixed cameras", fixed, fixed_truth, 0.01, 125.0),
            ("demo rig (3 cameras, 6 tags)", demo, demo_truth, 0.005, 2000.0)):
        noise = {y: (sigma, kappa) for y in exact.y_names}
        for factor, words in ((20.0, "20x too large"), (0.2, "5x too small")):
            stated = {y: (sigma * factor, kappa / factor**2) for y in exact.y_names}
            out.append((name, f"kappa {kappa:g}, sigma {100 * sigma:g} cm", words, exact,
                        truth, noise, stated))
    noise = {y: (0.002 * f, 2000.0 / f**2) for y, f in zip(demo.y_names, CAMERA_FACTORS,
                                                              strict=True)}
    out.append(("demo rig, cameras 1x / 2.2x / 5x", "sigma 2-10 mm, kappa 2000-80", "not stated "
                "(1 cm, 125)", demo, demo_truth, noise,
                {y: (0.01, 125.0) for y in demo.y_names}))
    return out


def estimated_noise(runs: int, seed: int) -> bool:
    """Monte-Carlo with the noise estimated (per camera) instead of the stated one."""
    from rwhec_ros.core.noise import NoiseOptions, solve_with_noise

    print("## With the noise estimated from the data (issue 34)\n")
    print(f"{runs} noise draws per row on one fixed design; the pairs state a wrong noise (or "
          "none: the start values), `solve_with_noise` estimates it per camera (Helmert "
          "variance components, `rwhec_ros.core.noise`) and solves with it; the predicted std "
          "is that of the estimated weights. *solves*: median (max) solves per run. Targets as "
          "above: pred/emp 0.80-1.20, coverage 90-98 %.\n")
    print("| scenario | true noise | stated | pairs | certified | solves | pred/emp | worst | "
          "coverage | targets |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    rng = np.random.default_rng(seed + 2)
    all_ok = True
    rig_runs = None
    for name, label, stated_words, exact, truth, noise, stated in _estimated_cases(seed):
        errs, covs, solves = [], [], []
        for _ in range(runs):
            problem = _noisy_per_camera(rng, exact, noise, stated)
            ns = solve_with_noise(problem, SolveOptions(mode="fast"), NoiseOptions())
            if not ns.result.certified:
                continue
            unc = frame_uncertainty(ns.problem, ns.result)
            errs.append(_errors(ns.result, truth))
            covs.append(np.stack([f.covariance for f in unc.frames]))
            solves.append(ns.estimate.solves)
        e, C = np.array(errs), np.array(covs)
        emp = np.sqrt(np.mean(e**2, axis=0))
        pred = np.sqrt(np.mean(np.diagonal(C, axis1=2, axis2=3), axis=0))
        ratio = pred / emp
        f, i = np.unravel_index(int(np.nanargmax(np.abs(ratio - 1.0))), ratio.shape)
        d2 = np.einsum("rfi,rfij,rfj->rf", e, np.linalg.inv(C), e)
        cov = float(np.mean(d2 <= CHI2_6_95))
        ok = bool(np.all(np.abs(ratio - 1.0) <= 0.2) and 0.90 <= cov <= 0.98)
        all_ok &= ok
        print(f"| {name} | {label} | {stated_words} | {exact.n_measurements} | "
              f"{len(errs)}/{runs} | {np.median(solves):.0f} ({max(solves)}) | "
              f"{np.nanmin(ratio):.2f}-{np.nanmax(ratio):.2f} | {exact.frame_names[f]} "
              f"{AXES[i]} {ratio[f, i]:.2f} | {100 * cov:.1f} % | "
              f"{'met' if ok else '**missed**'} |", flush=True)
        if stated_words.startswith("not stated"):
            rig_runs = (exact, truth, noise)
    print()
    return _weighting(runs, seed, *rig_runs) and all_ok


def _weighting(runs: int, seed: int, exact: Problem, truth: GroundTruth, noise: dict) -> bool:
    """The rig whose cameras differ 5x: the error against the truth with the true per-camera
    weights, the estimated per-camera weights, one estimated global weight and the start
    values."""
    from rwhec_ros.core.noise import NoiseOptions, solve_with_noise

    start = {y: (0.01, 125.0) for y in exact.y_names}
    ways = {
        "true per-camera noise (reference)": lambda p: solve(
            _restated(p, noise), SolveOptions(mode="fast")),
        "estimated per camera (the default)": lambda p: solve_with_noise(
            p, SolveOptions(mode="fast"), NoiseOptions()).result,
        "one global sigma/kappa, estimated": lambda p: solve_with_noise(
            p, SolveOptions(mode="fast"), NoiseOptions(groups="global")).result,
        "the start values (1 cm, 125), not estimated": lambda p: solve(
            p, SolveOptions(mode="fast")),
    }
    errs: dict[str, list] = {k: [] for k in ways}
    rng = np.random.default_rng(seed + 3)
    for _ in range(runs):
        problem = _noisy_per_camera(rng, exact, noise, start)
        for k, fn in ways.items():
            errs[k].append(_errors(fn(problem), truth))
    print(f"Per-camera weights on the rig whose cameras differ {CAMERA_FACTORS[0]:g}x / "
          f"{CAMERA_FACTORS[1]:g}x / {CAMERA_FACTORS[2]:g}x in noise ({runs} draws, the same "
          "draws for every weighting): RMS error against the simulation's truth of the worst "
          "frame (camera or tag), translation and rotation. Targets: estimated per camera within "
          "10 % of the true weights, and better than one global weight.\n")
    print("| weights | worst frame translation RMS | worst frame rotation RMS | vs true weights |")
    print("|---|---|---|---|")
    worst = {}
    for k in ways:
        e = np.array(errs[k])  # (runs, frames, 6)
        t = np.sqrt(np.mean(np.sum(e[:, :, :3] ** 2, axis=2), axis=0))
        r = np.degrees(np.sqrt(np.mean(np.sum(e[:, :, 3:] ** 2, axis=2), axis=0)))
        worst[k] = (float(t.max()), float(r.max()), exact.frame_names[int(t.argmax())],
                    exact.frame_names[int(r.argmax())])
    ref = worst["true per-camera noise (reference)"]
    for k, (t, r, ft, fr) in worst.items():
        print(f"| {k} | {1e3 * t:.2f} mm ({ft}) | {r:.3f} deg ({fr}) | "
              f"{t / ref[0]:.3f}x, {r / ref[1]:.3f}x |")
    est = worst["estimated per camera (the default)"]
    glob = worst["one global sigma/kappa, estimated"]
    ok = (est[0] <= 1.1 * ref[0] and est[1] <= 1.1 * ref[1] and est[0] < glob[0]
          and est[1] < glob[1])
    print(f"\nTargets {'met' if ok else '**missed**'}: estimated per camera "
          f"{est[0] / ref[0]:.3f}x / {est[1] / ref[1]:.3f}x the true weights' worst error "
          f"(target <= 1.1), one global weight {glob[0] / ref[0]:.3f}x / {glob[1] / ref[1]:.3f}x."
          "\n")
    return ok


def _restated(problem: Problem, noise: dict) -> Problem:
    """``problem`` stating camera ``y``'s true noise ``noise[y]``."""
    return Problem(problem.x_names, problem.y_names,
                   [Edge.build(e.x, e.y, e.A, e.B, *noise[e.y]) for e in problem.edges],
                   unknown_scale=problem.unknown_scale)


def _median_ms(fn, repeats: int) -> float:
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(ts))


def real_data_costs(repeats: int, seed: int) -> None:
    from rwhec_ros.data.paper_csv import read_paper_csv

    print("## Cost on the paper's real data\n")
    if not REAL.is_dir():
        print(f"(skipped: {REAL} not found)\n")
        return
    problem = read_paper_csv(REAL)
    opts = SolveOptions(mode="fast")
    res = solve(problem, opts)
    Q, _ = build_cost_matrices(problem)
    print(f"{problem.M} tags x {problem.P} cameras, {len(problem.edges)} edges, "
          f"{problem.n_measurements} pairs; single-threaded BLAS; median of {repeats} "
          "(cross-validation and guidance: one run).\n")
    print("| step | ms | / solve |")
    print("|---|---|---|")
    t_solve = _median_ms(lambda: solve(problem, opts), 5)
    print(f"| solve (`fast`, for reference) | {t_solve:.1f} | 1 |")
    t_unc = _median_ms(lambda: frame_uncertainty(problem, res), repeats)
    print(f"| `frame_uncertainty` (information assembled from the pairs, covariance) | "
          f"{t_unc:.1f} | {t_unc / t_solve:.2f} |")

    def from_q():
        info = information_from_cost_matrix(problem, Q, res.X, res.Y, res.scale)
        return uncertainty_from_information(info, problem)

    t_q = _median_ms(from_q, repeats)
    print(f"| uncertainty from the solve's cost matrix `Q` (`information_from_cost_matrix` + "
          f"covariance: the live path) | {t_q:.1f} | {t_q / t_solve:.2f} |")
    t0 = time.perf_counter()
    cross_validate(problem, np.random.default_rng(seed), result=res)
    t_cv = 1e3 * (time.perf_counter() - t0)
    print(f"| `cross_validate` (5 folds, `fast`) | {t_cv:.0f} | {t_cv / t_solve:.1f} |")
    t0 = time.perf_counter()
    g = suggest_next_motion(problem, res, GuidanceOptions(y_carrier="the rig",
                                                          x_carrier="the world"))
    t_g = 1e3 * (time.perf_counter() - t0)
    print(f"| `suggest_next_motion` ({len(problem.edges)} edges x 12 motions, and new edges) | "
          f"{t_g:.0f} | {t_g / t_solve:.1f} |")
    print("\nThe last column varies less with the machine's load than the times: the same "
          "`fast` solve takes 8.8 ms end to end on a quiet machine (README, "
          "`benchmarks/solver_speed.md`).")
    unc = frame_uncertainty(problem, res)
    t, r = unc.max_std()
    ta, ra = unc.max_std(a_posteriori=True)
    print(f"\nLargest std on these data: predicted (stated sigma = 0.1 m, kappa = 125) "
          f"{1e3 * t:.1f} mm / {r:.2f} deg; a posteriori (s0^2 = {unc.variance_factor:.3f}) "
          f"{1e3 * ta:.1f} mm / {ra:.2f} deg. Guidance: \"{g.message}\"\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--repeats", type=int, default=20)
    ap.add_argument("--quick", action="store_true", help="30 runs, 5 repeats")
    ap.add_argument("--parts", nargs="+", default=("stated", "estimated", "costs"),
                    choices=("stated", "estimated", "costs"),
                    help="which sections (default: all)")
    args = ap.parse_args()
    if args.quick:
        args.runs, args.repeats = 30, 5
    from threadpoolctl import threadpool_limits

    t0 = time.perf_counter()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print("# Uncertainty of the calibration: prediction vs Monte-Carlo, and costs\n")
    print(f"Generated by `benchmarks/uncertainty.py --runs {args.runs} --seed {args.seed}"
          + (f" --parts {' '.join(args.parts)}" if len(args.parts) < 3 else "") + "` "
          f"({platform.machine()}, Python {platform.python_version()}, numpy {np.__version__}; "
          f"load average {load:.1f} on {os.cpu_count()} cores when started: times are "
          "measured on a shared, busy machine).\n")
    with threadpool_limits(1, user_api="blas"):
        ok = True
        if "stated" in args.parts:
            ok = monte_carlo(args.runs, args.seed)
        if "estimated" in args.parts:
            ok = estimated_noise(args.runs, args.seed) and ok
        if "costs" in args.parts:
            real_data_costs(args.repeats, args.seed)
    print(f"All Monte-Carlo targets {'met' if ok else 'NOT met'}. Total "
          f"{(time.perf_counter() - t0) / 60:.1f} min.")


if __name__ == "__main__":
    main()
