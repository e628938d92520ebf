#!/usr/bin/env python3
"""Soundness of the certificate's extended-precision retry
(``rwhec_ros.core.pipeline.dense._certify``).

When a certificate fails on its bound alone and the Schur reduction's rounding terms take more
than a tenth of the allowed gap, the solver recomputes the bound on the recovery's residual
``F = Q_ee G + Q_ey`` in extended precision (:mod:`rwhec_ros.core.numerics.extended_residual`,
``reduce_cost(residual="extended")``) and certifies again. A wrong bound there would turn into a
false ``certified_optimal``. This study checks the retry by paths independent of it:

1. **Instances where the retry fires.** Seeded "precise rig" instances (own generator, numpy and
   scipy only): 2-4 cameras ``Y`` about 0.1 m from the rig origin, 3-10 tags ``X`` 1-3 m away
   (6-12 frames), 30-100 pairs per edge, the rig swaying by 0.3-3 degrees and 0.5-2 cm (the
   tag positions in the camera frames vary by centimetres, as in the camera-rate bag of
   ``test/core/fixtures/precise_rig.npz``), measurements far more precise (0.2-1 mm,
   0.01-0.05 degrees) than the stated ``sigma`` (3-8 mm) and ``kappa`` (200-800). Variants,
   round robin by index: known scale, unknown scale, outliers (1-5 % of the pairs: half mild,
   a few centimetres and degrees off, half gross, random poses) and near-planar motion (rotations
   about one axis tilted by 1e-4..0.2 rad, translations in the plane: most of these end
   ``not_identifiable``, the translation along the axis is fixed by the default gauge, and only
   the certified ones are checked; their reductions are in check 2). Every instance is first
   solved (``mode="fast"``); where the retry fired (``"tighten"`` in ``timing_s``) it is solved
   and checked again by ``certificate_soundness.evaluate``: the independent checker of
   :mod:`soundness_checker` (>= 20 random-start local solves of its own implementation of
   eq. (33) plus the product's estimate and the ground truth, costs in extended precision,
   violations confirmed in exact rational arithmetic).
2. **The reduction's bounds in exact arithmetic on those instances.** For the first
   ``--exact`` retry instances: ``|F|`` exactly (integer arithmetic on the doubles' mantissas)
   against :func:`~rwhec_ros.core.numerics.extended_residual.residual_bound` entry by entry,
   ``||F||_F`` against ``residual_norm`` and, for the first ``--exact-sg`` of them, the row sums of
   ``|Qr - S_G|`` (``S_G`` the exact reduced cost for the ``G`` used) against ``err_rows``.
3. **Random blocks.** ``residual_bound`` against the exact residual on random symmetric positive
   definite ``Q_ee`` (m = 30) and ``Q_ey`` (k = 60) with condition numbers 1e2..1e14 and ``G``
   from a double solve (and perturbed), once with numpy's ``longdouble`` and once with
   ``extended_dtype`` forced to ``(float64, 2**-53)`` (a platform whose ``longdouble`` is
   double); with that fallback the retry instances are also solved and checked again.

Run from the repository root::

    python benchmarks/retry_soundness.py --n 200 --output benchmarks/retry_soundness.md
    python benchmarks/retry_soundness.py --n 20 --max-instances 400        # a quick look

Instances ``(seed, index)`` are reproducible with :func:`make_instance`.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import platform
import sys
import time
import warnings
from pathlib import Path

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))
sys.path.insert(0, str(HERE))

from certificate_soundness import evaluate  # noqa: E402
from soundness_checker import CheckerOptions  # noqa: E402
from soundness_instances import Instance, _random_rotations, _transforms, _unit  # noqa: E402

VARIANTS = ("known_scale", "unknown_scale", "outliers", "near_planar")


# --- the instances ------------------------------------------------------------------------------

def _edges_of(rng: np.random.Generator, M: int, P: int) -> list[tuple[int, int]]:
    """Tag-camera edges: tag ``j`` seen by camera ``j mod P``, ``M`` random extra edges and a
    chain linking the cameras (a connected graph)."""
    edges = {(j, j % P) for j in range(M)}
    edges |= {(int(j), int(k)) for j, k in zip(rng.integers(0, M, M), rng.integers(0, P, M),
                                               strict=True)}
    edges |= {(k % M, k + 1) for k in range(P - 1)}
    return sorted(edges)


def _rig_motion(rng: np.random.Generator, variant: str, n: int, axis: np.ndarray,
                jitter: float, amplitude: float, shift: float) -> np.ndarray:
    """``n`` rig poses ``T_W_rig`` (n,4,4): rotations up to ``amplitude`` rad, translations of
    about ``shift`` m; near-planar: about ``axis`` tilted by ``jitter``, translations in its
    plane (and ``jitter`` times ``shift`` out of it)."""
    if variant == "near_planar":
        perp = _unit(rng, n)
        perp -= np.outer(perp @ axis, axis)
        perp /= np.linalg.norm(perp, axis=1, keepdims=True)
        axes = np.cos(jitter) * axis + np.sin(jitter) * perp
        t = shift * rng.standard_normal((n, 3))
        t -= np.outer(t @ axis, axis)
        t += jitter * shift * rng.standard_normal((n, 1)) * axis
    else:
        axes = _unit(rng, n)
        t = shift * rng.standard_normal((n, 3))
    angles = rng.uniform(0.1 * amplitude, amplitude, (n, 1)) * rng.choice([-1.0, 1.0], (n, 1))
    return _transforms(Rotation.from_rotvec(axes * angles).as_matrix().reshape(n, 3, 3), t)


def make_instance(seed: int, index: int) -> Instance:
    """The precise-rig instance ``(seed, index)`` (module docstring); variant by index."""
    variant = VARIANTS[index % len(VARIANTS)]
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), int(index), 18]))
    P = int(rng.integers(2, 5))
    M = int(rng.integers(6 - P + (P == 2), 12 - P + 1))
    Y = _transforms(_random_rotations(rng, P), 0.1 * _unit(rng, P) * rng.uniform(0.5, 1.5, (P, 1)))
    X = _transforms(_random_rotations(rng, M), _unit(rng, M) * rng.uniform(1.0, 3.0, (M, 1)))
    unknown = variant == "unknown_scale" or (variant != "known_scale" and rng.random() < 0.3)
    alpha = float(np.exp(rng.uniform(np.log(0.3), np.log(3.0)))) if unknown else 1.0
    noise_t = float(rng.uniform(0.2e-3, 1.0e-3))
    noise_r = float(np.radians(rng.uniform(0.01, 0.05)))
    sigma = float(rng.uniform(3e-3, 8e-3))
    kappa = float(rng.choice([200.0, 400.0, 800.0]))
    amplitude = float(np.radians(np.exp(rng.uniform(np.log(0.3), np.log(3.0)))))
    shift = float(np.exp(rng.uniform(np.log(0.005), np.log(0.02))))
    axis = _unit(rng, 1)[0]
    jitter = float(10 ** rng.uniform(-4, -0.7)) if variant == "near_planar" else 0.0
    outliers = float(rng.uniform(0.01, 0.05)) if variant == "outliers" else 0.0
    edges, n_pairs = [], []
    for j, k in _edges_of(rng, M, P):
        n = int(rng.integers(30, 101))
        n_pairs.append(n)
        A = np.linalg.inv(_rig_motion(rng, variant, n, axis, jitter, amplitude, shift))
        B = np.linalg.inv(Y[k])[None] @ A @ X[j][None]  # exact B = Y^-1 A X
        B[:, :3, 3] = alpha * B[:, :3, 3] + noise_t * rng.standard_normal((n, 3))
        B[:, :3, :3] = B[:, :3, :3] @ Rotation.from_rotvec(
            noise_r * rng.standard_normal((n, 3))).as_matrix()
        n_out = int(round(outliers * n))
        if n_out:
            idx = rng.choice(n, size=n_out, replace=False)
            gross = idx[: n_out // 2]
            mild = idx[n_out // 2:]
            B[gross] = _transforms(_random_rotations(rng, gross.size), alpha * _unit(
                rng, gross.size) * rng.uniform(1.0, 3.0, (gross.size, 1)))
            B[mild, :3, 3] += alpha * rng.uniform(0.01, 0.05) * _unit(rng, mild.size)
            B[mild, :3, :3] = B[mild, :3, :3] @ Rotation.from_rotvec(
                _unit(rng, mild.size) * np.radians(rng.uniform(0.5, 3.0))).as_matrix()
        U, _, Vt = np.linalg.svd(B[:, :3, :3])  # re-orthonormalise (drift ~1e-16)
        B[:, :3, :3] = U @ Vt
        edges.append((j, k, A, B, np.full(n, sigma), np.full(n, kappa)))
    params = {"shape": f"{M}X{P}Y", "noise": f"{1e3 * noise_t:.2f} mm, "
              f"{np.degrees(noise_r):.3f} deg", "sigma": sigma, "kappa": kappa,
              "motion": "near_planar" if variant == "near_planar" else "sway",
              "jitter": jitter, "outlier_fraction": outliers,
              "pairs": [min(n_pairs), max(n_pairs)], "unknown_scale": unknown,
              "amplitude_deg": float(np.degrees(amplitude)), "shift_m": shift}
    return Instance(int(seed), int(index), variant, params, M, P, edges, unknown, X, Y, alpha)


# --- exact arithmetic ---------------------------------------------------------------------------

def _to_int(M: np.ndarray) -> tuple[np.ndarray, int]:
    """``M`` (finite doubles) as ``(N, s)`` with ``M == N / 2**s`` exactly, ``N`` an object
    array of Python ints."""
    M = np.asarray(M, dtype=float)
    f, e = np.frexp(M)
    mant = (f * 2.0**53).astype(np.int64)  # exact: 53-bit significands
    e = e - 53
    nz = mant != 0
    s = int(-e[nz].min()) if nz.any() else 0
    out = np.empty(M.shape, dtype=object)
    for idx, (m_, ee) in enumerate(zip(mant.ravel(), e.ravel(), strict=True)):
        sh = int(ee) + s
        out.flat[idx] = int(m_) << sh if sh >= 0 else 0  # sh < 0 only where m_ == 0
    return out, s


def exact_residual(Qee: np.ndarray, G: np.ndarray, Qey: np.ndarray) -> tuple[np.ndarray, int]:
    """``F = Q_ee G + Q_ey`` exactly, as ``(N, s)``: ``F == N / 2**s`` (object ints)."""
    A, sa = _to_int(Qee)
    X, sx = _to_int(G)
    C, sc = _to_int(Qey)
    s = max(sa + sx, sc)
    return (A.dot(X) << (s - sa - sx)) + (C << (s - sc)), s


def _float_abs(N: np.ndarray, s: int) -> np.ndarray:
    """``|N| / 2**s`` rounded up to double (a correctly rounded value stepped up one ulp)."""
    from fractions import Fraction

    v = np.array([float(Fraction(abs(int(x)), 1 << s)) for x in N.ravel()]).reshape(N.shape)
    return np.where(v > 0, np.nextafter(v, np.inf), 0.0)


def exact_vs_bound(Qee, G, Qey, bound) -> tuple[bool, float]:
    """Does ``bound >= |Q_ee G + Q_ey|`` hold exactly everywhere? And the largest ratio
    ``|F| / bound`` (how much of the bound the residual uses)."""
    from fractions import Fraction

    N, s = exact_residual(Qee, G, Qey)
    ok = True
    for x, b in zip(N.ravel(), np.asarray(bound).ravel(), strict=True):
        if not np.isfinite(b) or Fraction(abs(int(x)), 1 << s) > Fraction(float(b)):
            ok = False
            break
    absF = _float_abs(N, s)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(bound > 0, absF / bound, 0.0)
    return ok, float(np.max(ratio))


def exact_reduction_check(Q: np.ndarray, layout, unknown_scale: bool, reduced) -> dict:
    """The tightened reduction of ``Q`` against exact arithmetic: ``|F| <= residual_bound``,
    ``||F||_F <= residual_norm`` and row sums of ``|Qr - S_G|`` against ``err_rows``
    (``S_G = Q_kk + G^T F + Q_ek^T G`` for the ``G`` used)."""
    from fractions import Fraction

    from rwhec_ros.core.numerics.extended_residual import residual_bound

    nt, a, r0, size = layout.n_t, layout.alpha, layout.r0, layout.size
    rot = np.arange(r0, size)
    elim = np.arange(nt + 1) if unknown_scale else np.arange(nt)
    keep = rot if unknown_scale else np.concatenate([rot, [a]])
    Qee = Q[np.ix_(elim, elim)]
    Qee = 0.5 * (Qee + Qee.T)  # the block as factorised (a no-op: Q is symmetric, checked)
    Qek, Qkk = Q[np.ix_(elim, keep)], Q[np.ix_(keep, keep)]
    k = keep.size
    G = reduced.recover[: elim.size, :k]
    Qr = reduced.Qr[:k, :k]
    Fb = residual_bound(Qee, G, Qek)
    N, s = exact_residual(Qee, G, Qek)
    F_ok = all(Fraction(abs(int(x)), 1 << s) <= Fraction(float(b))
               for x, b in zip(N.ravel(), Fb.ravel(), strict=True))
    absF = _float_abs(N, s)
    fro2 = sum(Fraction(int(x) * int(x), 1 << (2 * s)) for x in N.ravel())
    norm_ok = fro2 <= Fraction(float(reduced.residual_norm)) ** 2
    out = {"F_ok": bool(F_ok), "norm_ok": bool(norm_ok),
           "Q_symmetric": bool(np.array_equal(Q, Q.T)),
           "F_use": float(np.max(np.where(Fb > 0, absF / Fb, 0.0))),
           "norm_use": float(np.sqrt(float(fro2)) / reduced.residual_norm)}
    return out, (N, s, G, Qek, Qkk, Qr, k)


def exact_sg_check(parts, err_rows: np.ndarray) -> tuple[bool, float]:
    """Row sums of ``|Qr - S_G|`` exactly against ``err_rows`` (first ``k`` rows)."""
    from fractions import Fraction

    N, s, G, Qek, Qkk, Qr, k = parts
    Gi, sg = _to_int(G)
    Ei, se = _to_int(Qek)
    Ki, sk = _to_int(Qkk)
    Ri, sr = _to_int(Qr)
    GtF = Gi.T.dot(N)  # / 2**(sg + s)
    EtG = Ei.T.dot(Gi)  # / 2**(se + sg)
    S = max(sk, sg + s, se + sg, sr)
    diff = (Ri << (S - sr)) - ((Ki << (S - sk)) + (GtF << (S - sg - s)) + (EtG << (S - se - sg)))
    ok, use = True, 0.0
    for i in range(k):
        row = Fraction(sum(abs(int(x)) for x in diff[i]), 1 << S)
        bound = Fraction(float(err_rows[i]))
        ok = ok and row <= bound
        use = max(use, float(row / bound) if bound > 0 else (0.0 if row == 0 else np.inf))
    return ok, use


# --- random blocks ------------------------------------------------------------------------------

def random_blocks(rng: np.random.Generator, m: int, k: int, cond: float):
    U, _ = np.linalg.qr(rng.standard_normal((m, m)))
    Qee = (U * np.logspace(0.0, np.log10(cond), m)) @ U.T
    Qee = 0.5 * (Qee + Qee.T)
    Qey = rng.standard_normal((m, k)) * 10.0 ** rng.integers(-3, 4)
    G = -np.linalg.solve(Qee, Qey)
    return Qee, G, Qey


def block_study(seed: int, n_blocks: int, m: int, k: int) -> list[dict]:
    """``residual_bound`` against the exact residual, native and with the float64 fallback."""
    import rwhec_ros.core.numerics.extended_residual as er

    rng = np.random.default_rng(seed)
    out = []
    native = er.extended_dtype
    for b in range(n_blocks):
        cond = 10.0 ** (2 + 12 * b / max(n_blocks - 1, 1))
        Qee, G, Qey = random_blocks(rng, m, k, cond)
        G2 = G * (1 + 1e-9 * rng.standard_normal(G.shape))
        for label, fn in (("longdouble", native), ("float64 fallback",
                                                    lambda: (np.float64, 2.0**-53))):
            er.extended_dtype = fn
            try:
                for which, Gu in (("solve", G), ("perturbed", G2)):
                    ok, use = exact_vs_bound(Qee, Gu, Qey, er.residual_bound(Qee, Gu, Qey))
                    out.append({"cond": cond, "dtype": label, "G": which, "ok": ok, "use": use})
            finally:
                er.extended_dtype = native
    return out


# --- the study ----------------------------------------------------------------------------------

def _retry_fired(inst: Instance) -> tuple[bool, object]:
    from rwhec_ros.core.solve import SolveOptions, solve

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = solve(inst.to_problem(), SolveOptions(mode="fast"))
    return "tighten" in res.timing_s, res


def _deficit_ratio(rec: dict) -> float:
    """How much of the claimed bound ``p - d`` the checker's best point uses:
    ``(p_direct - c*) / (p - d)`` (> 1: a point below the dual bound)."""
    gap = rec["p_rep"] - rec["d"]
    return float((rec["p_direct"] - rec["c_best"]) / gap) if gap > 0 else float("nan")


def _exact_on(inst: Instance, with_sg: bool) -> dict:
    """Section 2 for one instance: rebuild the product's reduction (same calls as ``solve``)."""
    from rwhec_ros.core.model.reduction import reduce_cost
    from rwhec_ros.core.pipeline.dense import prepare_dense as _prepare
    from rwhec_ros.core.solve import SolveOptions

    problem = inst.to_problem()
    prep = _prepare(problem, SolveOptions(mode="fast"))
    Q = prep.Q.toarray() if hasattr(prep.Q, "toarray") else np.asarray(prep.Q)
    tight = reduce_cost(prep.Q, prep.layout, problem.unknown_scale, residual="extended")
    out, parts = exact_reduction_check(Q, prep.layout, problem.unknown_scale, tight)
    if with_sg:
        out["sg_ok"], out["sg_use"] = exact_sg_check(parts, tight.err_rows)
    return out


