"""Disc on a real arm (issue 15): 3D disc tracking, self-checking base frame, joints.txt anywhere."""
from pathlib import Path

import cv2
import numpy as np
import pytest

from tudorvision.io import SequenceWriter, open_sequence


def _write_rgbd_with_joints(root: Path, n=4):
    rng = np.random.default_rng(0)
    theta = rng.uniform(-1, 1, size=(n, 3))
    with SequenceWriter(root, kind="rgbd", rate_hz=30.0, depth_scale=1000.0) as w:
        for k in range(n):
            w.add_rgbd(k / 30.0, np.zeros((8, 10, 3), np.uint8), np.full((8, 10), 2000, np.uint16))
            w.add_joints(k / 30.0, theta[k])
    return theta


def test_joints_txt_read_when_not_listed_in_streams(tmp_path):
    theta = _write_rgbd_with_joints(tmp_path / "s")
    yml = tmp_path / "s" / "sequence.yaml"
    text = yml.read_text()
    assert "joints" in text
    # drop 'joints' from the streams list (as an independently written sequence does)
    lines = [ln.replace(", joints", "").replace("- joints", "") for ln in text.splitlines()]
    yml.write_text("\n".join(ln for ln in lines if ln.strip() != "") + "\n")
    seq = open_sequence(tmp_path / "s")
    assert "joints" not in seq.streams
    assert seq.joints_path is not None
    np.testing.assert_allclose(seq.joints().theta_rad, theta, atol=1e-8)


def test_joints_txt_read_in_folder_layouts(tmp_path):
    root = tmp_path / "pairs"
    root.mkdir()
    for k in range(3):
        cv2.imwrite(str(root / f"{k}.png"), np.zeros((8, 10, 3), np.uint8))
        cv2.imwrite(str(root / f"{k}_depth.png"), np.full((8, 10), 5000, np.uint16))
    (root / "joints.txt").write_text("0.0 0.1 0.2 0.3\n0.1 0.2 0.3 0.4\n")
    seq = open_sequence(root)
    np.testing.assert_allclose(seq.joints().theta_rad[1], [0.2, 0.3, 0.4])


def test_calib_sweep_reads_joints_txt_not_listed_in_streams(tmp_path):
    from tudorvision._checks import TudorVisionError
    from tudorvision.cli.calib_rgbd import observe_sweep
    from tudorvision.rgbd.disc import DiscOptions
    from tudorvision.rgbd.frames import Intrinsics

    _write_rgbd_with_joints(tmp_path / "s")
    yml = tmp_path / "s" / "sequence.yaml"
    lines = [ln.replace(", joints", "").replace("- joints", "") for ln in yml.read_text().splitlines()]
    yml.write_text("\n".join(ln for ln in lines if ln.strip() != "") + "\n")
    seq = open_sequence(tmp_path / "s")
    K = Intrinsics(fx=10.0, fy=10.0, cx=5.0, cy=4.0, width=10, height=8)
    # the joints are read (random angles: never vertical), not "no joints.txt"
    with pytest.raises(TudorVisionError, match="never reaches the vertical posture"):
        observe_sweep(seq, K, (5, 4), DiscOptions())
