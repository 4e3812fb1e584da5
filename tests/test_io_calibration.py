"""Calibration files: own YAML format, ROS camera_info, OpenCV stereo_calib .yml."""
from pathlib import Path

import cv2
import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.io import (Calibration, CameraModel, DepthModel, StereoExtrinsics, calibration_from_ros,
                            load_calibration, load_opencv_stereo, load_ros_camera_info, save_calibration,
                            save_opencv_stereo, save_ros_camera_info)

DATA = Path(__file__).resolve().parent / "data"


def _rot(rng, scale=0.3):
    return cv2.Rodrigues(rng.normal(size=3) * scale)[0]


def _T(rng):
    T = np.eye(4)
    T[:3, :3] = _rot(rng, 1.0)
    T[:3, 3] = rng.normal(size=3)
    return T


def _random_stereo(rng):
    cams = {}
    for name in ("left", "right"):
        K = np.array([[rng.uniform(600, 800), 0, rng.uniform(300, 340)],
                      [0, rng.uniform(600, 800), rng.uniform(220, 260)], [0, 0, 1]])
        cams[name] = CameraModel(K=K, dist=rng.normal(size=5) * 0.05, width=640, height=480,
                                 line_time_s=rng.uniform(1e-5, 5e-5))
    R = _rot(rng)
    T = np.array([-3.0, 0.0, 0.2]) + rng.normal(size=3) * 0.05
    R1, R2, P1, P2, Q, _, _ = cv2.stereoRectify(cams["left"].K, cams["left"].dist, cams["right"].K,
                                                cams["right"].dist, (640, 480), R, T.reshape(3, 1))
    return Calibration(cameras=cams, stereo=StereoExtrinsics(R=R, T=T, R1=R1, R2=R2, P1=P1, P2=P2, Q=Q))


def test_own_format_round_trip_all_fields(tmp_path):
    rng = np.random.default_rng(0)
    for k in range(5):
        cal = _random_stereo(rng).with_updates(
            cameras={"rgbd": CameraModel(K=[[525.0, 0, 319.5], [0, 525.0, 239.5], [0, 0, 1]], width=640,
                                         height=480, T_ref_cam=_T(rng))},
            transforms={"T_base_left": _T(rng), "T_ee_hand": _T(rng)},
            depth_model=DepthModel(sigma_z_poly=[0.51, -2.1, 5.12, -2.18], sigma_unit="cm",
                                   valid_range_m=(0.6, 6.0)),
            circle_rmse_m=0.0482, metadata={"source": "unit test", "run": k})
        path = save_calibration(cal, tmp_path / f"cal{k}.yaml", header="random calibration")
        back = load_calibration(path)
        assert back.allclose(cal, atol=0.0)           # repr floats: exact
        assert not back.allclose(cal.with_updates(circle_rmse_m=0.05))
        assert back.stereo.baseline_m == pytest.approx(np.linalg.norm(cal.stereo.T))
    assert path.read_text().startswith("# tudorvision calibration")


def test_partial_update_adds_transform_to_existing_file(tmp_path):
    rng = np.random.default_rng(1)
    cal = _random_stereo(rng)
    path = save_calibration(cal, tmp_path / "lab.yaml")
    T = _T(rng)
    updated = load_calibration(path).with_updates(transforms={"T_base_left": T})
    save_calibration(updated, path)
    again = load_calibration(path)
    assert np.allclose(again.transform("T_base_left"), T, atol=0)
    assert again.camera("left").allclose(cal.camera("left"), atol=0)
    merged = cal.merge(Calibration(transforms={"T_ee_cam": np.eye(4)}))
    assert sorted(merged.transforms) == ["T_ee_cam"] and merged.stereo is cal.stereo
    with pytest.raises(TudorVisionError, match="no transform 'T_base_rgbd'"):
        again.transform("T_base_rgbd")
    with pytest.raises(ValueError, match="must read T_<to>_<from>"):
        cal.with_updates(transforms={"base": np.eye(4)})
    with pytest.raises(ValueError, match="not a proper orthonormal"):
        cal.with_updates(transforms={"T_a_b": np.diag([1.0, 1.0, -1.0, 1.0])})


