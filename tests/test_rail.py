"""Appendix B.5 rail experiment: the scene's truth, the line-deviation metric, the pipeline on a few heights."""
from __future__ import annotations

import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.io import open_sequence
from tudorvision.lab.rail import (RAIL_HEIGHTS_M, RAIL_POSITIONS_M, RailOptions, fit_line, heights_in_view,
                                  rail_deviation, rail_lab, record_rail, user_pick_models)
from tudorvision.stereo import PipelineOptions, SegmentParams, TrackerParams, track_stereo, triangulate_spheres

HEIGHTS = (0.4, 0.8, 1.2)


def _transform(seq, row):
    tr = seq.groundtruth("transforms")
    return np.array([[tr[f"m{i}{j}"][row] for j in range(4)] for i in range(4)])


@pytest.fixture(scope="module")
def rail_seq(tmp_path_factory):
    out = tmp_path_factory.mktemp("rail") / "seq"
    record_rail(out, RailOptions(seed=3, heights_m=HEIGHTS, frames_per_height=3))
    return open_sequence(out)


def test_seed_heights():
    assert len(RAIL_HEIGHTS_M) == 25 and RAIL_HEIGHTS_M[0] == 0.3 and RAIL_HEIGHTS_M[-1] == 1.5
    assert np.allclose(np.diff(RAIL_HEIGHTS_M), 0.05)


def test_truth_lies_on_the_tilted_rail(rail_seq):
    gt, rail, ax = rail_seq.groundtruth("ee"), rail_seq.groundtruth("rail"), rail_seq.groundtruth("rail_axis")
    p = np.column_stack([gt["ee_x_m"], gt["ee_y_m"], gt["ee_z_m"]])
    assert len(rail_seq) == 9
    assert np.allclose(p[:, 2], rail["height_m"], atol=1e-12)
    assert np.allclose(rail["height_m"], np.repeat(HEIGHTS, 3))
    p0 = np.array([ax["p0_x_m"][0], ax["p0_y_m"][0], ax["p0_z_m"][0]])
    d = np.array([ax["d_x"][0], ax["d_y"][0], ax["d_z"][0]])
    q = p - p0
    assert np.abs(q - np.outer(q @ d, d)).max() < 1e-9                       # on the true line
    assert 0.0 <= np.degrees(np.arccos(d[2])) <= 1.0 + 1e-9                   # "not perfectly aligned"
    mid = 0.5 * (np.column_stack([gt["red_x_m"], gt["red_y_m"], gt["red_z_m"]])
                 + np.column_stack([gt["green_x_m"], gt["green_y_m"], gt["green_z_m"]]))
    assert np.allclose(mid, p, atol=1e-12)


def test_exact_centroids_triangulate_onto_the_line(rail_seq):
    """Oracle: exact silhouette centroids through the lab's calibration land within 0.2 mm of the truth."""
    gt = rail_seq.groundtruth("ee")
    uv = {c: {s: np.column_stack([gt[f"{c}_{s}_u_px"], gt[f"{c}_{s}_v_px"]]) for s in ("red", "green")}
          for c in ("left", "right")}
    ee = triangulate_spheres(uv["left"], uv["right"], rail_seq.calibration, T_base_left=_transform(rail_seq, 0)).ee
    truth = np.column_stack([gt["ee_x_m"], gt["ee_y_m"], gt["ee_z_m"]])
    assert np.abs(ee - truth).max() < 2e-4


