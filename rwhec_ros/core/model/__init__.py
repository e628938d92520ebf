"""The model and its cost: from a :class:`~rwhec_ros.core.problem.Problem` to the quadratic forms
the solvers work on (paper Sections 4.4-4.6).

In: a ``Problem`` (edges of ``(A_i, B_i)`` pairs with ``sigma_i``, ``kappa_i``) and the gauge
options. Out: the cost matrix ``Q`` of eq. (42) on the state layout and the direct cost of eq.
(33) (:mod:`.cost`); the translation directions the data do not determine and the prior that
fixes them (:mod:`.gauge`); for the dense path, the Schur reduction to ``Q'`` of eq. (48) with its
proven error terms (:mod:`.reduction`); for large problems, the sparse unreduced form of the same
cost (:mod:`.sparse_cost`); the re-centring of far-off data (:mod:`.recentre`) and the live
re-solve's cache of edge blocks (:mod:`.edge_cache`).
"""