def test_depth_model_units():
    dm = DepthModel(sigma_z_poly=[0.51, -2.1, 5.12, -2.18], sigma_unit="cm")
    z = np.array([1.0, 3.0])
    assert np.allclose(dm.sigma_m(z), np.polyval([0.51, -2.1, 5.12, -2.18], z) / 100)
    dm_mm = DepthModel(sigma_z_poly=[1.0, 0.0], z_unit="mm", sigma_unit="mm")   # sigma = z
    assert dm_mm.sigma_m(2.0) == pytest.approx(2.0)


def test_own_format_errors_name_file_and_line(tmp_path):
    path = save_calibration(_random_stereo(np.random.default_rng(2)), tmp_path / "c.yaml")
    text = path.read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("  right:\n    width: 640", "  right:\n    width: [640"))
    with pytest.raises(TudorVisionError, match=r"bad\.yaml:\d+: malformed YAML"):
        load_calibration(bad)
    lines = text.splitlines()
    k_line = next(i for i, line in enumerate(lines, 1) if line.strip() == "K:")
    lines[k_line] = "    - [1.0, 2.0]"
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(TudorVisionError, match=rf"bad\.yaml:{k_line + 1}: cameras\.left\.K: expected shape \(3, 3\)"):
        load_calibration(bad)
    bad.write_text(text.replace("format: tudorvision-calibration", "format: other"))
    with pytest.raises(TudorVisionError, match=r"bad\.yaml:\d+: format: expected 'tudorvision-calibration'"):
        load_calibration(bad)
    bad.write_text(text + "surprise: 1\n")
    with pytest.raises(TudorVisionError, match=r"bad\.yaml:\d+: surprise: unknown key"):
        load_calibration(bad)
    with pytest.raises(TudorVisionError, match="file not found"):
        load_calibration(tmp_path / "absent.yaml")


def test_ros_camera_info_read_fixture_and_round_trip(tmp_path):
    info = load_ros_camera_info(DATA / "io_ros_left.yaml")
    assert info.name == "narrow_stereo/left"
    assert (info.camera.width, info.camera.height, info.camera.fx, info.camera.cy) == (640, 480, 701.25, 241.25)
    assert np.allclose(info.camera.dist, [-0.25, 0.125, 0.001, -0.002, 0])
    assert info.P.shape == (3, 4) and info.P[0, 0] == 690.5
    rng = np.random.default_rng(3)
    cal = _random_stereo(rng)
    st = cal.stereo
    save_ros_camera_info(tmp_path / "left.yaml", cal.camera("left"), name="left", R_rect=st.R1, P=st.P1)
    save_ros_camera_info(tmp_path / "right.yaml", cal.camera("right"), name="right", R_rect=st.R2, P=st.P2)
    back = load_ros_camera_info(tmp_path / "right.yaml")
    assert back.name == "right"
    assert np.allclose(back.camera.K, cal.camera("right").K, atol=0)
    assert np.allclose(back.camera.dist, cal.camera("right").dist, atol=0)
    assert np.allclose(back.R_rect, st.R2, atol=0) and np.allclose(back.P, st.P2, atol=0)
    both = calibration_from_ros({"left": tmp_path / "left.yaml", "right": tmp_path / "right.yaml"})
    assert sorted(both.cameras) == ["left", "right"]


