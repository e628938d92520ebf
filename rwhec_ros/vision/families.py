"""AprilTag families available through ``cv2.aruco`` and their marker geometry.

Shared by :mod:`rwhec_ros.vision.detection` and :mod:`rwhec_ros.vision.render`.

Geometry (AprilTag convention): a tag of family ``tagNhM`` has ``sqrt(N)`` data bits per side,
surrounded by a one-bit black border (the *black square* whose edge length is the tag *size*)
and, outside it, a one-bit white quiet zone. ``cv2.aruco`` reports the four corners of the black
square.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["APRILTAG_FAMILIES", "aruco_dictionary", "marker_cells", "marker_bitmap"]

#: AprilTag family name -> ``cv2.aruco`` predefined dictionary id.
APRILTAG_FAMILIES: dict[str, int] = {
    "tag16h5": cv2.aruco.DICT_APRILTAG_16h5,
    "tag25h9": cv2.aruco.DICT_APRILTAG_25h9,
    "tag36h10": cv2.aruco.DICT_APRILTAG_36h10,
    "tag36h11": cv2.aruco.DICT_APRILTAG_36h11,
}


def _family_key(family: str) -> str:
    key = str(family).strip().lower()
    if not key.startswith("tag"):
        key = "tag" + key
    if key not in APRILTAG_FAMILIES:
        raise ValueError(f"family must be one of {sorted(APRILTAG_FAMILIES)}, got {family!r}")
    return key


def aruco_dictionary(family: str) -> cv2.aruco.Dictionary:
    """The ``cv2.aruco`` dictionary of an AprilTag family (``"tag36h11"`` or ``"36h11"``)."""
    return cv2.aruco.getPredefinedDictionary(APRILTAG_FAMILIES[_family_key(family)])


def marker_cells(family: str) -> int:
    """Number of cells across the black square (data bits + 2 border bits), e.g. 8 for 36h11."""
    return int(aruco_dictionary(family).markerSize) + 2


def marker_bitmap(family: str, tag_id: int, quiet_zone_cells: int = 1) -> np.ndarray:
    """One-pixel-per-cell bitmap of a tag with its white quiet zone.

    Parameters
    ----------
    family : str
        AprilTag family.
    tag_id : int
        Marker id, ``0 <= tag_id <`` number of markers of the family.
    quiet_zone_cells : int
        Width of the white border around the black square, in cells (>= 0).

    Returns
    -------
    ndarray, shape (n, n), uint8
        ``n = marker_cells(family) + 2 quiet_zone_cells``; 0 black, 255 white; row 0 is the top
        of the tag (tag ``+y``), column 0 its left side (tag ``-x``).
    """
    dictionary = aruco_dictionary(family)
    count = int(dictionary.bytesList.shape[0])
    if isinstance(tag_id, bool) or int(tag_id) != tag_id or not 0 <= int(tag_id) < count:
        raise ValueError(f"tag_id must be an integer in [0, {count}) for {family}, got {tag_id!r}")
    if int(quiet_zone_cells) != quiet_zone_cells or quiet_zone_cells < 0:
        raise ValueError(
            f"quiet_zone_cells must be a non-negative integer, got {quiet_zone_cells!r}"
        )
    cells = int(dictionary.markerSize) + 2
    marker = cv2.aruco.generateImageMarker(dictionary, int(tag_id), cells, borderBits=1)
    q = int(quiet_zone_cells)
    return cv2.copyMakeBorder(marker, q, q, q, q, cv2.BORDER_CONSTANT, value=255)
