"""Next-motion guidance on cases with a known answer (issue 11)."""

import numpy as np
import pytest
import yaml

from rwhec_ros.core.analysis.guidance import GuidanceOptions, suggest_next_motion
from rwhec_ros.core.analysis.uncertainty import frame_uncertainty
from rwhec_ros.core.lie import invert_transform, make_transform, so3_exp
from rwhec_ros.core.problem import Edge, Problem
from rwhec_ros.core.solve import solve
from rwhec_ros.simulation.synthetic import (
    perturb_measurements,
    planar_instance,
    random_instance,
    random_transforms,
)


def _planar(seed=1):
    """A ground robot that only yaws: camera and tag heights unobservable."""
    return planar_instance(np.random.default_rng(seed))[0]


def test_planar_motion_asks_for_a_tilt():
    problem = _planar()
    res = solve(problem)
    opts = GuidanceOptions(y_carrier="the rig", x_carrier="the world")
    g = suggest_next_motion(problem, res, opts)
    assert g.needed and g.n_unobservable == 4  # the height of every frame
    best = g.best
    # a tilt of the rig: rotation about its x or y axis (yaw adds nothing), and it makes every
    # height observable
    assert best.kind == "rotate" and best.axis in (0, 1), g.message
    assert best.n_unobservable == 0 and not best.new_edge
    assert "rotate the rig back and forth about its" in g.message
    assert f"while {best.y} sees {best.x}" in g.message
    yaml.safe_dump(g.to_dict())


def test_planar_motion_with_a_moving_target_carrier():
    """The same data read as a hand-held target (the tag carrier moves): still a tilt, now of
    the tag carrier, in its own axes."""
    problem = _planar(seed=3)
    opts = GuidanceOptions(moving="x", x_carrier="the target board", translations_m=())
    g = suggest_next_motion(problem, solve(problem), opts)
    assert g.best.kind == "rotate" and g.best.n_unobservable == 0
    assert "rotate the target board back and forth about its" in g.message


def _one_sided_camera(seed=5):
    """Three cameras and three tags seen from everywhere, plus cam3 that saw tag_1 only a few
    times from nearly the same pose (rotations within +-2 deg): cam3 is the weak frame."""
    rng = np.random.default_rng(seed)
    problem, truth = random_instance(rng, 3, 3, n_per_edge=40, sigma=0.003, kappa=2000.0)
    X = truth.X
    Y3 = random_transforms(rng, 1)[0]
    A0 = random_transforms(rng, 1)[0]
    A = A0 @ make_transform(so3_exp(np.radians(rng.uniform(-2, 2, (4, 3)))),
                            0.02 * rng.standard_normal((4, 3)))
    B = perturb_measurements(rng, invert_transform(Y3) @ A @ X[1], 0.003, 2000.0)
    names_x = [f"tag_{j}" for j in range(3)]
    edges = [Edge.build(f"tag_{e.x[1:]}", f"cam{e.y[1:]}", e.A, e.B, e.sigma, e.kappa)
             for e in problem.edges]
    edges.append(Edge.build("tag_1", "cam3", A, B, 0.003, 2000.0))
    return Problem(names_x, ["cam0", "cam1", "cam2", "cam3"], edges)


def test_a_camera_seen_from_one_side_asks_for_its_edge():
    problem = _one_sided_camera()
    res = solve(problem)
    unc = frame_uncertainty(problem, res)
    worst = max(unc.frames, key=lambda f: np.nanmax(f.std_translation_m))
    assert worst.name == "cam3"  # the premise of the test
    g = suggest_next_motion(problem, res)
    assert g.needed and g.worst.startswith("cam3")
    assert (g.best.x, g.best.y, g.best.new_edge) == ("tag_1", "cam3", False), g.message
    assert g.best.kind == "rotate"
    assert g.best.worst_ratio < 0.5 * g.worst_ratio  # a real improvement, not a tie


def test_well_conditioned_data_need_nothing():
    rng = np.random.default_rng(2)
    problem, _ = random_instance(rng, 3, 3, n_per_edge=30, sigma=0.002, kappa=2000.0)
    g = suggest_next_motion(problem, solve(problem))
    assert not g.needed and g.message.startswith("nothing needed")
    assert g.worst_ratio < 1.0
    # and with targets it cannot reach yet, it asks for something again
    g2 = suggest_next_motion(problem, solve(problem),
                             GuidanceOptions(target_std_translation_m=1e-5,
                                             target_std_rotation_deg=1e-3, new_edges=False))
    assert g2.needed and g2.best is not None and g2.best.worst_ratio < g2.worst_ratio


@pytest.mark.parametrize("kwargs, field", [
    ({"target_std_translation_m": 0.0}, "target_std_translation_m"),
    ({"angles_deg": (10.0, -5.0)}, "angles_deg"),
    ({"angles_deg": (), "translations_m": ()}, "need at least one motion"),
    ({"poses_per_motion": 1}, "poses_per_motion"),
    ({"moving": "z"}, "moving"),
    ({"view_distance_m": -1.0}, "view_distance_m"),
])
def test_options_are_validated(kwargs, field):
    with pytest.raises(ValueError, match=field):
        GuidanceOptions(**kwargs)