def test_pipeline_stays_in_the_seed_band(rail_seq):
    """The normal pipeline (a simulated user's pick; tracking reads no truth) keeps the seed's 2 mm band."""
    seg = SegmentParams(edge_refine=True)
    models, frame, picks = user_pick_models(rail_seq, verify_params=seg)
    assert len(picks) == 4 and frame in (0, 3, 6)
    opts = PipelineOptions(tracker=TrackerParams(segment=seg), sphere_separation_m=0.16)
    res = track_stereo(rail_seq, rail_seq.calibration, models, options=opts)
    assert res.trajectory.valid.all()
    h = rail_seq.groundtruth("rail")["height_m"]
    dev = rail_deviation(res.trajectory.p, h)
    assert np.all(dev.band_m < 2e-3), dev.band_m
    T_left_base = np.linalg.inv(_transform(rail_seq, 0))
    gt = rail_seq.groundtruth("ee")
    truth = np.column_stack([gt["ee_x_m"], gt["ee_y_m"], gt["ee_z_m"]]) @ T_left_base[:3, :3].T + T_left_base[:3, 3]
    assert np.linalg.norm(res.trajectory.p - truth, axis=1).max() < 5e-3
    # 0.4 m steps along the rail come out as 0.4 m steps
    assert np.allclose(np.linalg.norm(np.diff(dev.position_m, axis=0), axis=1), 0.4, atol=3e-3)


def test_border_rail_leaves_out_the_heights_out_of_view():
    opts = RailOptions(rail_xy_m=RAIL_POSITIONS_M["border"], frames_per_height=1)
    setup = rail_lab(np.random.default_rng([0, 5]), opts)
    keep = heights_in_view(setup, opts.heights_m)
    assert 0 in keep and len(RAIL_HEIGHTS_M) - 1 not in keep          # 1.5 m at the border is above the image
    with pytest.raises(TudorVisionError, match="outside an image"):
        record_rail("/nonexistent/never_written", RailOptions(rail_xy_m=RAIL_POSITIONS_M["border"],
                                                              skip_out_of_view=False))


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_deviation_oracle(seed):
    """Known per-height offsets perpendicular to a random line give their band, RMS and means back."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=3)
    d /= np.linalg.norm(d)
    n = np.cross(d, rng.normal(size=3))
    n /= np.linalg.norm(n)
    p0 = rng.normal(size=3)
    hs = np.arange(5) * 0.1
    off = np.array([0.0, 1.0, -1.0, 0.5, 0.0]) * 1e-3
    h = np.repeat(hs, 4)
    pts = p0 + np.outer(h, d) + np.outer(np.repeat(off, 4), n)
    dev = rail_deviation(pts, h, line=(p0, 3.0 * d))
    assert np.allclose(dev.mean_m, np.outer(off, n), atol=1e-12)
    assert np.allclose(dev.band_m, (np.outer(off, n)).max(0) - (np.outer(off, n)).min(0), atol=1e-12)
    assert dev.rms_m == pytest.approx(np.sqrt(np.mean(off ** 2)))
    assert np.allclose(dev.std_m, 0.0, atol=1e-12) and dev.n.tolist() == [4] * 5
    # in a rotated frame the band is that of the rotated residuals; the distance (RMS) is unchanged
    R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    rot = rail_deviation(pts, h, line=(p0, d), R=R)
    assert rot.rms_m == pytest.approx(dev.rms_m) and np.allclose(rot.mean_m, dev.mean_m @ R.T)
    # the fitted line of exactly collinear points has no residual; NaN rows are ignored
    pts2 = p0 + np.outer(h, d)
    pts2[3] = np.nan
    fit = rail_deviation(pts2, h)
    assert fit.rms_m < 1e-12 and abs(abs(fit.direction @ d) - 1.0) < 1e-12
    assert fit.n.sum() == len(h) - 1


def test_fit_line_and_bad_input():
    c, d = fit_line([[1, 0, 0], [3, 0, 0]])
    assert c.tolist() == [2.0, 0.0, 0.0] and d.tolist() == [1.0, 0.0, 0.0]
    with pytest.raises(ValueError, match="points"):
        fit_line([[0, 0, 0], [np.nan, 0, 0]])
    with pytest.raises(ValueError, match="heights_m"):
        rail_deviation(np.zeros((3, 3)), [0.1, 0.2])
    with pytest.raises(ValueError, match="heights_m"):
        RailOptions(heights_m=(0.5,))
    with pytest.raises(ValueError, match="frames_per_height"):
        RailOptions(frames_per_height=0)
