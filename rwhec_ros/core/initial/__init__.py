"""Initial estimates: a feasible start for the local solvers and the recovery of an estimate from
rotations.

In: the problem, its cost (``Q``, the rotation-only part, the reduction of
:mod:`rwhec_ros.core.model`) or rotations the user gives. Out: an
:class:`~rwhec_ros.core.model.estimate.Estimate` (rotations, translations, scale and its cost):
the closed-form rotations from the null vector of the rotation-only cost, translations and scale
by eq. (47), and the cost of an estimate evaluated directly with its proven rounding bound
(:mod:`.closed_form`). The large-problem form of the closed-form start is a method of the sparse
cost (:meth:`~rwhec_ros.core.model.sparse_cost.FullForm.closed_form_rotations`).
"""
