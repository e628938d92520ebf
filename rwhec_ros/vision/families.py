"""AprilTag families (and the other ``cv2.aruco`` dictionaries) and their marker geometry.

Shared by :mod:`rwhec_ros.vision.detection`, :mod:`rwhec_ros.vision.boards` and
:mod:`rwhec_ros.vision.render`.

Orientation: OpenCV 4.x draws (and decodes) its AprilTag dictionaries turned by 180 degrees
relative to the official AprilTag images (fixed in OpenCV 5, opencv/opencv#28823);
:func:`official_orientation_turned` tells which way the installed OpenCV does it and
:func:`official_marker_bitmap` gives the upright official image. :func:`marker_bitmap` is
OpenCV's drawing (the one the single-tag frame of :mod:`rwhec_ros.vision.detection` refers to).

Geometry (AprilTag convention): a tag of family ``tagNhM`` has ``sqrt(N)`` data bits per side,
surrounded by a one-bit black border (the *black square* whose edge length is the tag *size*)
and, outside it, a one-bit white quiet zone. ``cv2.aruco`` reports the four corners of the black
square.
"""

from __future__ import annotations

import functools

import cv2
import numpy as np

__all__ = [
    "APRILTAG_FAMILIES",
    "ARUCO_DICTIONARIES",
    "aruco_dictionary",
    "marker_cells",
    "marker_bitmap",
    "dictionary_key",
    "get_dictionary",
    "dictionary_size",
    "official_orientation_turned",
    "official_marker_bitmap",
]

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
    """The ``cv2.aruco`` dictionary of an AprilTag family (``"tag36h11"`` or ``"36h11"``) or an
    ArUco dictionary (``"DICT_6X6_250"``): single tags may be either (:func:`dictionary_key`)."""
    return get_dictionary(family)


def marker_cells(family: str) -> int:
    """Number of cells across the black square (data bits + 2 border bits), e.g. 8 for 36h11."""
    return int(aruco_dictionary(family).markerSize) + 2


def marker_bitmap(family: str, tag_id: int, quiet_zone_cells: int = 1) -> np.ndarray:
    """One-pixel-per-cell bitmap of a tag with its white quiet zone.

    Parameters
    ----------
    family : str
        AprilTag family or ArUco dictionary.
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


#: Canonical dictionary name -> ``cv2.aruco`` predefined dictionary id. AprilTag families keep
#: their usual names (``tag36h11``); ArUco ones are OpenCV's (``DICT_5X5_100``).
ARUCO_DICTIONARIES: dict[str, int] = {
    **{
        name: int(getattr(cv2.aruco, name))
        for name in dir(cv2.aruco)
        if name.startswith("DICT_") and "APRILTAG" not in name and name == name.upper()
    },
    **APRILTAG_FAMILIES,
}

# tag36h11 id 0 as printed by the AprilTag project (apriltag-imgs), read row by row from the top
# left of its 6 x 6 data cells, most significant bit first, 1 = white: the code of the AprilTag
# Java library and of Kalibr (its ``t36h11[0]``). Used to find how OpenCV draws AprilTags.
_TAG36H11_ID0_OFFICIAL_ROWS = 0xD5D628584


def dictionary_key(name: str) -> str:
    """Canonical name of a dictionary: ``"tag36h11"`` for AprilTag families (``"36h11"`` and
    ``"DICT_APRILTAG_36h11"`` are accepted), ``"DICT_5X5_100"`` for ArUco ones (``"5x5_100"``
    accepted).

    Raises
    ------
    ValueError
        If the name is no dictionary of the installed OpenCV (the message lists them).
    """
    text = str(name).strip()
    upper = text.upper()
    if upper.startswith("DICT_APRILTAG_"):
        text = "tag" + text[len("DICT_APRILTAG_"):].lower()
    try:
        return _family_key(text)
    except ValueError:
        pass
    key = upper if upper.startswith("DICT_") else "DICT_" + upper
    if key in ARUCO_DICTIONARIES:
        return key
    raise ValueError(f"unknown dictionary {name!r}; known: {sorted(ARUCO_DICTIONARIES)}")


def get_dictionary(name: str) -> cv2.aruco.Dictionary:
    """The ``cv2.aruco.Dictionary`` of a dictionary name (see :func:`dictionary_key`)."""
    return cv2.aruco.getPredefinedDictionary(ARUCO_DICTIONARIES[dictionary_key(name)])


def dictionary_size(name: str) -> int:
    """Number of markers in a dictionary."""
    return int(get_dictionary(name).bytesList.shape[0])


@functools.cache
def official_orientation_turned(name: str) -> bool:
    """True when the installed OpenCV draws the markers of ``name`` turned by 180 degrees
    relative to their official images (AprilTag families in OpenCV 4.x); False for ArUco
    dictionaries (OpenCV's own) and for OpenCV versions drawing AprilTags upright."""
    key = dictionary_key(name)
    if key not in APRILTAG_FAMILIES:
        return False
    d = cv2.aruco.getPredefinedDictionary(APRILTAG_FAMILIES["tag36h11"])
    bits = cv2.aruco.Dictionary_getBitsFromByteList(d.bytesList[0:1], int(d.markerSize))

    def code(b: np.ndarray) -> int:
        return int("".join(str(int(x)) for x in b.reshape(-1)), 2)

    if code(bits) == _TAG36H11_ID0_OFFICIAL_ROWS:
        return False
    if code(np.rot90(bits, 2)) == _TAG36H11_ID0_OFFICIAL_ROWS:
        return True
    raise RuntimeError("cv2.aruco's tag36h11 id 0 matches the official tag in no orientation")


def official_marker_bitmap(name: str, marker_id: int, border_bits: int = 1) -> np.ndarray:
    """One-pixel-per-cell image (0 black, 255 white) of a marker as officially printed, upright.

    Parameters
    ----------
    name : str
        Dictionary (see :func:`dictionary_key`).
    marker_id : int
        Id in the dictionary.
    border_bits : int
        Width of the black border in cells (>= 1).

    Returns
    -------
    ndarray, shape (n, n), uint8
        ``n = markerSize + 2 border_bits``, no quiet zone; row 0 is the top of the marker.
    """
    d = get_dictionary(name)
    count = int(d.bytesList.shape[0])
    if isinstance(marker_id, bool) or int(marker_id) != marker_id or not 0 <= marker_id < count:
        raise ValueError(f"marker_id must be an integer in [0, {count}) for {name}, "
                         f"got {marker_id!r}")
    n = int(d.markerSize) + 2 * int(border_bits)
    img = cv2.aruco.generateImageMarker(d, int(marker_id), n, borderBits=int(border_bits))
    return np.rot90(img, 2).copy() if official_orientation_turned(name) else img
