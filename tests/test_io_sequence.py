"""Sequence writer -> reader round trips, TUM layout, real recordings."""
from pathlib import Path

import cv2
import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.io import Calibration, CameraModel, SequenceWriter, open_sequence
from tudorvision.io._index import associate
from tudorvision.sensors import depth_m_from_raw, raw_from_depth_m

REAL = Path(__file__).resolve().parents[2] / "shared" / "realdata"


def _real(sub):
    p = REAL / sub
    if not p.exists():
        pytest.skip(f"real data {p} not available (see shared/realdata/SOURCES.md)")
    return p


def _img(rng, h=12, w=16, c=3):
    shape = (h, w, c) if c else (h, w)
    return rng.integers(0, 256, size=shape, dtype=np.uint8)


def test_stereo_round_trip_png_is_lossless(tmp_path):
    rng = np.random.default_rng(0)
    ts = np.cumsum(rng.uniform(0.015, 0.025, 6))
    pairs = [(_img(rng), _img(rng)) for _ in ts]
    cam = CameraModel(K=[[20.0, 0, 8], [0, 20, 6], [0, 0, 1]], width=16, height=12)
    cal = Calibration(cameras={"left": cam, "right": cam})
    with SequenceWriter(tmp_path / "s", kind="stereo", rate_hz=50.0, calibration=cal,
                        description="unit test") as w:
        for t, (a, b) in zip(ts, pairs):
            w.add_stereo(t, a, b)
    seq = open_sequence(tmp_path / "s")
    assert (seq.kind, seq.layout, len(seq), seq.rate_hz) == ("stereo", "tudorvision", 6, 50.0)
    assert seq.size == {"left": (16, 12), "right": (16, 12)}
    assert seq.description == "unit test"
    assert np.allclose(seq.timestamps, ts, atol=1e-6)
    frames = list(seq)
    assert [f.index for f in frames] == list(range(6))
    for f, (a, b) in zip(frames, pairs):
        assert np.array_equal(f.left, a) and np.array_equal(f.right, b)
    assert np.array_equal(seq[-1].right, pairs[-1][1])
    assert seq.calibration.allclose(cal)
    assert seq.report == []


def test_rgbd_round_trip_depth_metres_and_raw(tmp_path):
    rng = np.random.default_rng(1)
    depth = rng.uniform(0.6, 6.0, size=(12, 16))
    depth[0, :4] = np.nan          # invalid
    depth[1, 0] = 80.0              # beyond the 16-bit range at 1000/m -> invalid
    raw = rng.integers(1, 65535, size=(12, 16), dtype=np.uint16)
    bgr = [_img(rng), _img(rng)]
    with SequenceWriter(tmp_path / "r", kind="rgbd", rate_hz=30.0, depth_scale=1000.0,
                        image_ext=".png") as w:
        w.add_rgbd(1.0, bgr[0], depth)
        w.add_rgbd(1.0 + 1 / 30, bgr[1], raw)
    seq = open_sequence(tmp_path / "r")
    f0, f1 = seq[0], seq[1]
    assert f0.rgb.dtype == np.uint8 and f0.rgb.shape == (12, 16, 3)
    assert np.array_equal(f0.bgr, bgr[0])
    assert f0.depth_m.dtype == np.float32
    ok = np.isfinite(depth) & (depth < 65.5)
    assert np.array_equal(np.isfinite(f0.depth_m), ok)
    assert np.allclose(f0.depth_m[ok], depth[ok], atol=0.5e-3 + 1e-6)
    assert np.array_equal(f0.valid, ok) and np.all(f0.depth_raw[~ok] == 0)
    assert np.array_equal(f1.depth_raw, raw)
    assert np.allclose(f1.depth_m, raw / 1000.0, rtol=1e-6)
    assert f1.t_depth == pytest.approx(f1.t)


