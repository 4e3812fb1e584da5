"""Plane and circle fits against synthetic truth; rigid-transform helpers."""
import numpy as np
import pytest

from tudorvision.geometry import (fit_circle_3d, fit_plane, fit_rigid_transform, invert_transform,
                                  make_frame, rotation_angle, transform_difference, transform_points)


def _random_pose(rng):
    z = rng.normal(size=3)
    x = rng.normal(size=3)
    return make_frame(rng.uniform(-2, 2, 3), z, x)


def _circle_points(rng, T, radius, angles, noise):
    local = np.column_stack([radius * np.cos(angles), radius * np.sin(angles), np.zeros_like(angles)])
    return transform_points(T, local) + rng.normal(scale=noise, size=local.shape) if noise else \
        transform_points(T, local)


def test_make_frame_is_right_handed_and_respects_axes():
    rng = np.random.default_rng(0)
    for _ in range(50):
        o, z, x = rng.normal(size=(3, 3))
        T = make_frame(o, z, x)
        R = T[:3, :3]
        assert np.allclose(R @ R.T, np.eye(3))
        assert np.isclose(np.linalg.det(R), 1.0)
        assert np.allclose(R[:, 2], z / np.linalg.norm(z))
        assert R[:, 0] @ x > 0 and abs(R[:, 0] @ z) < 1e-12
        assert np.allclose(T[:3, 3], o)


def test_make_frame_rejects_parallel_hint():
    with pytest.raises(ValueError, match="x_hint"):
        make_frame([0, 0, 0], [0, 0, 1], [0, 0, 5])
    with pytest.raises(ValueError, match="z_axis"):
        make_frame([0, 0, 0], [0, 0, 0], [1, 0, 0])


def test_invert_and_transform_points_round_trip():
    rng = np.random.default_rng(1)
    T = _random_pose(rng)
    p = rng.normal(size=(10, 3))
    assert np.allclose(transform_points(invert_transform(T), transform_points(T, p)), p)
    assert np.allclose(invert_transform(T), np.linalg.inv(T))
    # NaN rows pass through, shape of single points kept
    p[3] = np.nan
    out = transform_points(T, p)
    assert np.isnan(out[3]).all() and np.isfinite(np.delete(out, 3, axis=0)).all()
    assert transform_points(T, [1.0, 2.0, 3.0]).shape == (3,)


def test_transform_checks_name_argument():
    with pytest.raises(ValueError, match="T: expected shape"):
        transform_points(np.eye(3), [[0, 0, 0]])
    with pytest.raises(ValueError, match="points"):
        transform_points(np.eye(4), [[0, 0]])


def test_rotation_angle_and_difference():
    T = make_frame([0, 0, 0], [0, 0, 1], [np.cos(0.3), np.sin(0.3), 0])
    assert np.isclose(rotation_angle(T[:3, :3]), 0.3)
    T2 = T.copy()
    T2[:3, 3] = [0.001, 0, 0]
    dt, da = transform_difference(T, T2)
    assert np.isclose(dt, 0.001) and da < 1e-12
    assert np.isclose(rotation_angle(np.diag([1.0, -1.0, -1.0])), np.pi)


def test_fit_rigid_transform_recovers_pose():
    rng = np.random.default_rng(2)
    T = _random_pose(rng)
    pb = rng.normal(size=(20, 3))
    assert np.allclose(fit_rigid_transform(pb, transform_points(T, pb)), T, atol=1e-12)


def test_plane_fit_noise_and_hint():
    rng = np.random.default_rng(3)
    T = _random_pose(rng)
    local = np.column_stack([rng.uniform(-1, 1, (200, 2)), rng.normal(scale=1e-3, size=200)])
    fit = fit_plane(transform_points(T, local), normal_hint=T[:3, 2])
    assert np.arccos(min(1.0, fit.normal @ T[:3, 2])) < 2e-3
    assert 0.7e-3 < fit.rmse < 1.3e-3


@pytest.mark.parametrize("arc", [2 * np.pi, np.pi / 2])
def test_circle_fit_recovers_truth_full_circle_and_short_arc(arc):
    rng = np.random.default_rng(4)
    for _ in range(5):
        T = _random_pose(rng)
        r = rng.uniform(0.3, 1.5)
        ang = np.linspace(0.1, 0.1 + arc, 80, endpoint=arc < 2 * np.pi)
        fit = fit_circle_3d(_circle_points(rng, T, r, ang, 1e-4))
        assert np.linalg.norm(fit.centre - T[:3, 3]) < (1e-4 if arc > 6 else 1e-3)
        assert abs(fit.radius - r) < (5e-5 if arc > 6 else 1e-3)
        # counter-clockwise point order about +z_local: normal = +z_local
        assert np.arccos(min(1.0, fit.normal @ T[:3, 2])) < 2e-3
        assert 0.8e-4 < fit.rmse < 2e-4
        assert fit.inliers.mean() > 0.95


def test_circle_fit_orientation_follows_point_order_or_hint():
    rng = np.random.default_rng(5)
    T = _random_pose(rng)
    pts = _circle_points(rng, T, 0.8, np.linspace(0, 4, 30), 0)
    assert np.allclose(fit_circle_3d(pts[::-1]).normal, -T[:3, 2], atol=1e-9)
    assert np.allclose(fit_circle_3d(pts[::-1], normal_hint=T[:3, 2]).normal, T[:3, 2], atol=1e-9)


def test_circle_fit_is_robust_to_outliers():
    rng = np.random.default_rng(6)
    T = _random_pose(rng)
    pts = _circle_points(rng, T, 0.84, np.linspace(-3, 3, 100), 2e-4)
    bad = rng.choice(100, 10, replace=False)
    pts[bad] += rng.normal(scale=0.05, size=(10, 3))
    robust = fit_circle_3d(pts)
    plain = fit_circle_3d(pts, loss="linear")
    err_r = np.linalg.norm(robust.centre - T[:3, 3])
    err_p = np.linalg.norm(plain.centre - T[:3, 3])
    assert err_r < 5e-4 < err_p
    assert not robust.inliers[bad].any()
    assert robust.inliers.sum() >= 85
    assert robust.rmse < 5e-4 < robust.rmse_all


def test_circle_fit_bad_input_names_argument():
    with pytest.raises(ValueError, match="points: need at least 3"):
        fit_circle_3d([[0, 0, 0], [1, 0, 0]])
    line = np.column_stack([np.linspace(0, 1, 10), np.zeros(10), np.zeros(10)])
    with pytest.raises(ValueError, match="points: points are collinear"):
        fit_circle_3d(line)
    with pytest.raises(ValueError, match="points: contains NaN"):
        fit_circle_3d([[0, 0, 0], [1, 0, 0], [0, np.nan, 0]])
    with pytest.raises(ValueError, match="loss"):
        fit_circle_3d(np.eye(3), loss="l2")
    with pytest.raises(ValueError, match="points: need at least 3"):
        fit_plane(np.zeros((2, 3)))
