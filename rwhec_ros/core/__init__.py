"""ROS-free mathematics of generalized robot-world/hand-eye calibration, laid out by the stages of
a solve.

* :mod:`.solve` -- the one entry point, :func:`~rwhec_ros.core.solve.solve`; it runs
  :mod:`.pipeline` (the dense and the large-problem path), which runs the stages in order:
  :mod:`.model` (the cost, the gauge fix, the reduction) -> :mod:`.initial` (the closed-form
  estimate) -> :mod:`.local` (Riemannian Newton) -> :mod:`.certify` (the certificate, the SDP).
* After a solve: :mod:`.analysis` (information, uncertainty, validation, guidance),
  :mod:`.noise` (the noise estimated from the data and the solve re-weighted with it),
  :mod:`.identifiability`, :mod:`.outliers` (robust solves) and :mod:`.verdict` (read first).
* :mod:`.baselines`: the solvers the paper compares against.
* Shared by all: :mod:`.problem` (the input), :mod:`.result` (options' results and statuses),
  :mod:`.lie` (SO(3)/SE(3)) and :mod:`.numerics` (linear algebra proven in floating point).

The modules ``cost``, ``gauge``, ``certificate``, ``relaxation``, ``local_solver``,
``uncertainty``, ``validation``, ``guidance``, ``synthetic``, ``scenarios`` and ``lom`` at this
level are deprecated re-exports of their new homes, kept for one release.
"""
