"""The paths of a solve, stage after stage: what :func:`rwhec_ros.core.solve.solve` runs.

In: a :class:`~rwhec_ros.core.problem.Problem` and the
:class:`~rwhec_ros.core.pipeline.options.SolveOptions`. Out: a
:class:`~rwhec_ros.core.result.CalibrationResult` with its certificate. :mod:`.dense` runs the
stages on the reduced ``Q'`` (modes ``fast``, ``local`` and the SDP of ``sdp``); :mod:`.sparse`
runs them on the sparse unreduced cost of large rigs and says when to take that path
(:func:`~rwhec_ros.core.pipeline.sparse.use_sparse`), falling back to the dense path when its
certificate is inconclusive; both build their results with :mod:`.common`; :mod:`.statuses` adds
what the certificate alone cannot know.
"""
