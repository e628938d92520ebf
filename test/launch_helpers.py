"""Helpers shared by the tests in this directory (not a test module)."""

import ast

import numpy as np

from rwhec_ros.core.lie import transform_from_quat_xyzw


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
