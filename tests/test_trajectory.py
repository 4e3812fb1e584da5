"""Finite-difference velocity/acceleration against analytic derivatives; CSV round trip; plot."""
import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.stereo.trajectory import (finite_differences, plot_trajectory, read_trajectory_csv,
                                           trajectory_from_points, write_trajectory_csv)


def _motion(t):
    """A step-like swing: 0.5 m amplitude at 1.7 Hz (peak speed ~5.3 m/s) plus a slow drift."""
    w = 2 * np.pi * 1.7
    p = np.column_stack([0.5 * np.sin(w * t), 0.3 * np.cos(w * t), 0.1 * t])
    v = np.column_stack([0.5 * w * np.cos(w * t), -0.3 * w * np.sin(w * t), np.full_like(t, 0.1)])
    a = np.column_stack([-0.5 * w * w * np.sin(w * t), -0.3 * w * w * np.cos(w * t), 0 * t])
    return p, v, a


def test_central_differences_match_analytic_derivatives_at_50hz():
    t = np.arange(100) * 0.02
    p, v, a = _motion(t)
    vd, ad = finite_differences(t, p)
    # O(h^2) truncation: |v'''| h^2 / 6 and |a''| h^2 / 12
    w = 2 * np.pi * 1.7
    assert np.nanmax(np.abs(vd - v)) < 0.5 * w ** 3 * 0.02 ** 2 / 6 * 1.01
    assert np.nanmax(np.abs(ad - a)) < 0.5 * w ** 4 * 0.02 ** 2 / 12 * 1.01
    assert np.isnan(vd[[0, -1]]).all() and np.isnan(ad[[0, -1]]).all()
    assert np.isfinite(vd[1:-1]).all()


def test_nonuniform_spacing_is_exact_for_quadratics():
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.015, 0.045, 40))       # dropped and jittered frames
    p = np.column_stack([3 * t ** 2 - t, 0.5 * t ** 2, np.ones_like(t)])
    v, a = finite_differences(t, p)
    assert np.allclose(a[1:-1], [6.0, 1.0, 0.0], atol=1e-8)
    # central difference on uneven spacing: exact derivative at the midpoint time
    tm = (t[2:] + t[:-2]) / 2
    assert np.allclose(v[1:-1, 0], 6 * tm - 1, atol=1e-9)


def test_gaps_give_nan_only_next_to_missing_samples():
    t = np.arange(12) * 0.02
    p, _, _ = _motion(t)
    p[5] = np.nan
    p[8, 2] = np.nan                     # a partially missing row counts as missing
    tr = trajectory_from_points(t, p)
    assert tr.valid.tolist() == [True] * 5 + [False] + [True] * 2 + [False] + [True] * 3
    nan_v = np.isnan(tr.v).any(axis=1)
    assert nan_v.tolist() == [True, False, False, False, True, True, True, True, True, True, False, True]
    assert np.isnan(tr.p[8]).all()
    # long dropouts: max_dt_s refuses differences across them
    t2 = np.array([0.0, 0.02, 0.04, 0.3, 0.32, 0.34])
    v, a = finite_differences(t2, np.c_[t2, t2, t2], max_dt_s=0.05)
    assert np.isnan(v[[2, 3]]).all() and np.isfinite(v[[1, 4]]).all()


def test_bad_input_names_argument():
    with pytest.raises(ValueError, match="t: timestamps must increase"):
        finite_differences([0.0, 0.02, 0.02], np.zeros((3, 3)))
    with pytest.raises(ValueError, match="p: expected"):
        trajectory_from_points([0.0, 0.02], np.zeros((3, 3)))
    with pytest.raises(ValueError, match="frame"):
        trajectory_from_points([0.0], np.zeros((1, 3)), frame="a,b")


def test_csv_round_trip_keeps_partial_trajectory(tmp_path):
    t = np.arange(30) * 0.02 + 100.0
    p, _, _ = _motion(t)
    p[10:13] = np.nan
    tr = trajectory_from_points(t, p, frame="base")
    path = write_trajectory_csv(tmp_path / "sub" / "traj.csv", tr, comment="made by a test")
    text = path.read_text().splitlines()
    assert text[0].startswith("# tudorvision trajectory")
    assert text[1] == "# frame: base (robot base frame, z up)"
    assert "m/s^2" in text[2] and text[3] == "# made by a test"
    assert text[4] == "t,x,y,z,vx,vy,vz,ax,ay,az,valid"
    assert len(text) == 5 + 30 and text[5 + 11].endswith(",0")
    back = read_trajectory_csv(path)
    assert back.frame == "base"
    assert np.array_equal(back.valid, tr.valid)
    for name in ("t", "p", "v", "a"):
        assert np.allclose(getattr(back, name), getattr(tr, name), equal_nan=True, rtol=0, atol=0)


def test_csv_reader_errors_name_file_and_line(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("# frame: left\nt,x,y\n")
    with pytest.raises(TudorVisionError, match="bad.csv:2: expected header"):
        read_trajectory_csv(bad)
    bad.write_text("t,x,y,z,vx,vy,vz,ax,ay,az,valid\n0,1,2,3,4,5,6,7,8,9,1\n0.1,1,2,oops,4,5,6,7,8,9,1\n")
    with pytest.raises(TudorVisionError, match="bad.csv:3: malformed number"):
        read_trajectory_csv(bad)
    with pytest.raises(TudorVisionError, match="not found"):
        read_trajectory_csv(tmp_path / "missing.csv")


def test_plot_writes_png(tmp_path):
    t = np.arange(60) * 0.02
    p, _, _ = _motion(t)
    p[20] = np.nan
    out = plot_trajectory(trajectory_from_points(t, p), tmp_path / "traj.png")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
