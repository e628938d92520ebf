"""The certificate and its dual: is a candidate the global optimum, proven in floating point?

In: the scaled cost, a candidate estimate with its direct cost ``p``, and multipliers
``lambda`` -- first-order ones at the local solution (:mod:`.multipliers`, SE-Sync style) or the
SDP's dual solution (:mod:`.relaxation`, Problem 7, solved in the cheapest exact form that
:mod:`.sparsity` picks). Out: a :class:`~rwhec_ros.core.result.Certificate`: status, the
rigorous dual bound ``d``, the suboptimality bound and its margins. :mod:`.dense` bounds the
smallest eigenvalue of the reduced ``Z(lambda)``; :mod:`.sparse` proves the same bound on the
sparse unreduced ``Z`` of large rigs. The eigenvalue bounds themselves are
:mod:`rwhec_ros.core.numerics.verified`.
"""
