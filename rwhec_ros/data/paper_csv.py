"""The paper's CSV data layout (``shared/data/paper_real_world/README.md``).

One pair of files per observed edge, ``tag_<j>_cam_<k>_A.csv`` and ``tag_<j>_cam_<k>_B.csv``;
row ``i`` of both forms pair ``i``. Each row: a unit quaternion **w, x, y, z** (scalar first)
then a translation x, y, z in metres. Tags are the X variables (``tag_<j>``), cameras the Y
variables (``cam_<k>``):
``A = T_rig_world``, ``X_j = T_world_tag_j``, ``Y_k = T_rig_cam_k``, ``B = T_cam_k_tag_j``.

The scalar-first order is converted by :func:`rwhec_ros.core.lie.quat_wxyz_to_xyzw` only.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ..core.lie import (
    quat_wxyz_to_xyzw,
    quat_xyzw_to_wxyz,
    transform_from_quat_xyzw,
    transform_to_quat_xyzw,
)
from ..core.problem import Edge, Problem

__all__ = ["read_paper_csv", "write_paper_csv", "read_pose_csv", "PAPER_FILE_RE"]

PAPER_FILE_RE = re.compile(r"^tag_(?P<tag>[^_]+)_cam_(?P<cam>[^_]+)_A\.csv$")

#: Allowed deviation of a stored quaternion's norm from 1 before the row is rejected.
QUAT_NORM_TOL = 1e-3


def read_pose_csv(path: Path) -> np.ndarray:
    """Read one CSV of ``w, x, y, z, tx, ty, tz`` rows into transforms (N, 4, 4).

    Raises ``ValueError`` naming the file and 1-based line for a wrong column count, a
    non-number, a non-finite value, or a quaternion whose norm is off by more than
    ``QUAT_NORM_TOL`` (rows within it are normalised).
    """
    path = Path(path)
    rows = []
    with open(path, encoding="utf-8") as fh:
        for lineno, line in enumerate(fh, start=1):
            text = line.strip()
            if not text or text.startswith("#"):
                continue
            fields = text.split(",")
            if len(fields) != 7:
                raise ValueError(f"{path}:{lineno}: expected 7 comma-separated numbers "
                                 f"(w,x,y,z,tx,ty,tz), got {len(fields)}: {text!r}")
            try:
                vals = [float(f) for f in fields]
            except ValueError:
                raise ValueError(f"{path}:{lineno}: not a number in {text!r}") from None
            if not np.all(np.isfinite(vals)):
                raise ValueError(f"{path}:{lineno}: non-finite value in {text!r}")
            norm = float(np.linalg.norm(vals[:4]))
            if abs(norm - 1.0) > QUAT_NORM_TOL:
                raise ValueError(f"{path}:{lineno}: quaternion norm {norm:.6g} is not 1 "
                                 f"(w,x,y,z = {vals[:4]})")
            rows.append(vals)
    if not rows:
        raise ValueError(f"{path}: no data rows")
    arr = np.asarray(rows)
    return transform_from_quat_xyzw(quat_wxyz_to_xyzw(arr[:, :4]), arr[:, 4:7])


def _sort_key(name: str):
    return (0, int(name)) if name.isdigit() else (1, name)


def read_paper_csv(
    directory: str | Path,
    *,
    sigma: float = 0.1,
    kappa: float = 125.0,
    min_pairs: int = 3,
    unknown_scale: bool = False,
) -> Problem:
    """Load a directory in the paper's layout as a :class:`Problem`.

    Edges with fewer than ``min_pairs`` pairs are skipped (the authors used 3). Every pair gets the
    same ``sigma`` [m] and ``kappa`` (the authors used 0.1 m and 125). Frames are named
    ``tag_<j>`` (X) and ``cam_<k>`` (Y), sorted numerically.
    """
    directory = Path(directory)
    if not directory.is_dir():
        raise ValueError(f"not a directory: {directory}")
    found = []
    for a_path in sorted(directory.iterdir()):
        m = PAPER_FILE_RE.match(a_path.name)
        if not m:
            continue
        b_path = a_path.with_name(a_path.name[:-6] + "_B.csv")
        if not b_path.exists():
            raise ValueError(f"{a_path}: matching B file {b_path.name} is missing")
        found.append((m.group("tag"), m.group("cam"), a_path, b_path))
    if not found:
        raise ValueError(f"{directory}: no files named tag_<j>_cam_<k>_A.csv")
    edges = []
    for tag, cam, a_path, b_path in found:
        A = read_pose_csv(a_path)
        B = read_pose_csv(b_path)
        if A.shape[0] != B.shape[0]:
            raise ValueError(f"{b_path}: {B.shape[0]} rows but {a_path.name} has {A.shape[0]}")
        if A.shape[0] < min_pairs:
            continue
        edges.append(Edge.build(f"tag_{tag}", f"cam_{cam}", A, B, sigma=sigma, kappa=kappa))
    if not edges:
        raise ValueError(f"{directory}: no edge has at least {min_pairs} pairs")
    tags = sorted({e.x[4:] for e in edges}, key=_sort_key)
    cams = sorted({e.y[4:] for e in edges}, key=_sort_key)
    return Problem([f"tag_{t}" for t in tags], [f"cam_{c}" for c in cams], edges,
                   unknown_scale=unknown_scale)


def write_paper_csv(problem: Problem, directory: str | Path) -> list[Path]:
    """Write ``problem`` in the paper's layout; X names ``tag_<j>`` and Y names ``cam_<k>`` are
    used as they are (other names are written as ``tag_<name>``/``cam_<name>``)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    written = []
    for e in problem.edges:
        tag = e.x[4:] if e.x.startswith("tag_") else e.x
        cam = e.y[4:] if e.y.startswith("cam_") else e.y
        for suffix, T in (("A", e.A), ("B", e.B)):
            q, t = transform_to_quat_xyzw(T)
            rows = np.hstack([quat_xyzw_to_wxyz(q), t])
            path = directory / f"tag_{tag}_cam_{cam}_{suffix}.csv"
            np.savetxt(path, rows, delimiter=",", fmt="%.18e")
            written.append(path)
    return written