def test_mono_jpeg_joints_and_groundtruth_round_trip(tmp_path):
    rng = np.random.default_rng(2)
    smooth = [cv2.GaussianBlur(_img(rng, 32, 48), (0, 0), 3) for _ in range(3)]
    theta = rng.uniform(-1, 1, size=(20, 3))
    t_j = np.arange(20) * 0.0005
    p = rng.normal(size=(3, 3))
    with SequenceWriter(tmp_path / "m", kind="mono", rate_hz=10.0, image_ext=".jpg",
                        jpeg_quality=95, meta={"seed": 7}) as w:
        for k, im in enumerate(smooth):
            w.add_mono(k * 0.1, im)
        for t, th in zip(t_j, theta):
            w.add_joints(t, th)
        w.write_groundtruth("ee", {"t": [0, 0.1, 0.2], "x_m": p[:, 0], "y_m": p[:, 1], "z_m": p[:, 2]},
                            comment="end effector, base frame")
        w.write_groundtruth("spheres", (["t", "r"], np.array([[0.0, 1.5], [0.1, 2.5]])))
    seq = open_sequence(tmp_path / "m")
    assert seq.streams == ("image", "joints") and seq.meta["seed"] == 7
    for f, im in zip(seq, smooth):   # JPEG: close, not equal
        assert np.abs(f.image.astype(int) - im).mean() < 3
    log = seq.joints()
    assert np.allclose(log.t, t_j) and np.allclose(log.theta_rad, theta, atol=1e-8)
    assert np.allclose(log.at(t_j[3]), theta[3], atol=1e-8)
    assert seq.groundtruth_names == ["ee", "spheres"]
    gt = seq.groundtruth("ee")
    assert list(gt) == ["t", "x_m", "y_m", "z_m"] and np.array_equal(gt["y_m"], p[:, 1])
    assert np.array_equal(seq.groundtruth("spheres")["r"], [1.5, 2.5])
    with pytest.raises(TudorVisionError, match="no ground truth 'nope'"):
        seq.groundtruth("nope")


def test_writer_rejects_bad_calls(tmp_path):
    w = SequenceWriter(tmp_path / "w", kind="stereo", rate_hz=50.0)
    img = np.zeros((4, 6, 3), np.uint8)
    w.add_stereo(0.0, img, img)
    with pytest.raises(ValueError, match="must increase"):
        w.add_stereo(0.0, img, img)
    with pytest.raises(ValueError, match="image is 7x4"):
        w.add_stereo(0.1, img, np.zeros((4, 7, 3), np.uint8))
    with pytest.raises(ValueError, match="records kind 'stereo'"):
        w.add_mono(0.2, img)
    w.close()
    with pytest.raises(TudorVisionError, match="not empty"):
        SequenceWriter(tmp_path / "w", kind="stereo", rate_hz=50.0)
    with pytest.raises(ValueError, match="kind"):
        SequenceWriter(tmp_path / "x", kind="lidar", rate_hz=50.0)
    with pytest.raises(ValueError, match="meta: key 'kind' is reserved"):
        SequenceWriter(tmp_path / "y", kind="mono", rate_hz=5.0, meta={"kind": "x"})


def test_writer_overwrite_and_calibration_file_copy(tmp_path):
    from tudorvision.io import save_calibration
    cam = CameraModel(K=[[30.0, 0, 3], [0, 30, 2], [0, 0, 1]], width=6, height=4)
    cal_path = save_calibration(Calibration(cameras={"camera": cam}), tmp_path / "lab.yaml")
    img = np.zeros((4, 6), np.uint8)
    for n in (3, 1):                      # the second recording replaces the first one
        with SequenceWriter(tmp_path / "o", kind="mono", rate_hz=5.0, calibration=cal_path,
                            overwrite=True) as w:
            for k in range(n):
                w.add_mono(k * 0.2, img)
    seq = open_sequence(tmp_path / "o")
    assert len(seq) == 1 and sorted(p.name for p in (tmp_path / "o" / "image").iterdir()) == ["000000.png"]
    assert seq.calibration.camera("camera").allclose(cam)
    bad = tmp_path / "bad.yaml"
    bad.write_text("cameras: [\n")
    with pytest.raises(TudorVisionError, match=r"bad\.yaml:2: malformed YAML"):
        SequenceWriter(tmp_path / "p", kind="mono", rate_hz=5.0, calibration=bad)


def test_depth_conversions():
    raw = np.array([[0, 1, 65535]], np.uint16)
    m = depth_m_from_raw(raw, 5000.0)
    assert np.isnan(m[0, 0]) and m[0, 1] == np.float32(1 / 5000)
    assert np.array_equal(raw_from_depth_m(m, 5000.0), raw)
    with pytest.raises(ValueError, match="depth_scale"):
        depth_m_from_raw(raw, 0.0)


def test_associate_is_greedy_nearest_within_tolerance():
    rng = np.random.default_rng(3)
    t_a = np.cumsum(rng.uniform(0.03, 0.04, 50))
    jitter = rng.uniform(-0.01, 0.01, 50)
    t_b = np.sort(t_a + jitter)
    pairs = associate(t_a, t_b, 0.02)
    # brute-force oracle: every pair within tolerance, one-to-one, each a its nearest b here
    assert len(pairs) == 50
    assert len(set(pairs[:, 1])) == 50
    for i, j in pairs:
        assert j == np.argmin(np.abs(t_b - t_a[i]))
    assert len(associate(t_a, t_b + 100.0, 0.02)) == 0


