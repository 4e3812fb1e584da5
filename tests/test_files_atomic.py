"""Issue 14, files: outputs are written atomically; a full disk or a read-only folder is one line.

Real files in ``tmp_path``; a full disk is simulated by making the flush
(``os.fsync``) or the temporary file creation raise ``OSError``.
"""
from __future__ import annotations

import errno
import os
import tempfile

import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.cli import main
from tudorvision.io import Calibration, CameraModel, SequenceWriter, load_calibration, save_calibration
from tudorvision.io.atomic import atomic_path, write_text_atomic
from tudorvision.stereo.trajectory import trajectory_from_points, write_trajectory_csv


def _enospc(*_a, **_k):
    raise OSError(errno.ENOSPC, "No space left on device")


def _no_temp_left(folder):
    return [p.name for p in folder.iterdir() if ".tmp" in p.name] == []


def _rgbd_sequence(path, n=6, *, size=(16, 12)):
    w, h = size
    K = np.array([[20.0, 0, w / 2], [0, 20.0, h / 2], [0, 0, 1]])
    cal = Calibration(cameras={"rgbd": CameraModel(K=K, width=w, height=h)})
    with SequenceWriter(path, kind="rgbd", rate_hz=30.0, calibration=cal) as wr:
        for k in range(n):
            wr.add_rgbd(k / 30.0, np.full((h, w, 3), 40 + k, np.uint8), np.full((h, w), 2.0))
    return path


def test_write_text_atomic_full_disk_keeps_the_previous_file(tmp_path, monkeypatch):
    path = tmp_path / "out.txt"
    path.write_text("previous good content\n")
    monkeypatch.setattr(os, "fsync", _enospc)
    with pytest.raises(TudorVisionError, match=r"out\.txt: cannot write \(no space left on device\)"):
        write_text_atomic(path, "new content\n")
    assert path.read_text() == "previous good content\n"
    assert _no_temp_left(tmp_path)


def test_trajectory_csv_full_disk_keeps_the_previous_csv(tmp_path, monkeypatch):
    path = tmp_path / "traj.csv"
    tr = trajectory_from_points([0.0, 0.02], [[0, 0, 1], [0.1, 0, 1]])
    write_trajectory_csv(path, tr)
    before = path.read_bytes()
    monkeypatch.setattr(os, "fsync", _enospc)
    with pytest.raises(TudorVisionError, match="traj.csv: cannot write"):
        write_trajectory_csv(path, trajectory_from_points([0.0], [[1, 1, 1]]))
    assert path.read_bytes() == before and _no_temp_left(tmp_path)


def test_ctrl_c_while_writing_keeps_the_previous_file(tmp_path):
    path = tmp_path / "cal.yaml"
    path.write_text("old\n")
    with pytest.raises(KeyboardInterrupt):
        with atomic_path(path) as tmp:
            tmp.write_text("half")
            raise KeyboardInterrupt
    assert path.read_text() == "old\n" and _no_temp_left(tmp_path)


def test_calibration_yaml_read_only_folder_is_one_line(tmp_path, monkeypatch):
    cal = Calibration(cameras={"c": CameraModel(K=np.diag([500.0, 500.0, 1.0]), width=640, height=480)})
    path = save_calibration(cal, tmp_path / "cal.yaml")
    before = path.read_bytes()

    def read_only(*_a, **_k):
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(tempfile, "mkstemp", read_only)
    with pytest.raises(TudorVisionError, match=r"cal\.yaml: cannot write \(read-only file system\)"):
        save_calibration(cal, path)
    assert path.read_bytes() == before
    assert load_calibration(path).camera("c").width == 640


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root ignores folder permissions")
def test_real_read_only_folder_keeps_the_file(tmp_path):
    path = tmp_path / "ro" / "out.txt"
    path.parent.mkdir()
    path.write_text("old\n")
    path.parent.chmod(0o555)
    try:
        with pytest.raises(TudorVisionError, match="out.txt: cannot write"):
            write_text_atomic(path, "new\n")
    finally:
        path.parent.chmod(0o755)
    assert path.read_text() == "old\n"


def test_cli_full_disk_is_one_line_exit_2_and_keeps_the_previous_csv(tmp_path, monkeypatch, capsys):
    seq = _rgbd_sequence(tmp_path / "seq")
    out = tmp_path / "balls.csv"
    assert main(["detect", "ball", str(seq), "--out", str(out), "--background", "2"]) == 0
    before = out.read_bytes()
    capsys.readouterr()
    monkeypatch.setattr(os, "fsync", _enospc)
    rc = main(["detect", "ball", str(seq), "--out", str(out), "--background", "2"])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2
    assert err == [f"tudorvision detect: error: {out}: cannot write (no space left on device)"]
    assert out.read_bytes() == before and _no_temp_left(tmp_path)


def test_cli_plain_oserror_is_one_line(tmp_path, monkeypatch, capsys):
    """Any OSError reaching main (not only the known subclasses) is one line naming the file."""
    seq = _rgbd_sequence(tmp_path / "seq", n=2)

    def broken(*_a, **_k):
        raise OSError(errno.EIO, "Input/output error", str(tmp_path / "x"))

    monkeypatch.setattr("tudorvision.cli.rgbd._ball_rows", broken)
    rc = main(["detect", "ball", str(seq), "--out", str(tmp_path / "b.csv")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and "input/output error" in err[0] and str(tmp_path / "x") in err[0]
