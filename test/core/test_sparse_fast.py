"""The status decisions of the large-rig sparse path (:mod:`rwhec_ros.core.pipeline.sparse`): each
way it can end -- certified, local only, not converged, the local solver or the certificate
failing, an inconclusive certificate with and without the dense fallback and its frame limit,
a translation block that cannot be factorised -- with the status, notes and path asserted (issue
19). The inner solver and certificate are replaced by failing ones where a failure is needed."""

import dataclasses
import time

import numpy as np
import pytest

from rwhec_ros.core.local.dense import LocalSolverOptions
from rwhec_ros.core.pipeline import sparse as sparse_fast
from rwhec_ros.core.result import Status
from rwhec_ros.core.solve import SolveOptions, solve
from rwhec_ros.simulation.synthetic import random_instance

SPARSE = "sparse unreduced path (5 frames"
DENSE_AGAIN = "solved again by the dense path"


@pytest.fixture(scope="module")
def problem():
    """One target seen by four cameras (5 frames), well posed."""
    rng = np.random.default_rng(31)
    return random_instance(rng, 1, 4, n_per_edge=10, sigma=0.01, kappa=125)[0]


def _solve(problem, **kw):
    t0 = time.perf_counter()
    res = solve(problem, SolveOptions(fast_form="sparse", **kw))
    wall = time.perf_counter() - t0
    # each step's time is a duration inside the call, not a clock reading
    assert all(0.0 <= t <= wall for t in res.timing_s.values()), res.timing_s
    return res


def _not_tight(monkeypatch):
    """Make the sparse certificate inconclusive: its numbers kept, the status not tight."""
    real = sparse_fast.certify_sparse

    def inconclusive(*args, **kwargs):
        cert, strengthened = real(*args, **kwargs)
        return dataclasses.replace(cert, status=Status.NOT_TIGHT,
                                   message="crafted: not tight"), strengthened

    monkeypatch.setattr(sparse_fast, "certify_sparse", inconclusive)


def test_certified_on_the_sparse_path_alone(problem):
    res = _solve(problem)
    assert res.certified, res.certificate.message
    assert res.notes[0].startswith(SPARSE) and len(res.notes) == 1
    assert res.mode == "fast" and res.solver_status == "converged"
    assert res.rounding_displacement == 0.0  # the local solver's rotations are exact
    assert {"local", "certify"} <= set(res.timing_s)


def test_local_mode_on_the_sparse_path(problem):
    res = _solve(problem, mode="local")
    assert res.certificate.status is Status.LOCAL_ONLY
    assert res.mode == "local" and res.solver_status == "converged"
    assert res.rounding_displacement == 0.0
    assert len(res.notes) == 1 and "certify" not in res.timing_s


def test_local_solver_not_converged_is_said(problem):
    res = _solve(problem, mode="local", local=LocalSolverOptions(max_iterations=1))
    assert res.solver_status == "not converged"
    assert res.notes[1].startswith("local solver stopped after 1 iterations without converging")


def test_local_solver_failure(monkeypatch, problem):
    def boom(*args, **kwargs):
        raise np.linalg.LinAlgError("singular Newton system")

    monkeypatch.setattr(sparse_fast, "refine_rotations_sparse", boom)
    res = _solve(problem)
    c = res.certificate
    assert c.status is Status.SOLVER_FAILED
    assert c.message == "the local solver failed: singular Newton system"
    assert res.notes[1] == "local solver failed (LinAlgError: singular Newton system)"
    assert res.mode == "fast" and res.solver_status == "failed"
    assert res.rounding_displacement == 0.0 and c.null_space_dim == -1
    assert np.all(np.isfinite(res.X)) and np.all(np.isfinite(res.Y))  # the closed-form start


def test_certificate_failure_without_fallback(monkeypatch, problem):
    def boom(*args, **kwargs):
        raise np.linalg.LinAlgError("Lanczos broke down")

    monkeypatch.setattr(sparse_fast, "certify_sparse", boom)
    res = _solve(problem, fallback_to_sdp=False)
    c = res.certificate
    assert c.status is Status.SOLVER_FAILED
    assert c.message == ("the certificate's eigen-analysis failed (LinAlgError: Lanczos broke "
                         "down)")
    assert res.solver_status == "converged" and len(res.notes) == 1


def test_inconclusive_without_fallback_is_returned_as_is(monkeypatch, problem):
    _not_tight(monkeypatch)
    res = _solve(problem, fallback_to_sdp=False)
    assert res.certificate.status is Status.NOT_TIGHT
    assert res.certificate.message == "crafted: not tight"
    assert len(res.notes) == 1 and res.mode == "fast" and res.rounding_displacement == 0.0


def test_inconclusive_falls_back_to_the_dense_path_up_to_the_frame_limit(monkeypatch, problem):
    """At the limit (5 frames) the dense path runs and certifies; one frame above it the sparse
    result is returned uncertified, with the limit named."""
    _not_tight(monkeypatch)
    res = _solve(problem, sdp_fallback_max_frames=5)
    assert res.certified, res.certificate.message
    assert res.notes[1] == f"sparse certificate inconclusive (crafted: not tight); {DENSE_AGAIN}"
    assert len(res.notes) == 2  # the dense fast path certified: no SDP
    res = _solve(problem, sdp_fallback_max_frames=4)
    assert res.certificate.status is Status.NOT_TIGHT
    assert res.notes[1] == ("sparse certificate inconclusive; the dense path and the SDP are "
                            "skipped above sdp_fallback_max_frames=4 frames")
    assert res.mode == "fast" and res.rounding_displacement == 0.0


def test_translation_block_that_cannot_be_factorised(monkeypatch, problem):
    """The sparse path cannot start: the dense path up to the frame limit, above it a
    solver_failed result of identity transforms saying why."""
    def boom(*args, **kwargs):
        raise np.linalg.LinAlgError("translation block not positive definite")

    monkeypatch.setattr(sparse_fast, "prepare_sparse", boom)
    why = ("the sparse path could not start (LinAlgError: translation block not positive "
           "definite)")
    res = _solve(problem)
    assert res.certified and res.notes[0] == why
    res = _solve(problem, sdp_fallback_max_frames=4)
    c = res.certificate
    assert c.status is Status.SOLVER_FAILED and c.message == why and res.notes == [why]
    assert res.X.shape == (1, 4, 4) and res.Y.shape == (4, 4, 4)
    assert np.array_equal(res.X, np.eye(4)[None]) and np.array_equal(res.Y, np.tile(np.eye(4),
                                                                                     (4, 1, 1)))
    assert res.scale == 1.0 and res.rounding_displacement == 0.0
    assert res.mode == "fast" and res.solver_status == "failed" and np.isnan(c.primal_cost)
