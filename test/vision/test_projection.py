"""IntrinsicsProjector: the pixels of CameraIntrinsics.project_points and their exact derivatives
(against central differences) for every distortion model."""

from __future__ import annotations

import numpy as np
import pytest

from rwhec_ros.vision.intrinsics import CameraIntrinsics
from rwhec_ros.vision.projection import IntrinsicsProjector

K = [[480.0, 0.0, 320.0], [0.0, 485.0, 240.0], [0.0, 0.0, 1.0]]
MODELS = {
    "none": CameraIntrinsics(640, 480, K, []),
    "plumb_bob": CameraIntrinsics(640, 480, K, [-0.3, 0.1, 1e-3, -2e-3, -0.02]),
    "rational_polynomial": CameraIntrinsics(640, 480, K, [-0.3, 0.1, 1e-3, -2e-3, -0.02, 0.01,
                                                          0.002, 0.001], "rational_polynomial"),
    "equidistant": CameraIntrinsics(640, 480, K, [0.05, -0.01, 0.003, -0.001], "equidistant"),
}


@pytest.mark.parametrize("model", list(MODELS))
def test_pixels_and_derivatives(model):
    intr = MODELS[model]
    rng = np.random.default_rng(0)
    P = np.c_[rng.uniform(-0.6, 0.6, (20, 2)), rng.uniform(0.8, 2.0, 20)]
    uv, J = IntrinsicsProjector(intr).project_with_jacobian(P)
    assert uv.shape == (20, 2) and J.shape == (20, 2, 3)
    assert np.allclose(uv, intr.project_points(P), atol=1e-9)
    h = 1e-6
    for a in range(3):
        d = np.zeros(3)
        d[a] = h
        num = (intr.project_points(P + d) - intr.project_points(P - d)) / (2 * h)
        assert np.allclose(J[:, :, a], num, rtol=1e-5, atol=1e-4), (model, a)


def test_empty_and_bad_input():
    proj = IntrinsicsProjector(MODELS["none"])
    uv, J = proj.project_with_jacobian(np.zeros((0, 3)))
    assert uv.shape == (0, 2) and J.shape == (0, 2, 3)
    with pytest.raises(ValueError, match="points must have shape"):
        proj.project_with_jacobian(np.zeros((3, 2)))
    with pytest.raises(ValueError, match="intrinsics: expected CameraIntrinsics"):
        IntrinsicsProjector("cam0")
