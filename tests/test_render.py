"""Ray-cast renderer: sphere centroids, culling, blur, rolling shutter, sensor noise, errors."""
import numpy as np
import pytest

from tudorvision.sim.camera import intrinsic_matrix, look_at, project_points, sphere_silhouette_centroid
from tudorvision.sim.lighting import AmbientLight, DirectionalLight, SensorModel, Varying, apply_sensor
from tudorvision.sim.render import (Box, Capsule, Cylinder, Disc, Rectangle, Scene, Sphere, cast_rays,
                                    render_bgr, render_gbuffer, render_radiance)
from tudorvision.sim.scenes import arm_geometry_from_joints, stereo_lab, stereo_rig

LIGHTS = [AmbientLight(intensity=0.4), DirectionalLight(intensity=0.5)]


def _sphere_scene(centers, radius):
    floor = Rectangle(center=(0, 0, 0), half_size=(5, 5), color_rgb=(0.5, 0.5, 0.5))

    def dynamic(t):
        return [Sphere(center=c, radius=radius, color_rgb=(0.8, 0.1, 0.1), name=f"s{i}") for i, c in enumerate(centers)]
    return Scene(static=[floor], lights=LIGHTS, dynamic=dynamic)


@pytest.mark.parametrize("seed", range(4))
def test_rendered_sphere_centroid_matches_exact_silhouette_centroid(seed):
    """Blur-free frame, both rig cameras with distortion: id-mask centroid vs the analytic silhouette centroid.

    The reference is :func:`sphere_silhouette_centroid` (area centroid of the
    exact perspective silhouette through the lens distortion), not the
    projection of the sphere centre, which differs by up to ~0.1 px here.
    """
    rng = np.random.default_rng(seed)
    left, right = stereo_rig(np.eye(4), rng=rng)
    radius = 0.025 * rng.uniform(1.0, 2.0)
    centers = [rng.uniform([-0.8, -0.8, 0.1], [0.8, 0.8, 1.2]) for _ in range(2)]
    scene = _sphere_scene(centers, radius)
    for cam in (left, right):
        g = render_gbuffer(cam, scene, 0.0)
        for i, c in enumerate(centers):
            v, u = np.nonzero(g.object_id == 2 + i)
            assert u.size > 20
            exact = sphere_silhouette_centroid(cam, c, radius)
            err = np.hypot(u.mean() - exact[0], v.mean() - exact[1])
            assert err < 0.2, (err, cam.T_world_cam[:3, 3])


def test_rendered_centroid_bias_is_perspective_not_render_error():
    """A large off-axis sphere: the mask centroid follows the silhouette centroid, not the projected centre."""
    K = intrinsic_matrix(300.0, 159.5, 119.5)
    cam = look_at([0, -2.5, 1.0], [0, 0, 1.0], K=K, dist=[-0.15, 0.04, 0, 0, 0], width=320, height=240)
    c = np.array([0.8, 0.0, 1.5])
    scene = _sphere_scene([c], 0.3)
    g = render_gbuffer(cam, scene)
    v, u = np.nonzero(g.object_id == 2)
    exact = sphere_silhouette_centroid(cam, c, 0.3)
    proj = project_points(cam, [c])[0]
    assert np.hypot(*(exact - proj)) > 0.5
    assert np.hypot(u.mean() - exact[0], v.mean() - exact[1]) < 0.2


def test_bounding_box_culling_matches_naive_casting():
    rng = np.random.default_rng(3)
    setup = stereo_lab(rng, arm=arm_geometry_from_joints([0.4, 0.9, 0.5], n_points=3))
    cam = setup.cameras["left"]
    from dataclasses import replace
    small = replace(cam, K=np.diag([cam.K[0, 0] / 4, cam.K[1, 1] / 4, 1.0]) + np.array(
        [[0, 0, (160 - 1) / 2], [0, 0, (120 - 1) / 2], [0, 0, 0]]), width=160, height=120)
    shapes = list(setup.scene.static) + list(setup.scene.dynamic(0.0))
    t_fast, id_fast, _ = cast_rays(small, shapes, cull=True)
    t_slow, id_slow, _ = cast_rays(small, shapes, cull=False)
    assert np.array_equal(id_fast, id_slow)
    assert np.array_equal(t_fast, t_slow)
    assert len(np.unique(id_fast)) > 8


