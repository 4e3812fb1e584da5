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
import tudorvision.cli
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


@pytest.fixture(autouse=True)
def _only_needed_commands(monkeypatch):
    """Build the real CLI with the commands these tests run (others may be mid-development)."""
    monkeypatch.setattr(tudorvision.cli, "COMMAND_MODULES", ("tudorvision.cli.seq", "tudorvision.cli.stereo"))


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


@pytest.mark.parametrize("flavour,float_depth", [("ros1", False), ("sqlite3", True), ("mcap", False)])
def test_rgbd_bag_depth_in_mm_and_metres(tmp_path, flavour, float_depth):
    path = _bag_path(tmp_path, flavour, "rgbd")
    rgb, depth = write_rgbd_bag(path, flavour, float_depth=float_depth)
    with open_sequence(path) as seq:
        assert seq.kind == "rgbd" and len(seq) == N and seq.depth_scale == 1000.0
        for k, f in enumerate(seq):
            assert np.array_equal(f.rgb, rgb[k])
            assert f.depth_raw.dtype == np.uint16 and np.array_equal(f.depth_raw, depth[k])
            assert np.isnan(f.depth_m[0, 0]) and f.depth_m[5, 5] == pytest.approx(depth[k][5, 5] / 1000.0)
            assert f.t_depth - f.t == pytest.approx(0.002, abs=1e-6)
        assert seq.calibration.camera("rgbd").K[0, 0] == 400.0


@pytest.mark.parametrize("flavour", FLAVOURS)
def test_seq_import_round_trip(tmp_path, flavour, capsys):
    src = _bag_path(tmp_path, flavour, "stereo")
    left, right = write_stereo_bag(src, flavour)
    out = tmp_path / "imported"
    assert main(["seq", "import", str(src), "--out", str(out)]) == 0
    assert "wrote" in capsys.readouterr().out
    assert not (out / "INCOMPLETE").exists()
    with open_sequence(out) as seq:                    # our own layout now, read strictly
        assert seq.layout == "tudorvision" and seq.kind == "stereo" and len(seq) == N
        np.testing.assert_allclose(seq.timestamps, T0 + np.arange(N) * DT_NS * 1e-9, atol=1e-6)
        for k, f in enumerate(seq):
            assert np.array_equal(f.left, left[k]) and np.array_equal(f.right, right[k])
        cal = seq.calibration
        np.testing.assert_allclose(cal.camera("left").K, K_LEFT)
        np.testing.assert_allclose(cal.stereo.T, [-BASELINE_M, 0, 0], atol=1e-9)
        assert seq.meta["source_topics"]["left"] == "/stereo/left/image_raw"
    assert main(["seq", "check", str(out)]) == 0


def test_seq_import_rgbd_keeps_raw_depth(tmp_path):
    src = _bag_path(tmp_path, "mcap", "rgbd")
    rgb, depth = write_rgbd_bag(src, "mcap")
    out = tmp_path / "imported"
    assert main(["seq", "import", str(src), "--out", str(out)]) == 0
    with open_sequence(out) as seq:
        assert seq.depth_scale == 1000.0
        assert all(np.array_equal(f.depth_raw, depth[f.index]) and np.array_equal(f.rgb, rgb[f.index]) for f in seq)
        assert seq.calibration.camera("rgbd").size == (W, H)


def test_seq_info_lists_topics_types_and_counts(tmp_path, capsys):
    src = _bag_path(tmp_path, "ros1", "rgbd")
    write_rgbd_bag(src, "ros1")
    assert main(["seq", "info", str(src)]) == 0
    out = capsys.readouterr().out
    rows = {ln.split()[0]: ln.split()[1:] for ln in out.splitlines() if ln.startswith("/")}
    assert rows["/camera/color/image_raw"] == ["sensor_msgs/msg/Image", "5"]
    assert rows["/camera/color/camera_info"] == ["sensor_msgs/msg/CameraInfo", "1"]
    assert rows["/joint_states_dummy"] == ["std_msgs/msg/String", "1"]
    assert "kind         rgbd" in out and "frames       5 (5 readable)" in out


