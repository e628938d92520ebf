"""CompressedImage decoding: the image_transport format strings, equality with the raw path,
truncated and corrupt data refused with reasons; rosbags' Jazzy message classes."""

import cv2
import numpy as np
import pytest

from rwhec_ros.core.lie import rotation_distance
from rwhec_ros.vision.compressed import (
    CompressedFormat,
    compressed_image_to_gray,
    compressed_to_gray,
    parse_compressed_format,
)
from rwhec_ros.vision.detection import DetectorConfig, TagDetector
from rwhec_ros.vision.image import image_to_gray
from rwhec_ros.vision.intrinsics import CameraIntrinsics
from rwhec_ros.vision.render import RenderedTag, render_tags

typesys = pytest.importorskip("rosbags.typesys")
TS = typesys.get_typestore(typesys.Stores.ROS2_JAZZY)
MSG = "sensor_msgs/msg/CompressedImage"

CAM = CameraIntrinsics.pinhole(640, 480, 500.0)
SIZE = 0.12


def scene(seed=0):
    """A rendered tag (id 4, 0.7 m, tilted) and its pose ``T_cam_tag``."""
    rvec = np.array([0.3, -0.2, 0.1])
    T = np.eye(4)
    T[:3, :3] = cv2.Rodrigues(rvec)[0] @ np.diag([1.0, -1.0, -1.0])
    T[:3, 3] = [0.03, -0.02, 0.7]
    img = render_tags(
        CAM,
        [RenderedTag(4, T, SIZE)],
        noise_std=2.0,
        blur_sigma=0.6,
        rng=np.random.default_rng(seed),
    )
    return img, T


