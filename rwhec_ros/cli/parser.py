"""The argument parser of ``rwhec-calibrate``: one set of shared options, one help style.

Every solving subcommand (``csv``, ``bag``, ``samples``, ``poses``, ``dataset``, ``demo``) takes
the same options with the same meaning: ``-o/--output DIR``, ``--force``, ``--config FILE``
(``--node-name``), ``--mode``, ``--min-pairs``, ``--robust``, ``--prior``, ``--folds``,
``--no-refine``, ``--no-guidance``, ``--report`` and ``-q/--quiet``; ``report`` takes ``-o`` and
``--force``. Help texts end with ``(default: ...)``; a default that comes from the configuration
reads "the configuration's <parameter>, else <value>".
"""

from __future__ import annotations

import argparse
from pathlib import Path

from .. import __version__
from .check import add_check_parser
from .common import DEFAULT_OUTPUT, MODES, PROG, SDP_BACKENDS

__all__ = ["build_parser"]

_OUTPUT_HELP = (
    "directory that receives result.yaml, static_transforms.launch.py, "
    "calibration.urdf.xacro, frames.yaml, dataset.yaml (and dataset.npz for a large data set) "
    "and (with --report) report.png/.html; existing files are refused unless --force "
    "(default: a new "
    "calibration_<UTC stamp> directory under the configuration's output.directory, else "
    f"{DEFAULT_OUTPUT}/)"
)


def _add_output(p: argparse.ArgumentParser, help_text: str = _OUTPUT_HELP) -> None:
    p.add_argument("-o", "--output", metavar="DIR", type=Path, default=None, help=help_text)
    p.add_argument("--force", action="store_true",
                   help="overwrite existing files in the output directory (default: refuse)")


def _add_config(p: argparse.ArgumentParser, help_text: str, *, required: bool = False) -> None:
    p.add_argument("--config", type=Path, metavar="FILE", required=required, default=None,
                   help=help_text)
    p.add_argument("--node-name", metavar="NAME", default=None,
                   help="the node whose sections of the configuration file apply, by ROS's rule "
                        "('/**', '/**/NAME', '/NAME'); a fully qualified /NS/NAME gives the "
                        "namespace (default: the file's only section, else calibrator)")


def _add_solver(p: argparse.ArgumentParser) -> None:
    p.add_argument("--mode", choices=MODES, default=None,
                   help="solver mode (default: the configuration's solver.mode, else fast)")
    p.add_argument("--sdp-backend", choices=SDP_BACKENDS, default=None,
                   help="the SDP's solver (mode sdp, and fast when its certificate is "
                        "inconclusive): structured, cvxpy (cvxpy + Clarabel) or auto (default: "
                        "the configuration's solver.sdp_backend, else auto)")
    p.add_argument("--min-pairs", type=int, default=None, metavar="N",
                   help="leave out edges with fewer pairs (default: the configuration's "
                        "solver.min_pairs, else 3)")
    p.add_argument("--robust", action="store_true",
                   help="reject outliers first: per-edge RANSAC on eq. (70), then GNC-TLS "
                        "(default: the configuration's solver.reject_outliers, else off)")
    p.add_argument("--prior", action="append", default=None, metavar="FRAME.AXIS=VALUE",
                   help="a known translation component [m] of a frame in its carrier, e.g. "
                        "cam0.z=0.45 (repeatable); fixes a translation the data do not "
                        "determine, such as heights on a ground robot (default: the "
                        "configuration's priors.*, else none)")
    p.add_argument("--folds", type=int, default=None, metavar="K",
                   help="k-fold cross-validation over the pairs, per edge held-out vs in-sample "
                        "residuals; 0: off (default: the configuration's "
                        "accuracy.cross_validation_folds, else 5)")
    p.add_argument("--no-refine", action="store_true",
                   help="publish the certified pose-level estimate without the corner-level "
                        "refinement (default: the configuration's solver.refine, else on)")
    p.add_argument("--no-guidance", action="store_true",
                   help="do not compute the next-motion guidance (default: the configuration's "
                        "accuracy.guidance, else on)")
    p.add_argument("--no-noise-estimate", action="store_true",
                   help="weight the pairs with the stated noise (--sigma/--kappa, noise.*) "
                        "instead of the noise estimated from the data per camera (default: the "
                        "configuration's noise.estimate, else estimated)")
    p.add_argument("--noise-groups", choices=("camera", "camera_target", "global"),
                   default=None,
                   help="noise groups of the estimate: one sigma/kappa per camera, per "
                        "camera-target edge or for all pairs (default: the configuration's "
                        "noise.groups, else camera)")
    p.add_argument("--report", action="store_true",
                   help="also write report.png and report.html (default: off)")
    p.add_argument("-q", "--quiet", action="store_true",
                   help="no progress output on stderr (default: off)")


