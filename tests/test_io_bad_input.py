"""Every kind of bad input: strict raises TudorVisionError naming file and line; lenient skips and reports."""
from pathlib import Path

import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.io import SequenceWriter, open_sequence

N = 5


def _stereo(root: Path, n=N, size=(16, 12)) -> Path:
    rng = np.random.default_rng(11)
    w, h = size
    with SequenceWriter(root, kind="stereo", rate_hz=50.0) as wr:
        for k in range(n):
            wr.add_stereo(0.02 * k, rng.integers(0, 255, (h, w, 3), np.uint8),
                          rng.integers(0, 255, (h, w, 3), np.uint8))
            wr.add_joints(0.02 * k, [0.0, 1.0, 0.5])
    return root


def _edit_line(path: Path, lineno: int, text: str) -> None:
    lines = path.read_text().splitlines()
    lines[lineno - 1] = text
    path.write_text("\n".join(lines) + "\n")


def _line_of(path: Path, needle: str) -> int:
    return next(k for k, line in enumerate(path.read_text().splitlines(), 1) if needle in line)


def test_index_line_pointing_at_absent_file(tmp_path):
    root = _stereo(tmp_path / "s")
    (root / "left" / "000002.png").unlink()
    line = _line_of(root / "left.txt", "left/000002.png")
    with pytest.raises(TudorVisionError, match=rf"left\.txt:{line}: file 'left/000002.png' does not exist"):
        open_sequence(root)
    seq = open_sequence(root, strict=False)
    assert len(seq) == N - 1 and len(list(seq)) == N - 1
    where = [p.where for p in seq.report]
    assert f"{root / 'left.txt'}:{line}" in where
    # the right image of that pair has lost its partner: reported too
    assert any("no left image" in p.reason for p in seq.report)


def test_malformed_index_line_names_line(tmp_path):
    root = _stereo(tmp_path / "s")
    line = _line_of(root / "right.txt", "right/000001.png")
    _edit_line(root / "right.txt", line, "0.02right/000001.png")
    with pytest.raises(TudorVisionError, match=rf"right\.txt:{line}: malformed"):
        open_sequence(root)
    _edit_line(root / "right.txt", line, "zero.02 right/000001.png")
    with pytest.raises(TudorVisionError, match=rf"right\.txt:{line}: malformed timestamp 'zero.02'"):
        open_sequence(root)
    seq = open_sequence(root, strict=False)
    assert len(seq) == N - 1
    assert any(p.where.endswith(f"right.txt:{line}") and "malformed" in p.reason for p in seq.report)


def test_non_monotonic_timestamps(tmp_path):
    root = _stereo(tmp_path / "s")
    line = _line_of(root / "left.txt", "left/000003.png")
    _edit_line(root / "left.txt", line, "0.010000 left/000003.png")
    with pytest.raises(TudorVisionError, match=rf"left\.txt:{line}: timestamp 0\.010000 is not after .*must increase"):
        open_sequence(root)
    seq = open_sequence(root, strict=False)
    assert len(seq) == N - 1
    assert np.all(np.diff(seq.timestamps) > 0)
    assert any(p.where.endswith(f"left.txt:{line}") for p in seq.report)


def test_wrong_image_size(tmp_path):
    root = _stereo(tmp_path / "s")
    import cv2
    cv2.imwrite(str(root / "right" / "000001.png"), np.zeros((10, 16, 3), np.uint8))
    line = _line_of(root / "right.txt", "right/000001.png")
    seq = open_sequence(root)                      # sizes are checked when frames load
    with pytest.raises(TudorVisionError, match=rf"right\.txt:{line} .*16x10, expected 16x12"):
        list(seq)
    seq = open_sequence(root, strict=False)
    frames = list(seq)
    assert [f.index for f in frames] == [0, 2, 3, 4]
    assert len(seq.report) == 1 and seq.report[0].frame == 1 and "expected 16x12" in seq.report[0].reason
    with pytest.raises(TudorVisionError, match="expected 16x12"):   # direct indexing always raises
        seq[1]
    # an explicit size= applies to layouts without sequence.yaml too
    with pytest.raises(TudorVisionError, match="expected 20x12"):
        open_sequence(root, size=(20, 12))[0]