def _fmt(x: float, spec: str = ".3g") -> str:
    return "–" if x is None or not np.isfinite(x) else format(x, spec)


def _summary_row(label: str | None, recs: list[dict]) -> str:
    fired = [r for r in recs if r["fired"]]
    checked = [r for r in fired if r.get("certified")]
    fc = sum(1 for r in checked if r.get("false_cert"))
    ratios = [r["deficit_ratio"] for r in checked if np.isfinite(r.get("deficit_ratio", np.nan))]
    rho = [r["rho_hat"] for r in checked]
    head = "|" if label is None else f"| {label} |"
    return (f"{head} {len(recs)} | {len(fired)} | {len(checked)} | **{fc}** | "
            f"{_fmt(max(ratios, default=np.nan), '.2e')} | {_fmt(max(rho, default=np.nan), '.2e')}"
            f" | {sum(1 for r in fired if r.get('status') != 'certified_optimal')} |")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=200, help="retry-fired instances to check")
    ap.add_argument("--max-instances", type=int, default=5000, help="instances to generate")
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--starts", type=int, default=20, help="checker random starts (>= 20)")
    ap.add_argument("--exact", type=int, default=20, help="instances for the exact F check")
    ap.add_argument("--exact-sg", type=int, default=3, help="of those, with the exact S_G")
    ap.add_argument("--fallback", type=int, default=40,
                    help="retry instances re-solved and checked with the float64 fallback")
    ap.add_argument("--blocks", type=int, default=6, help="random blocks per (m, k)")
    ap.add_argument("--output", type=Path, default=None, help="Markdown report (else stdout)")
    ap.add_argument("--log", type=Path, default=None,
                    help="JSON-lines log of the checked instances (default <output>.jsonl)")
    args = ap.parse_args(argv)
    log = args.log or (args.output.with_suffix(".jsonl") if args.output else None)
    if log is not None:
        log.write_text("")
    t_start = time.perf_counter()
    ck = CheckerOptions(n_random=args.starts)
    recs: list[dict] = []
    fired_insts: list[Instance] = []
    for index in range(args.max_instances):
        if len(fired_insts) >= args.n:
            break
        inst = make_instance(args.seed, index)
        fired, _ = _retry_fired(inst)
        rec = {"index": index, "variant": inst.category, "fired": fired}
        if fired:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                rec.update(evaluate(inst, "fast", ck))
            rec["fired"] = bool(rec.get("retry"))  # the checked solve fired it too
            if rec.get("certified"):
                rec["deficit_ratio"] = _deficit_ratio(rec)
            fired_insts.append(inst)
            if log is not None:
                with open(log, "a") as fh:
                    fh.write(json.dumps(rec, default=float) + "\n")
            flag = " FALSE-CERT" if rec.get("false_cert") else ""
            print(f"[{len(fired_insts)}/{args.n}] index {index} {inst.category} "
                  f"{inst.params['shape']} {rec.get('status')} rho {rec.get('rho_hat', 0):.2e} "
                  f"ratio {rec.get('deficit_ratio', np.nan):.2e}{flag} "
                  f"({time.perf_counter() - t_start:.0f} s)", file=sys.stderr, flush=True)
        recs.append(rec)
    t_main = time.perf_counter() - t_start

    # section 2: exact arithmetic on the retry instances' reductions
    exact = []
    for i, inst in enumerate(fired_insts[: args.exact]):
        t0 = time.perf_counter()
        e = _exact_on(inst, i < args.exact_sg)
        e.update(index=inst.index, variant=inst.category, shape=inst.params["shape"],
                 seconds=time.perf_counter() - t0)
        exact.append(e)
        print(f"exact {i}: {e}", file=sys.stderr, flush=True)

    # section 3: random blocks, native and fallback precision
    blocks = block_study(args.seed, args.blocks, 30, 60) + block_study(args.seed + 1, 2, 60, 120)

    # the float64 fallback on the retry instances
    import rwhec_ros.core.numerics.extended_residual as er

    native = er.extended_dtype
    fb = []
    er.extended_dtype = lambda: (np.float64, 2.0**-53)
    try:
        for inst in fired_insts[: args.fallback]:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                r = evaluate(inst, "fast", ck)
            r["fired"] = bool(r.get("retry"))
            if r.get("certified"):
                r["deficit_ratio"] = _deficit_ratio(r)
            fb.append(r)
    finally:
        er.extended_dtype = native
    wall = time.perf_counter() - t_start

    cmd = "python benchmarks/retry_soundness.py " + " ".join(
        argv if argv is not None else sys.argv[1:])
    out = ["# Soundness of the certificate's extended-precision retry", "",
           f"Generated {_dt.date.today().isoformat()} by `{cmd}` (seed {args.seed}; "
           f"{args.starts} random starts per check; {platform.machine()}, Python "
           f"{platform.python_version()}, numpy {np.__version__}, longdouble "
           f"{np.finfo(np.longdouble).nmant + 1}-bit significand; {wall:.0f} s on a shared, "
           "loaded 2-core machine). See the module docstring for the instances and the checks.",
           "", "*claimed bound* = ``p - d`` (the certificate's primal cost minus its dual bound); "
           "*deficit* = ``p_direct - c*`` (cost of the returned estimate, in extended "
           "precision, minus the checker's best). A deficit above the bound is a point below the "
           "dual bound; *false certificate* is the verdict of `certificate_soundness.evaluate` "
           "(below bound, suboptimal beyond the allowance, infeasible or scale <= 0; "
           "confirmed in exact arithmetic).", "",
           "## Retry-fired instances (native extended precision)", "",
           "| variant | instances solved | retry fired | certified after retry | "
           "**false certificates** | max deficit / claimed bound | max rho_hat | "
           "fired, not certified |", "|---|---|---|---|---|---|---|---|"]
    for v in VARIANTS:
        out.append(_summary_row(v, [r for r in recs if r["variant"] == v]))
    out.append(_summary_row("**all**", recs))
    n_fired = sum(1 for r in recs if r["fired"])
    out += ["", f"{len(recs)} instances generated, the retry fired on {n_fired} "
            f"({100 * n_fired / max(len(recs), 1):.1f} %); screening and checks took "
            f"{t_main:.0f} s.", ""]
    st = {}
    for r in recs:
        if r["fired"]:
            st[r["status"]] = st.get(r["status"], 0) + 1
    out += ["Status after the retry: " + ", ".join(f"{k} {v}" for k, v in sorted(st.items())),
            ""]
    out += ["## The tightened reduction in exact arithmetic (retry instances)", "",
            "| index | variant | shape | exact abs(F) <= bound | max abs(F) / bound | exact "
            "norm(F)_F <= residual_norm | norm / residual_norm | exact row sums of abs(Qr - S_G) "
            "<= err_rows | max row / err_rows |", "|---|---|---|---|---|---|---|---|---|"]
    for e in exact:
        out.append(f"| {e['index']} | {e['variant']} | {e['shape']} | "
                   f"{'yes' if e['F_ok'] else '**NO**'} | {e['F_use']:.9f} | "
                   f"{'yes' if e['norm_ok'] else '**NO**'} | {e['norm_use']:.9f} | "
                   + (f"{'yes' if e['sg_ok'] else '**NO**'} | {e['sg_use']:.3g} |"
                      if "sg_ok" in e else "– | – |"))
    out += ["", f"``Q`` exactly symmetric in {sum(e['Q_symmetric'] for e in exact)} of "
            f"{len(exact)} (the exact ``S_G`` is that of ``x^T Q x`` only then). Ratios use "
            "``abs(F)`` rounded up to double, so 1.000000000 can still be below the bound; the "
            "verdict columns are exact."]
    out += ["", "## Random blocks: residual_bound against the exact residual", "",
            "| m x k | precision | blocks x G | all bounds hold | max abs(F) / bound |",
            "|---|---|---|---|---|"]
    split = 4 * args.blocks  # 2 precisions x 2 G per block
    for (m, k), rows in (((30, 60), blocks[:split]), ((60, 120), blocks[split:])):
        for label in ("longdouble", "float64 fallback"):
            rs = [b for b in rows if b["dtype"] == label]
            conds = [b["cond"] for b in rs]
            out.append(f"| {m} x {k} (cond {min(conds):.0e}..{max(conds):.0e}) | {label} | "
                       f"{len(rs)} | {'yes' if all(b['ok'] for b in rs) else '**NO**'} | "
                       f"{max(b['use'] for b in rs):.9f} |")
    out += ["", "## The retry instances with the float64 fallback (`extended_dtype` forced to "
            "`(float64, 2**-53)`)", "",
            "| instances | retry fired | certified after retry | **false certificates** | "
            "max deficit / claimed bound | max rho_hat | fired, not certified |",
            "|---|---|---|---|---|---|---|"]
    out.append(_summary_row(None, fb))
    out.append("")
    text = "\n".join(out)
    if args.output is None:
        print(text)
        return 0
    args.output.write_text(text)
    print(f"wrote {args.output}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