def test_shapes_intersections_against_closed_forms():
    o = np.zeros(3)
    d = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8]]).T  # component-first (3, N)
    box = Box(center=(0, 0, 3), half_extents=(0.5, 0.5, 0.5))
    np.testing.assert_allclose(box.intersect(o, d), [2.5, np.inf])
    disc = Disc(center=(0, 0, 2), normal=(0, 0, 1), radius=0.3)
    np.testing.assert_allclose(disc.intersect(o, d), [2.0, np.inf])
    cap = Capsule(p0=(-1, 0, 2), p1=(1, 0, 2), radius=0.1)
    np.testing.assert_allclose(cap.intersect(o, d), [1.9, np.inf])  # slanted ray passes beyond the end cap
    slanted = Capsule(p0=(0, 0, 2), p1=(3, 0, 2), radius=0.1)
    np.testing.assert_allclose(slanted.intersect(o, d), [1.9, 1.9 / 0.8])
    cyl = Cylinder(p0=(0, 0, 2), p1=(0, 0, 3), radius=0.2)
    np.testing.assert_allclose(cyl.intersect(o, d), [2.0, np.inf])
    rect = Rectangle(center=(0, 0, 4), half_size=(4, 1))
    np.testing.assert_allclose(rect.intersect(o, d), [4.0, 5.0])


def _moving_scene(velocity, radius=0.3):
    wall = Rectangle(center=(0, 4, 0), axis_u=(1, 0, 0), axis_v=(0, 0, 1), half_size=(10, 10),
                     color_rgb=(0.5, 0.5, 0.5))
    v = np.asarray(velocity, float)
    return Scene(static=[wall], lights=[AmbientLight(intensity=1.0)],
                 dynamic=lambda t: [Sphere(center=np.array([0.0, 0.0, 0.0]) + v * t, radius=radius,
                                           color_rgb=(0.9, 0.05, 0.05))])


def _small_camera():
    return look_at([0, -3, 0], [0, 0, 0], K=intrinsic_matrix(150.0, 79.5, 59.5), width=160, height=120)


def test_motion_blur_changes_moving_sphere_only():
    cam = _small_camera()
    moving, still = _moving_scene([2.0, 0, 0]), _moving_scene([0, 0, 0])
    for scene, should_change in ((moving, True), (still, False)):
        sharp = render_radiance(cam, scene, 0.0)
        blurred = render_radiance(cam, scene, 0.0, exposure_s=0.04, n_subframes=8)
        diff = np.abs(sharp - blurred).max()
        if should_change:
            assert diff > 0.2
            # blurred silhouette is wider: partially covered pixels appear
            red_sharp = (sharp[..., 0] - sharp[..., 1]) > 0.4
            red_any = (blurred[..., 0] - blurred[..., 1]) > 0.05
            assert red_any.sum() > red_sharp.sum() + 50
        else:
            assert diff < 1e-5


def _row_centroids(rad):
    mask = (rad[..., 0] - rad[..., 1]) > 0.4
    rows = np.nonzero(mask.sum(axis=1) > 4)[0]
    u = np.array([np.nonzero(mask[r])[0].mean() for r in rows])
    return rows, u


def test_rolling_shutter_shifts_moving_sphere_row_dependently():
    cam = _small_camera()
    line_time = 1e-3
    speed = 3.0  # m/s along world x = image u at depth 3 m
    expected_slope = cam.K[0, 0] * speed / 3.0 * line_time  # px per row
    rs = render_radiance(cam, _moving_scene([speed, 0, 0]), 0.0, line_time_s=line_time, band_rows=2)
    rows, u = _row_centroids(rs)
    slope = np.polyfit(rows, u, 1)[0]
    assert abs(slope - expected_slope) < 0.2 * expected_slope
    # global shutter, or a static sphere under rolling shutter: no shear
    for rad in (render_radiance(cam, _moving_scene([speed, 0, 0]), 0.0),
                render_radiance(cam, _moving_scene([0, 0, 0]), 0.0, line_time_s=line_time)):
        rows, u = _row_centroids(rad)
        assert abs(np.polyfit(rows, u, 1)[0]) < 0.2 * expected_slope


def test_rolling_shutter_row_time_matches_global_frame_at_that_time():
    """Row r of a rolling-shutter frame equals row r of a global frame taken at t0 + r * line_time."""
    cam = _small_camera()
    scene = _moving_scene([3.0, 0, 0])
    line_time = 1e-3
    rs = render_radiance(cam, scene, 0.0, line_time_s=line_time, band_rows=1)
    for r in (50, 60, 70):
        g = render_radiance(cam, scene, r * line_time)
        np.testing.assert_allclose(rs[r], g[r], atol=1e-5)


