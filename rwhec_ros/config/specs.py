"""The parameter schema: one :class:`ParamSpec` per parameter, shared by the node and the CLI.

Per-camera parameters (:data:`CAMERA_SPECS`) are expanded to ``cameras.<name>.<key>`` by
:func:`parameter_specs`. Units: metres, seconds, radians (suffixes ``_m``, ``_s``, ``_rad``).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

__all__ = [
    "ParamSpec",
    "GLOBAL_SPECS",
    "CAMERA_SPECS",
    "TIME_OFFSET_SPEC",
    "TARGET_SPECS",
    "TARGET_TYPES",
    "parameter_specs",
    "global_spec",
    "is_valid_name",
    "DEFAULT_NODE_NAME",
    "ROS_MANAGED_PARAMETERS",
    "ROS_MANAGED_PREFIXES",
    "KINDS",
    "SOLVER_MODES",
    "SDP_BACKENDS",
    "POSE_SOURCE_TYPES",
    "IMAGE_QOS",
    "IMAGE_TRANSPORTS",
    "CAPTURE_MODES",
    "CHECK_HOLDS",
    "CHECK_NOISE",
]

#: Node name used by the console script, the launch files and the example configurations.
DEFAULT_NODE_NAME = "calibrator"

#: Parameters that ROS itself declares on every node; accepted in a file and ignored here.
ROS_MANAGED_PARAMETERS = ("use_sim_time", "start_type_description_service")
#: Prefixes of parameters managed by ROS (QoS overrides); accepted and ignored.
ROS_MANAGED_PREFIXES = ("qos_overrides.",)

#: Parameter kinds, named after ``rclpy.Parameter.Type`` (see ``rwhec_ros.ros.params``), plus
#: ``int_or_auto``: an integer or the string ``"auto"`` (declared as a string by default).
KINDS = ("bool", "int", "double", "string", "int_array", "double_array", "string_array",
         "int_or_auto")

_NAME_RE = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")

SOLVER_MODES = ("fast", "sdp", "local")
#: ``solver.sdp_backend`` values (:attr:`rwhec_ros.core.relaxation.SdpOptions.backend`).
SDP_BACKENDS = ("auto", "structured", "cvxpy")
POSE_SOURCE_TYPES = ("topic", "tf")
IMAGE_QOS = ("sensor_data", "reliable")
IMAGE_TRANSPORTS = ("raw", "compressed")
#: ``capture.mode`` values: which images become candidate views (:mod:`rwhec_ros.session.capture`).
CAPTURE_MODES = ("continuous", "capture", "both")
#: Values of ``noise.groups`` (:data:`rwhec_ros.core.noise.GROUPINGS`).
NOISE_GROUPS = ("camera", "camera_target", "global")
#: ``targets.<name>.type`` values: one tag of ``tags.family`` with its own frame name, a
#: Kalibr-style AprilGrid, a ChArUco board (:mod:`rwhec_ros.vision.boards`), a chessboard, a
#: circle grid with a larger origin circle, OpenCV's asymmetric circle grid
#: (:mod:`rwhec_ros.vision.grids`).
TARGET_TYPES = ("tag", "aprilgrid", "charuco", "chessboard", "circles", "asymmetric_circles")
#: ``check.hold`` values: what holds the reference while a frame is tested
#: (:mod:`rwhec_ros.session.bringup`).
CHECK_HOLDS = ("none", "targets")
#: ``check.noise`` values: the noise of the bring-up check's test.
CHECK_NOISE = ("data", "stated")


@dataclass(frozen=True)
class ParamSpec:
    """One parameter of the schema.

    Attributes
    ----------
    name : str
        Dotted parameter name (per-camera specs: the part after ``cameras.<name>.``).
    kind : str
        One of :data:`KINDS`.
    default : object
        Value when absent; ``None`` with ``required=False`` means "unset" (optional).
    required : bool
        Absent -> ``ValueError``.
    doc : str
        One-line description (also used as the ROS parameter description).
    """

    name: str
    kind: str
    default: Any = None
    required: bool = False
    doc: str = ""


GLOBAL_SPECS: tuple[ParamSpec, ...] = (
    ParamSpec("camera_carrier.frame", "string", required=True,
              doc="frame the cameras are rigidly attached to (Y_k = T_<this>_cam_k)"),
    ParamSpec("camera_carrier.moving", "bool", required=True,
              doc="true if the camera carrier moves relative to the tag carrier"),
    ParamSpec("tag_carrier.frame", "string", required=True,
              doc="frame the tags are rigidly attached to (X_j = T_<this>_tag_j)"),
    ParamSpec("tag_carrier.moving", "bool", required=True,
              doc="true if the tag carrier moves relative to the camera carrier"),
    ParamSpec("pose_source.type", "string", "topic",
              doc="'topic' (geometry_msgs/PoseStamped) or 'tf' (lookup at each image stamp)"),
    ParamSpec("pose_source.topic", "string", "",
              doc="PoseStamped topic (type 'topic'); header.frame_id must be pose_source.parent"),
    ParamSpec("pose_source.parent", "string", required=True,
              doc="parent frame of the pose stream T_parent_child (one of the carriers)"),
    ParamSpec("pose_source.child", "string", required=True,
              doc="child frame of the pose stream T_parent_child (the other carrier)"),
    ParamSpec("cameras.names", "string_array", required=True,
              doc="camera names; each needs cameras.<name>.* parameters"),
    ParamSpec("tags.family", "string", "tag36h11",
              doc="AprilTag family (tag36h11, ...) or ArUco dictionary (DICT_6X6_250, ...) of the "
                  "single tags"),
    ParamSpec("tags.ids", "int_array", (),
              doc="ids of the single tags to calibrate (frames <tags.frame_prefix><id>); any "
                  "other id is ignored (and counted); may be empty when targets.names is not"),
    ParamSpec("tags.default_size", "double", None,
              doc="edge length [m] (black square) of every tag not in tags.sizes.ids"),
    ParamSpec("tags.sizes.ids", "int_array", (), doc="ids with an individual size"),
    ParamSpec("tags.sizes.values", "double_array", (),
              doc="sizes [m] of tags.sizes.ids, same order and length"),
    ParamSpec("tags.frame_prefix", "string", "tag_", doc="tag frame names are <prefix><id>"),
    ParamSpec("tags.unknown_scale", "bool", False,
              doc="estimate a common scale (monocular, paper Problem 3): sizes may be nominal"),
    ParamSpec("targets.names", "string_array", (),
              doc="named targets, each its own frame (X variable): a board (AprilGrid, ChArUco: "
                  "one pose from all its corners) or a single tag; each needs "
                  "targets.<name>.* parameters"),
    ParamSpec("noise.sigma", "double", 0.0,
              doc="translation standard deviation of B [m] (paper sigma, eq. (14)) as you know "
                  "it; 0: not stated (with noise.estimate, estimated from the data, starting "
                  "from 0.01). Stated (with noise.kappa), it is compared with the estimate"),
    ParamSpec("noise.kappa", "double", 0.0,
              doc="Langevin concentration of the rotation of B (paper kappa, eq. (16)) as you "
                  "know it; 0: not stated (starting from 125)"),
    ParamSpec("noise.from_reprojection", "bool", False,
              doc="use per-detection sigma/kappa from the PnP reprojection error instead "
                  "(with noise.estimate: scaled by each noise group's estimated factor)"),
    ParamSpec("noise.estimate", "bool", True,
              doc="estimate the noise of each noise group from the residuals (Helmert "
                  "variance components) and solve with it; false: solve with the stated noise"),
    ParamSpec("noise.groups", "string", "camera",
              doc="noise groups of the estimate: camera (one sigma/kappa per camera and kind "
                  "of target: tags, each board type), camera_target (per camera-target edge) "
                  "or global (one for all pairs)"),
    ParamSpec("sync.max_gap_s", "double", 0.1,
              doc="largest pose gap [s] bridged by interpolation at an image stamp"),
    ParamSpec("sync.extrapolation_tolerance_s", "double", 0.01,
              doc="how far [s] an image stamp may lie outside the pose buffer"),
    ParamSpec("sync.pose_buffer_size", "int", 4000, doc="poses kept for lookups"),
    ParamSpec("sync.image_queue_size", "int", 8,
              doc="images waiting for detection per camera; the oldest is dropped (and counted); "
                  "8 hold about a quarter of a second at 30 Hz, the slack a camera needs while a "
                  "worker searches back or the machine hiccups"),
    ParamSpec("sync.detection_threads", "int_or_auto", "auto",
              doc="threads running tag detection (node and bag replay): 'auto' = the cores "
                  "available to the process, at most one per camera; or an integer >= 1"),
    ParamSpec("sync.max_pose_wait_s", "double", 1.0,
              doc="longest wait [s] of an image for the pose at its stamp (it waits as long as "
                  "the pose stream's measured lateness needs, at most this; see "
                  "docs/ros-transport.md)"),
    ParamSpec("sync.max_waiting_mb", "double", 256.0,
              doc="memory [MB] of the images held while they wait for their pose (the node's "
                  "queue; the session's own); beyond it the oldest is given up and counted"),
    ParamSpec("sync.tf_timeout_s", "double", 0.2,
              doc="wait [s] for tf at an image stamp (pose_source.type 'tf')"),
    ParamSpec("sync.at_rest_max_gap_s", "double", 2.0,
              doc="stop-and-go: an image between two pose samples further apart than "
                  "sync.max_gap_s but at most this [s], that agree within sync.at_rest_*, gets "
                  "the pose at rest (an image newer than the newest sample waits this long for "
                  "one after it when the two newest agree); 0 = off"),
    ParamSpec("sync.at_rest_translation_m", "double", 0.0005,
              doc="two pose samples are the same pose at rest when their translations differ "
                  "by at most this [m] ..."),
    ParamSpec("sync.at_rest_rotation_rad", "double", 0.001,
              doc="... and their rotations by at most this [rad]"),
    ParamSpec("sync.estimate_time_offset", "bool", True,
              doc="estimate each camera's time offset to the pose stream (t_pose = t_image + "
                  "offset) from the motion at calibrate (and in the live estimate), apply a "
                  "significant one (beyond 3 std) and report each with its std; needs "
                  "pose_source.type 'topic' (the stream around each pair is recorded)"),
    ParamSpec("sync.time_offset_range_s", "double", 0.1,
              doc="time offsets are searched within +- this [s]"),
    ParamSpec("sync.time_offset_max_std_s", "double", 0.005,
              doc="an estimated time offset with a larger std [s] is reported as not "
                  "determined (too little motion)"),
    ParamSpec("keyframe.min_rotation_rad", "double", 0.05,
              doc="a new pair needs this rotation [rad] from the last kept one (same edge)"),
    ParamSpec("keyframe.min_translation_m", "double", 0.02,
              doc="... or this translation [m]"),
    ParamSpec("keyframe.max_pairs_per_edge", "int", 300, doc="cap on kept pairs per edge"),
    ParamSpec("capture.mode", "string", "continuous",
              doc="'continuous' (every image is a candidate view, kept by the keyframe test), "
                  "'capture' (only the images taken by the ~/capture service) or 'both'"),
    ParamSpec("capture.rest_s", "double", 0.5,
              doc="~/capture takes each camera's next image whose pose has been at rest "
                  "(sync.at_rest_* tolerances, over that camera's images) for this long [s]"),
    ParamSpec("capture.timeout_s", "double", 10.0,
              doc="~/capture answers with what it has after this long [s]"),
    ParamSpec("detection.corner_refinement", "string", "edge",
              doc="corner refinement: 'edge' (sub-pixel edge-line fit, the most accurate "
                  "measured, see benchmarks/perception.md), or cv2.aruco's 'subpix', "
                  "'apriltag', 'contour', 'none'"),
    ParamSpec("detection.chessboard_refinement", "string", "sb",
              doc="chessboard corners: 'sb' as cv2.findChessboardCornersSB finds them (the "
                  "more accurate on real images, benchmarks/real_data.md), or 'subpix': "
                  "polished by cv2.cornerSubPix (more accurate on renders at an angle)"),
    ParamSpec("detection.max_reprojection_rms_px", "double", 1.0,
              doc="reprojection gate, floor [px]: a target whose RMS corner reprojection "
                  "error is at or below this is never rejected for it"),
    ParamSpec("detection.reprojection_gate_factor", "double", 4.0,
              doc="reprojection gate above the floor: reject a target whose corner noise "
                  "exceeds this factor times the median of its camera's (the camera's "
                  "earlier poses and this one): the gate follows what the camera's images "
                  "give, lens model errors included, instead of a fixed pixel count"),
    ParamSpec("detection.min_side_px", "double", 20.0,
              doc="reject a tag whose shortest side is below this [px]"),
    ParamSpec("detection.max_obliquity_deg", "double", 70.0,
              doc="reject a tag seen more obliquely than this [deg] (0 = face-on)"),
    ParamSpec("detection.decimate", "int_or_auto", "auto",
              doc="candidate search on the image shrunk by this factor, corners refined at "
                  "full resolution: 'auto' = max(W, H) // 600 (2 at 1280x1024: tags below "
                  "about 37 px are not found), or an integer >= 1 (1 = full image)"),
    ParamSpec("detection.motion_gate", "bool", True,
              doc="examine only the tags whose pair the keyframe test could keep at the "
                  "image's pose, and skip images where it could keep none"),
    ParamSpec("detection.discovery_step", "double", 0.5,
              doc="motion gate, targets out of view: an image whose pose is within this "
                  "fraction of the keyframe thresholds of its camera's last searched image "
                  "counts only the targets found there, so a target coming into view is found "
                  "within this fraction of a keyframe step, and then looked for in the images "
                  "skipped since the previous search (up to 8 per camera held); 0 = every edge "
                  "counts, also of "
                  "targets out of view (exactly the pairs of examining every image, few images "
                  "skipped)"),
    ParamSpec("solver.mode", "string", "fast", doc="'fast', 'sdp' or 'local'"),
    ParamSpec("solver.min_pairs", "int", 3, doc="edges with fewer pairs are left out"),
    ParamSpec("solver.sdp_backend", "string", "auto",
              doc="the SDP's solver (mode sdp and the fallback of fast): 'structured' (the "
                  "interior-point method on the frame blocks, docs/sdp.md), 'cvxpy' (cvxpy + "
                  "Clarabel) or 'auto' (structured unless Clarabel's chordal decomposition is "
                  "estimated cheaper)"),
    ParamSpec("solver.reject_outliers", "bool", False,
              doc="outlier rejection: per-edge RANSAC on eq. (70) (paper Sec. 9.1), then a "
                  "GNC-TLS robust solve, re-certified on the inlier set"),
    ParamSpec("solver.unobservable_std_m", "double", 1.0,
              doc="a translation direction whose predicted std [m] exceeds this is not "
                  "determined by the data (e.g. motion about one axis): it is fixed by "
                  "priors.* or the default and the result says so"),
    ParamSpec("solver.min_scale", "double", 0.01,
              doc="unknown scale: an estimate at or below this floor is never certified"),
    ParamSpec("solver.refine", "bool", True,
              doc="after the certified solve, refine the frames on the reprojection error of "
                  "the detected corners when the data keep them (docs/refinement.md); the "
                  "refined estimate is published when it lowers the corner residual, stays "
                  "within the uncertainties of the certified one, predicts held-out corners "
                  "no worse and is at least as precise; false = the certified pose-level "
                  "estimate only"),
    ParamSpec("solver.live_period_s", "double", 2.0,
              doc="re-solve in the background ('fast', no SDP fallback) at most this often [s] "
                  "while new pairs arrive, for the running estimate and its convergence "
                  "(node: ~/estimate, /diagnostics; bag: the progress line); 0 = off"),
    ParamSpec("convergence.max_std_translation_m", "double", 0.005,
              doc="the live estimate has converged when every frame's translation std (the "
                  "larger of predicted and a posteriori) is at or below this [m] ..."),
    ParamSpec("convergence.max_std_rotation_deg", "double", 0.25,
              doc="... and every frame's rotation std at or below this [deg]"),
    ParamSpec("priors.frames", "string_array", (),
              doc="frames (camera names or tag frames) with a known translation component, "
                  "parallel to priors.axes and priors.values_m"),
    ParamSpec("priors.axes", "string_array", (),
              doc="'x', 'y' or 'z': the axis of the frame's carrier for each priors.frames entry"),
    ParamSpec("priors.values_m", "double_array", (),
              doc="the known translation components [m] (fix unobservable directions only)"),
    ParamSpec("output.directory", "string", "",
              doc="root of the output directories (one new per calibrate/save_dataset, never "
                  "overwritten); '' = $ROS_HOME/rwhec_ros (~/.ros/rwhec_ros) for the node, "
                  "./rwhec_output for the CLI; relative: under that directory for the node, "
                  "under the current directory for the CLI"),
    ParamSpec("output.frame_suffix", "string", "_calibrated",
              doc="published child frame = <frame><suffix> unless set per camera"),
    ParamSpec("output.publish_tf", "bool", True, doc="publish results on /tf_static"),
    ParamSpec("output.publish_uncertified", "bool", False,
              doc="also publish results the certificate does not prove optimal"),
    ParamSpec("output.publish_unusable", "bool", False,
              doc="also publish frames whose verdict is 'unusable' (default: only usable "
                  "frames go to /tf_static and the launch file)"),
    ParamSpec("verdict.significance", "double", 1e-3,
              doc="p-value below which a chi-square fit test is significant (per-edge tests: "
                  "divided by the number of edges)"),
    ParamSpec("verdict.fit_caution_ratio", "double", 1.5,
              doc="caution when the residuals fit this many times the stated noise (std units: "
                  "estimated sigma / noise.sigma, or the rotation equivalent)"),
    ParamSpec("verdict.fit_unusable_ratio", "double", 3.0,
              doc="unusable when the residuals fit this many times the stated noise"),
    ParamSpec("verdict.edge_ratio", "double", 5.0,
              doc="an edge whose noise is this many times the median edge's is named as an "
                  "outlier (caution) ..."),
    ParamSpec("verdict.edge_min_noise_ratio", "double", 0.5,
              doc="... if its noise also reaches this fraction of the stated noise"),
    ParamSpec("verdict.edge_noisy_ratio", "double", 2.0,
              doc="an edge this many times the median edge's noise and beyond "
                  "verdict.fit_caution_ratio of the stated noise is named too"),
    ParamSpec("verdict.min_edges", "int", 3,
              doc="edges needed to compare an edge with the median edge"),
    ParamSpec("verdict.scale_check", "bool", True,
              doc="known scale: also solve with an unknown scale and check that it is 1 (tag "
                  "sizes, focal lengths, pose units)"),
    ParamSpec("verdict.scale_sigmas", "double", 4.0,
              doc="the scale differs from 1 only beyond this many standard deviations ... "
                  "(from 0.75 of it: a caution that it may)"),
    ParamSpec("verdict.scale_caution", "double", 0.02,
              doc="... and beyond this relative difference: caution (0.02 = 2 %)"),
    ParamSpec("verdict.scale_unusable", "double", 0.05,
              doc="... beyond this one: unusable"),
    ParamSpec("verdict.caution_std_translation_m", "double", 0.06,
              doc="caution when a frame's predicted translation std exceeds this [m]"),
    ParamSpec("verdict.caution_std_rotation_deg", "double", 4.0,
              doc="caution when a frame's predicted rotation std exceeds this [deg]"),
    ParamSpec("verdict.unusable_std_translation_m", "double", 0.1,
              doc="a frame is unusable when its predicted translation std exceeds this [m]"),
    ParamSpec("verdict.unusable_std_rotation_deg", "double", 6.0,
              doc="a frame is unusable when its predicted rotation std exceeds this [deg]"),
    ParamSpec("verdict.caution_scale_rel_std", "double", 0.02,
              doc="unknown scale: caution when the scale's relative std exceeds this"),
    ParamSpec("verdict.unusable_scale_rel_std", "double", 0.1,
              doc="unknown scale: unusable when the scale's relative std exceeds this"),
    ParamSpec("verdict.focal_check", "bool", True,
              doc="with tag corners and intrinsics in the data: check per camera the focal "
                  "length that the corners fit, each image through its own pose"),
    ParamSpec("verdict.focal_sigmas", "double", 4.0,
              doc="a camera's fitted focal length differs from its camera info only beyond "
                  "this many standard deviations ..."),
    ParamSpec("verdict.focal_caution", "double", 0.02,
              doc="... and beyond this relative difference: caution for that camera (0.02 = "
                  "2 %)"),
    ParamSpec("verdict.reprojection_ratio", "double", 5.0,
              doc="with tag corners and intrinsics in the data: a camera whose corners "
                  "reproject through the calibration this many times worse (RMS) than the "
                  "median of the other cameras' ..."),
    ParamSpec("verdict.reprojection_min_px", "double", 2.0,
              doc="... and worse than this [px] is named (caution for that camera)"),
    ParamSpec("verdict.exclude_misfits", "bool", True,
              doc="exclude a target or an edge that does not fit (all its edges far worse "
                  "than the others, an outlier edge, most of its pairs rejected by "
                  "solver.reject_outliers) and solve again without it; the published result "
                  "is that solve, the excluded target is named and not published "
                  "(docs/verdict.md)"),
    ParamSpec("verdict.exclusion_max_rounds", "int", 3,
              doc="exclude at most this many targets or edges, one per re-solve ..."),
    ParamSpec("verdict.exclusion_max_share", "double", 0.34,
              doc="... leaving out at most this share of the pairs (< 1): beyond it the misfit "
                  "is not one target's, and the cameras on it are not calibrated"),
    ParamSpec("verdict.exclusion_rejected_share", "double", 0.5,
              doc="with solver.reject_outliers: a target (or an edge) more than this share of "
                  "whose pairs were rejected does not fit and is excluded (< 1)"),
    ParamSpec("verdict.noise_confidence", "double", 0.95,
              doc="with estimated noise, the precision check uses each frame's std times the "
                  "upper confidence factor of the noise estimate at this level (few pairs: "
                  "wider)"),
    ParamSpec("verdict.noise_group_ratio", "double", 5.0,
              doc="a camera whose estimated noise is this many times the others' median is "
                  "named (caution)"),
    ParamSpec("verdict.lag_check", "bool", True,
              doc="check whether the residuals follow the motion between neighbouring pairs "
                  "(poses out of step with the images, seen without stamps; each edge's pairs "
                  "in recording order)"),
    ParamSpec("verdict.lag_sigmas", "double", 4.0,
              doc="... caution when that lag is beyond this many standard deviations ..."),
    ParamSpec("verdict.lag_shift_std", "double", 1.0,
              doc="... and taking it out moves a frame by at least this many of its std"),
    ParamSpec("verdict.pair_check", "bool", True,
              doc="name a single pair far off its camera's other pairs (beyond "
                  "verdict.significance over all pairs) ..."),
    ParamSpec("verdict.pair_shift_std", "double", 1.0,
              doc="... when leaving it out would move a frame by at least this many of its std"),
    ParamSpec("accuracy.cross_validation_folds", "int", 5,
              doc="k-fold cross-validation over the pairs at calibrate (held-out vs in-sample "
                  "residuals per edge); 0: off"),
    ParamSpec("accuracy.guidance", "bool", True,
              doc="suggest the next motion at calibrate (the one that most reduces the largest "
                  "std)"),
    ParamSpec("check.reference", "string", "",
              doc="bring-up check (~/check): the stored calibration to test the data against: a "
                  "result.yaml, check.yaml, frames.yaml or URDF file, or 'tf' (the frames as tf "
                  "has them now, e.g. robot_state_publisher from the URDF); '' = no reference"),
    ParamSpec("check.tolerance_translation_m", "double", 0.002,
              doc="a camera is consistent when its change is within this [m] (and the rotation "
                  "tolerance) with confidence, moved when beyond it with confidence"),
    ParamSpec("check.tolerance_rotation_deg", "double", 0.2,
              doc="... and this rotation [deg]"),
    ParamSpec("check.false_alarm_rate", "double", 0.01,
              doc="probability of any wrong camera decision (moved / consistent), over the "
                  "cameras (Bonferroni) and over every look of the node"),
    ParamSpec("check.hold", "string", "none",
              doc="what holds the reference while a camera is tested: 'none' (the pose stream "
                  "defines the carriers; targets are tested too) or 'targets' (the targets "
                  "are held at the reference: tags fixed in the room that were not touched)"),
    ParamSpec("check.noise", "string", "data",
              doc="noise of the test: 'data' (per camera from the residuals) or 'stated' "
                  "(noise.sigma / noise.kappa or each pair's own)"),
    ParamSpec("check.tf_frames", "string", "calibrated",
              doc="check.reference 'tf', a frames.yaml or a URDF: look each frame up under its "
                  "published name first ('calibrated': <frame><output.frame_suffix>) or under "
                  "its own frame name first ('sensor')"),
    ParamSpec("check.period_s", "double", 0.0,
              doc="node: also check every this many seconds while new pairs arrive (each a new "
                  "look; /diagnostics shows the answer); 0 = only on ~/check"),
    ParamSpec("ros.image_qos", "string", "sensor_data",
              doc="image/camera_info QoS: 'sensor_data' (best effort) or 'reliable'"),
    ParamSpec("ros.diagnostics_period_s", "double", 1.0, doc="period of /diagnostics [s]"),
    ParamSpec("ros.detections_rate_hz", "double", 2.0,
              doc="rate [Hz] of ~/detections (annotated image of what the calibrator sees, "
                  "published only while subscribed); 0 = off"),
    ParamSpec("ros.image_queue_depth", "int", 5,
              doc="history depth of each image/camera_info subscription: a burst of more "
                  "images than this between two executor turns is dropped by the middleware, "
                  "uncounted"),
)

#: Per-camera ``sync.time_offset.<name>`` (the known delay of a camera's stamps).
TIME_OFFSET_SPEC = ParamSpec(
    "time_offset", "double", 0.0,
    doc="the known time offset [s] of this camera's image stamps to the pose stream: the pose "
        "of an image is looked up at its stamp + this (t_pose = t_image + offset; positive "
        "when the images are stamped early); estimated on top with sync.estimate_time_offset")

CAMERA_SPECS: tuple[ParamSpec, ...] = (
    ParamSpec("image_topic", "string", required=True, doc="sensor_msgs/Image topic"),
    ParamSpec("camera_info_topic", "string", required=True, doc="sensor_msgs/CameraInfo topic"),
    ParamSpec("image_transport", "string", "raw",
              doc="'raw' (sensor_msgs/Image on image_topic) or 'compressed' "
                  "(sensor_msgs/CompressedImage on <image_topic>/compressed, JPEG or PNG)"),
    ParamSpec("frame", "string", "", doc="optical frame name (default: the camera name)"),
    ParamSpec("calibrated_frame", "string", "",
              doc="published child frame (default: <frame><output.frame_suffix>)"),
)

#: Per-target parameters ``targets.<name>.<key>``. Layout keys have no schema default (unset):
#: the default of the target's type applies, and a key of another type is refused by name.
TARGET_SPECS: tuple[ParamSpec, ...] = (
    ParamSpec("type", "string", required=True,
              doc="'aprilgrid' (Kalibr-style grid of AprilTags), 'charuco' (OpenCV ChArUco "
                  "board), 'chessboard', 'circles' (a circle grid with a larger origin "
                  "circle), 'asymmetric_circles' (OpenCV's) or 'tag' (one tag of tags.family); "
                  "see docs/targets.md"),
    ParamSpec("min_corners", "int", None,
              doc="boards: fewest detected corners for a pose (>= 4; default 8, or all corners "
                  "of a smaller board); a partly seen board gives a pose from the corners seen "
                  "(a chessboard only where its corner index is resolved)"),
    ParamSpec("tag_id", "int", None, doc="tag: id in tags.family"),
    ParamSpec("tag_size", "double", None,
              doc="tag, aprilgrid: edge of a tag's black square [m]"),
    ParamSpec("rows", "int", None,
              doc="aprilgrid: rows of tags (Kalibr tagRows); chessboard: inner corners along y; "
                  "circles, asymmetric_circles: rows of circles (asymmetric: odd)"),
    ParamSpec("cols", "int", None,
              doc="aprilgrid: columns of tags (Kalibr tagCols); chessboard: inner corners "
                  "along x (not equal to rows; cols + rows even: a turn-symmetric board, "
                  "each view's turn told by the pose stream); circles, asymmetric_circles: "
                  "circles per row"),
    ParamSpec("spacing", "double", None,
              doc="aprilgrid: gap between tags as a fraction of tag_size (Kalibr tagSpacing; "
                  "default 0.3)"),
    ParamSpec("border_bits", "int", None,
              doc="aprilgrid: black border of each tag in cells (default 2 as Kalibr prints; "
                  "1 for tags printed from the AprilTag images)"),
    ParamSpec("family", "string", None,
              doc="aprilgrid: AprilTag family of the grid (default tag36h11)"),
    ParamSpec("first_id", "int", None,
              doc="aprilgrid: id of the bottom-left tag; charuco: id of marker 0 (default 0)"),
    ParamSpec("squares_x", "int", None, doc="charuco: chessboard squares along x (>= 2)"),
    ParamSpec("squares_y", "int", None, doc="charuco: chessboard squares along y (>= 2)"),
    ParamSpec("square_size", "double", None,
              doc="charuco, chessboard: edge of a chessboard square [m]"),
    ParamSpec("circle_spacing", "double", None,
              doc="circles: centre distance of neighbouring circles [m]; asymmetric_circles: "
                  "OpenCV's square size (half the centre distance in a row) [m]"),
    ParamSpec("origin_circle", "bool", None,
              doc="circles: the bottom-left circle is larger (industrial_calibration's modified "
                  "circle grid); false: a plain symmetric grid (cols != rows), which looks the "
                  "same turned by 180 deg: each view's turn told by the pose stream"),
    ParamSpec("circle_diameter", "double", None,
              doc="circles, asymmetric_circles: printed circle diameter [m] (default: measured "
                  "in each image; it corrects the circle-centre projection bias)"),
    ParamSpec("marker_size", "double", None,
              doc="charuco: edge of a marker's black square [m] (< square_size)"),
    ParamSpec("dictionary", "string", None,
              doc="charuco: ArUco dictionary, e.g. DICT_5X5_100 (default), or an AprilTag "
                  "family"),
    ParamSpec("legacy_pattern", "bool", None,
              doc="charuco: board made by OpenCV < 4.6 with an even number of rows"),
)


def is_valid_name(name: str) -> bool:
    """True for a camera name usable in parameter names (letter, then letters, digits, ``_``)."""
    return bool(_NAME_RE.match(str(name)))


def parameter_specs(camera_names: tuple[str, ...] | list[str] = (),
                    target_names: tuple[str, ...] | list[str] = ()) -> list[ParamSpec]:
    """The full schema with per-camera specs expanded to ``cameras.<name>.<key>`` and
    per-target specs to ``targets.<name>.<key>``."""
    out = list(GLOBAL_SPECS)
    for prefix, names, specs in (("cameras", camera_names, CAMERA_SPECS),
                                 ("targets", target_names, TARGET_SPECS)):
        for name in names:
            for s in specs:
                out.append(ParamSpec(f"{prefix}.{name}.{s.name}", s.kind, s.default, s.required,
                                     s.doc))
    t = TIME_OFFSET_SPEC
    out += [ParamSpec(f"sync.{t.name}.{name}", t.kind, t.default, t.required, t.doc)
            for name in camera_names]
    return out



def global_spec(name: str) -> ParamSpec:
    """The spec of the global parameter ``name`` (``KeyError`` if there is none)."""
    for s in GLOBAL_SPECS:
        if s.name == name:
            return s
    raise KeyError(name)
