"""Camera model of the virtual lab: projection, rays, distortion, silhouette centroid."""
import cv2
import numpy as np
import pytest

from tudorvision.sim.camera import (PinholeCamera, intrinsic_matrix, look_at, project_points,
                                    ray_directions_cam, ray_directions_world, sphere_silhouette_centroid,
                                    undistort_normalized, distort_normalized, with_pose)


def _random_camera(rng, width=640, height=480, f=700.0):
    eye = rng.uniform([-2, -3, 1.5], [2, -1, 3])
    target = rng.uniform([-0.5, -0.5, 0.0], [0.5, 0.5, 1.0])
    dist = np.array([rng.uniform(-0.25, 0.05), rng.uniform(-0.05, 0.1), rng.uniform(-2e-3, 2e-3),
                     rng.uniform(-2e-3, 2e-3), rng.uniform(-0.02, 0.02)])
    K = intrinsic_matrix(f * rng.uniform(0.9, 1.1), (width - 1) / 2 + rng.uniform(-5, 5),
                         (height - 1) / 2 + rng.uniform(-5, 5), fy_px=f * rng.uniform(0.9, 1.1))
    return look_at(eye, target, K=K, dist=dist, width=width, height=height)


@pytest.mark.parametrize("seed", range(5))
def test_projection_matches_opencv(seed):
    rng = np.random.default_rng(seed)
    cam = _random_camera(rng)
    pts = rng.uniform([-1, -1, 0], [1, 1, 1.5], (200, 3))
    uv = project_points(cam, pts)
    R_cam_world = cam.T_world_cam[:3, :3].T
    t_cam_world = -R_cam_world @ cam.T_world_cam[:3, 3]
    rvec, _ = cv2.Rodrigues(R_cam_world)
    uv_cv, _ = cv2.projectPoints(pts.reshape(-1, 1, 3), rvec, t_cam_world, cam.K, cam.dist)
    np.testing.assert_allclose(uv, uv_cv.reshape(-1, 2), atol=1e-6)


def test_undistort_matches_opencv_and_inverts_distortion():
    rng = np.random.default_rng(7)
    cam = _random_camera(rng)
    uv = rng.uniform([0, 0], [640, 480], (300, 2))
    xn = ((uv - cam.K[:2, 2]) / np.diag(cam.K)[:2])
    xy = undistort_normalized(xn, cam.dist)
    xy_cv = cv2.undistortPoints(uv.reshape(-1, 1, 2), cam.K, cam.dist, None, None, None,
                                    (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)).reshape(-1, 2)
    np.testing.assert_allclose(xy, xy_cv, atol=1e-7)
    np.testing.assert_allclose(distort_normalized(xy, cam.dist), xn,
                               atol=1e-12)


@pytest.mark.parametrize("seed", range(3))
def test_ray_projection_round_trip(seed):
    rng = np.random.default_rng(100 + seed)
    cam = _random_camera(rng, width=96, height=72, f=105.0)
    rays = ray_directions_world(cam)
    np.testing.assert_allclose(np.linalg.norm(rays, axis=-1), 1.0, atol=1e-12)
    depth = rng.uniform(0.5, 8.0, rays.shape[:2])
    pts = cam.T_world_cam[:3, 3] + depth[..., None] * rays
    uv = project_points(cam, pts.reshape(-1, 3)).reshape(72, 96, 2)
    v, u = np.mgrid[0:72, 0:96]
    np.testing.assert_allclose(uv[..., 0], u, atol=1e-6)
    np.testing.assert_allclose(uv[..., 1], v, atol=1e-6)
    assert ray_directions_cam(cam) is ray_directions_cam(cam)  # cached


def test_look_at_axis_and_up():
    cam = look_at([1.0, -2.0, 2.5], [0.0, 0.0, 0.5], K=intrinsic_matrix(500, 320, 240))
    z = cam.T_world_cam[:3, 2]
    target_dir = np.array([-1.0, 2.0, -2.0]) / 3.0
    np.testing.assert_allclose(z, target_dir, atol=1e-12)
    # a point above the target appears above it in the image (smaller v)
    uv = project_points(cam, [[0.0, 0.0, 0.5], [0.0, 0.0, 0.8]])
    assert uv[1, 1] < uv[0, 1]
    moved = with_pose(cam, np.eye(4))
    assert np.allclose(moved.T_world_cam, np.eye(4)) and moved.width == cam.width


def test_points_behind_camera_give_nan():
    cam = PinholeCamera(K=intrinsic_matrix(500, 320, 240), dist=np.zeros(5), width=640, height=480,
                        T_world_cam=np.eye(4))
    uv = project_points(cam, [[0, 0, -1.0], [0, 0, 1.0]])
    assert np.all(np.isnan(uv[0])) and np.all(np.isfinite(uv[1]))