def test_lighting_varies_with_time_and_sensor_noise_is_seeded():
    cam = _small_camera()
    scene = Scene(static=[Rectangle(center=(0, 4, 0), axis_u=(1, 0, 0), axis_v=(0, 0, 1), half_size=(10, 10))],
                  lights=[AmbientLight(intensity=Varying(base=0.5, rel_amplitude=0.5, period_s=10.0))])
    a = render_radiance(cam, scene, 0.0).mean()
    b = render_radiance(cam, scene, 2.5).mean()
    assert b > 1.3 * a
    img1 = render_bgr(cam, scene, 0.0, rng=np.random.default_rng(1))
    img2 = render_bgr(cam, scene, 0.0, rng=np.random.default_rng(1))
    img3 = render_bgr(cam, scene, 0.0, rng=np.random.default_rng(2))
    clean = render_bgr(cam, scene, 0.0)
    assert img1.dtype == np.uint8 and img1.shape == (120, 160, 3)
    assert np.array_equal(img1, img2) and not np.array_equal(img1, img3)
    assert 0.5 < np.std(img1.astype(float) - clean) < 10


def test_output_is_bgr():
    img = apply_sensor(np.array([[[1.0, 0.0, 0.0]]]), SensorModel(), None)
    assert img[0, 0].tolist() == [0, 0, 255]
    cam = _small_camera()
    bgr = render_bgr(cam, _moving_scene([0, 0, 0]), 0.0)
    assert bgr[60, 80, 2] > 3 * bgr[60, 80, 0]


def test_lab_scene_spheres_visible_in_both_cameras():
    rng = np.random.default_rng(11)
    setup = stereo_lab(rng, arm=arm_geometry_from_joints([0.3, 1.0, 0.4]))
    ids = setup.meta["object_ids"]
    centres = arm_geometry_from_joints([0.3, 1.0, 0.4]).sphere_centers_base
    for cam in setup.cameras.values():
        g = render_gbuffer(cam, setup.scene, 0.0)
        for colour in ("red", "green"):
            v, u = np.nonzero(g.object_id == ids[f"{colour}_sphere"])
            assert u.size > 10
            exact = sphere_silhouette_centroid(cam, centres[colour], setup.meta["sphere_radius_m"])
            assert np.hypot(u.mean() - exact[0], v.mean() - exact[1]) < 1.0


@pytest.mark.parametrize("make, name", [
    (lambda: Sphere(radius=-1.0), "radius"),
    (lambda: Sphere(center=(0, 0)), "center"),
    (lambda: Sphere(color_rgb=(2, 0, 0)), "color_rgb"),
    (lambda: Rectangle(axis_u=(1, 0, 0), axis_v=(1, 1, 0)), "axis_v"),
    (lambda: Rectangle(half_size=(1, -1)), "half_size"),
    (lambda: Rectangle(checker_squares=(3, 3)), "checker_square_m"),
    (lambda: Box(half_extents=(1, 0, 1)), "half_extents"),
    (lambda: Box(R_world_box=2 * np.eye(3)), "R_world_box"),
    (lambda: Disc(normal=(0, 0, 0)), "normal"),
    (lambda: Scene(static=[], lights=[]), "lights"),
    (lambda: Varying(base=1.0, period_s=0.0), "period_s"),
    (lambda: SensorModel(gain=0.0), "gain"),
    (lambda: DirectionalLight(direction_world=(0, 0, 0)), "direction_world"),
])
def test_bad_shape_arguments_raise(make, name):
    with pytest.raises(ValueError, match=name):
        make()


@pytest.mark.parametrize("kwargs, name", [
    (dict(exposure_s=-0.01), "exposure_s"),
    (dict(exposure_s=0.01, n_subframes=0), "n_subframes"),
    (dict(line_time_s=-1.0), "line_time_s"),
    (dict(line_time_s=1e-4, band_rows=0), "band_rows"),
])
def test_bad_render_arguments_raise(kwargs, name):
    cam = _small_camera()
    scene = _moving_scene([0, 0, 0])
    with pytest.raises(ValueError, match=name):
        render_bgr(cam, scene, 0.0, **kwargs)


