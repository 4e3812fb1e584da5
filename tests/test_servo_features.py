"""Square features on rendered eye-in-hand RGB-D frames, scored against the known square and camera pose."""
import numpy as np
import pytest

from tudorvision.servo import extract_square
from tudorvision.servo.features import depth_at, diagonal_intersection, order_corners, polygon_centroid
from tudorvision.sensors import depth_m_from_raw
from tudorvision.sim import eye_in_hand, look_at, project_points, render_rgbd, with_pose

SQUARE = np.array([0.6, 0.0, 0.0])


def _views():
    """(eye, target, yaw) camera placements: fronto-parallel, oblique, rotated, square off-centre."""
    return [
        (SQUARE + [0.0, 0.0, 0.75], SQUARE, 0.0),
        (SQUARE + [0.12, -0.08, 0.7], SQUARE + [0.02, 0.0, 0.0], 0.3),     # oblique (about 12 deg)
        (SQUARE + [-0.05, 0.1, 0.85], SQUARE + [0.15, 0.1, 0.0], -0.2),    # square off-centre, tilted view
    ]


@pytest.fixture(scope="module")
def frames():
    out = []
    for i, (eye, target, yaw) in enumerate(_views()):
        rng = np.random.default_rng(10 + i)
        T = look_at(eye, target, K=np.eye(3), up_world=(1.0, 0.0, 0.0)).T_world_cam
        setup = eye_in_hand(T, rng, square_center_world=SQUARE, square_size_m=0.1, square_yaw_rad=yaw)
        cam = with_pose(setup.cameras["rgbd"], T)
        bgr, depth, gb = render_rgbd(cam, setup.scene, 0.0, rng=rng)
        out.append((cam, setup.meta["square_corners_world"], bgr, depth_m_from_raw(depth, 1000.0), gb))
    return out


def test_centroid_and_centre_match_the_projected_square(frames):
    for cam, corners_world, bgr, depth_m, gb in frames:
        f = extract_square(bgr, depth_m)
        assert f.found, f.reason
        corners_img = project_points(cam, corners_world)
        # the region centroid is the area centroid of the projected quadrilateral (not the projected centre)
        truth_centroid = polygon_centroid(order_corners(corners_img))
        assert np.linalg.norm(f.centroid_uv - truth_centroid) < 0.3
        # the diagonal intersection is the projection of the 3-D centre
        truth_center = project_points(cam, corners_world.mean(axis=0, keepdims=True))[0]
        assert np.linalg.norm(f.center_uv - truth_center) < 0.3
        # ordered corners TL, TR, BR, BL (lines fitted to sub-pixel edge points)
        assert np.max(np.linalg.norm(f.corners_uv - order_corners(corners_img), axis=1)) < 0.3


def test_perspective_centroid_differs_from_the_projected_centre(frames):
    # in the oblique views the two centre features differ measurably: the test above is not vacuous
    cam, corners_world, *_ = frames[2]
    corners_img = project_points(cam, corners_world)
    d = polygon_centroid(order_corners(corners_img)) - diagonal_intersection(order_corners(corners_img))
    assert np.linalg.norm(d) > 0.3


def test_feature_depth_is_the_true_depth(frames):
    from tudorvision.sim.depth_sensor import DepthSensorModel, pattern_field

    for cam, corners_world, bgr, depth_m, gb in frames:
        f = extract_square(bgr, depth_m)
        u, v = np.rint(f.centroid_uv).astype(int)
        # the lab's Kinect reports the true depth moved by its fixed pattern (a disparity offset) at that pixel
        c = pattern_field(DepthSensorModel(), cam.height, cam.width)[v, u]
        z_seen = 1.0 / (1.0 / gb.depth_m[v, u] + c)
        assert abs(f.depth_m[0] - z_seen) < 0.001        # Kinect sigma at 0.75 m: 0.7 mm per pixel (seed fit in mm)
        assert np.all(np.isfinite(f.depth_m))