def test_corrupt_image_bytes(tmp_path):
    root = _stereo(tmp_path / "s")
    data = (root / "left" / "000004.png").read_bytes()
    (root / "left" / "000004.png").write_bytes(data[:40] + b"\x00garbage" * 10)
    (root / "right" / "000000.png").write_bytes(b"")
    with pytest.raises(TudorVisionError, match=r"right\.txt:\d+ \(000000\.png\): empty image file"):
        list(open_sequence(root))
    with pytest.raises(TudorVisionError, match=r"left\.txt:\d+ \(000004\.png\): corrupt"):
        open_sequence(root)[4]
    seq = open_sequence(root, strict=False)
    assert [f.index for f in seq] == [1, 2, 3]
    assert sorted(p.frame for p in seq.report) == [0, 4]


def test_depth_image_must_be_16_bit(tmp_path):
    rng = np.random.default_rng(3)
    root = tmp_path / "r"
    with SequenceWriter(root, kind="rgbd", rate_hz=30.0, depth_scale=1000.0) as wr:
        for k in range(3):
            wr.add_rgbd(k / 30, rng.integers(0, 255, (6, 8, 3), np.uint8), np.full((6, 8), 2.0))
    import cv2
    cv2.imwrite(str(root / "depth" / "000001.png"), np.zeros((6, 8), np.uint8))
    with pytest.raises(TudorVisionError, match=r"depth\.txt:\d+ .*must be single-channel 16-bit"):
        open_sequence(root)[1]
    seq = open_sequence(root, strict=False)
    assert len(list(seq)) == 2 and seq.report[0].frame == 1


def test_malformed_sequence_yaml_names_line(tmp_path):
    root = _stereo(tmp_path / "s")
    y = root / "sequence.yaml"
    text = y.read_text()
    y.write_text(text.replace("rate_hz: 50.0", "rate_hz: [50.0"))
    for strict in (True, False):   # nothing to play without the header: both modes raise cleanly
        with pytest.raises(TudorVisionError, match=r"sequence\.yaml:\d+: malformed YAML"):
            open_sequence(root, strict=strict)
    y.write_text(text.replace("kind: stereo", "kind: lidar"))
    line = _line_of(y, "kind: lidar")
    with pytest.raises(TudorVisionError, match=rf"sequence\.yaml:{line}: kind: expected one of"):
        open_sequence(root)
    y.write_text(text.replace("rate_hz: 50.0", "rate_hz: -3"))
    line = _line_of(y, "rate_hz")
    with pytest.raises(TudorVisionError, match=rf"sequence\.yaml:{line}: rate_hz: expected a positive"):
        open_sequence(root)
    y.write_text(text.replace("size: [16, 12]", "size: [16]"))
    with pytest.raises(TudorVisionError, match=r"sequence\.yaml:\d+: size: expected \[width, height\]"):
        open_sequence(root)


def test_missing_pieces(tmp_path):
    root = _stereo(tmp_path / "s")
    (root / "right.txt").unlink()
    with pytest.raises(TudorVisionError, match=r"right\.txt: index file for stream 'right' not found"):
        open_sequence(root, strict=False)
    with pytest.raises(TudorVisionError, match="no such file or directory"):
        open_sequence(tmp_path / "nothing")
    (tmp_path / "empty").mkdir()
    with pytest.raises(TudorVisionError, match="not a recognised sequence"):
        open_sequence(tmp_path / "empty")
    (tmp_path / "fake.mp4").write_bytes(b"not a video at all")
    with pytest.raises(TudorVisionError, match="cannot open as a video"):
        open_sequence(tmp_path / "fake.mp4")