def _add_carriers(p: argparse.ArgumentParser, *, stored: bool = False) -> None:
    also = ", else the data set's carrier of each frame" if stored else ""
    p.add_argument("--camera-carrier", default=None, metavar="FRAME",
                   help="frame the cameras (Y) are published in (default: the configuration's "
                        f"camera_carrier.frame{also}, else rig)")
    p.add_argument("--tag-carrier", default=None, metavar="FRAME",
                   help="frame the tags (X) are published in (default: the configuration's "
                        f"tag_carrier.frame{also}, else world)")


def _add_mount(p: argparse.ArgumentParser, default: str) -> None:
    group = p.add_mutually_exclusive_group()
    group.add_argument("--eye-in-hand", action="store_true",
                       help="the cameras ride on the robot's flange (the pose's child frame), "
                            f"the target is fixed (default: {default})")
    group.add_argument("--eye-to-hand", action="store_true",
                       help="the cameras are fixed (in the pose's parent frame), the target "
                            f"rides on the flange (default: {default})")


def _add_unknown_scale(p: argparse.ArgumentParser) -> None:
    p.add_argument("--unknown-scale", action="store_true",
                   help="estimate a common scale of the camera-target translations, paper "
                        "Problem 3: for target sizes or intrinsics not known to the per cent "
                        "(default: the configuration's tags.unknown_scale, else off)")


def _add_detections(p: argparse.ArgumentParser) -> None:
    p.add_argument("--detections", type=Path, default=None, metavar="DIR",
                   help="write every image searched, with what was detected drawn on it (as the "
                        "node's ~/detections: green kept, orange refused with the reason), into "
                        "DIR as <camera>_<view>_<image>.jpg (samples) or <camera>_<stamp "
                        "ns>.jpg (bag) (default: none)")


