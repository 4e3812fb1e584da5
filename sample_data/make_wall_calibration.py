"""Write ``rgbd-throws/wall_calibration.yaml``: the throw camera's calibration with its true ``T_base_cam``.

The wall camera of ``rgbd-throws`` is not the one of ``rgbd-disc`` (a different pose), so
``calib rgbd-base`` on the disc sweep does not fit it; this file holds what a wall-camera
calibration of the throw camera gives: its intrinsics (``calibration.yaml``) and its pose from the
recording's ground truth (``groundtruth/T_base_cam.csv``). Run by ``make sample-data``:
``.venv/bin/python sample_data/make_wall_calibration.py sample_data/rgbd-throws``.
"""
from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np

from tudorvision.io import load_calibration, open_sequence, save_calibration


def main(seq_dir: str) -> None:
    seq = open_sequence(seq_dir)
    gt = seq.groundtruth("T_base_cam")
    T_base_cam = np.array([gt[f"m{i}{j}"][0] for i in range(4) for j in range(4)], float).reshape(4, 4)
    cal = load_calibration(Path(seq_dir) / "calibration.yaml")
    meta = dict(cal.metadata, note="T_base_cam: the recording's true camera pose (groundtruth/T_base_cam.csv)")
    cal = dataclasses.replace(cal, transforms={**cal.transforms, "T_base_cam": T_base_cam}, metadata=meta)
    out = Path(seq_dir) / "wall_calibration.yaml"
    save_calibration(cal, out)
    print(f"wrote {out}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "sample_data/rgbd-throws")
