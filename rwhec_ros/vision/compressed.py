"""Decoding of ``sensor_msgs/CompressedImage`` to 8-bit grayscale with OpenCV (no cv_bridge).

The message carries ``header``, ``format`` and ``data`` (the bytes of one JPEG, PNG, ... file).
``format`` is free text; the convention is that of ``image_transport``'s ``compressed`` plugin
(``compressed_image_transport``), which writes::

    "<encoding>; <codec> compressed <stored>"

with ``<encoding>`` the original ``sensor_msgs/Image`` encoding, ``<codec>`` ``jpeg`` or ``png``
(``tiff`` in newer releases) and ``<stored>`` the pixel layout inside the file: ``bgr8`` (JPEG) or
``bgr8``/``bgr16`` (PNG) for colour images, ``mono8`` or nothing for mono images, e.g.
``"mono8; jpeg compressed mono8"``, ``"bgr8; jpeg compressed bgr8"``, ``"rgb8; png compressed
bgr8"``, ``"mono16; png compressed "``. Older publishers wrote just ``"jpeg"`` or ``"png"``. A
colour format *without* ``compressed bgr`` marks legacy data whose channels were stored in RGB
order (the plugin's subscriber then swaps them back); this module does the same. Depth images of
``compressed_depth_image_transport`` (``"16UC1; compressedDepth png"``, a private header before
the PNG) are refused with a reason.

Decoding never guesses silently: data that OpenCV cannot decode, a JPEG without its end-of-image
marker (a truncated frame that libjpeg would otherwise fill with grey) and decoded pixel types
other than 8/16-bit with 1, 3 or 4 channels raise ``ValueError`` naming the field and the value,
as :func:`rwhec_ros.vision.image.image_to_gray` does for raw images.

Conversion to gray: mono data is used as is; colour data is converted with ``cv2.cvtColor``
(``BGR2GRAY``: the same weights as the raw ``bgr8`` path), except that a colour JPEG is decoded
straight to its luma channel (``IMREAD_GRAYSCALE``: libjpeg skips the chroma, ~30 % faster, equal
to decode-then-convert up to JPEG rounding). 16-bit data (``mono16`` PNG) is reduced to 8 bit by the
same right shift as the raw ``mono16`` path (``mono16_shift``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from .image import _as_bytes, mono16_to_mono8

__all__ = [
    "CompressedFormat",
    "parse_compressed_format",
    "compressed_to_gray",
    "compressed_image_to_gray",
]

_JPEG_NAMES = ("jpeg", "jpg")
_COLOR_TO_GRAY = {3: cv2.COLOR_BGR2GRAY, 4: cv2.COLOR_BGRA2GRAY}
_RGB_TO_GRAY = {3: cv2.COLOR_RGB2GRAY, 4: cv2.COLOR_RGBA2GRAY}


@dataclass(frozen=True)
class CompressedFormat:
    """The parts of a ``CompressedImage.format`` string.

    Attributes
    ----------
    encoding : str
        Original image encoding (``"mono8"``, ``"bgr8"``, ...); ``""`` when the format names
        only the codec (older publishers).
    codec : str
        ``"jpeg"``, ``"png"``, ``"tiff"``, ... (lower case; ``"jpg"`` reads as ``"jpeg"``);
        ``""`` when not stated.
    rgb_order : bool
        The file holds a colour image with its channels in RGB order (a colour ``encoding``
        without ``compressed bgr``: legacy publishers).
    """

    encoding: str
    codec: str
    rgb_order: bool

    @property
    def is_jpeg(self) -> bool:
        """The codec is JPEG."""
        return self.codec == "jpeg"


def _is_color(encoding: str) -> bool:
    """``sensor_msgs::image_encodings::isColor``: rgb/bgr/rgba/bgra at 8 or 16 bits."""
    return encoding.lower() in {
        f"{order}{bits}" for order in ("rgb", "bgr", "rgba", "bgra") for bits in (8, 16)
    }


def parse_compressed_format(fmt: str) -> CompressedFormat:
    """Split a ``CompressedImage.format`` string (see the module docstring).

    Raises
    ------
    ValueError
        For a ``compressedDepth`` format (depth images are not supported) or a non-string.
    """
    if not isinstance(fmt, str):
        raise ValueError(f"format must be a string, got {type(fmt).__name__}")
    if "compresseddepth" in fmt.lower():
        raise ValueError(
            f"format {fmt!r} is compressed_depth_image_transport's (depth images are not "
            "supported; tag detection needs an intensity image)"
        )
    if ";" not in fmt:
        codec = fmt.strip().lower()
        return CompressedFormat("", "jpeg" if codec in _JPEG_NAMES else codec, False)
    encoding, rest = (part.strip() for part in fmt.split(";", 1))
    words = rest.lower().split()
    codec = words[0] if words else ""
    codec = "jpeg" if codec in _JPEG_NAMES else codec
    rgb_order = _is_color(encoding) and "compressed bgr" not in rest.lower()
    return CompressedFormat(encoding, codec, rgb_order)


def _check_jpeg_complete(buf: np.ndarray) -> None:
    """Raise unless the JPEG data ends with the end-of-image marker ``FF D9`` (trailing zero
    padding allowed): libjpeg decodes a truncated frame, filling the missing rows."""
    nonzero = np.flatnonzero(buf[-4096:])  # padding, if any, is short
    end = buf.size - min(buf.size, 4096) + (int(nonzero[-1]) + 1 if nonzero.size else 0)
    if end < 4 or buf[end - 2] != 0xFF or buf[end - 1] != 0xD9:
        raise ValueError(
            f"data ({buf.size} bytes) does not end with the JPEG end-of-image marker FF D9: "
            "truncated or corrupt"
        )


def compressed_to_gray(
    data: bytes | np.ndarray,
    fmt: str,
    *,
    mono16_shift: int | None = None,
) -> np.ndarray:
    """Decode the ``data`` of a ``sensor_msgs/CompressedImage`` into an 8-bit grayscale image.

    Parameters
    ----------
    data : bytes-like or ndarray
        The compressed file (JPEG, PNG, or another format ``cv2.imdecode`` reads).
    fmt : str
        The message's ``format`` (see the module docstring).
    mono16_shift : int, optional
        Right shift reducing 16-bit data to 8 bit; None picks the smallest shift that fits the
        image's maximum (as :func:`rwhec_ros.vision.image.image_to_gray`).

    Returns
    -------
    ndarray, shape (height, width), uint8
        A new C-contiguous array; the size is the file's (the caller compares it with the
        camera's ``CameraInfo``).

    Raises
    ------
    ValueError
        Naming the field: empty or undecodable ``data``, a truncated JPEG, a depth format, a
        decoded type other than 8/16-bit with 1, 3 or 4 channels, ``mono16_shift`` out of range.
    """
    layout = parse_compressed_format(fmt)
    buf = _as_bytes(data)
    if buf.size == 0:
        raise ValueError("data is empty")
    jpeg = layout.is_jpeg or (buf.size >= 3 and buf[0] == 0xFF and buf[1] == 0xD8)
    if jpeg:
        _check_jpeg_complete(buf)
    # A JPEG in BGR order decodes straight to luma; everything else keeps its channels.
    flag = cv2.IMREAD_GRAYSCALE if jpeg and not layout.rgb_order else cv2.IMREAD_UNCHANGED
    try:
        image = cv2.imdecode(buf, flag)
    except cv2.error as exc:
        raise ValueError(
            f"data ({buf.size} bytes, format {fmt!r}) could not be decoded: {str(exc).strip()}"
        ) from exc
    if image is None or image.size == 0:
        codec = layout.codec or "an image"
        raise ValueError(
            f"data ({buf.size} bytes, format {fmt!r}) could not be decoded as {codec}: "
            "truncated, corrupt or not that format"
        )
    channels = 1 if image.ndim == 2 else int(image.shape[2])
    if image.dtype not in (np.uint8, np.uint16) or channels not in (1, 3, 4):
        raise ValueError(
            f"data of format {fmt!r} decoded to {channels} channel(s) of {image.dtype}; "
            "supported: 8 or 16 bit with 1, 3 or 4 channels"
        )
    if channels > 1:
        table = _RGB_TO_GRAY if layout.rgb_order else _COLOR_TO_GRAY
        image = cv2.cvtColor(image, table[channels])
    if image.dtype == np.uint16:
        return mono16_to_mono8(image, mono16_shift)
    return np.ascontiguousarray(image)


def compressed_image_to_gray(msg: Any, *, mono16_shift: int | None = None) -> np.ndarray:
    """(height, width) uint8 grayscale of a ``sensor_msgs/CompressedImage``-like object.

    Duck-typed: reads ``msg.format`` and ``msg.data`` (``msg.header`` carries the stamp, read by
    the caller as for raw images). See :func:`compressed_to_gray` for the rules and errors.
    """
    return compressed_to_gray(msg.data, str(msg.format), mono16_shift=mono16_shift)
