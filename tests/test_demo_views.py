"""The demo's ``views.png``: six labelled tiles and a depth colour bar (issue 16: the tiles were unlabelled)."""
from __future__ import annotations

import cv2
import numpy as np

from tudorvision.lab.demo import views_sheet


def test_views_sheet_labels_every_tile_and_adds_a_depth_scale(tmp_path):
    out = tmp_path / "views.png"
    views_sheet("sample_data/stereo-step", ["sample_data/rgbd-disc", "sample_data/servo-views"], out)
    img = cv2.imread(str(out))
    assert img.shape == (480 + 240 + 64, 1280, 3)
    # a dark label box in the top-left corner of each of the six tiles
    for y, x in ((8, 8), (8, 648), (488, 8), (488, 328), (488, 648), (488, 968)):
        box = img[y:y + 6, x:x + 6].reshape(-1, 3)
        assert np.all(np.abs(box.astype(int) - 30) < 4) or np.all(box > 200), (y, x)
        label = img[y - 4:y + 22, x - 4:x + 120]
        assert (label > 200).all(axis=2).any() and (np.abs(label.astype(int) - 30) < 4).all(axis=2).any(), (y, x)
    # the colour bar's ramp is the turbo map, dark blue at 0 m to dark red at 6 m
    ramp = img[480 + 240 + 30, 20:1260]
    turbo = cv2.applyColorMap(np.array([[0, 255]], np.uint8), cv2.COLORMAP_TURBO)[0]
    assert np.abs(ramp[0].astype(int) - turbo[0]).max() <= 3
    assert np.abs(ramp[-1].astype(int) - turbo[1]).max() <= 3
    # the depth tile of the disc recording uses the same map: its floor runs through green to red
    depth_tile = img[480:720, 320:640]
    assert depth_tile[..., 1].max() > 200 and depth_tile[..., 2].max() > 200