def colour(gray):
    """A BGR image whose channels differ (so channel order matters for the gray value)."""
    bgr = np.stack([gray // 4, gray, 255 - gray // 2], axis=2)  # B far from R everywhere
    return np.ascontiguousarray(bgr)


def message(data, fmt, stamp=(12, 345)):
    """A real sensor_msgs/msg/CompressedImage, sent through CDR and back (as read from a bag)."""
    t = TS.types
    msg = t[MSG](
        header=t["std_msgs/msg/Header"](
            stamp=t["builtin_interfaces/msg/Time"](sec=stamp[0], nanosec=stamp[1]),
            frame_id="cam0_optical",
        ),
        format=fmt,
        data=np.frombuffer(bytes(data), dtype=np.uint8),
    )
    return TS.deserialize_cdr(TS.serialize_cdr(msg, MSG), MSG)


def encode(ext, img, *params):
    ok, buf = cv2.imencode(ext, img, list(params))
    assert ok
    return buf.tobytes()


@pytest.mark.parametrize(
    "fmt, expected",
    [
        ("jpeg", CompressedFormat("", "jpeg", False)),
        ("PNG", CompressedFormat("", "png", False)),
        ("mono8; jpeg compressed mono8", CompressedFormat("mono8", "jpeg", False)),
        ("mono8; jpeg compressed ", CompressedFormat("mono8", "jpeg", False)),
        ("bgr8; jpeg compressed bgr8", CompressedFormat("bgr8", "jpeg", False)),
        ("rgb8; png compressed bgr8", CompressedFormat("rgb8", "png", False)),
        ("bgr16; png compressed bgr16", CompressedFormat("bgr16", "png", False)),
        ("mono16; png compressed ", CompressedFormat("mono16", "png", False)),
        ("rgb8; jpeg compressed rgb8", CompressedFormat("rgb8", "jpeg", True)),  # legacy
        ("bgr8; tiff compressed ", CompressedFormat("bgr8", "tiff", True)),
    ],
)
def test_format_strings_of_image_transport(fmt, expected):
    assert parse_compressed_format(fmt) == expected


def test_png_is_identical_to_the_raw_path():
    """PNG is lossless: mono8, bgr8 and rgb8 sources (stored as image_transport stores them)
    give exactly the gray image of the raw sensor_msgs/Image path."""
    img, _ = scene()
    h, w = img.shape
    bgr = colour(img)
    rgb = np.ascontiguousarray(bgr[..., ::-1])
    cases = [
        (img, "mono8", "mono8; png compressed ", img),
        (bgr, "bgr8", "bgr8; png compressed bgr8", bgr),
        (rgb, "rgb8", "rgb8; png compressed bgr8", bgr),  # the plugin stores BGR order
        (rgb, "rgb8", "rgb8; png compressed rgb8", rgb),  # legacy: RGB bytes as if BGR
        (bgr, "bgr8", "png", bgr),  # no ';': colour is BGR
    ]
    for raw, encoding, fmt, stored in cases:
        channels = 1 if raw.ndim == 2 else 3
        expected = image_to_gray(raw.tobytes(), w, h, encoding, w * channels)
        got = compressed_image_to_gray(message(encode(".png", stored), fmt))
        assert got.dtype == np.uint8 and got.flags.c_contiguous
        np.testing.assert_array_equal(got, expected, err_msg=fmt)


def test_png_mono16_uses_the_raw_shift_rule():
    rng = np.random.default_rng(1)
    twelve_bit = rng.integers(0, 4096, (48, 64)).astype(np.uint16)
    raw = image_to_gray(twelve_bit.astype("<u2").tobytes(), 64, 48, "mono16", 128)
    data = encode(".png", twelve_bit)
    np.testing.assert_array_equal(compressed_to_gray(data, "mono16; png compressed "), raw)
    np.testing.assert_array_equal(
        compressed_to_gray(data, "mono16; png compressed ", mono16_shift=8),
        (twelve_bit >> 8).astype(np.uint8),
    )
    with pytest.raises(ValueError, match="mono16_shift"):
        compressed_to_gray(data, "mono16; png compressed ", mono16_shift=9)


def test_jpeg_keeps_the_tag_pose():
    """mono8 and bgr8 JPEG at image_transport's default quality 95: the gray image is within
    JPEG error of the original and the detected pose within the detector's noise."""
    img, T = scene()
    detector = TagDetector(DetectorConfig(default_tag_size=SIZE))
    reference = detector.detect(img, CAM).observations[0].T_cam_tag
    bgr = colour(img)
    luma = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
    for source, fmt, expected in (
        (img, "mono8; jpeg compressed mono8", img),
        (bgr, "bgr8; jpeg compressed bgr8", luma),
    ):
        msg = message(encode(".jpg", source, cv2.IMWRITE_JPEG_QUALITY, 95), fmt)
        gray = compressed_image_to_gray(msg)
        assert gray.shape == img.shape and gray.dtype == np.uint8
        # JPEG q95 on 2-grey-level noise: mean error about one grey level (measured 1.2 mono,
        # 0.6 colour).
        assert np.mean(np.abs(gray.astype(int) - expected)) < 2.0
        obs = detector.detect(gray, CAM).observations
        assert [o.tag_id for o in obs] == [4]
        T_est = obs[0].T_cam_tag
        # 0.2 mm / 0.15 deg from the raw image's pose (measured 0.07 mm / 0.05 deg; the raw
        # pose is 0.05 mm / 0.02 deg from the truth for this 81 px tag).
        assert 1000 * np.linalg.norm(T_est[:3, 3] - reference[:3, 3]) < 0.2
        assert np.degrees(rotation_distance(T_est[:3, :3], reference[:3, :3])) < 0.15
        assert 1000 * np.linalg.norm(T_est[:3, 3] - T[:3, 3]) < 0.5


def test_colour_jpeg_in_rgb_order_is_swapped_back():
    """Legacy 'rgb8; jpeg compressed rgb8': the file's channels are RGB; the gray value must
    be that of the true colours (R and B weights differ: 0.299 vs 0.114)."""
    img, _ = scene()
    bgr = colour(img)
    rgb = np.ascontiguousarray(bgr[..., ::-1])
    truth = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY).astype(int)
    data = encode(".jpg", rgb, cv2.IMWRITE_JPEG_QUALITY, 95)
    right = compressed_to_gray(data, "rgb8; jpeg compressed rgb8").astype(int)
    wrong = compressed_to_gray(data, "rgb8; jpeg compressed bgr8").astype(int)
    # JPEG error ~1-2 grey levels; reading the channels the wrong way round is off by
    # (0.299 - 0.114) (R - B), about 30 grey levels here.
    assert np.mean(np.abs(right - truth)) < 3.0
    assert np.mean(np.abs(wrong - truth)) > 20.0


def test_jpeg_with_trailing_padding_is_accepted():
    img, _ = scene()
    data = encode(".jpg", img, cv2.IMWRITE_JPEG_QUALITY, 90)
    padded = compressed_to_gray(data + bytes(16), "jpeg")
    np.testing.assert_array_equal(padded, compressed_to_gray(data, "jpeg"))


@pytest.mark.parametrize(
    "mutate, fmt, match",
    [
        (lambda d: b"", "jpeg", "data is empty"),
        (lambda d: d[: len(d) // 2], "mono8; jpeg compressed mono8", "end-of-image"),
        (lambda d: d[:-2], "mono8; jpeg compressed mono8", "end-of-image"),  # only EOI cut
        (lambda d: d[:-2], "jpeg", "end-of-image"),
        (lambda d: bytes(200) + d[200:], "jpeg", "could not be decoded"),  # header destroyed
        (lambda d: b"not an image at all", "png", "could not be decoded as png"),
        (lambda d: d, "16UC1; compressedDepth png", "compressedDepth"),
    ],
)
def test_bad_jpeg_data_is_refused_with_a_reason(mutate, fmt, match):
    img, _ = scene()
    with pytest.raises(ValueError, match=match):
        compressed_image_to_gray(message(mutate(encode(".jpg", img)), fmt))


def test_truncated_png_and_unsupported_pixel_types_are_refused():
    img, _ = scene()
    png = encode(".png", img)
    with pytest.raises(ValueError, match="could not be decoded as png"):
        compressed_to_gray(png[: len(png) - 20], "mono8; png compressed ")
    depth = encode(".tiff", np.ones((8, 8), np.float32))
    with pytest.raises(ValueError, match="float32"):
        compressed_to_gray(depth, "32FC1; tiff compressed ")
    with pytest.raises(ValueError, match="format must be a string"):
        compressed_to_gray(png, None)


def test_data_types_of_rclpy_and_rosbags():
    """bytes, bytearray, memoryview, array('B') (rclpy's uint8[]) and numpy (rosbags)."""
    import array

    img, _ = scene()
    data = encode(".png", img)
    for buf in (
        data,
        bytearray(data),
        memoryview(data),
        array.array("B", data),
        np.frombuffer(data, np.uint8),
    ):
        np.testing.assert_array_equal(compressed_to_gray(buf, "png"), img)
