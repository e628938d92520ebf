"""The machinery of ``benchmarks/retry_soundness.py`` (the study of the certificate's
extended-precision retry): its exact residual is exact, its bound check can fail, its generator
makes instances on which the retry fires, and the soundness harness counts retries."""

import sys
from fractions import Fraction
from pathlib import Path

import numpy as np

BENCH = Path(__file__).resolve().parents[2] / "benchmarks"
sys.path.insert(0, str(BENCH))

import certificate_soundness as cs  # noqa: E402
import retry_soundness as rs  # noqa: E402


def test_exact_residual_is_the_rational_one():
    rng = np.random.default_rng(0)
    Qee = rng.standard_normal((4, 4)) * 10.0 ** rng.integers(-30, 30, (4, 4))
    Qee[0, 1] = 0.0
    G = rng.standard_normal((4, 3))
    Qey = rng.standard_normal((4, 3)) * 1e-300  # subnormal products: still exact
    N, s = rs.exact_residual(Qee, G, Qey)
    F = lambda a: [[Fraction(float(v)) for v in row] for row in a]
    A, X, C = F(Qee), F(G), F(Qey)
    for i in range(4):
        for j in range(3):
            exact = sum(A[i][t] * X[t][j] for t in range(4)) + C[i][j]
            assert Fraction(int(N[i, j]), 1 << s) == exact


def test_exact_check_fails_on_a_bound_below_the_residual():
    """The exact comparison is not vacuous: half the true residual is rejected."""
    from rwhec_ros.core.numerics.extended_residual import residual_bound

    rng = np.random.default_rng(1)
    Qee, G, Qey = rs.random_blocks(rng, 8, 5, 1e10)
    bound = residual_bound(Qee, G, Qey)
    assert rs.exact_vs_bound(Qee, G, Qey, bound)[0]
    assert not rs.exact_vs_bound(Qee, G, Qey, 0.5 * bound)[0]


def test_generator_fires_the_retry_and_the_harness_counts_it():
    inst = rs.make_instance(2026, 0)  # known scale, 10 tags x 2 cameras (first of the study)
    assert inst.to_problem().n_frames == inst.M + inst.P
    fired, res = rs._retry_fired(inst)
    assert fired and res.certificate.certified
    line = cs._retry_line([{"retry": True, "certified": True, "false_cert": False},
                           {"retry": False, "certified": True}])
    assert "fired on 1 instances (1 certified after it, 0 of them false" in line