def test_blurred_sphere_centroid_is_mean_over_exposure():
    """Coverage-weighted centroid of a blurred sphere = mean silhouette centroid over the sub-frame times."""
    from tudorvision.sim.render import exposure_times
    cam = look_at([0, -3, 0], [0, 0, 0], K=intrinsic_matrix(150.0, 79.5, 59.5), dist=[-0.1, 0.02, 0, 0, 0],
                  width=160, height=120)
    v = np.array([4.0, 0.0, 1.5])
    scene = _moving_scene(v, radius=0.15)
    rad = render_radiance(cam, scene, 0.0, exposure_s=0.05, n_subframes=10)
    bg, fg = 0.5, 0.9  # ambient-only: radiance = albedo (red channel)
    cover = np.clip((rad[..., 0] - bg) / (fg - bg), 0.0, 1.0)
    vv, uu = np.mgrid[0:120, 0:160]
    centroid = np.array([(cover * uu).sum(), (cover * vv).sum()]) / cover.sum()
    times = exposure_times(0.0, exposure_s=0.05, n_subframes=10)
    truth = np.mean([sphere_silhouette_centroid(cam, v * tt, 0.15) for tt in times], axis=0)
    assert np.hypot(*(centroid - truth)) < 0.2
    sharp = sphere_silhouette_centroid(cam, [0.0, 0.0, 0.0], 0.15)
    assert np.hypot(*(truth - sharp)) > 3.0  # the blur moved the centroid by several pixels


@pytest.mark.parametrize("seed", range(3))
def test_culling_is_exact_for_shapes_around_and_behind_the_camera(seed):
    """Random shapes straddling the image plane and behind the camera: culled casting = naive casting."""
    rng = np.random.default_rng(50 + seed)
    cam = look_at([0, 0, 0], [0, 1, 0.2], K=intrinsic_matrix(60.0, 39.5, 29.5), dist=[-0.2, 0.05, 1e-3, 0, 0],
                  width=80, height=60)
    shapes = []
    for _ in range(25):
        c = rng.uniform(-3, 3, 3)
        kind = rng.integers(5)
        if kind == 0:
            shapes.append(Sphere(center=c, radius=rng.uniform(0.05, 1.0)))
        elif kind == 1:
            q, _ = np.linalg.qr(rng.standard_normal((3, 3)))
            R = q * np.sign(np.linalg.det(q))
            shapes.append(Box(center=c, half_extents=rng.uniform(0.05, 1.0, 3), R_world_box=R))
        elif kind == 2:
            shapes.append(Capsule(p0=c, p1=c + rng.uniform(-2, 2, 3), radius=rng.uniform(0.02, 0.3)))
        elif kind == 3:
            u = rng.standard_normal(3)
            u /= np.linalg.norm(u)
            v = np.cross(u, rng.standard_normal(3))
            shapes.append(Rectangle(center=c, axis_u=u, axis_v=v, half_size=rng.uniform(0.1, 3.0, 2)))
        else:
            shapes.append(Disc(center=c, normal=rng.standard_normal(3), radius=rng.uniform(0.1, 1.5)))
    t_fast, id_fast, _ = cast_rays(cam, shapes)
    t_slow, id_slow, _ = cast_rays(cam, shapes, cull=False)
    assert np.array_equal(id_fast, id_slow)
    assert len(np.unique(id_fast)) > 3


@pytest.mark.parametrize("exposure, K", [(0.0, 1), (0.02, 6)])
def test_rolling_shutter_sphere_truth_matches_render(exposure, K):
    """Coverage-weighted centroid of a rolling-shutter (and blurred) sphere vs sphere_image_truth."""
    from tudorvision.sim.scenes import sphere_image_truth
    cam = look_at([0, -3, 0], [0, 0, 0], K=intrinsic_matrix(150.0, 79.5, 59.5), dist=[-0.1, 0.02, 0, 0, 0],
                  width=160, height=120)
    v = np.array([3.0, 0.0, -1.0])
    scene = _moving_scene(v, radius=0.15)
    line_time = 5e-4
    rad = render_radiance(cam, scene, 0.0, exposure_s=exposure, n_subframes=K, line_time_s=line_time, band_rows=1)
    cover = np.clip((rad[..., 0] - 0.5) / (0.9 - 0.5), 0.0, 1.0)
    vv, uu = np.mgrid[0:120, 0:160]
    centroid = np.array([(cover * uu).sum(), (cover * vv).sum()]) / cover.sum()
    truth = sphere_image_truth(cam, lambda t: v * t, 0.15, 0.0, exposure_s=exposure, n_subframes=K,
                               line_time_s=line_time)
    global_truth = sphere_image_truth(cam, lambda t: v * t, 0.15, 0.0, exposure_s=exposure, n_subframes=K)
    assert np.hypot(*(centroid - truth)) < 0.2
    assert np.hypot(*(truth - global_truth)) > 2.0  # the read-out delay matters here
