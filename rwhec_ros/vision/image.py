"""Conversion of raw ``sensor_msgs/Image`` buffers to 8-bit grayscale (no cv_bridge).

The fields mirror the message: ``data`` (row-major bytes, each row ``step`` bytes long, possibly
padded), ``width``, ``height``, ``encoding``, ``step`` and ``is_bigendian`` (only relevant for
16-bit encodings).
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np

__all__ = ["SUPPORTED_ENCODINGS", "image_to_gray", "mono16_to_mono8"]

#: ROS encoding -> (channels, bytes per channel, cv2 colour conversion or None).
SUPPORTED_ENCODINGS: dict[str, tuple[int, int, int | None]] = {
    "mono8": (1, 1, None),
    "mono16": (1, 2, None),
    "bgr8": (3, 1, cv2.COLOR_BGR2GRAY),
    "rgb8": (3, 1, cv2.COLOR_RGB2GRAY),
    "bgra8": (4, 1, cv2.COLOR_BGRA2GRAY),
    "rgba8": (4, 1, cv2.COLOR_RGBA2GRAY),
}


def _as_bytes(data: Any) -> np.ndarray:
    """Flat uint8 view of a bytes-like object or array (no copy when possible)."""
    if isinstance(data, np.ndarray):
        return np.ascontiguousarray(data).reshape(-1).view(np.uint8)
    try:
        return np.frombuffer(memoryview(data), dtype=np.uint8)
    except TypeError as exc:
        raise ValueError(
            f"data must be bytes-like or an ndarray, got {type(data).__name__}"
        ) from exc


def _positive_int(name: str, value: Any) -> int:
    if isinstance(value, bool) or int(value) != value or int(value) <= 0:
        raise ValueError(f"{name} must be a positive integer, got {value!r}")
    return int(value)


def mono16_to_mono8(mono: np.ndarray, shift: int | None = None) -> np.ndarray:
    """Reduce a 16-bit image to 8 bits by a right shift (values above 255 saturate).

    Parameters
    ----------
    mono : ndarray, shape (H, W), uint16
    shift : int, optional
        ``None`` picks the smallest shift that fits the image's maximum into 8 bits (so 10/12-bit
        sensors packed into 16 bit keep their contrast; full-range 16 bit gets 8); else an
        integer in ``0..8``.

    Returns
    -------
    ndarray, shape (H, W), uint8

    Raises
    ------
    ValueError
        If ``shift`` is not None or an integer in ``0..8``.
    """
    if shift is None:
        shift = max(0, int(mono.max()).bit_length() - 8)
    elif isinstance(shift, bool) or int(shift) != shift or not (0 <= int(shift) <= 8):
        raise ValueError(f"mono16_shift must be an integer in 0..8, got {shift!r}")
    return np.minimum(mono >> int(shift), 255).astype(np.uint8)


def image_to_gray(
    data: bytes | np.ndarray,
    width: int,
    height: int,
    encoding: str,
    step: int,
    is_bigendian: int = 0,
    *,
    mono16_shift: int | None = None,
) -> np.ndarray:
    """Decode a raw ROS image buffer into an 8-bit grayscale image.

    Parameters
    ----------
    data : bytes-like or ndarray
        The message's ``data``: at least ``step * height`` bytes (extra bytes are ignored).
    width, height : int
        Image size in pixels.
    encoding : str
        One of ``mono8, mono16, bgr8, rgb8, bgra8, rgba8``.
    step : int
        Row length in bytes, ``>= width * bytes_per_pixel`` (larger when rows are padded).
    is_bigendian : int
        Byte order of ``mono16`` samples (0 little-endian, non-zero big-endian).
    mono16_shift : int, optional
        ``mono16`` is reduced to 8 bit by a right shift. ``None`` (default) picks the smallest
        shift that fits the image's maximum into 8 bits (so 10/12-bit sensors packed into 16 bit
        keep their contrast; a 16-bit full-range image gets a shift of 8); an explicit value
        in ``0..8`` fixes it (values above 255 after shifting saturate).

    Returns
    -------
    ndarray, shape (height, width), uint8
        A new C-contiguous array (never a view of ``data``).

    Raises
    ------
    ValueError
        Naming the field: unknown ``encoding``; non-positive ``width``/``height``; ``step`` smaller
        than a row; ``data`` shorter than ``step * height``; ``mono16_shift`` out of range.
    """
    width = _positive_int("width", width)
    height = _positive_int("height", height)
    if encoding not in SUPPORTED_ENCODINGS:
        raise ValueError(f"encoding must be one of {sorted(SUPPORTED_ENCODINGS)}, got {encoding!r}")
    channels, depth, conversion = SUPPORTED_ENCODINGS[encoding]
    row_bytes = width * channels * depth
    step = _positive_int("step", step)
    if step < row_bytes:
        raise ValueError(
            f"step must be >= width * bytes_per_pixel = {row_bytes} for {encoding!r} at width "
            f"{width}, got {step}"
        )
    buf = _as_bytes(data)
    needed = step * height
    if buf.size < needed:
        raise ValueError(f"data must hold step * height = {needed} bytes, got {buf.size}")
    rows = buf[:needed].reshape(height, step)[:, :row_bytes]

    if depth == 2:
        dtype = np.dtype(">u2") if is_bigendian else np.dtype("<u2")
        mono = np.ascontiguousarray(rows).view(dtype).reshape(height, width).astype(np.uint16)
        return mono16_to_mono8(mono, mono16_shift)

    pixels = rows.reshape(height, width, channels) if channels > 1 else rows
    if conversion is None:
        return np.array(pixels, dtype=np.uint8, order="C")
    return cv2.cvtColor(np.ascontiguousarray(pixels), conversion)
