"""The status decisions of :func:`rwhec_ros.core.solve.solve` around the certificate: which SDP
form runs, when the fast certificate is strengthened (and what stands when that fails), which
rotations are named as not determined (crafted Hessian eigenpairs at the thresholds) and when
that analysis runs at all, the notes on the translation priors, and the scale floor (issue 19:
each of these once changed without a test noticing)."""

import dataclasses
import time
from types import SimpleNamespace

import numpy as np
import pytest
from test_gauge import _planar_rig

from rwhec_ros.core.certify.relaxation import SdpOptions
from rwhec_ros.core.model.gauge import GaugeOptions, TranslationPrior
from rwhec_ros.core.pipeline import dense as dense_path
from rwhec_ros.core.pipeline import statuses
from rwhec_ros.core.result import CalibrationResult, Certificate, Status
from rwhec_ros.core.solve import SolveOptions, solve
from rwhec_ros.simulation.synthetic import random_instance

NULL_TOL = 1e-6  # the default CertificateOptions.null_tol; the Hessian threshold is 10x this


def _timed(problem, options):
    t0 = time.perf_counter()
    res = solve(problem, options)
    return res, time.perf_counter() - t0


def _assert_step_times(res, wall):
    """Each step's time is a duration inside the call, not a clock reading."""
    assert all(0.0 <= t <= wall for t in res.timing_s.values()), res.timing_s


def test_explicit_arrow_form_is_solved_and_certified():
    """``SdpOptions(form="arrow")`` on three frames (where ``auto`` would pick ``reduced``): the
    hub/leaf split is computed for it, the arrow SDP runs and certifies."""
    rng = np.random.default_rng(21)
    problem, _ = random_instance(rng, 1, 2, n_per_edge=10, sigma=0.01, kappa=125)
    res = solve(problem, SolveOptions(mode="sdp", sdp=SdpOptions(form="arrow")))
    assert "SDP form: arrow" in res.notes
    assert res.certificate.status is Status.CERTIFIED_OPTIMAL, res.certificate.message
    auto = solve(problem, SolveOptions(mode="sdp"))
    assert "SDP form: reduced" in auto.notes and auto.certified
    # the same optimum: both relaxations are exact here (cost relative 1e-9: Clarabel's accuracy)
    assert res.certificate.primal_cost == pytest.approx(auto.certificate.primal_cost, rel=1e-9)


def _sphere_problem():
    from rwhec_ros.simulation.scenarios import hand_camera_sphere

    problem, _ = hand_camera_sphere(np.random.default_rng(0), sigma=0.01, kappa=125)
    return problem


def test_strengthening_that_fails_keeps_the_inconclusive_certificate(monkeypatch):
    """Single-sphere data need the handedness multipliers (see test_solve); when that step fails
    numerically the first certificate stands: not tight, no 'strengthened' note, and the attempt
    is timed."""
    problem = _sphere_problem()
    ok, wall = _timed(problem, SolveOptions(fallback_to_sdp=False))
    assert ok.certified and "strengthened" in ok.notes[0]
    _assert_step_times(ok, wall)
    assert "strengthen" in ok.timing_s

    def boom(*args, **kwargs):
        raise np.linalg.LinAlgError("no step")

    monkeypatch.setattr(dense_path, "strengthen_certificate", boom)
    res, wall = _timed(problem, SolveOptions(fallback_to_sdp=False))
    assert res.certificate.status is Status.NOT_TIGHT, res.certificate.message
    assert res.certificate.null_space_dim >= 2  # e_s left in the null space of Z
    assert not any("strengthened" in n for n in res.notes)
    assert "strengthen" in res.timing_s
    _assert_step_times(res, wall)


def _identity_result(problem, cert):
    eye = np.broadcast_to(np.eye(4), (problem.n_frames, 4, 4)).copy()
    return CalibrationResult(x_names=problem.x_names, y_names=problem.y_names,
                             X=eye[:problem.M], Y=eye[problem.M:], scale=1.0, certificate=cert,
                             mode="fast", timing_s={}, solver_status="converged",
                             rounding_displacement=0.0, notes=[])


def _cert(status, null_dim, message="crafted"):
    return Certificate(status, 1.0, 1.0, 0.0, 0.0, np.zeros(6), null_dim, 1e-6, message)


def _stub_prep(problem, w, V, calls=None):
    """What ``_check_identifiability`` / ``_rotation_gauge_words`` read of a prepared problem,
    with the Riemannian Hessian's eigenpairs given."""
    def eigenpairs(R, null_tol):
        if calls is not None:
            calls.append(null_tol)
        return np.asarray(w, float), np.asarray(V, float)

    return SimpleNamespace(problem=problem, gauge=None, hessian_eigenpairs=eigenpairs)


@pytest.fixture(scope="module")
def two_frames():
    """One tag and one camera (names x0, y0); only the names and sizes are used."""
    problem, _ = random_instance(np.random.default_rng(3), 1, 1, n_per_edge=3)
    return problem


def _words(problem, w, V):
    prep = _stub_prep(problem, w, V)
    cert = _cert(Status.NOT_TIGHT, 2)
    return statuses._rotation_gauge_words(prep, _identity_result(problem, cert), NULL_TOL)


