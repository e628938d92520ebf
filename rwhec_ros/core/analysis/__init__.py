"""Analyses of a solved calibration: how well the data determine it and what to record next.

In: the problem and a :class:`~rwhec_ros.core.result.CalibrationResult` (and the solve options,
whose gauge fix they share). Out: the information matrix of the MLE, the Hessian of the negative
log-likelihood on the manifold (:mod:`.information`); each frame's predicted and empirical
covariance (:mod:`.uncertainty`); the held-out error of k-fold cross-validation, which solves
again through :func:`rwhec_ros.core.solve.solve` (:mod:`.validation`); the next motion that most
reduces the largest remaining uncertainty (:mod:`.guidance`). Identifiability of the data
(:mod:`rwhec_ros.core.identifiability`, also used before any solve) and the verdict that reads
all of these (:mod:`rwhec_ros.core.verdict`) are subpackages of their own.
"""
