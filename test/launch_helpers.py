"""Helpers shared by the tests in this directory (not a test module)."""

import ast
from pathlib import Path

import numpy as np

from rwhec_ros.config import CalibratorConfig, read_parameter_file
from rwhec_ros.core.lie import transform_from_quat_xyzw

DEMO_YAML = Path(__file__).resolve().parents[1] / "config" / "demo.yaml"


def demo_config(tmp: Path, **overrides) -> CalibratorConfig:
    """config/demo.yaml with ``output.directory`` = ``tmp`` and ``overrides`` (flat names)."""
    flat = read_parameter_file(DEMO_YAML)
    flat["output.directory"] = str(tmp)
    flat.update(overrides)
    return CalibratorConfig.from_parameters(flat)


def launch_transforms(text: str) -> dict[str, tuple[str, np.ndarray]]:
    """child -> (parent, T_parent_child) parsed from a generated static-transform launch file."""
    out = {}
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.keyword) and node.arg == "arguments":
            args = ast.literal_eval(node.value)
            kv = dict(zip(args[::2], args[1::2], strict=True))
            q = [float(kv[k]) for k in ("--qx", "--qy", "--qz", "--qw")]
            t = [float(kv[k]) for k in ("--x", "--y", "--z")]
            out[kv["--child-frame-id"]] = (kv["--frame-id"], transform_from_quat_xyzw(q, t))
    return out