# the Hessian thresholds: a saddle below -10 null_tol, a flat direction |w| <= 10 null_tol
_FLAT = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]
_X0_ABOUT_X = "rotation of x0 about x (in their carriers) not determined by the data"


@pytest.mark.parametrize("w,expected", [
    (_FLAT, _X0_ABOUT_X),
    ([-2e-5, 0.0, 1.0, 2.0, 3.0, 4.0], ""),  # a saddle: nothing named, even with a flat pair
    ([-5e-6, 1.0, 2.0, 3.0, 4.0, 5.0], _X0_ABOUT_X),  # within 10 null_tol below zero: flat
    ([-10.0 * NULL_TOL, 1.0, 2.0, 3.0, 4.0, 5.0], _X0_ABOUT_X),  # the threshold itself: flat
    ([1e-4, 1.0, 2.0, 3.0, 4.0, 5.0], ""),  # 100 null_tol: curved, determined
    ([1.0, 2.0, 3.0, 4.0, 5.0, 6.0], ""),
])
def test_rotation_gauge_words_at_the_thresholds(two_frames, w, expected):
    assert _words(two_frames, w, np.eye(6)) == expected


def test_rotation_gauge_words_name_the_frames_and_a_canonical_axis(two_frames):
    """Frames with at least 0.1 of the flat direction are named (0.1 itself counts), the axis
    sign is canonical (largest component of the first frame's axis positive), different axes are
    said to be different."""
    V = np.eye(6)
    V[:, 0] = [-1.0, 0, 0, -1.0, 0, 0]  # both about -x: reported as x
    assert _words(two_frames, _FLAT, V) == ("rotation of x0, y0 about x (in their carriers) "
                                            "not determined by the data")
    V[:, 0] = [0.05, 0, 0, 0, 0, np.sqrt(1 - 0.05**2)]  # 5 % on the tag: only the camera
    assert _words(two_frames, _FLAT, V) == ("rotation of y0 about z (in their carriers) not "
                                            "determined by the data")
    V[:, 0] = [0.1, 0, 0, 0, 0, np.sqrt(1 - 0.1**2)]  # exactly 0.1 on the tag: both, two axes
    assert _words(two_frames, _FLAT, V) == ("rotation of x0, y0 about different axes (in "
                                            "their carriers) not determined by the data")
    # a near tie between two components: the first frame's largest one (x) decides the sign,
    # although the second frame's largest is y (both axes read the same to two decimals)
    V[:, 0] = [0.7072, -0.7070, 0.01, 0.7070, -0.7072, 0.01] / np.sqrt(2.0)
    assert _words(two_frames, _FLAT, V) == ("rotation of x0, y0 about [+0.71, -0.71, +0.01] (in "
                                            "their carriers) not determined by the data")
    V[:, 0] = -V[:, 0]
    assert _words(two_frames, _FLAT, V) == ("rotation of x0, y0 about [+0.71, -0.71, +0.01] (in "
                                            "their carriers) not determined by the data")


@pytest.mark.parametrize("status,null_dim,analysed", [
    (Status.NOT_TIGHT, 2, True),  # inconclusive with a second null direction: analysed
    (Status.NOT_TIGHT, 3, True),
    (Status.NOT_TIGHT, 1, False),  # one null direction (the optimum's): no rotation gauge
    (Status.CERTIFIED_OPTIMAL, 1, False),
])
def test_rotation_gauge_analysis_runs_only_for_a_larger_null_space(two_frames, status, null_dim,
                                                                   analysed):
    calls = []
    prep = _stub_prep(two_frames, _FLAT, np.eye(6), calls)
    res = _identity_result(two_frames, _cert(status, null_dim))
    statuses.check_identifiability(prep, SolveOptions(), res)
    assert calls == ([NULL_TOL] if analysed else [])
    if analysed:
        assert res.certificate.status is Status.NOT_IDENTIFIABLE
        assert res.certificate.message == f"not identifiable: {_X0_ABOUT_X}. [crafted]"
    else:
        assert res.certificate.status is status and res.certificate.message == "crafted"
    assert res.notes == []


def test_well_posed_data_get_no_gauge_note():
    """No unobservable direction: no translation words, no prior note, nothing downgraded."""
    rng = np.random.default_rng(4)
    problem, _ = random_instance(rng, 2, 2, n_per_edge=20, sigma=0.01, kappa=125)
    res = solve(problem)
    assert res.certified and res.unobservable == []
    assert not any("prior" in n or "not determined" in n for n in res.notes), res.notes


def _prior_note(p, got):
    return (f"prior {p.frame} {np.round(p.axis, 3).tolist()} = {p.value_m:.4f} m: estimate "
            f"{got:.4f} m (the priors disagree with each other or with the data)")


