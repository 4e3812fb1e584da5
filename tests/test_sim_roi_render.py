"""The servo lab's region-of-interest renderer against the full ray-caster (the oracle)."""
from dataclasses import replace

import numpy as np
import pytest

from tudorvision.sim.roi_render import RoiRenderer
from tudorvision.sim import eye_in_hand, render_rgbd, with_pose
from tudorvision.sim.lighting import PointLight
from tudorvision.sim.depth_sensor import DepthSensorModel
from tudorvision.sim.render import Scene


def _down_pose(x, y, h, yaw_deg=0.0, tilt_deg=0.0):
    """Camera at (x, y, h) looking down (optical axis -z), rotated about it and tilted about its x axis."""
    a, b = np.deg2rad(yaw_deg), np.deg2rad(tilt_deg)
    Rz = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    Rx = np.array([[1, 0, 0], [0, np.cos(b), -np.sin(b)], [0, np.sin(b), np.cos(b)]])
    T = np.eye(4)
    T[:3, :3] = Rz @ np.diag([1.0, -1.0, -1.0]) @ Rx
    T[:3, 3] = [x, y, h]
    return T


POSES = [(0.0, 0.0, 0.75, 0, 0), (0.05, -0.03, 0.7, 30, 10), (0.2, 0.12, 0.8, -20, -15),   # square near a corner
         (0.27, 0.0, 0.7, 0, 0),                                                            # square half out of view
         (1.5, 1.5, 0.8, 0, 0)]                                                              # square not in view


@pytest.mark.parametrize("pose", POSES)
def test_noise_free_frames_equal_the_full_render(pose):
    setup = eye_in_hand(_down_pose(*pose), np.random.default_rng(3), square_center_world=(0, 0, 0),
                        width=320, height=240)
    cam = setup.cameras["rgbd"]
    r = RoiRenderer(setup.scene, DepthSensorModel())
    bgr, depth = r.render(cam, 0.0, rng=None)
    ref_bgr, ref_depth, _ = render_rgbd(cam, setup.scene, 0.0, rng=None)
    assert r.n_roi == 1 and r.n_full == 0
    np.testing.assert_array_equal(bgr, ref_bgr)
    # plane depth in closed form vs ray casting: equal up to a rounding tie
    assert np.mean(depth != ref_depth) < 1e-4 and np.abs(depth.astype(int) - ref_depth).max() <= 1
    np.testing.assert_array_equal(depth == 0, ref_depth == 0)


def test_moved_camera_and_dynamic_square():
    setup = eye_in_hand(_down_pose(0, 0, 0.75), np.random.default_rng(1), square_center_world=(0, 0, 0),
                        width=320, height=240)
    sq = [s for s in setup.scene.static if s.name == "square"][0]
    ground = [s for s in setup.scene.static if s.name == "ground"]
    scene = Scene(static=ground, lights=setup.scene.lights,
                  dynamic=lambda t: [replace(sq, center=np.asarray(sq.center) + [0.1 * t, 0, 0])])
    r = RoiRenderer(scene, DepthSensorModel())
    for k, t in enumerate((0.0, 0.5, 1.0)):
        cam = with_pose(setup.cameras["rgbd"], _down_pose(0.02 * k, -0.01 * k, 0.75 - 0.03 * k, 10 * k))
        bgr, depth = r.render(cam, t, rng=None)
        ref_bgr, ref_depth, _ = render_rgbd(cam, scene, t, rng=None)
        np.testing.assert_array_equal(bgr, ref_bgr)
        assert np.abs(depth.astype(int) - ref_depth).max() <= 1
    assert r.n_roi == 3


