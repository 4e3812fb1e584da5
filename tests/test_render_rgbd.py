"""Kinect-like RGB-D rendering: depth noise model, z not range, invalid pixels, scene builders."""
import cv2
import numpy as np
import pytest

from tudorvision.sensors import KINECT_DEPTH_NOISE, DepthNoiseModel
from tudorvision.sim.camera import look_at, project_points
from tudorvision.sim.depth_sensor import DepthSensorModel, depth_mm_from_gbuffer

NO_PATTERN = DepthSensorModel(pattern_disparity_px=0.0)
from tudorvision.sim.raycast import GBuffer
from tudorvision.sim.render import Rectangle, render_gbuffer, render_rgbd
from tudorvision.sim.scenes import ArmGeometry, arm_geometry_from_joints, checkerboard_lab, stereo_lab
from tudorvision.sim.scenes_rgbd import ball_throw, ballistic, eye_in_hand, planar_target, wall_disc

W, H = 80, 60


def _sigma_mm(z):
    """The seed's fit written out independently: sigma in mm (issue 18), z in m."""
    return 0.51 * z ** 3 - 2.1 * z ** 2 + 5.12 * z - 2.18


def test_depth_sigma_is_the_seed_polynomial_in_mm():
    z = np.linspace(0.6, 6.0, 7)
    np.testing.assert_allclose(KINECT_DEPTH_NOISE.sigma_m(z) * 1000, _sigma_mm(z), rtol=1e-12)


@pytest.mark.parametrize("distance", [0.8, 1.0, 1.5, 3.0, 4.5, 5.0, 5.5])
def test_depth_noise_std_matches_sigma_z(distance):
    """Planar target perpendicular to the axis, 100 frames: the simulated std is sigma_z(z) within sampling error.

    The output is rounded to 1 mm, which adds 1/12 mm^2 of variance (Sheppard; exact up to
    exp(-2 pi^2 sigma^2 / step^2) < 1e-6 for sigma >= 0.8 mm); the pooled per-pixel variance minus it
    estimates sigma^2 with a relative standard error sqrt(2 / (pixels * 99)) for independent pixels.
    The noise is correlated between pixels (``noise_corr_px``, Gaussian correlation with scales 2 su, 2 sv):
    the pooled variance then has sum(rho^2) = 2 pi su sv times that variance of its estimate, and the
    mean sum(rho) = 4 pi su sv times the variance of a mean of independent pixels.
    """
    rng = np.random.default_rng(int(distance * 10))
    setup = planar_target(distance, rng, width=W, height=H)
    cam = setup.cameras["rgbd"]
    g = render_gbuffer(cam, setup.scene, 0.0)
    n_frames = 100
    # the noise alone: the sensor's fixed pattern is its own test (test_fixed_pattern_*)
    frames = np.stack([depth_mm_from_gbuffer(g, NO_PATTERN, rng) for _ in range(n_frames)]).astype(float)
    region = (g.object_id == setup.meta["target_id"]) & np.all(frames > 0, axis=0)
    n_px = int(region.sum())
    assert n_px > 30
    var_mm2 = frames[:, region].var(axis=0, ddof=1).mean() - 1.0 / 12.0
    sigma_mm = _sigma_mm(distance)
    su, sv = DepthSensorModel().noise_corr_px
    sum_rho2, sum_rho = max(2 * np.pi * su * sv, 1.0), max(4 * np.pi * su * sv, 1.0)
    se_rel = np.sqrt(2.0 * sum_rho2 / (n_px * (n_frames - 1)))           # of the variance
    assert abs(var_mm2 / sigma_mm ** 2 - 1) < 4 * se_rel
    # the mean is unbiased: within 4 standard errors (and the half-millimetre of rounding noise)
    mean_mm = frames[:, region].mean()
    assert abs(mean_mm - 1000 * distance) < 4 * np.sqrt((sigma_mm ** 2 * sum_rho + 1 / 12) / (n_px * n_frames))


def test_depth_is_z_along_axis_not_ray_length():
    setup = planar_target(2.0, np.random.default_rng(0), width=W, height=H)
    cam = setup.cameras["rgbd"]
    bgr, depth, g = render_rgbd(cam, setup.scene, 0.0, rng=None, depth_model=NO_PATTERN)
    region = (g.object_id == setup.meta["target_id"]) & (depth > 0)
    assert np.all(depth[region] == 2000)
    # the ray length grows towards the image corners, the depth does not
    assert g.distance_m[region].max() > 2.05
    assert bgr.shape == (H, W, 3) and depth.dtype == np.uint16


