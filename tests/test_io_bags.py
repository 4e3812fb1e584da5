"""ROS bags as sequences: bags written here with rosbags' own writers, read back pixel-exact.

Covers ROS 1 ``.bag``, ROS 2 sqlite3 and mcap folders and a bare ``.mcap``
file; raw and compressed images, 16UC1 and 32FC1 depth, CameraInfo as
calibration; ``seq import`` / ``seq info``; topic choice; damaged bags.
"""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.cli import main
from tudorvision.io import open_sequence
from tudorvision.io.bags import (BagTopic, bag_topics, camera_from_info, choose_topics, decode_image, parse_topics,
                                 stereo_from_infos)

rosbags = pytest.importorskip("rosbags")
from rosbags.rosbag1 import Writer as Writer1  # noqa: E402
from rosbags.rosbag2 import StoragePlugin  # noqa: E402
from rosbags.rosbag2 import Writer as Writer2  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

W, H, N = 32, 24, 5
T0 = 1_700_000_000          # epoch seconds of the first stamp
DT_NS = 33_333_333          # 30 Hz
K_LEFT = np.array([[400.0, 0, 15.5], [0, 401.0, 11.5], [0, 0, 1]])
BASELINE_M = 0.12


def _images(seed: int, n: int = N):
    rng = np.random.default_rng(seed)
    return [rng.integers(0, 256, (H, W, 3), dtype=np.uint8) for _ in range(n)]


def _depths_mm(seed: int, n: int = N):
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        d = rng.integers(300, 8000, (H, W)).astype(np.uint16)
        d[0, :3] = 0                                   # invalid pixels
        out.append(d)
    return out


