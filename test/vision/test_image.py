"""image_to_gray: every supported ROS encoding, row padding, 16-bit byte order, errors."""

import array

import numpy as np
import pytest

from rwhec_ros.vision.image import SUPPORTED_ENCODINGS, image_to_gray

H, W = 5, 7


def padded_buffer(pixels: np.ndarray, pad: int) -> tuple[bytes, int]:
    """Row-major bytes of (H, W[, C]) pixels with ``pad`` junk bytes after every row."""
    rows = pixels.reshape(pixels.shape[0], -1).view(np.uint8)
    junk = np.full((rows.shape[0], pad), 0xAB, dtype=np.uint8)
    padded = np.concatenate([rows, junk], axis=1)
    return padded.tobytes(), padded.shape[1]


def luminance(rgb: np.ndarray) -> np.ndarray:
    """ITU-R BT.601 luma, the weights OpenCV's RGB2GRAY uses."""
    return 0.299 * rgb[..., 0] + 0.587 * rgb[..., 1] + 0.114 * rgb[..., 2]


@pytest.mark.parametrize("pad", [0, 3])
def test_mono8_with_and_without_padding(pad):
    img = np.random.default_rng(0).integers(0, 256, (H, W), dtype=np.uint8)
    data, step = padded_buffer(img, pad)
    out = image_to_gray(data, W, H, "mono8", step)
    np.testing.assert_array_equal(out, img)
    assert out.dtype == np.uint8 and out.flags.c_contiguous


@pytest.mark.parametrize("encoding", ["rgb8", "bgr8", "rgba8", "bgra8"])
@pytest.mark.parametrize("pad", [0, 5])
def test_colour_encodings(encoding, pad):
    rng = np.random.default_rng(1)
    rgb = rng.integers(0, 256, (H, W, 3), dtype=np.uint8)
    channels = rgb if encoding.startswith("rgb") else rgb[..., ::-1]
    if encoding.endswith("a8"):
        alpha = rng.integers(0, 256, (H, W, 1), dtype=np.uint8)
        channels = np.concatenate([channels, alpha], axis=2)
    data, step = padded_buffer(np.ascontiguousarray(channels), pad)
    out = image_to_gray(data, W, H, encoding, step)
    # 1 grey level: OpenCV's fixed-point luma rounds; alpha and padding must not leak in.
    np.testing.assert_allclose(out, luminance(rgb.astype(float)), atol=1.0)


@pytest.mark.parametrize("big_endian", [0, 1])
@pytest.mark.parametrize("pad", [0, 2])
def test_mono16_byte_order_and_padding(big_endian, pad):
    rng = np.random.default_rng(2)
    values = rng.integers(0, 65536, (H, W)).astype(np.uint16)
    values[0, 0] = 65535  # full 16-bit range: automatic shift is 8
    img = values.astype(">u2" if big_endian else "<u2")
    data, step = padded_buffer(img, pad)
    out = image_to_gray(data, W, H, "mono16", step, is_bigendian=big_endian)
    np.testing.assert_array_equal(out, (values >> 8).astype(np.uint8))


def test_mono16_automatic_shift_keeps_12_bit_contrast():
    values = np.arange(H * W, dtype=np.uint16).reshape(H, W) * 100  # max 3400 < 4096: 12 bit
    out = image_to_gray(values.astype("<u2").tobytes(), W, H, "mono16", 2 * W)
    np.testing.assert_array_equal(out, (values >> 4).astype(np.uint8))
    fixed = image_to_gray(values.astype("<u2").tobytes(), W, H, "mono16", 2 * W, mono16_shift=8)
    np.testing.assert_array_equal(fixed, (values >> 8).astype(np.uint8))
    with pytest.raises(ValueError, match="mono16_shift"):
        image_to_gray(values.tobytes(), W, H, "mono16", 2 * W, mono16_shift=9)


def test_accepts_ndarray_array_and_bytearray_and_never_aliases():
    img = np.random.default_rng(3).integers(0, 256, (H, W), dtype=np.uint8)
    for data in (img, img.reshape(-1), array.array("B", img.tobytes()), bytearray(img.tobytes())):
        out = image_to_gray(data, W, H, "mono8", W)
        np.testing.assert_array_equal(out, img)
    out = image_to_gray(img, W, H, "mono8", W)
    out[0, 0] ^= 0xFF
    assert out[0, 0] != img[0, 0]


def test_extra_trailing_bytes_are_ignored():
    img = np.full((H, W), 9, dtype=np.uint8)
    out = image_to_gray(img.tobytes() + b"\x00" * 10, W, H, "mono8", W)
    np.testing.assert_array_equal(out, img)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(encoding="yuv422"), "encoding"),
        (dict(encoding="16UC1"), "encoding"),
        (dict(step=3 * W - 1, encoding="rgb8"), "step"),
        (dict(step=W - 1), "step"),
        (dict(data=b"\x00" * (W * H - 1)), "data"),
        (dict(width=0), "width"),
        (dict(height=-1), "height"),
        (dict(data=12345), "data"),
    ],
)
def test_errors_name_the_field(kwargs, field):
    args = dict(data=b"\x00" * (3 * W * H), width=W, height=H, encoding="mono8", step=W)
    args.update(kwargs)
    with pytest.raises(ValueError, match=field):
        image_to_gray(**args)


def test_supported_encodings_are_the_documented_ones():
    assert set(SUPPORTED_ENCODINGS) == {"mono8", "mono16", "bgr8", "rgb8", "bgra8", "rgba8"}