def test_malformed_joint_log(tmp_path):
    root = _stereo(tmp_path / "s")
    line = _line_of(root / "joints.txt", "0.040000")
    _edit_line(root / "joints.txt", line, "0.040000 0.0 1.0")
    with pytest.raises(TudorVisionError, match=rf"joints\.txt:{line}: malformed line .*expected 4 numbers"):
        open_sequence(root).joints()
    seq = open_sequence(root, strict=False)
    log = seq.joints()
    assert log.theta_rad.shape == (N - 1, 3)
    assert seq.report[0].where.endswith(f"joints.txt:{line}")


def test_tum_directory_with_bad_lines(tmp_path):
    root = tmp_path / "tum"
    (root / "rgb").mkdir(parents=True)
    (root / "depth").mkdir()
    import cv2
    lines_rgb, lines_d = ["# timestamp filename"], ["# timestamp filename"]
    for k in range(4):
        cv2.imwrite(str(root / "rgb" / f"{k}.png"), np.zeros((4, 4, 3), np.uint8))
        cv2.imwrite(str(root / "depth" / f"{k}.png"), np.full((4, 4), 5000, np.uint16))
        lines_rgb.append(f"{k / 30:.6f} rgb/{k}.png")
        lines_d.append(f"{k / 30 + 0.001:.6f} depth/{k}.png")
    lines_rgb[3] = "garbage"
    (root / "rgb.txt").write_text("\n".join(lines_rgb) + "\n")
    (root / "depth.txt").write_text("\n".join(lines_d) + "\n")
    with pytest.raises(TudorVisionError, match=r"rgb\.txt:4: malformed line 'garbage'"):
        open_sequence(root)
    seq = open_sequence(root, strict=False)
    assert len(seq) == 3 and float(seq[0].depth_m[0, 0]) == 1.0
    assert [str(p) for p in seq.report] == [f"{root / 'rgb.txt'}:4: malformed line 'garbage': "
                                            "expected 'timestamp path'"]


def test_bad_sidecar_values_name_the_line(tmp_path):
    import cv2
    cv2.imwrite(str(tmp_path / "1.png"), np.zeros((4, 4, 3), np.uint8))
    cv2.imwrite(str(tmp_path / "1_depth.png"), np.full((4, 4), 5000, np.uint16))
    (tmp_path / "sequence.yaml").write_text("layout: numbered_pairs\nrate_hz: fast\n")
    with pytest.raises(TudorVisionError, match=r"sequence\.yaml:2: rate_hz: expected a positive number"):
        open_sequence(tmp_path)
    (tmp_path / "sequence.yaml").write_text("layout: numbered_pairs\nintrinsics: {fx: 1}\n")
    with pytest.raises(TudorVisionError, match=r"sequence\.yaml:2: intrinsics: expected"):
        open_sequence(tmp_path)
    (tmp_path / "sequence.yaml").write_text("layout: pile\n")
    with pytest.raises(TudorVisionError, match=r"sequence\.yaml:1: layout: expected one of"):
        open_sequence(tmp_path)
    (tmp_path / "sequence.yaml").write_text("layout: numbered_pairs\ndepth_scale: 1000\nrate_hz: 10\n")
    seq = open_sequence(tmp_path)
    assert seq.rate_hz == 10.0 and float(seq[0].depth_m[0, 0]) == 5.0 and seq.notes == []


def test_load_joint_log_standalone(tmp_path):
    from tudorvision.io import load_joint_log
    p = tmp_path / "joints.txt"
    p.write_text("# t th1 th2 th3\n0.0 0 1.5 0\n0.001 0.1 1.5 0\n0.0005 0.2 1.5 0\nx y z w\n")
    with pytest.raises(TudorVisionError, match=r"joints\.txt:4: timestamp 0\.0005 is not after"):
        load_joint_log(p)
    report = []
    log = load_joint_log(p, strict=False, report=report)
    assert np.array_equal(log.t, [0.0, 0.001]) and log.theta_rad[1, 0] == 0.1
    assert [r.where.rsplit(":", 1)[1] for r in report] == ["4", "5"]