def test_invalid_pixels_out_of_range_edges_and_dark():
    rng = np.random.default_rng(1)
    # too near and too far
    for d in (0.5, 6.5):
        setup = planar_target(d, rng, width=W, height=H)
        g = render_gbuffer(setup.cameras["rgbd"], setup.scene)
        depth = depth_mm_from_gbuffer(g, DepthSensorModel(), rng)
        assert np.all(depth[g.object_id == setup.meta["target_id"]] == 0)
    # the limits are parameters
    depth = depth_mm_from_gbuffer(g, DepthSensorModel(max_depth_m=7.0), rng)
    assert np.mean(depth[g.object_id == setup.meta["target_id"]] > 0) > 0.5
    # edges: with an unlimited range the background is valid, but the target's border is not
    setup = planar_target(2.0, rng, width=W, height=H, textured=False)
    g = render_gbuffer(setup.cameras["rgbd"], setup.scene)
    depth = depth_mm_from_gbuffer(g, DepthSensorModel(max_depth_m=60.0), None)
    target = g.object_id == setup.meta["target_id"]
    border = target & ~cv2.erode(target.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    interior = cv2.erode(target.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    assert border.sum() > 20 and np.all(depth[border] == 0)
    assert np.all(depth[interior] > 0)
    # dark surfaces: a black target gives no depth
    dark = Rectangle(center=(0.0, 2.0, 1.2), axis_u=(1, 0, 0), axis_v=(0, 0, 1), half_size=(0.5, 0.4),
                     color_rgb=(0.01, 0.01, 0.01))
    from tudorvision.sim.render import Scene
    scene = Scene(static=[dark] + list(setup.scene.static[1:]), lights=setup.scene.lights)
    g = render_gbuffer(setup.cameras["rgbd"], scene)
    depth = depth_mm_from_gbuffer(g, DepthSensorModel(), rng)
    assert np.all(depth[g.object_id == 1] == 0)


def test_wall_disc_is_uniform_depth_and_moves_with_time():
    rng = np.random.default_rng(2)
    centre = lambda t: np.array([0.5 * np.cos(t), 0.0, 0.35 + 0.5 * np.sin(t)])  # noqa: E731
    setup = wall_disc(centre, rng, arm=lambda t: arm_geometry_from_joints([0.0, t, 0.0]), width=160, height=120)
    cam = setup.cameras["rgbd"]
    disc_id = setup.meta["object_ids"]["disc"]
    for t in (0.3, 1.2):
        _, depth, g = render_rgbd(cam, setup.scene, t, rng=None)
        mask = g.object_id == disc_id
        assert mask.sum() > 10
        v, u = np.nonzero(mask)
        uv = project_points(cam, [setup.meta["disc_center_world"](t)])[0]
        assert np.hypot(u.mean() - uv[0], v.mean() - uv[1]) < 1.5
        z = depth[mask & (depth > 0)]
        assert z.size > 5 and np.ptp(z) < 40   # nearly fronto-parallel: uniform depth


def test_ball_throw_only_ball_moves():
    rng = np.random.default_rng(3)
    traj = ballistic([0.2, -5.0, 1.5], [0.0, 5.0, 2.5])
    setup = ball_throw(traj, rng, width=160, height=120)
    cam = setup.cameras["rgbd"]
    _, d0, g0 = render_rgbd(cam, setup.scene, 0.2, rng=None)
    _, d1, g1 = render_rgbd(cam, setup.scene, 0.25, rng=None)
    ball = setup.meta["object_ids"]["ball"]
    changed = d0 != d1
    assert changed.sum() > 0
    assert np.all((g0.object_id == ball) | (g1.object_id == ball) | ~changed)
    dist = np.linalg.norm(traj(0.2) - cam.T_world_cam[:3, 3])
    assert dist < 4.5


def test_eye_in_hand_square_and_checkerboard_corners():
    rng = np.random.default_rng(4)
    T = look_at([0.62, 0.03, 0.9], [0.6, 0.0, 0.0], K=np.eye(3), up_world=(1, 0, 0)).T_world_cam
    setup = eye_in_hand(T, rng, square_center_world=(0.6, 0.0, 0.0), width=160, height=120)
    bgr, depth, g = render_rgbd(setup.cameras["rgbd"], setup.scene, 0.0, rng=rng)
    sq = g.object_id == setup.meta["object_ids"]["square"]
    assert sq.sum() > 50
    assert bgr[sq].mean() < 0.4 * bgr[~sq & (g.object_id > 0)].mean()
    # checkerboard for stereo calibration: OpenCV finds the inner corners where the metadata says
    Tb = look_at([0.2, 0.3, 1.2], [0.5, -3.0, 3.0], K=np.eye(3)).T_world_cam
    cb = checkerboard_lab(Tb, rng, squares=(7, 5), square_m=0.08)
    from tudorvision.sim.render import render_bgr
    for cam in cb.cameras.values():
        img = cv2.cvtColor(render_bgr(cam, cb.scene, 0.0, rng=rng), cv2.COLOR_BGR2GRAY)
        ok, corners = cv2.findChessboardCorners(img, cb.meta["pattern_size"])
        assert ok
        corners = cv2.cornerSubPix(img, corners, (5, 5), (-1, -1),
                                   (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-3)).reshape(-1, 2)
        truth = project_points(cam, cb.meta["inner_corners_world"])
        dmin = np.linalg.norm(corners[:, None] - truth[None], axis=2).min(axis=1)
        assert np.median(dmin) < 0.3 and dmin.max() < 1.0


@pytest.mark.parametrize("make, name", [
    (lambda: DepthSensorModel(min_depth_m=3.0, max_depth_m=2.0), "max_depth_m"),
    (lambda: DepthSensorModel(edge_width_px=-1), "edge_width_px"),
    (lambda: DepthSensorModel(units_per_m=1e5), "units_per_m"),
    (lambda: planar_target(0.0, np.random.default_rng(0)), "distance_m"),
    (lambda: stereo_lab(np.random.default_rng(0), T_world_base=np.ones((4, 4))), "T_world_base"),
    (lambda: stereo_lab(np.random.default_rng(0), arm=3), "arm"),
    (lambda: ArmGeometry(link_points_base=[np.zeros((2, 3))], sphere_centers_base={"red": np.zeros(3)}),
     "sphere_centers_base"),
    (lambda: ArmGeometry(link_points_base=[np.zeros((1, 3))],
                         sphere_centers_base={"red": np.zeros(3), "green": np.zeros(3)}), "link_points_base"),
    (lambda: ball_throw(np.zeros(3), np.random.default_rng(0)), "ball_center_world"),
    (lambda: checkerboard_lab(np.eye(4), np.random.default_rng(0), squares=(1, 5)), "squares"),
    (lambda: wall_disc([0, 0, 1], np.random.default_rng(0), disc_radius_m=0.0), "disc_radius_m"),
])
def test_bad_rgbd_and_scene_arguments_raise(make, name):
    with pytest.raises(ValueError, match=name):
        make()


def test_moving_checkerboard_matches_static_boards():
    """A board given as a function of time renders like a static board at that pose."""
    from tudorvision.sim.render import render_gbuffer as gbuf
    poses = [look_at([x, 0.2, 1.0], [0.3, -3.0, 3.0], K=np.eye(3)).T_world_cam for x in (-0.3, 0.3)]
    moving = checkerboard_lab(lambda t: poses[int(round(t))], np.random.default_rng(5), squares=(5, 4))
    cam = moving.cameras["left"]
    for k, T in enumerate(poses):
        still = checkerboard_lab(T, np.random.default_rng(5), squares=(5, 4))
        g_move = gbuf(cam, moving.scene, float(k))
        g_still = gbuf(still.cameras["left"], still.scene, 0.0)
        m_move = g_move.object_id == moving.meta["object_ids"]["board"]
        m_still = g_still.object_id == still.meta["object_ids"]["board"]
        assert m_move.sum() > 100 and np.array_equal(m_move, m_still)
        np.testing.assert_allclose(moving.meta["inner_corners_world"](k), still.meta["inner_corners_world"])


def test_depth_noise_is_correlated_as_configured_and_scales_with_the_image_width():
    """Neighbouring pixels of a flat target: correlation exp(-1 / (4 s^2)) along u and v (s of 0.9 px and more,
    where the sampled Gaussian follows the continuous one), none with (0, 0), and a half-width image sees half
    the correlation scale (the sensor's own pixels are 640 across)."""
    from tudorvision.sim.depth_sensor import noise_field

    def lag1(res):
        return (np.corrcoef(res[:, 1:].ravel(), res[:, :-1].ravel())[0, 1],
                np.corrcoef(res[1:, :].ravel(), res[:-1, :].ravel())[0, 1])

    rng = np.random.default_rng(5)
    for width, corr, expect in [(640, (1.5, 0.9), (np.exp(-1 / 9.0), np.exp(-1 / 3.24))),
                                (320, (3.0, 1.8), (np.exp(-1 / 9.0), np.exp(-1 / 3.24))),
                                (640, (0.0, 0.0), (0.0, 0.0))]:
        sigma = 0.004
        z = np.full((120, width), 2.0)
        g = GBuffer(distance_m=z, depth_m=z, normal_world=np.zeros(z.shape + (3,), np.float32),
                    object_id=np.ones(z.shape, np.int32), albedo_rgb=np.full(z.shape + (3,), 0.5, np.float32))
        model = DepthSensorModel(noise_corr_px=corr, noise=DepthNoiseModel(coeffs=(0.0, 0.0, 0.0, sigma)),
                                 units_per_m=10000.0, max_depth_m=6.0, pattern_disparity_px=0.0)
        res = depth_mm_from_gbuffer(g, model, rng).astype(float) / 1e4 - 2.0
        assert abs(res.std() / sigma - 1) < 0.06                        # each pixel keeps sigma_z
        np.testing.assert_allclose(lag1(res), expect, atol=0.04)
    f = noise_field((50, 60), np.random.default_rng(0), (2.0, 1.0), np.float32)
    assert f.shape == (50, 60) and f.dtype == np.float32
    with pytest.raises(ValueError, match="noise_corr_px"):
        DepthSensorModel(noise_corr_px=(1.0,))
    with pytest.raises(ValueError, match="noise_corr_px"):
        DepthSensorModel(noise_corr_px=(-1.0, 0.5))


def test_fixed_pattern_is_the_units_own_and_moves_depth_as_a_disparity_offset():
    """The sensor's fixed pattern: the same in every frame and with or without noise (the unit's, drawn from
    its own seed), a disparity offset (``z -> 1 / (1 / z + c)``: four times the depth error at twice the
    distance), the measured RMS and no affine part over the image; another unit has another pattern."""
    from tudorvision.sim.depth_sensor import KINECT_FOCAL_BASELINE_PX_M, KINECT_PATTERN_DISPARITY_PX, pattern_field

    H, W_ = 120, 160
    m = DepthSensorModel(units_per_m=10000.0)
    assert m.pattern_disparity_px == KINECT_PATTERN_DISPARITY_PX          # the lab's Kinect has it by default
    c = pattern_field(m, H, W_)
    assert abs(np.sqrt(np.mean(c ** 2)) * KINECT_FOCAL_BASELINE_PX_M / KINECT_PATTERN_DISPARITY_PX - 1) < 1e-9
    vv, uu = np.mgrid[0:H, 0:W_]
    A = np.stack([np.ones(c.size), uu.ravel(), vv.ravel()], 1)
    assert np.abs(np.linalg.lstsq(A, c.ravel(), rcond=None)[0]).max() < 1e-12
    errs = {}
    for z0 in (2.0, 4.0):
        z = np.full((H, W_), z0)
        g = GBuffer(distance_m=z, depth_m=z, normal_world=np.zeros(z.shape + (3,), np.float32),
                    object_id=np.ones(z.shape, np.int32), albedo_rgb=np.full(z.shape + (3,), 0.5, np.float32))
        clean = depth_mm_from_gbuffer(g, m, None).astype(float) / 1e4
        np.testing.assert_allclose(clean, 1.0 / (1.0 / z0 + c), atol=0.6e-4)     # the 0.1 mm output step
        errs[z0] = np.sqrt(np.mean((clean - z0) ** 2))
        noisy = np.mean([depth_mm_from_gbuffer(g, m, np.random.default_rng(k)).astype(float) / 1e4
                         for k in range(30)], axis=0)
        # the noise averages away over frames, the pattern does not
        assert np.sqrt(np.mean((noisy - clean) ** 2)) < 0.25 * errs[z0]
    assert 3.6 < errs[4.0] / errs[2.0] < 4.4
    other = pattern_field(DepthSensorModel(pattern_seed=1), H, W_)
    assert abs(np.corrcoef(c.ravel(), other.ravel())[0, 1]) < 0.5
    with pytest.raises(ValueError, match="pattern_disparity_px"):
        DepthSensorModel(pattern_disparity_px=-0.1)
    with pytest.raises(ValueError, match="pattern_seed"):
        DepthSensorModel(pattern_seed=1.5)
    with pytest.raises(ValueError, match="pattern_corr_px"):
        DepthSensorModel(pattern_corr_px=(0.0, 20.0))


def _step_edge(c0, shape=(480, 640), slope=0.03):
    """A straight depth edge: 1.5 m from column ``c0 + slope (v - 240)`` rightwards, 2.5 m to its left."""
    vv, uu = np.mgrid[0:shape[0], 0:shape[1]].astype(float)
    z = np.where(uu >= c0 + slope * (vv - 240.0), 1.5, 2.5)
    return GBuffer(distance_m=z, depth_m=z, normal_world=np.zeros(z.shape + (3,), np.float32),
                   object_id=np.ones(z.shape, np.int32), albedo_rgb=np.full(z.shape + (3,), 0.5, np.float32))


def _edge_cols(depth_mm, rows):
    """First column of the near (1.5 m) side per row."""
    return np.array([np.nonzero((depth_mm[r] > 1350) & (depth_mm[r] < 1700))[0][0] for r in rows], float)


@pytest.mark.parametrize("jitter, sd_range", [((0.0, 0.0), (0.2, 0.35)), ((0.9, 2.0), (0.75, 1.05)),
                                              ((0.5, 2.0), (0.45, 0.7))])
def test_edge_jitter_scatters_a_straight_edge_as_configured_without_moving_it(jitter, sd_range):
    """A straight step edge through the sensor: the first near column per row scatters about the true edge
    line by the jitter (plus the whole-pixel rounding, 0.29 px for a slanted edge) and is unbiased (the true
    edge of row v is at ``ceil(c0 + 0.03 (v - 240))``, the pixels on either side of a jump invalid); the
    real Kinect's monitor sides give 0.77 / 0.92 px (``benchmarks/bench_depth_noise_real.py``)."""
    rows = np.arange(100, 400)
    sds, offsets = [], []
    for i in range(6):
        c0 = 300.3 + 0.37 * i
        d = depth_mm_from_gbuffer(_step_edge(c0), DepthSensorModel(edge_jitter_px=jitter), np.random.default_rng(i))
        cols = _edge_cols(d, rows)
        truth = np.ceil(c0 + 0.03 * (rows - 240.0))
        res = cols - np.polyval(np.polyfit(rows, cols, 1), rows)
        sds.append(res.std())
        offsets.append(np.mean(cols - (truth + 1)))
    assert sd_range[0] < np.mean(sds) < sd_range[1]
    assert abs(np.mean(offsets)) < 0.15


def test_edge_jitter_leaves_smooth_surfaces_and_the_noise_draw_alone():
    """A steep but smooth plane (1 mm per pixel, no depth edge) without depth noise comes out exactly as with
    no jitter, and the depth noise itself is the same draw with and without jitter (drawn first)."""
    vv, uu = np.mgrid[0:120, 0:160].astype(float)
    z = 2.0 + 0.001 * uu + 0.0005 * vv
    g = GBuffer(distance_m=z, depth_m=z, normal_world=np.zeros(z.shape + (3,), np.float32),
                object_id=np.ones(z.shape, np.int32), albedo_rgb=np.full(z.shape + (3,), 0.5, np.float32))
    quiet = DepthNoiseModel(coeffs=(0.0,), floor_m=0.0)
    a = depth_mm_from_gbuffer(g, DepthSensorModel(noise=quiet), np.random.default_rng(0))
    b = depth_mm_from_gbuffer(g, DepthSensorModel(noise=quiet, edge_jitter_px=(0.0, 0.0)), np.random.default_rng(0))
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a, depth_mm_from_gbuffer(g, DepthSensorModel(noise=quiet), None))
    a = depth_mm_from_gbuffer(g, DepthSensorModel(), np.random.default_rng(3))
    b = depth_mm_from_gbuffer(g, DepthSensorModel(edge_jitter_px=(0.0, 0.0)), np.random.default_rng(3))
    np.testing.assert_array_equal(a, b)
    for bad in [(1.0,), (-0.5, 2.0), (0.9, 30.0), "x"]:
        with pytest.raises(ValueError, match="edge_jitter_px"):
            DepthSensorModel(edge_jitter_px=bad)