def test_priors_that_disagree_are_reported_beyond_a_tenth_of_a_millimetre():
    """Planar motion, the height pinned by two priors (cam0 along z, cam1 along (0, 1, 2)/sqrt 5).
    Priors consistent with the data: met, no note. Priors disagreeing by 2 mm along the
    unobservable height: each misses by ~1 mm and both are named with the estimate; by 0.1 mm:
    each misses by ~0.05 mm, within the 0.1 mm the note allows."""
    problem, _, Y = _planar_rig(np.random.default_rng(2), jitter=1e-6)
    p0 = TranslationPrior("cam0", "z", float(Y[0, 2, 3]))
    one = solve(problem, SolveOptions(gauge=GaugeOptions(priors=(p0,))))
    assert one.certified, one.certificate.message
    fixed = [n for n in one.notes if "fixed by the given priors" in n]
    assert len(fixed) == 1 and fixed[0].startswith("translation along")
    assert not any(n.startswith("prior ") for n in one.notes)
    d = one.unobservable[0]
    assert d.fixed_by == "prior"
    # the direction's value is the component of the returned translations along it
    t = {name: T[:3, 3] for name, T in zip(problem.frame_names,
                                           np.concatenate([one.X, one.Y]), strict=True)}
    norm = np.sqrt(sum(v @ v for v in d.components.values()))
    assert d.value_m == pytest.approx(sum(v @ t[k] for k, v in d.components.items()) / norm,
                                      abs=1e-12)  # the same sum, up to rounding
    axis = np.array([0.0, 1.0, 2.0]) / np.sqrt(5.0)
    consistent = float(axis @ one.Y[1, :3, 3])
    p1 = TranslationPrior("cam1", [0.0, 1.0, 2.0], consistent)
    both = solve(problem, SolveOptions(gauge=GaugeOptions(priors=(p0, p1))))
    assert both.certified and not any(n.startswith("prior ") for n in both.notes), both.notes
    for delta, noted in ((2e-3, True), (1e-4, False)):
        p1 = TranslationPrior("cam1", [0.0, 1.0, 2.0], consistent + delta)
        res = solve(problem, SolveOptions(gauge=GaugeOptions(priors=(p0, p1))))
        assert res.certified, res.certificate.message
        got0 = float(res.Y[0, 2, 3])
        got1 = float(p1.axis @ res.Y[1, :3, 3])
        miss0, miss1 = got0 - p0.value_m, got1 - p1.value_m
        # the least-squares compromise along the height: opposite signs, each about delta / 2
        assert miss0 * miss1 < 0
        for miss in (miss0, miss1):
            assert 0.3 * delta < abs(miss) < 0.7 * delta
        notes = [n for n in res.notes if n.startswith("prior ")]
        if noted:
            assert notes == [_prior_note(p0, got0), _prior_note(p1, got1)]
            assert "[0.0, 0.447, 0.894]" in notes[1]
        else:
            assert notes == []


def test_strengthening_is_tried_down_to_minus_null_tol(monkeypatch):
    """An inconclusive fast certificate whose smallest eigenvalue is at -null_tol (the tolerance
    counts as positive semidefinite) gets the handedness multipliers; just below, a negative
    eigenvalue, it does not (no SDP fallback here, so the first certificate is returned)."""
    rng = np.random.default_rng(12)
    problem, _ = random_instance(rng, 3, 2, n_per_edge=15, sigma=0.01, kappa=125)
    real = dense_path._certify
    for lam_min, strengthened in ((-NULL_TOL, True), (np.nextafter(-NULL_TOL, -1.0), False)):
        calls = []

        def first_inconclusive(*args, **kwargs):
            cert = real(*args, **kwargs)
            calls.append(cert)
            if len(calls) == 1:
                cert = dataclasses.replace(cert, status=Status.NOT_TIGHT, lambda_min=lam_min,
                                           message="crafted: not tight")
            return cert

        monkeypatch.setattr(dense_path, "_certify", first_inconclusive)
        res = solve(problem, SolveOptions(fallback_to_sdp=False))
        assert len(calls) == (2 if strengthened else 1)
        assert ("strengthen" in res.timing_s) is strengthened
        if strengthened:  # the second certificate (of the real Z) is certified and replaces it
            assert res.certified and res.notes == [
                "fast certificate strengthened with handedness multipliers"]
        else:
            assert res.certificate.status is Status.NOT_TIGHT and res.notes == []


def test_unknown_scale_at_the_floor_is_not_identifiable():
    """``min_scale`` is exclusive: an estimate equal to it is never certified, the next double
    below it as the floor leaves the certificate alone."""
    rng = np.random.default_rng(11)
    problem, _ = random_instance(rng, 2, 1, n_per_edge=20, sigma=0.01, kappa=125,
                                 unknown_scale=True, alpha=0.5)
    res = solve(problem)
    assert res.certified and 0.4 < res.scale < 0.6  # alpha = 0.5, 1 cm noise
    at = solve(problem, SolveOptions(min_scale=res.scale))
    assert at.scale == res.scale  # the same deterministic solve; only the floor differs
    assert at.certificate.status is Status.NOT_IDENTIFIABLE
    assert f"alpha = {res.scale:.4g} is not above the floor" in at.certificate.message
    below = solve(problem, SolveOptions(min_scale=float(np.nextafter(res.scale, 0.0))))
    assert below.certified, below.certificate.message
