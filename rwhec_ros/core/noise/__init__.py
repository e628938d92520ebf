"""The noise of the measurements, estimated from the data (variance components).

Users rarely know the noise of their camera-target poses, and the MLE's weights, the predicted
standard deviations and the verdict's fit all rest on it. This stage estimates it from the
residuals, per noise group (:mod:`.groups`: per camera by default), by Helmert's / Foerstner's
iterated variance-component estimation (:mod:`.estimate`: each group's chi-square over its
redundancy), and solves again with the estimated weights until they agree (:mod:`.reweight`);
:mod:`.words` says it in sentences. The solve with the final weights is certified as any solve:
the certificate is for the weighted problem that it states.
"""

from .estimate import (
    GIVEN_KINDS,
    ComponentNoise,
    GroupNoise,
    NoiseEstimate,
    NoiseOptions,
    estimate_noise,
)
from .groups import GROUPINGS, NoiseGroups, noise_groups
from .reweight import NoiseSolve, solve_with_noise, weighted_as, weighted_problem

__all__ = [
    "GIVEN_KINDS",
    "GROUPINGS",
    "ComponentNoise",
    "GroupNoise",
    "NoiseEstimate",
    "NoiseGroups",
    "NoiseOptions",
    "NoiseSolve",
    "estimate_noise",
    "noise_groups",
    "solve_with_noise",
    "weighted_as",
    "weighted_problem",
]