# ----------------------------------------------------------------------------- choosing topics
def _three_camera_bag(path):
    bag = _Bag(path, "ros1")
    imgs = _images(7, 3)
    for k in range(3):
        t = T0 * 10**9 + k * DT_NS
        for cam in ("cam_a", "cam_b", "cam_c"):
            bag.image(f"/{cam}/image", t, imgs[k], "bgr8")
    bag.close()
    return imgs


def test_ambiguous_topics_one_line_error_and_explicit_choice(tmp_path, capsys):
    path = tmp_path / "three.bag"
    imgs = _three_camera_bag(path)
    with pytest.raises(TudorVisionError, match=r"cannot choose the image topics \(/cam_a/image, /cam_b/image, "
                                               r"/cam_c/image\); pass --topics"):
        open_sequence(path)
    assert main(["seq", "check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--topics" in err and "Traceback" not in err
    with open_sequence(path, topics="left=/cam_a/image,right=/cam_c/image") as seq:
        assert seq.kind == "stereo" and np.array_equal(seq[1].right, imgs[1])
    with open_sequence(path, topics={"image": "/cam_b/image"}) as seq:
        assert seq.kind == "mono" and len(seq) == 3
    out = tmp_path / "mono"
    assert main(["seq", "import", str(path), "--out", str(out), "--topics", "image=/cam_b/image"]) == 0
    assert main(["seq", "info", str(path)]) == 0     # ambiguity is not a defect: the table answers it
    assert "pass --topics" in capsys.readouterr().out


def test_topic_choice_rules():
    img, cimg, info = "sensor_msgs/msg/Image", "sensor_msgs/msg/CompressedImage", "sensor_msgs/msg/CameraInfo"
    tops = [BagTopic("/cam/image_raw", img, 3), BagTopic("/cam/image_raw/compressed", cimg, 3),
            BagTopic("/cam/camera_info", info, 3), BagTopic("/tf", "tf2_msgs/msg/TFMessage", 9)]
    assert choose_topics(tops) == ("mono", {"image": "/cam/image_raw"}, {"image": "/cam/camera_info"})
    with pytest.raises(TudorVisionError, match="left=/nope: expected an image topic, not in the bag"):
        choose_topics(tops, "left=/nope,right=/cam/image_raw")
    with pytest.raises(TudorVisionError, match="give left= and right="):
        choose_topics(tops, "left=/cam/image_raw")
    with pytest.raises(TudorVisionError, match="no image topics"):
        choose_topics(tops[3:])
    with pytest.raises(TudorVisionError, match="STREAM=TOPIC"):
        parse_topics("colour=/x")
    rs = [BagTopic("/camera/color/image_raw", img, 3), BagTopic("/camera/depth/image_rect_raw", img, 3),
          BagTopic("/camera/aligned_depth_to_color/image_raw", img, 3),
          BagTopic("/camera/color/camera_info", info, 3), BagTopic("/camera/depth/camera_info", info, 3)]
    assert choose_topics(rs) == ("rgbd", {"rgb": "/camera/color/image_raw",
                                          "depth": "/camera/aligned_depth_to_color/image_raw"},
                                 {"rgb": "/camera/color/camera_info"})
    with pytest.raises(TudorVisionError, match="cannot choose"):
        choose_topics(rs + [BagTopic("/camera/infra1/image_rect_raw", img, 3)])


# ----------------------------------------------------------------------------- decoding
class _Msg:
    def __init__(self, **kw):
        self.__dict__.update(kw)


def test_decode_image_encodings_padding_and_byte_order():
    rng = np.random.default_rng(3)
    g16 = rng.integers(0, 65536, (3, 4)).astype(np.uint16)
    padded = np.zeros((3, 10), np.uint8)                       # step 10 > 8 bytes per row
    padded[:, :8] = g16.astype(">u2").view(np.uint8).reshape(3, 8)
    out = decode_image(_Msg(encoding="mono16", height=3, width=4, step=10, is_bigendian=1, data=padded.ravel()))
    assert out.dtype == np.uint16 and np.array_equal(out, g16)
    rgba = rng.integers(0, 256, (2, 3, 4), dtype=np.uint8)
    out = decode_image(_Msg(encoding="rgba8", height=2, width=3, step=12, is_bigendian=0, data=rgba.ravel()))
    assert np.array_equal(out, rgba[:, :, 2::-1])
    with pytest.raises(Exception, match="unsupported image encoding 'yuv422'"):
        decode_image(_Msg(encoding="yuv422", height=2, width=2, step=4, is_bigendian=0, data=np.zeros(8, np.uint8)))
    with pytest.raises(Exception, match="does not hold 4x3 mono8"):
        decode_image(_Msg(encoding="mono8", height=3, width=4, step=4, is_bigendian=0, data=np.zeros(5, np.uint8)))


def test_camera_info_to_calibration_and_stereo_geometry():
    K = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    ang = 0.05
    Rl = np.array([[np.cos(ang), 0, np.sin(ang)], [0, 1, 0], [-np.sin(ang), 0, np.cos(ang)]])
    Rr = Rl.T
    P2 = np.hstack([K, [[-500.0 * 0.2], [0], [0]]])
    msg = _Msg(k=K.ravel(), d=np.zeros(0), r=Rl.ravel(), p=np.hstack([K, np.zeros((3, 1))]).ravel(), width=640,
               height=480, distortion_model="plumb_bob")
    cam, R1, P1 = camera_from_info(msg)
    assert cam.size == (640, 480) and np.allclose(cam.K, K) and not np.any(cam.dist)
    st = stereo_from_infos((cam, R1, P1), (cam, Rr, P2))
    assert st.baseline_m == pytest.approx(0.2)
    # a point seen by both rectified cameras at the same row: x_right = R x_left + T
    x_left = np.array([0.3, -0.1, 2.0])
    x_right = st.R @ x_left + st.T
    assert np.allclose(Rr @ x_right, Rl @ x_left + [-0.2, 0, 0])
    bad = _Msg(**{**msg.__dict__, "d": np.array([0.1, 0, 0, 0, 0, 0.3, 0, 0]),
                  "distortion_model": "rational_polynomial"})
    with pytest.raises(ValueError, match="cannot be represented"):
        camera_from_info(bad)


# ----------------------------------------------------------------------------- damaged files
@pytest.mark.parametrize("flavour", FLAVOURS)
def test_truncated_or_corrupt_bag_one_line_error(tmp_path, flavour, capsys):
    path = _bag_path(tmp_path, flavour, "stereo")
    write_stereo_bag(path, flavour)
    target = path if flavour == "ros1" else next(p for p in path.iterdir() if p.suffix in (".db3", ".mcap"))
    data = target.read_bytes()
    target.write_bytes(data[: len(data) // 2])
    for argv in (["seq", "info", str(path)], ["seq", "import", str(path), "--out", str(tmp_path / "o")]):
        rc = main(argv)
        err = capsys.readouterr().err
        assert rc == 2, err
        assert "Traceback" not in err and err.strip().count("\n") == 0
        assert str(path) in err


def test_garbage_bag_and_mcap_files(tmp_path, capsys):
    for name in ("junk.bag", "junk.mcap"):
        p = tmp_path / name
        p.write_bytes(b"\x00not a bag at all" * 10)
        with pytest.raises(TudorVisionError, match=f"{name}: cannot read bag"):
            open_sequence(p)
        assert main(["seq", "import", str(p), "--out", str(tmp_path / "o")]) == 2
        err = capsys.readouterr().err
        assert err.startswith("tudorvision seq: error: ") and name in err and "Traceback" not in err
    assert not (tmp_path / "o").exists()


# ----------------------------------------------------------------------------- plain folders (the same opener)
def _write_png(path: Path, img) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    assert cv2.imwrite(str(path), img)


def test_left_right_folders_are_a_stereo_sequence(tmp_path, capsys):
    left, right = _images(11, 4), _images(12, 4)
    for k in range(4):
        _write_png(tmp_path / "s" / "left" / f"left{k:02d}.png", left[k])
        _write_png(tmp_path / "s" / "right" / f"right{k:02d}.png", right[k])
    with open_sequence(tmp_path / "s", rate_hz=10.0) as seq:
        assert (seq.layout, seq.kind, len(seq)) == ("stereo_folders", "stereo", 4)
        assert all(np.array_equal(f.left, left[f.index]) and np.array_equal(f.right, right[f.index]) for f in seq)
        assert seq[3].t == pytest.approx(0.3)
    out = tmp_path / "imported"
    assert main(["seq", "import", str(tmp_path / "s"), "--out", str(out)]) == 0
    with open_sequence(out) as seq:
        assert seq.kind == "stereo" and np.array_equal(seq[2].right, right[2])
    (tmp_path / "s" / "right" / "right03.png").unlink()        # a left image without its partner
    with pytest.raises(TudorVisionError, match="left03.png: no right image with the same number"):
        open_sequence(tmp_path / "s")
    with open_sequence(tmp_path / "s", strict=False) as seq:
        assert len(seq) == 3 and len(seq.report) == 1


def test_rgb_depth_folders_are_an_rgbd_sequence(tmp_path):
    rgb, depth = _images(13, 3), _depths_mm(14, 3)
    for k in range(3):
        _write_png(tmp_path / "r" / "rgb" / f"{k:06d}.png", rgb[k])
        _write_png(tmp_path / "r" / "depth" / f"{k:06d}.png", depth[k])
    with open_sequence(tmp_path / "r") as seq:
        assert (seq.layout, seq.kind, len(seq), seq.depth_scale) == ("rgbd_folders", "rgbd", 3, 1000.0)
        assert all(np.array_equal(f.depth_raw, depth[f.index]) and np.array_equal(f.rgb, rgb[f.index]) for f in seq)
        assert any("depth_scale not given" in n for n in seq.notes)


def test_sidecar_image_folder_with_kind_stereo_is_stereo_or_an_error(tmp_path):
    root = tmp_path / "s"
    for side in ("left", "right"):
        for k in range(2):
            _write_png(root / side / f"{k}.png", _images(5, 1)[0])
    (root / "sequence.yaml").write_text("layout: image_folder\nkind: stereo\nrate_hz: 15\n")
    with open_sequence(root) as seq:       # the folders exist: the stereo pair, not 0 mono frames
        assert (seq.kind, len(seq), seq.rate_hz) == ("stereo", 2, 15.0)
    flat = tmp_path / "flat"
    _write_png(flat / "a.png", _images(5, 1)[0])
    (flat / "sequence.yaml").write_text("layout: image_folder\nkind: stereo\n")
    with pytest.raises(TudorVisionError, match=r"sequence.yaml:2: kind: 'stereo' contradicts layout "
                                               r"'image_folder'.*left/ \+ right/"):
        open_sequence(flat)


# ----------------------------------------------------------------------------- tracking straight from a bag
@pytest.mark.parametrize("flavour", ["ros1", "mcap"])
def test_colormodel_and_track_mono_on_a_bag(tmp_path, flavour, capsys):
    folder = _bag_path(tmp_path, flavour, "disc")
    bag = _Bag(folder, flavour)
    for k in range(6):
        img = np.full((120, 160, 3), (90, 110, 100), np.uint8)
        cv2.circle(img, (40 + 12 * k, 60), 15, (30, 30, 220), -1, lineType=cv2.LINE_AA)
        bag.image("/cam/image_raw", T0 * 10**9 + k * DT_NS, img, "bgr8")
    bag.close()
    src = folder if flavour == "ros1" else _bare_mcap(folder)
    cm, out = tmp_path / "cm.yaml", tmp_path / "track.csv"
    assert main(["colormodel", str(src), "--pick", "mono:red:40,60:55,60", "--out", str(cm)]) == 0
    assert main(["track", "mono", str(src), "--colormodel", str(cm), "--sphere", "red", "--out", str(out)]) == 0
    rows = np.loadtxt(out, delimiter=",", comments="#", skiprows=5)
    assert rows.shape == (6, 5) and np.all(rows[:, 4] == 1)
    np.testing.assert_allclose(rows[:, 2], 40 + 12 * np.arange(6), atol=0.5)
    np.testing.assert_allclose(rows[:, 1], T0 + np.arange(6) * DT_NS * 1e-9, atol=1e-6)


# ----------------------------------------------------------------------------- order, random access, partial imports
def test_right_logged_before_left_and_random_access(tmp_path):
    path = tmp_path / "order.bag"
    left, right = _images(21, 8), _images(22, 8)
    bag = _Bag(path, "ros1")
    for k in range(8):
        t = T0 * 10**9 + k * DT_NS
        bag.image("/cam/right/image", t - 500_000, right[k], "bgr8")     # right logged (and stamped) first
        bag.image("/cam/left/image", t, left[k], "bgr8")
    bag.close()
    with open_sequence(path) as seq:
        assert len(seq) == 8
        for i in [7, 0, 3, 4, 5, 1, 6, 2, 2]:
            f = seq[i]
            assert np.array_equal(f.left, left[i]) and np.array_equal(f.right, right[i])
        assert [f.index for f in seq] == list(range(8))


def _unsupported_frame_bag(path):
    imgs = _images(31, 6)
    bag = _Bag(path, "ros1")
    for k in range(6):
        t = T0 * 10**9 + k * DT_NS
        if k == 2:
            bag.image("/cam/image", t, np.zeros((H, W * 2), np.uint8), "yuv422")
        else:
            bag.image("/cam/image", t, imgs[k], "bgr8")
    bag.close()
    return imgs


def test_import_skips_undecodable_frames_and_flags_them(tmp_path, capsys):
    src, out = tmp_path / "yuv.bag", tmp_path / "o"
    imgs = _unsupported_frame_bag(src)
    assert main(["seq", "import", str(src), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "partial: 1 defect(s) skipped" in err and "unsupported image encoding 'yuv422'" in err
    with open_sequence(out) as seq:
        assert len(seq) == 5 and not (out / "INCOMPLETE").exists()
        assert "yuv422" in seq.meta["skipped_frames"][0]
        assert np.array_equal(seq[2].image, imgs[3])
    assert main(["seq", "import", str(src), "--out", str(tmp_path / "s"), "--strict"]) == 2
    assert "yuv422" in capsys.readouterr().err
    assert (tmp_path / "s" / "INCOMPLETE").exists()
    with pytest.raises(TudorVisionError, match="incomplete"):
        open_sequence(tmp_path / "s")


def test_import_interrupted_by_ctrl_c_is_flagged(tmp_path, monkeypatch, capsys):
    from tudorvision.io.bags import BagFrames

    src, out = tmp_path / "s.bag", tmp_path / "o"
    write_stereo_bag(src, "ros1")
    real = BagFrames.read

    def read(self, i):
        if i == 3:
            raise KeyboardInterrupt
        return real(self, i)

    monkeypatch.setattr(BagFrames, "read", read)
    assert main(["seq", "import", str(src), "--out", str(out)]) == 130
    assert "interrupted" in capsys.readouterr().err
    assert (out / "INCOMPLETE").exists()
    assert "interrupted (Ctrl-C) after 3 frames" in (out / "sequence.yaml").read_text()
    with open_sequence(out, strict=False) as seq:
        assert len(seq) == 3 and "incomplete" in str(seq.report[0])


def test_decoded_frames_are_writable_copies(tmp_path):
    path = _bag_path(tmp_path, "ros1", "stereo")
    left, _ = write_stereo_bag(path, "ros1")
    with open_sequence(path) as seq:
        f = seq[0]
        assert f.left.flags.writeable and f.right.flags.writeable and f.left.flags.c_contiguous
        f.left[:] = 0                                       # a consumer drawing on a frame
        assert np.array_equal(seq[0].left, left[0])


def test_compressed_depth_png_and_mono16_colour(tmp_path):
    depth = _depths_mm(41, 1)[0]
    png = cv2.imencode(".png", depth)[1].ravel()
    msg = _Msg(format="16UC1; compressedDepth png", data=np.concatenate([np.zeros(12, np.uint8), png]))
    out = decode_image(msg)
    assert out.dtype == np.uint16 and np.array_equal(out, depth)
    with pytest.raises(Exception, match="quantised 32FC1 compressedDepth is not supported"):
        decode_image(_Msg(format="32FC1; compressedDepth png", data=np.concatenate([np.zeros(12, np.uint8), png])))
    path = tmp_path / "mono16.bag"
    bag = _Bag(path, "ros1")
    grey16 = [np.random.default_rng(k).integers(0, 65536, (H, W)).astype(np.uint16) for k in range(3)]
    for k, g in enumerate(grey16):
        bag.image("/ir/image", T0 * 10**9 + k * DT_NS, g, "mono16")
    bag.close()
    with open_sequence(path) as seq:
        assert seq.kind == "mono"
        assert all(f.image.dtype == np.uint8 and np.array_equal(f.image, grey16[f.index] >> 8) for f in seq)