def test_noise_has_the_full_renders_distribution():
    setup = eye_in_hand(_down_pose(0.03, 0.02, 0.8, 15), np.random.default_rng(5), square_center_world=(0, 0, 0),
                        width=320, height=240)
    cam = setup.cameras["rgbd"]
    r = RoiRenderer(setup.scene, DepthSensorModel())
    clean_bgr, clean_depth, gb = render_rgbd(cam, setup.scene, 0.0, rng=None)
    a_bgr, a_depth = r.render(cam, 0.0, rng=np.random.default_rng(11))
    b_bgr, b_depth, _ = render_rgbd(cam, setup.scene, 0.0, rng=np.random.default_rng(12))
    ground = gb.object_id == 1
    square = gb.object_id == 2
    for region in (ground, square):
        for c in range(3):
            a = a_bgr[..., c][region].astype(float)
            b = b_bgr[..., c][region].astype(float)
            assert abs(a.mean() - b.mean()) < 4 * b.std() / np.sqrt(region.sum()) + 0.02
            assert a.std() == pytest.approx(b.std(), rel=0.1)
            assert a.std() > 0.3           # there is noise
        da = (a_depth.astype(float) - clean_depth)[region]
        db = (b_depth.astype(float) - clean_depth)[region]
        for d in (da, db):
            assert abs(d.mean()) < 4 * d.std() / np.sqrt(d.size) + 0.05
        assert da.std() == pytest.approx(db.std(), rel=0.1)
    # independent noise: two draws differ
    c_bgr, _ = r.render(cam, 0.0, rng=np.random.default_rng(13))
    assert np.mean(c_bgr != a_bgr) > 0.3


def test_falls_back_to_the_full_render_where_the_shortcut_does_not_hold():
    setup = eye_in_hand(_down_pose(0, 0, 0.75), np.random.default_rng(2), square_center_world=(0, 0, 0),
                        width=160, height=120)
    cam = setup.cameras["rgbd"]
    lit = Scene(static=setup.scene.static, lights=[*setup.scene.lights,
                                                   PointLight(position_world=(0.3, 0.0, 1.5), intensity=0.2)])
    r = RoiRenderer(lit, DepthSensorModel())
    bgr, depth = r.render(cam, 0.0, rng=np.random.default_rng(4))
    ref_bgr, ref_depth, _ = render_rgbd(cam, lit, 0.0, rng=np.random.default_rng(4))
    assert not r.applicable and r.n_full == 1
    np.testing.assert_array_equal(bgr, ref_bgr)
    np.testing.assert_array_equal(depth, ref_depth)
    # camera so close that the square fills the frame: full render, same noise stream
    near = with_pose(cam, _down_pose(0, 0, 0.08))
    r2 = RoiRenderer(setup.scene, DepthSensorModel())
    bgr, depth = r2.render(near, 0.0, rng=np.random.default_rng(4))
    ref_bgr, ref_depth, _ = render_rgbd(near, setup.scene, 0.0, rng=np.random.default_rng(4))
    assert r2.n_full == 1
    np.testing.assert_array_equal(bgr, ref_bgr)


def test_supersampling_gives_edge_pixels_their_covered_fraction():
    """k x k samples per pixel: a pixel half covered by the square gets the mean of square and ground."""
    setup = eye_in_hand(_down_pose(0.0, 0.0, 0.75), np.random.default_rng(3), square_center_world=(0, 0, 0),
                        width=320, height=240)
    cam = setup.cameras["rgbd"]
    point, _ = RoiRenderer(setup.scene, DepthSensorModel()).render(cam, 0.0, rng=None)
    fine, _ = RoiRenderer(setup.scene, DepthSensorModel(), supersample=8).render(cam, 0.0, rng=None)
    g, sq = float(point[0, 0, 1]), float(point[120, 160, 1])
    assert abs(float(fine[0, 0, 1]) - g) <= 1 and abs(float(fine[120, 160, 1]) - sq) <= 1   # interiors unchanged
    # the square's area in pixels, from the grey levels, matches its projected area (point sampling: whole pixels)
    from tudorvision.sim.camera import project_points
    c = project_points(cam, setup.meta["square_corners_world"])
    x, y = c[:, 0], c[:, 1]
    area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
    # linear radiance would be exact; the 8-bit gamma output is monotone, so compare coverage via the LUT inverse
    def lin(v):
        return (np.asarray(v, float) / 255.0) ** 2.2

    cov_fine = np.clip((lin(g) - lin(fine[..., 1])) / (lin(g) - lin(sq)), 0, 1)
    assert cov_fine.sum() == pytest.approx(area, rel=0.01)
    assert np.count_nonzero((cov_fine > 0.05) & (cov_fine < 0.95)) > 50          # grey edge pixels exist
    with pytest.raises(ValueError, match="supersample"):
        RoiRenderer(setup.scene, DepthSensorModel(), supersample=0)