def test_depth_at_uses_valid_neighbours_and_fits_a_plane():
    vv, uu = np.mgrid[0:40, 0:40]
    plane = 0.8 + 0.001 * uu - 0.0005 * vv
    d = plane.astype(np.float32)
    d[18:23, 18:23] = np.nan                              # a hole at the feature
    assert depth_at(d, (20.3, 19.7)) == pytest.approx(0.8 + 0.001 * 20.3 - 0.0005 * 19.7, abs=1e-5)
    d[:] = np.nan
    assert np.isnan(depth_at(d, (20.0, 20.0)))


def test_lost_square_and_bad_input():
    img = np.full((120, 160, 3), 215, np.uint8)
    f = extract_square(img)
    assert not f.found and f.reason
    img[0:50, 0:60] = 15                                  # dark region cut by the image border
    assert not extract_square(img).found
    img = np.full((120, 160, 3), 215, np.uint8)
    img[40:80, 60:100] = 15
    f = extract_square(img, np.full((120, 160), np.nan))
    assert f.found and not f.centroid_depth_ok
    with pytest.raises(ValueError, match="depth_m"):
        extract_square(img, np.zeros((10, 10)))
    with pytest.raises(ValueError, match="bgr"):
        extract_square(np.zeros((4, 4, 2), np.uint8))


def test_blob_choice_matches_connected_components():
    """The contour-based detector picks the blob that a full connected-components labelling picks."""
    import cv2

    from tudorvision.servo.features import _largest_inner_component
    rng = np.random.default_rng(7)
    for trial in range(60):
        mask = np.zeros((60, 80), np.uint8)
        for _ in range(rng.integers(0, 6)):
            x, y = rng.integers(-5, 75), rng.integers(-5, 55)
            w, h = rng.integers(1, 25, size=2)
            mask[max(y, 0):y + h, max(x, 0):x + w] = 255
            if rng.random() < 0.3:                      # a hole, sometimes with a blob inside
                mask[max(y + 2, 0):y + h - 2, max(x + 2, 0):x + w - 2] = 0
                if rng.random() < 0.5:
                    mask[max(y + 4, 0):y + h - 4, max(x + 4, 0):x + w - 4] = 255
        mask[rng.random(mask.shape) < 0.02] = 255      # speckle
        border, min_area = 1, float(rng.integers(1, 40))
        n, _, st, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        st = st[1:]
        ok = ((st[:, 4] >= min_area) & (st[:, 0] >= border) & (st[:, 1] >= border)
              & (st[:, 0] + st[:, 2] <= 80 - border) & (st[:, 1] + st[:, 3] <= 60 - border))
        got = _largest_inner_component(mask, border, min_area)
        if not ok.any():
            assert got is None
            continue
        areas = np.where(ok, st[:, 4], -1)
        winners = {tuple(int(v) for v in st[i, :4]) for i in np.nonzero(areas == areas.max())[0]}
        assert got in winners


def test_batched_depth_equals_the_single_estimate():
    """depth_at_many is depth_at vectorised: same values (or NaN) on noisy, holed, outlier-ridden depth."""
    from tudorvision.servo.features import depth_at_many
    rng = np.random.default_rng(3)
    for trial in range(40):
        vv, uu = np.mgrid[0:40, 0:50]
        d = (0.8 + rng.normal(0, 0.002, (40, 50)) + 0.001 * uu * rng.uniform(-1, 1)).astype(np.float32)
        d[rng.random(d.shape) < rng.uniform(0, 0.95)] = np.nan
        d[rng.random(d.shape) < 0.05] = 3.0                       # outliers
        pts = rng.uniform(-3, [53, 43], (6, 2))                  # some windows cut by the border
        got = depth_at_many(d, pts)
        want = np.array([depth_at(d, q) for q in pts])
        np.testing.assert_array_equal(np.isnan(got), np.isnan(want))
        np.testing.assert_allclose(got[~np.isnan(want)], want[~np.isnan(want)], rtol=0, atol=1e-9)