def _brute_force_silhouette_centroid(cam, center, radius):
    """Dense pixel-space sampling with OpenCV's undistortion and the cone test (an independent oracle)."""
    uv_c = project_points(cam, [center])[0]
    pc = (np.asarray(center) - cam.T_world_cam[:3, 3]) @ cam.T_world_cam[:3, :3]
    r_px = cam.K[0, 0] * radius / pc[2] * 1.6 + 3
    step = r_px / 250
    g = np.arange(-r_px, r_px, step) + step / 2
    uu, vv = np.meshgrid(uv_c[0] + g, uv_c[1] + g)
    uv = np.stack([uu.ravel(), vv.ravel()], 1)
    xy = cv2.undistortPoints(uv.reshape(-1, 1, 2), cam.K, cam.dist, None, None, None,
                                 (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)).reshape(-1, 2)
    d = np.concatenate([xy, np.ones((len(xy), 1))], 1)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    cos_a = np.sqrt(1 - radius ** 2 / (pc @ pc))
    inside = d @ (pc / np.linalg.norm(pc)) >= cos_a
    return uv[inside].mean(axis=0)


@pytest.mark.parametrize("seed", range(3))
def test_silhouette_centroid_matches_brute_force(seed):
    rng = np.random.default_rng(200 + seed)
    cam = _random_camera(rng)
    center = rng.uniform([-0.8, -0.8, 0.2], [0.8, 0.8, 1.2])
    radius = rng.uniform(0.1, 0.2)
    exact = sphere_silhouette_centroid(cam, center, radius)
    brute = _brute_force_silhouette_centroid(cam, center, radius)
    np.testing.assert_allclose(exact, brute, atol=0.02)


def test_silhouette_centroid_differs_from_projected_centre_off_axis():
    cam = PinholeCamera(K=intrinsic_matrix(700, 320, 240), dist=np.zeros(5), width=640, height=480,
                        T_world_cam=np.eye(4))
    center = np.array([0.8, 0.0, 2.0])
    c = sphere_silhouette_centroid(cam, center, 0.2)
    p = project_points(cam, [center])[0]
    # perspective pushes the silhouette centre outwards: (tan of the tangent rays' mean)
    a = np.arctan2(0.8, 2.0)
    half = np.arcsin(0.2 / np.hypot(0.8, 2.0))
    u_ellipse_centre = 320 + 700 * 0.5 * (np.tan(a + half) + np.tan(a - half))
    assert c[0] > p[0] + 1.0
    assert abs(c[0] - u_ellipse_centre) < 1e-6
    assert abs(c[1] - 240) < 1e-9


@pytest.mark.parametrize("kwargs, name", [
    (dict(K=np.eye(2)), "K"),
    (dict(dist=np.zeros(4)), "dist"),
    (dict(width=0), "width"),
    (dict(height=2.5), "height"),
    (dict(T_world_cam=np.diag([1.0, 1.0, -1.0, 1.0])), "T_world_cam"),
])
def test_bad_camera_arguments_raise(kwargs, name):
    args = dict(K=intrinsic_matrix(500, 320, 240), dist=np.zeros(5), width=640, height=480, T_world_cam=np.eye(4))
    args.update(kwargs)
    with pytest.raises(ValueError, match=name):
        PinholeCamera(**args)


def test_bad_look_at_and_silhouette_arguments_raise():
    K = intrinsic_matrix(500, 320, 240)
    with pytest.raises(ValueError, match="target_world"):
        look_at([0, 0, 1], [0, 0, 1], K=K)
    with pytest.raises(ValueError, match="up_world"):
        look_at([0, 0, 1], [0, 0, 0], K=K)
    cam = look_at([0, -2, 1], [0, 0, 1], K=K)
    with pytest.raises(ValueError, match="center_world"):
        sphere_silhouette_centroid(cam, [0, -2, 1], 0.1)
    with pytest.raises(ValueError, match="radius"):
        sphere_silhouette_centroid(cam, [0, 0, 1], -0.1)


def test_with_pose_rays_match_a_fresh_camera():
    rng = np.random.default_rng(5)
    cam = _random_camera(rng, width=64, height=48, f=70.0)
    ray_directions_world(cam)
    T = look_at([0.3, -1.0, 2.0], [0.0, 0.5, 0.0], K=cam.K).T_world_cam
    moved = with_pose(cam, T)
    fresh = type(cam)(K=cam.K, dist=cam.dist, width=64, height=48, T_world_cam=T)
    np.testing.assert_allclose(ray_directions_world(moved), ray_directions_world(fresh), atol=1e-15)
    assert not np.allclose(ray_directions_world(moved), ray_directions_world(cam))
