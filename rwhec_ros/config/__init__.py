"""Calibrator configuration: ONE file format, a ROS 2 parameter YAML, read with or without ROS.

The same file serves ``ros2 run rwhec_ros calibrator --ros-args --params-file FILE`` and the CLI's
``--config FILE``::

    /**:                        # any node name in any namespace (ROS's wildcard)
      ros__parameters:
        camera_carrier: {frame: rig, moving: true}
        ...

The top-level keys select the node as ROS does (:func:`~.parameter_file.section_pattern`):
``/**`` any node, ``/**/calibrator`` the node ``calibrator`` in any namespace, ``calibrator`` only
``/calibrator`` (no namespace), ``/rig1/calibrator`` only that node; the shipped files use
``/**`` so that they work under any ``namespace:=`` and node name.

Nested mappings are dotted parameter names (``camera_carrier.frame``), exactly as the ROS 2
parameter-file parser flattens them. ROS parameters are scalars or homogeneous arrays only (no
lists of mappings), hence the scheme used here:

* cameras: ``cameras.names: [cam0, cam1]`` (string array) and, per name,
  ``cameras.<name>.image_topic``, ``cameras.<name>.camera_info_topic``, ``cameras.<name>.frame``
  (optical frame) and optionally ``cameras.<name>.calibrated_frame``;
* tag sizes: parallel arrays ``tags.sizes.ids: [0, 1]`` (integers) and
  ``tags.sizes.values: [0.16, 0.08]`` (metres) plus ``tags.default_size`` for every other id;
* boards (and tags with a frame name of their own): ``targets.names: [board]`` and, per name,
  ``targets.<name>.type`` (``aprilgrid``, ``charuco``, ``tag``) with that type's keys
  (:mod:`.targets`).

Frame convention (paper eq. (1)/(7), ``A_i X_j = Y_k B_i``): cameras are the Y variables, tags the
X variables::

    B   = T_cam_tag                             (PnP of one tag in one image, noisy)
    Y_k = T_<camera carrier>_cam_k              (unknown, estimated)
    X_j = T_<tag carrier>_tag_j                 (unknown, estimated)
    A   = T_<camera carrier>_<tag carrier>      (pose stream, taken as noise-free)

The pose source delivers ``T_parent_child`` (a ``geometry_msgs/PoseStamped`` whose
``header.frame_id`` is ``parent`` and whose pose is that of the ``child`` body, or a tf lookup
``parent <- child``); ``{parent, child}`` must be the two carrier frames. ``A = T_parent_child``
when ``parent`` is the camera carrier, and ``A = (T_parent_child)^-1`` when it is the tag carrier
(e.g. motion capture gives ``T_world_rig`` with cameras on the rig and tags in the world, so
``A = T_rig_world``).

Types are as strict as in ROS: a ``double`` parameter must be written with a decimal point
(``1.0``, not ``1``), because ``ros2`` rejects an integer for a double parameter; the loader
enforces the same rule so that a file accepted here is accepted by the node.
Units: metres, seconds, radians (suffixes ``_m``, ``_s``, ``_rad`` in the names).

Modules: :mod:`.specs` (the parameter schema), :mod:`.sections` (the typed sections),
:mod:`.targets` (the named targets: boards),
:mod:`.calibrator` (:class:`CalibratorConfig`, built from its sections), :mod:`.validation`
(types and values, naming the parameter), :mod:`.parameter_file` (reading a ROS 2 parameter
file without ROS) and :mod:`.reference` (the Markdown reference of every parameter,
``docs/configuration-reference.md``, rendered from the specs).
"""

from . import sections, specs
from .calibrator import CalibratorConfig
from .parameter_file import (
    flatten_parameters,
    fully_qualified_name,
    load_config,
    matching_sections,
    read_parameter_file,
    section_pattern,
)
from .sections import *  # noqa: F403 - every section class, listed in sections.__all__
from .specs import *  # noqa: F403 - the schema, listed in specs.__all__

__all__ = [
    "CalibratorConfig",
    "load_config",
    "read_parameter_file",
    "flatten_parameters",
    "fully_qualified_name",
    "section_pattern",
    "matching_sections",
    *sections.__all__,
    *specs.__all__,
]
