"""Local solvers: Riemannian Newton on SO(3)^n for the MLE cost with translations and scale
eliminated (paper Problem 6).

In: the scaled cost (the dense reduced ``Q'`` or the sparse unreduced form) and start rotations.
Out: a :class:`~rwhec_ros.core.local.dense.LocalSolution` (rotations at a first-order critical
point, iterations, convergence). :mod:`.dense` works on ``Q'``; :mod:`.sparse` on the sparse
form of large rigs, re-optimising translations and scale after every step (variable
projection), with the same step control.
"""
