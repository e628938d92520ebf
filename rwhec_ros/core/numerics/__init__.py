"""Linear algebra whose answers hold in floating point: the numbers every stage relies on.

In: symmetric matrices (dense or sparse upper triangles) from the cost, the gauge fix, the
reduction and the certificate. Out: Cholesky and sparse ``L D L^T`` factors with backward-error
bounds (:mod:`.cholesky`, :mod:`.sparse_ldl`), lower bounds on smallest eigenvalues that are true
for the matrix as stored (:mod:`.verified`) and proven bounds on the residual of a linear solve
(:mod:`.extended_residual`). No module here knows the calibration problem.
"""