def _greedy_all_pairs(t_a, t_b, tol):
    cand = sorted((abs(a - b), i, j) for i, a in enumerate(t_a) for j, b in enumerate(t_b)
                  if abs(a - b) <= tol)
    ua, ub, out = set(), set(), []
    for _, i, j in cand:
        if i not in ua and j not in ub:
            ua.add(i)
            ub.add(j)
            out.append((i, j))
    return sorted(out)


def test_associate_matches_exhaustive_greedy_on_tum_like_streams():
    rng = np.random.default_rng(5)
    for _ in range(20):
        t_a = np.cumsum(rng.uniform(0.025, 0.045, 40))
        t_b = np.cumsum(rng.uniform(0.025, 0.045, 40)) + rng.uniform(-0.05, 0.05)
        got = associate(t_a, t_b, 0.02).tolist()
        assert got == [list(p) for p in _greedy_all_pairs(t_a, t_b, 0.02)]


def _write_tum(root, rng, n=5):
    (root / "rgb").mkdir(parents=True)
    (root / "depth").mkdir()
    t_rgb = 1305031102.0 + np.arange(n) / 30.0
    t_d = t_rgb + rng.uniform(-0.008, 0.008, n)
    keep_d = [k for k in range(n) if k != 2]   # rgb frame 2 has no depth within 0.02 s
    rgb_lines = ["# color images", "# timestamp filename"]
    d_lines = ["# depth maps", "# timestamp filename"]
    depths = []
    for k in range(n):
        cv2.imwrite(str(root / "rgb" / f"{t_rgb[k]:.6f}.png"), _img(rng, 8, 10))
        d = rng.integers(0, 20000, size=(8, 10), dtype=np.uint16)
        depths.append(d)
        cv2.imwrite(str(root / "depth" / f"{t_d[k]:.6f}.png"), d)
        rgb_lines.append(f"{t_rgb[k]:.6f} rgb/{t_rgb[k]:.6f}.png")
        if k in keep_d:
            d_lines.append(f"{t_d[k]:.6f} depth/{t_d[k]:.6f}.png")
    (root / "rgb.txt").write_text("\n".join(rgb_lines) + "\n")
    (root / "depth.txt").write_text("\n".join(d_lines) + "\n")
    (root / "groundtruth.txt").write_text("# ground truth\n# timestamp tx ty tz qx qy qz qw\n"
                                          f"{t_rgb[0]:.4f} 1 2 3 0 0 0 1\n")
    return t_rgb, t_d, depths


def test_tum_layout_associates_and_uses_scale_5000(tmp_path):
    rng = np.random.default_rng(4)
    t_rgb, t_d, depths = _write_tum(tmp_path / "tum", rng)
    seq = open_sequence(tmp_path / "tum")
    assert (seq.layout, seq.kind, seq.depth_scale) == ("tum", "rgbd", 5000.0)
    assert len(seq) == 4 and any("left out" in n for n in seq.notes)
    assert np.allclose(seq.timestamps, np.delete(t_rgb, 2))
    f = seq[2]                      # third kept frame is recorded frame 3
    assert f.t == pytest.approx(t_rgb[3]) and f.t_depth == pytest.approx(t_d[3])
    assert np.allclose(f.depth_m, np.where(depths[3] > 0, depths[3] / 5000.0, np.nan), equal_nan=True)
    assert seq.groundtruth("groundtruth")["tz"][0] == 3.0
    assert seq.rate_hz == pytest.approx(30.0, rel=0.3)


def test_real_tum_desk_frames():
    root = _real("rgbd_tum_desk")
    K = [[520.9, 0, 325.1], [0, 521.0, 249.7], [0, 0, 1]]
    seq = open_sequence(root, K=K)
    assert (seq.layout, seq.depth_scale, len(seq)) == ("numbered_pairs", 5000.0, 2)
    cam = seq.calibration.camera("rgbd")
    assert (cam.width, cam.height, cam.fx) == (640, 480, 520.9)
    f = seq[0]
    assert f.rgb.shape == (480, 640, 3) and f.depth_raw.dtype == np.uint16
    desk = f.depth_m[330:380, 90:200]
    assert np.isfinite(desk).mean() > 0.9
    assert np.nanmedian(desk) == pytest.approx(1.23, abs=0.03)


def test_real_kinect_room_frames():
    root = _real("rgbd_kinect_room")
    seq = open_sequence(root, depth_scale=1000.0, K=[[518.0, 0, 325.5], [0, 519.0, 253.5], [0, 0, 1]],
                        size=(640, 480))
    assert (seq.layout, len(seq)) == ("kinect_folders", 5)
    assert seq.notes == []            # depth scale was given
    f = seq[0]
    valid = f.valid.mean()
    assert 0.6 < valid < 0.8
    assert np.nanmin(f.depth_m) == pytest.approx(0.95, abs=0.02)
    assert np.nanmax(f.depth_m) == pytest.approx(9.8, abs=0.1)
    pose = seq.groundtruth("pose")
    assert len(pose["qw"]) == 5
    q = np.column_stack([pose[k] for k in ("qx", "qy", "qz", "qw")])
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-3)