def _add_solving(sub, name: str, help_text: str, positional: tuple[str, str, str] | None,
                 config_help: str, *, config_required: bool = False) -> argparse.ArgumentParser:
    """A solving subcommand: its positional argument ``(dest, metavar, help)`` and the shared
    options."""
    p = sub.add_parser(name, help=help_text)
    if positional is not None:
        dest, metavar, text = positional
        p.add_argument(dest, metavar=metavar, type=Path, help=text)
    _add_output(p)
    _add_config(p, config_help, required=config_required)
    _add_solver(p)
    return p


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``rwhec-calibrate`` (subcommands csv, bag, samples, poses, dataset,
    demo, report)."""
    parser = argparse.ArgumentParser(
        prog=PROG,
        description="Certifiably globally optimal robot-world/hand-eye calibration "
                    "(A_i X_j = Y_k B_i) without ROS.",
        epilog="The first line printed is the verdict: GOOD, CAUTION or UNUSABLE, with the "
               "reason. Exit codes: 0 usable result (good or caution), 2 bad input or output, "
               "3 no solution, 4 result unusable (written, do not use it), 5 check: a camera "
               "moved, 6 check: not enough data yet, 130 interrupted (Ctrl-C), 143 terminated "
               "(SIGTERM), 141 output pipe closed (e.g. | head); the pairs gathered are kept in "
               "dataset.yaml however a run ends.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    p = _add_solving(sub, "csv", "the paper's CSV layout (tag_<j>_cam_<k>_A.csv / _B.csv)",
                     ("directory", "DIR", "directory of tag_<j>_cam_<k>_A.csv / _B.csv files"),
                     "take the noise, carriers, scale, solver and output settings from a node "
                     "parameter file (default: none)")
    p.add_argument("--sigma", type=float, default=None,
                   help="translation std of B [m] as you know it: a check of the estimate "
                        "and the start of it (default: the configuration's noise.sigma, else "
                        "not stated: estimated from the data; the authors stated 0.1)")
    p.add_argument("--kappa", type=float, default=None,
                   help="Langevin concentration of the B rotations as you know it (default: "
                        "the configuration's noise.kappa, else not stated: estimated; the "
                        "authors stated 125)")
    p.add_argument("--unknown-scale", action="store_true",
                   help="estimate a common scale of the B translations, paper Problem 3 "
                        "(default: the configuration's tags.unknown_scale, else off)")
    _add_carriers(p)

    p = _add_solving(sub, "bag", "a rosbag2 recording (sqlite3 or mcap) with the node's config",
                     ("bag", "BAG", "rosbag2 directory (sqlite3 or mcap)"),
                     "the node's parameter file, e.g. config/demo.yaml (required)",
                     config_required=True)
    _add_unknown_scale(p)
    _add_detections(p)

    p = _add_solving(sub, "samples", "a folder of stop-and-go views: an image per camera and "
                     "the robot pose per view (our manifest samples.yaml, industrial_calibration's "
                     "cal_data.yaml, camera_calibration_toolkit's N.jpg + N.json)",
                     ("path", "DIR", "the folder (or the manifest file) of the views"),
                     "a node parameter file, full (its cameras, carriers and targets replace "
                     "the data's) or partial (e.g. noise, keyframe, solver), on top of the "
                     "settings the data give (default: none)")
    _add_mount(p, "the data's mount: the manifest's mount or camera_carrier, "
                  "industrial_calibration's static_camera; else the configuration's carriers")
    p.add_argument("--intrinsics", action="append", default=None, metavar="[CAMERA=]FILE",
                   help="intrinsics of a camera: a ROS camera_calibration YAML or an OpenCV "
                        "FileStorage YAML/XML; repeatable, CAMERA= with several cameras "
                        "(default: the data's own)")
    p.add_argument("--layout", default="auto",
                   choices=("auto", "manifest", "industrial_calibration",
                            "camera_calibration_toolkit"),
                   help="how the folder is laid out (default: %(default)s, from the files "
                        "found)")
    _add_unknown_scale(p)
    _add_detections(p)

    p = _add_solving(sub, "poses", "a pose list: robot poses and target-in-camera poses "
                     "(OpenCV's gripper2base and target2cam), CSV or YAML",
                     ("file", "FILE", "the pose list (.csv, or .yaml/.yml)"),
                     "take the noise, solver and output settings from a node parameter file "
                     "(default: none)")
    _add_mount(p, "the YAML file's mount, else the configuration's carriers")
    p.add_argument("--sigma", type=float, default=None,
                   help="translation std of B [m] as you know it: a check of the estimate "
                        "and the start of it (default: the configuration's noise.sigma, else "
                        "not stated: estimated from the data)")
    p.add_argument("--kappa", type=float, default=None,
                   help="Langevin concentration of the B rotations as you know it (default: "
                        "the configuration's noise.kappa, else not stated: estimated)")
    p.add_argument("--unknown-scale", action="store_true",
                   help="estimate a common scale of the B translations, paper Problem 3 "
                        "(default: the configuration's tags.unknown_scale, else off)")

    p = _add_solving(sub, "dataset", "a data set saved by the session or the CLI",
                     ("file", "FILE", "dataset.yaml written by the node or the CLI"),
                     "a node parameter file to use instead of the configuration stored in the "
                     "data set (default: the stored one, if any)")
    _add_carriers(p, stored=True)

    p = _add_solving(sub, "demo", "simulated mobile rig: render, detect, sync, solve, compare",
                     None, "calibrator settings (noise, sync, keyframe, detection, solver, "
                     "output) from a node parameter file; the rig's frames, topics and tags stay "
                     "the simulation's (default: the values of config/demo.yaml)")
    p.add_argument("--cameras", type=int, default=3,
                   help="cameras on the rig (default: %(default)s)")
    p.add_argument("--tags", type=int, default=6, help="tags in the room (default: %(default)s)")
    p.add_argument("--board", action="append", default=[], metavar="KIND",
                   choices=("aprilgrid", "charuco", "chessboard", "circles",
                            "asymmetric_circles"),
                   help="put a board of this kind (aprilgrid: 3 x 3 tags of 7 cm; charuco: "
                        "5 x 4 squares of 5 cm; chessboard: 8 x 5 inner corners, 3 cm squares; "
                        "circles: 6 x 5 with an origin circle; asymmetric_circles: 4 x 7) in "
                        "place of the next tag, from tag 0 on; repeatable, e.g. --board "
                        "aprilgrid --board chessboard (default: none)")
    p.add_argument("--seconds", type=float, default=24.0,
                   help="simulated duration [s] (default: %(default)s, one full yaw turn)")
    p.add_argument("--rate", type=float, default=5.0, help="image rate [Hz] (default: %(default)s)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default: %(default)s)")
    p.add_argument("--bag", type=Path, default=None, metavar="DIR",
                   help="write the simulated recording as a rosbag2 directory DIR instead of "
                        "calibrating (then: rwhec-calibrate bag DIR --config "
                        "config/demo.yaml); an existing DIR is refused unless --force "
                        "(default: calibrate)")
    p.add_argument("--storage", choices=("sqlite3", "mcap"), default="sqlite3",
                   help="storage of --bag (default: %(default)s)")

    add_check_parser(sub, _add_output, _add_config)

    p = sub.add_parser("report", help="report PNG + HTML of a written result")
    p.add_argument("result", metavar="RESULT.yaml", type=Path,
                   help="result.yaml written by the node or the CLI")
    p.add_argument("--dataset", type=Path, default=None, metavar="FILE",
                   help="the data set that was solved (default: the one beside the result)")
    _add_output(p, "directory that receives report.png and report.html; existing files are "
                   "refused unless --force (default: the result's directory)")
    return parser