class _Bag:
    """Write messages to a ROS 1 bag or a ROS 2 bag (sqlite3 / mcap) with the right serialiser."""

    def __init__(self, path: Path, flavour: str):
        self.ros1 = flavour == "ros1"
        self.ts = get_typestore(Stores.ROS1_NOETIC if self.ros1 else Stores.ROS2_HUMBLE)
        if self.ros1:
            self.w = Writer1(path)
        else:
            plugin = StoragePlugin.MCAP if flavour == "mcap" else StoragePlugin.SQLITE3
            self.w = Writer2(path, version=9, storage_plugin=plugin)
        self.w.open()
        self.conns = {}

    def header(self, t_ns):
        T = self.ts.types
        stamp = T["builtin_interfaces/msg/Time"](sec=t_ns // 10**9, nanosec=t_ns % 10**9)
        if self.ros1:
            return T["std_msgs/msg/Header"](seq=0, stamp=stamp, frame_id="cam")
        return T["std_msgs/msg/Header"](stamp=stamp, frame_id="cam")

    def write(self, topic, msgtype, msg, t_ns):
        if topic not in self.conns:
            self.conns[topic] = self.w.add_connection(topic, msgtype, typestore=self.ts)
        ser = self.ts.serialize_ros1 if self.ros1 else self.ts.serialize_cdr
        self.w.write(self.conns[topic], t_ns, ser(msg, msgtype))

    def image(self, topic, t_ns, img, encoding):
        arr = np.ascontiguousarray(img)
        step = arr.shape[1] * arr.itemsize * (arr.shape[2] if arr.ndim == 3 else 1)
        msg = self.ts.types["sensor_msgs/msg/Image"](
            header=self.header(t_ns), height=arr.shape[0], width=arr.shape[1], encoding=encoding,
            is_bigendian=0, step=step, data=np.frombuffer(arr.tobytes(), np.uint8))
        self.write(topic, "sensor_msgs/msg/Image", msg, t_ns)

    def compressed(self, topic, t_ns, img, ext=".png"):
        ok, buf = cv2.imencode(ext, img)
        msg = self.ts.types["sensor_msgs/msg/CompressedImage"](
            header=self.header(t_ns), format=ext[1:].replace("jpg", "jpeg"), data=buf.ravel())
        self.write(topic, "sensor_msgs/msg/CompressedImage", msg, t_ns)

    def info(self, topic, t_ns, K, *, P=None, R=None, d=(0.1, -0.05, 0.001, 0.002, 0.0)):
        P = np.hstack([K, np.zeros((3, 1))]) if P is None else P
        R = np.eye(3) if R is None else R
        names = ("D", "K", "R", "P") if self.ros1 else ("d", "k", "r", "p")
        fields = dict(zip(names, (np.array(d, float), np.asarray(K, float).ravel(), R.ravel(), P.ravel())))
        roi = self.ts.types["sensor_msgs/msg/RegionOfInterest"](x_offset=0, y_offset=0, height=0, width=0,
                                                                do_rectify=False)
        msg = self.ts.types["sensor_msgs/msg/CameraInfo"](
            header=self.header(t_ns), height=H, width=W, distortion_model="plumb_bob", binning_x=0,
            binning_y=0, roi=roi, **fields)
        self.write(topic, "sensor_msgs/msg/CameraInfo", msg, t_ns)

    def close(self):
        self.w.close()


def _bag_path(tmp_path: Path, flavour: str, name: str) -> Path:
    return tmp_path / (f"{name}.bag" if flavour == "ros1" else name)


def _bare_mcap(folder: Path) -> Path:
    return next(folder.glob("*.mcap"))


def write_stereo_bag(path: Path, flavour: str, *, compressed: bool = False):
    left, right = _images(1), _images(2)
    bag = _Bag(path, flavour)
    P2 = np.hstack([K_LEFT, [[-K_LEFT[0, 0] * BASELINE_M], [0], [0]]])
    for k in range(N):
        t = T0 * 10**9 + k * DT_NS
        if compressed:
            bag.compressed("/stereo/left/image_raw/compressed", t, left[k])
            bag.compressed("/stereo/right/image_raw/compressed", t + 1000, right[k])
        else:
            bag.image("/stereo/left/image_raw", t, left[k][:, :, ::-1], "rgb8")
            bag.image("/stereo/right/image_raw", t + 1000, right[k], "bgr8")
        if k == 0:
            bag.info("/stereo/left/camera_info", t, K_LEFT)
            bag.info("/stereo/right/camera_info", t, K_LEFT, P=P2)
    bag.close()
    return left, right


def write_rgbd_bag(path: Path, flavour: str, *, float_depth: bool = False):
    rgb, depth = _images(3), _depths_mm(4)
    bag = _Bag(path, flavour)
    for k in range(N):
        t = T0 * 10**9 + k * DT_NS
        bag.image("/camera/color/image_raw", t, rgb[k], "bgr8")
        if float_depth:
            d = depth[k].astype(np.float32) / 1000.0
            d[depth[k] == 0] = np.nan
            bag.image("/camera/depth/image_raw", t + 2_000_000, d, "32FC1")
        else:
            bag.image("/camera/depth/image_raw", t + 2_000_000, depth[k], "16UC1")
        if k == 0:
            bag.info("/camera/color/camera_info", t, K_LEFT)
    bag.write("/joint_states_dummy", "std_msgs/msg/String", bag.ts.types["std_msgs/msg/String"](data="x"),
              T0 * 10**9)
    bag.close()
    return rgb, depth


FLAVOURS = ["ros1", "sqlite3", "mcap"]


# ----------------------------------------------------------------------------- reading
@pytest.mark.parametrize("flavour", FLAVOURS)
def test_stereo_bag_reads_pixel_exact_with_stamps_and_calibration(tmp_path, flavour):
    path = _bag_path(tmp_path, flavour, "stereo")
    left, right = write_stereo_bag(path, flavour)
    with open_sequence(path) as seq:
        assert seq.kind == "stereo" and len(seq) == N
        assert seq.layout == {"ros1": "rosbag1", "sqlite3": "rosbag2", "mcap": "rosbag2"}[flavour]
        np.testing.assert_allclose(seq.timestamps, T0 + np.arange(N) * DT_NS * 1e-9, atol=1e-6)
        assert seq.rate_hz == pytest.approx(30.0, rel=1e-3)
        for k, f in enumerate(seq):
            assert np.array_equal(f.left, left[k]) and np.array_equal(f.right, right[k])
        assert np.array_equal(seq[2].left, left[2])          # random access after the end
        cal = seq.calibration
        np.testing.assert_allclose(cal.camera("left").K, K_LEFT)
        np.testing.assert_allclose(cal.camera("left").dist, [0.1, -0.05, 0.001, 0.002, 0.0])
        assert cal.camera("right").size == (W, H)
        np.testing.assert_allclose(cal.stereo.T, [-BASELINE_M, 0, 0], atol=1e-12)
        np.testing.assert_allclose(cal.stereo.R, np.eye(3))


def test_bare_mcap_file_and_compressed_images(tmp_path):
    folder = tmp_path / "comp"
    left, right = write_stereo_bag(folder, "mcap", compressed=True)
    path = _bare_mcap(folder)
    with open_sequence(path) as seq:
        assert seq.layout == "mcap" and seq.kind == "stereo" and len(seq) == N
        assert all(np.array_equal(f.left, left[f.index]) and np.array_equal(f.right, right[f.index]) for f in seq)