def test_real_kinect_room_sidecar(tmp_path):
    root = _real("rgbd_kinect_room")
    # a sidecar cannot live in the read-only real-data folder: link the folders into tmp
    (tmp_path / "color").symlink_to(root / "color")
    (tmp_path / "depth").symlink_to(root / "depth")
    (tmp_path / "sequence.yaml").write_text(
        "layout: kinect_folders\nrate_hz: 15\ndepth_scale: 1000\n"
        "intrinsics: {fx: 518.0, fy: 519.0, cx: 325.5, cy: 253.5}\n")
    seq = open_sequence(tmp_path)
    assert seq.rate_hz == 15.0 and seq.timestamps[1] == pytest.approx(1 / 15)
    assert seq.calibration.camera("rgbd").cy == 253.5


def test_real_video():
    path = _real("ball_videos") / "ball.mp4"
    with open_sequence(path) as seq:
        assert (seq.layout, seq.kind, len(seq)) == ("video", "mono", 60)
        frames = list(seq)
        assert len(frames) == 60
        assert [f.index for f in frames] == list(range(60))
        assert frames[0].image.shape == (720, 1280, 3)
        t = np.array([f.t for f in frames])
        assert t[0] == 0.0 and np.all(np.diff(t) > 0)
        assert np.allclose(t, seq.timestamps, atol=2e-3)
        back = seq[17]                 # random access after a full pass seeks
        assert back.index == 17 and np.array_equal(back.image, frames[17].image)


def _write_avi(path, n=8, size=(32, 24), fps=25.0):
    vw = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), fps, size)
    if not vw.isOpened():
        pytest.skip("this OpenCV build cannot write MJPG video")
    for k in range(n):
        vw.write(np.full((size[1], size[0], 3), 20 * k, np.uint8))
    vw.release()


def test_mono_sequence_pointing_at_a_video(tmp_path):
    _write_avi(tmp_path / "clip.avi")
    (tmp_path / "sequence.yaml").write_text("kind: mono\nrate_hz: 25\nvideo: clip.avi\nsize: [32, 24]\n")
    seq = open_sequence(tmp_path)
    assert (seq.layout, seq.kind, len(seq)) == ("tudorvision", "mono", 8)
    means = [float(f.image.mean()) for f in seq]
    assert np.allclose(means, 20 * np.arange(8), atol=3)           # decode order = index order
    assert np.allclose(seq.timestamps, np.arange(8) / 25.0)
    (tmp_path / "sequence.yaml").write_text("kind: mono\nrate_hz: 25\nvideo: clip.avi\nsize: [30, 24]\n")
    with pytest.raises(TudorVisionError, match=r"clip\.avi frame 0: image is 32x24, expected 30x24"):
        open_sequence(tmp_path)[0]
    (tmp_path / "sequence.yaml").write_text("kind: mono\nrate_hz: 25\nvideo: other.avi\n")
    with pytest.raises(TudorVisionError, match=r"sequence\.yaml:3: video: video file 'other.avi' does not exist"):
        open_sequence(tmp_path)


def test_image_folder_in_natural_order(tmp_path):
    for k in (10, 2, 1):
        cv2.imwrite(str(tmp_path / f"img{k}.png"), np.full((4, 5), k, np.uint8))
    seq = open_sequence(tmp_path, rate_hz=5.0)
    assert (seq.layout, seq.kind) == ("image_folder", "mono")
    assert [int(f.image[0, 0]) for f in seq] == [1, 2, 10]
    assert np.allclose(seq.timestamps, [0.0, 0.2, 0.4])


def test_max_frames_limits_every_source(tmp_path):
    """``max_frames`` keeps only the first frames of a recorded sequence (not only of live sources)."""
    import numpy as np
    from tudorvision.io import SequenceWriter, open_sequence

    with SequenceWriter(tmp_path / "s", kind="mono", rate_hz=10.0, image_ext=".png") as w:
        for i in range(6):
            w.add_mono(0.1 * i, np.full((4, 6), i, np.uint8))
    seq = open_sequence(tmp_path / "s", max_frames=4)
    assert len(seq) == 4 and seq.timestamps.shape == (4,)
    assert [int(f.image[0, 0]) for f in seq] == [0, 1, 2, 3]
    assert len(open_sequence(tmp_path / "s", max_frames=100)) == 6
    with pytest.raises(ValueError, match="max_frames"):
        open_sequence(tmp_path / "s", max_frames=0)