def test_ros_camera_info_errors(tmp_path):
    text = (DATA / "io_ros_left.yaml").read_text()
    bad = tmp_path / "bad.yaml"
    bad.write_text(text.replace("data: [701.25, 0, 318.5, 0, 700.75, 241.25, 0, 0, 1]",
                                "data: [701.25, 0, 318.5, 0, 700.75, 241.25]"))
    with pytest.raises(TudorVisionError, match=r"bad\.yaml:7: camera_matrix\.data: expected 9 numbers, got 6"):
        load_ros_camera_info(bad)
    bad.write_text(text.replace("plumb_bob", "equidistant"))
    with pytest.raises(TudorVisionError, match=r"bad\.yaml:8: distortion_model: unsupported"):
        load_ros_camera_info(bad)
    bad.write_text(text.replace("image_width: 640\n", ""))
    with pytest.raises(TudorVisionError, match=r"bad\.yaml:1: missing 'image_width'"):
        load_ros_camera_info(bad)
    bad.write_text(text.replace("cols: 3\n  data: [701", "cols: 3\n  data: {701"))
    with pytest.raises(TudorVisionError, match=r"bad\.yaml:\d+: malformed YAML"):
        load_ros_camera_info(bad)


def test_opencv_stereo_read_fixture_written_by_opencv_4():
    cal = load_opencv_stereo(DATA / "io_opencv_intrinsics.yml", DATA / "io_opencv_extrinsics.yml",
                             size=(640, 480), m_per_unit=0.025)
    assert cal.camera("left").fx == 701.25 and cal.camera("right").cx == 321.5
    assert np.allclose(cal.camera("right").dist, [-0.24, 0.11, 0, 0.001, 0])
    assert np.allclose(cal.stereo.T, [-3.0, 0.0, 1.0])
    assert not cal.stereo.has_rectification
    with pytest.raises(TudorVisionError, match="no image size in the file: pass size"):
        load_opencv_stereo(DATA / "io_opencv_intrinsics.yml")


def test_opencv_stereo_round_trip(tmp_path):
    rng = np.random.default_rng(4)
    for m_per_unit in (1.0, 0.025):
        cal = _random_stereo(rng)
        ipath, epath = save_opencv_stereo(cal, tmp_path / "intrinsics.yml", tmp_path / "extrinsics.yml",
                                          m_per_unit=m_per_unit)
        fs = cv2.FileStorage(str(epath), cv2.FILE_STORAGE_READ)      # OpenCV itself reads our file
        assert np.allclose(fs.getNode("T").mat().ravel() * m_per_unit, cal.stereo.T)
        fs.release()
        back = load_opencv_stereo(ipath, epath, m_per_unit=m_per_unit)
        cams = {n: c.replace(line_time_s=None) for n, c in cal.cameras.items()}   # not in the format
        assert back.allclose(Calibration(cameras=cams, stereo=cal.stereo), atol=1e-9)
        # rectification stays consistent after unit conversion: Q maps disparity to metres
        Q = back.stereo.Q
        assert abs(1.0 / Q[3, 2]) == pytest.approx(np.linalg.norm(cal.stereo.T), rel=1e-6)


def test_opencv_stereo_errors(tmp_path):
    bad = tmp_path / "intrinsics.yml"
    bad.write_text("%YAML:1.0\nM1: !!opencv-matrix\n   rows: 3\n   cols: [\n")
    with pytest.raises(TudorVisionError, match=r"intrinsics\.yml:4: malformed OpenCV YAML"):
        load_opencv_stereo(bad, size=(640, 480))
    text = (DATA / "io_opencv_intrinsics.yml").read_text()
    bad.write_text(text.split("M2:")[0])
    with pytest.raises(TudorVisionError, match=r"intrinsics\.yml: missing matrix 'M2'"):
        load_opencv_stereo(bad, size=(640, 480))
    bad.write_text("%YAML:1.0\nM1: 3\n")
    with pytest.raises(TudorVisionError, match=r"intrinsics\.yml: M1 is not an OpenCV matrix"):
        load_opencv_stereo(bad, size=(640, 480))
    bad.write_text("")
    with pytest.raises(TudorVisionError, match="empty file"):
        load_opencv_stereo(bad, size=(640, 480))
    with pytest.raises(TudorVisionError, match="no stereo extrinsics"):
        save_opencv_stereo(Calibration(), tmp_path / "i.yml", tmp_path / "e.yml")
