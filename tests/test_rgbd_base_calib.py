"""Disc segmentation/tracking and the wall-camera to robot-base calibration on synthetic sweeps."""
import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.geometry import invert_transform, rotation_angle, transform_points
from tudorvision.rgbd.base_calib import base_frame_from_theta2_sweep
from tudorvision.rgbd.disc import DiscOptions, DiscTracker, observe_disc, segment_uniform_depth, track_disc
from tudorvision.rgbd.frames import Intrinsics
from tudorvision.robot import fk_ee, load_robot_params
from tudorvision.sensors import KINECT_SIGMA_Z_COEFFS, DepthNoiseModel

K = Intrinsics(525.0, 525.0, 159.5, 119.5, 320, 240)     # Kinect optics, central 320 x 240 crop
PARAMS = load_robot_params()
DISC_RADIUS = 0.09
#: these synthetic sweeps draw the seed's fit read in cm (35 cm per pixel at 5 m, the lab's reading before
#: issue 18); the segmentation is told the same noise
CM_NOISE = DepthNoiseModel(coeffs=tuple(c / 100.0 for c in KINECT_SIGMA_Z_COEFFS))


def seed_sigma_m(z):
    return np.maximum(0.51 * z ** 3 - 2.1 * z ** 2 + 5.12 * z - 2.18, 0.0) / 100.0


def rot(axis, a):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    X = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(a) * X + (1 - np.cos(a)) * X @ X


def camera_pose(rng, distance=5.0):
    """T_base_cam of a wall camera about ``distance`` in front of the arm plane (base x-z plane)."""
    R = np.column_stack([[1, 0, 0], [0, 0, -1], [0, 1, 0]]).astype(float)   # looks along base +y, z up
    R = rot(rng.normal(size=3), np.radians(rng.uniform(3, 10))) @ R
    target = np.array([0.0, 0.0, 0.6])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = target - distance * R[:, 2]
    return T


def render_depth(rng, T_base_cam, discs_base, normal_base=(0.0, -1.0, 0.0), wall_y=1.0, noise=True):
    """Ray-cast discs (centres in the base frame) before a wall at base y = wall_y; metres, NaN invalid."""
    T_cam_base = invert_transform(T_base_cam)
    vv, uu = np.mgrid[: K.height, : K.width]
    rays = np.stack([(uu - K.cx) / K.fx, (vv - K.cy) / K.fy, np.ones(K.shape)], axis=-1)   # z = 1
    z = np.full(K.shape, np.inf)
    n_cam = T_cam_base[:3, :3] @ np.asarray(normal_base, float)
    for c_base in discs_base:
        c = transform_points(T_cam_base, c_base)
        t = (c @ n_cam) / (rays @ n_cam)                 # depth along z since rays have z = 1
        hit = np.linalg.norm(rays * t[..., None] - c, axis=-1) <= DISC_RADIUS
        z = np.where(hit & (t > 0) & (t < z), t, z)
    # wall plane y_base = wall_y: point p_cam with (T_base_cam p)[1] = wall_y
    r1, t1 = T_base_cam[1, :3], T_base_cam[1, 3]
    tw = (wall_y - t1) / (rays @ r1)
    z = np.where(np.isinf(z) & (tw > 0), tw, z)
    z[~np.isfinite(z) | (z > 6.5)] = np.nan
    # like a Kinect (and the virtual lab): no depth at jumps of more than 3 % between 4-neighbours
    zf = np.nan_to_num(z, nan=1e9)
    jump_v = np.abs(np.diff(zf, axis=0)) > 0.03 * np.minimum(zf[1:], zf[:-1])
    jump_u = np.abs(np.diff(zf, axis=1)) > 0.03 * np.minimum(zf[:, 1:], zf[:, :-1])
    edge = np.zeros(z.shape, bool)
    edge[1:] |= jump_v
    edge[:-1] |= jump_v
    edge[:, 1:] |= jump_u
    edge[:, :-1] |= jump_u
    z[edge] = np.nan
    if noise:
        z = z + seed_sigma_m(np.nan_to_num(z)) * rng.standard_normal(K.shape)
        z = np.rint(z * 1000) / 1000
    return z


def sweep(theta2_deg):
    return fk_ee(np.column_stack([np.zeros(len(theta2_deg)), np.radians(theta2_deg),
                                  np.zeros(len(theta2_deg))]))


def project(T_base_cam, p_base):
    p = transform_points(invert_transform(T_base_cam), p_base)
    return np.array([K.fx * p[0] / p[2] + K.cx, K.fy * p[1] / p[2] + K.cy])


def frame_errors(T_est, T_true):
    o_est = invert_transform(T_est)[:3, 3]
    o_true = invert_transform(T_true)[:3, 3]
    return float(np.linalg.norm(o_est - o_true)), float(np.degrees(rotation_angle(T_est[:3, :3].T @ T_true[:3, :3])))


def test_segment_uniform_depth_on_noisy_disc():
    rng = np.random.default_rng(20)
    T = camera_pose(rng)
    p = sweep([40.0])[0]
    depth = render_depth(rng, T, [p])
    truth = render_depth(rng, T, [p], noise=False)
    on = np.abs(truth - transform_points(invert_transform(T), p)[2]) < 0.3
    mask, z_ref, tol = segment_uniform_depth(depth, project(T, p), DiscOptions(depth_model=CM_NOISE))
    iou = (mask & on).sum() / (mask | on).sum()
    assert iou > 0.7
    obs = observe_disc(depth, K, project(T, p), DiscOptions(depth_model=CM_NOISE))
    c_true = transform_points(invert_transform(T), p)
    assert obs.valid and np.linalg.norm(obs.centroid_cam - c_true) < 0.06


def test_track_disc_and_recover_base_frame_at_5m():
    """The whole chain at 5 m with the seed's depth noise (35 cm per pixel there).

    Every frame of the sweep is a circle sample (6 noisy frames per 5 deg step, a
    0.2 s hold at 30 Hz) and the vertical posture is held for 20 frames. At this
    noise level fewer frames do not reliably reach 1 cm / 1 deg.
    """
    rng = np.random.default_rng(21)
    T_true = camera_pose(rng, 5.0)
    theta2 = np.repeat(np.arange(-10.0, 191.0, 5.0), 6)
    p_base = sweep(theta2)
    frames = [render_depth(rng, T_true, [p]) for p in p_base]
    obs = track_disc(frames, K, project(T_true, p_base[0]) + [1.0, -2.0],
                     DiscOptions(depth_model=CM_NOISE, disc_radius_m=DISC_RADIUS))
    assert all(o.valid for o in obs)
    pts = np.array([o.centroid_cam for o in obs])
    truth_cam = transform_points(invert_transform(T_true), p_base)
    # the tracker followed the disc: laterally every centroid lies on its own disc
    # (neighbouring steps are 7 cm apart); depth errors are noise, ~sigma_z / sqrt(n)
    assert np.max(np.linalg.norm(pts[:, :2] - truth_cam[:, :2], axis=1)) < 0.03
    z_err = pts[:, 2] - truth_cam[:, 2]
    assert abs(z_err.mean()) < 0.01 and np.sqrt(np.mean(z_err ** 2)) < 2 * seed_sigma_m(5.0) / np.sqrt(150)
    p_vert = sweep([90.0])[0]
    vertical = track_disc([render_depth(rng, T_true, [p_vert]) for _ in range(20)], K, project(T_true, p_vert),
                          DiscOptions(depth_model=CM_NOISE))
    vertical = [o.centroid_cam for o in vertical]
    T_est, rep = base_frame_from_theta2_sweep(pts, vertical, theta2_rad=np.radians(theta2))
    d_origin, d_angle = frame_errors(T_est, T_true)
    assert d_origin <= 0.01 and d_angle <= 1.0          # issue 4 acceptance on the virtual lab
    assert abs(rep["circle_radius_m"] - (PARAMS.link2_length_m + PARAMS.link3_length_m)) < 0.02
    assert rep["circle_rmse_m"] < 0.06 and len(rep["points_used"]) >= 0.95 * len(theta2)
    # the joint-2 origin option is the circle centre, link1_height above the base plate
    T_j2, _ = base_frame_from_theta2_sweep(pts, vertical, theta2_rad=np.radians(theta2), origin="joint2")
    o_j2 = transform_points(T_j2, transform_points(invert_transform(T_true), [0, 0, PARAMS.link1_height_m]))
    assert np.linalg.norm(o_j2) < 0.01


@pytest.mark.parametrize("seed", range(5))
def test_base_frame_exact_construction_with_outliers(seed):
    rng = np.random.default_rng(100 + seed)
    T_true = camera_pose(rng, rng.uniform(3.0, 6.0))
    theta2 = np.sort(rng.uniform(-14, 192, 30))
    p_cam = transform_points(invert_transform(T_true), sweep(theta2)) + rng.normal(0, 0.005, (30, 3))
    bad = rng.choice(30, 3, replace=False)
    p_cam[bad] += rng.normal(0, 0.4, (3, 3))
    p_cam[rng.choice(np.setdiff1d(np.arange(30), bad))] = np.nan           # a lost sample
    vertical = transform_points(invert_transform(T_true), sweep([90.0])[0])
    order = rng.permutation(30) if seed % 2 else np.arange(30)              # sweep direction from theta2
    T_est, rep = base_frame_from_theta2_sweep(p_cam[order], vertical, theta2_rad=np.radians(theta2[order]))
    d_origin, d_angle = frame_errors(T_est, T_true)
    assert d_origin < 0.01 and d_angle < 1.0
    rejected = {r["index"]: r["reason"] for r in rep["rejected"]}
    assert {int(np.nonzero(order == b)[0][0]) for b in bad} <= {i for i, r in rejected.items() if r == "outlier"}
    assert sum(r.startswith("invalid") for r in rejected.values()) == 1
    # x points toward the end effector at theta2 = 0 (zero configuration)
    p0 = transform_points(T_est, transform_points(invert_transform(T_true), sweep([0.0])[0]))
    assert p0[0] > 0.8 and abs(p0[1]) < 0.01
    # without theta2 the sample order gives the direction
    T_ord, _ = base_frame_from_theta2_sweep(p_cam, vertical)
    assert frame_errors(T_ord, T_true)[1] < 1.0
    T_rev, _ = base_frame_from_theta2_sweep(p_cam[::-1], vertical)
    assert frame_errors(T_rev, T_true)[1] > 170.0          # reversed sweep: x and y flip


def test_lost_disc_and_bad_sweeps():
    rng = np.random.default_rng(22)
    T = camera_pose(rng, 4.0)
    p = sweep([30.0, 35.0])
    d0 = render_depth(rng, T, [p[0]])
    seed = project(T, p[0])
    # seed pixel without valid depth
    holey = d0.copy()
    u, v = np.rint(seed).astype(int)
    holey[v - 5:v + 6, u - 5:u + 6] = np.nan
    with pytest.raises(TudorVisionError, match="no valid depth"):
        observe_disc(holey, K, seed)
    # disc removed: the seed lands on the wall, the region is far too large
    empty = render_depth(rng, T, [])
    with pytest.raises(TudorVisionError, match="too large"):
        observe_disc(empty, K, seed, DiscOptions(depth_model=CM_NOISE, disc_radius_m=DISC_RADIUS))
    lost = observe_disc(empty, K, seed, DiscOptions(depth_model=CM_NOISE, disc_radius_m=DISC_RADIUS), strict=False)
    assert not lost.valid and np.all(np.isnan(lost.centroid_cam)) and "too large" in lost.reason
    # tracking flags a single lost frame, then raises when the disc stays lost
    tr = DiscTracker(K, seed, DiscOptions(depth_model=CM_NOISE, disc_radius_m=DISC_RADIUS), max_consecutive_lost=2)
    assert tr.update(d0).valid
    assert not tr.update(empty).valid
    assert tr.update(render_depth(rng, T, [p[1]])).valid
    tr.update(empty)
    with pytest.raises(TudorVisionError, match="disc lost in 2 consecutive frames"):
        tr.update(empty)
    with pytest.raises(TudorVisionError, match="outside"):
        observe_disc(d0, K, (700, 10))
    # too few circle points
    pts = transform_points(invert_transform(T), sweep([0.0, 30.0, 60.0, 90.0]))
    with pytest.raises(TudorVisionError, match="at least 6 valid points"):
        base_frame_from_theta2_sweep(pts, pts[3])
    pts8 = transform_points(invert_transform(T), sweep(np.arange(0.0, 160.0, 20.0)))
    pts8[:4] = np.nan
    with pytest.raises(TudorVisionError, match="at least 6 valid points, got 4"):
        base_frame_from_theta2_sweep(pts8, pts8[-1])
    # vertical point at the circle centre
    full = transform_points(invert_transform(T), sweep(np.arange(0.0, 160.0, 20.0)))
    centre = transform_points(invert_transform(T), [0.0, 0.0, PARAMS.link1_height_m])
    with pytest.raises(TudorVisionError, match="from the circle centre"):
        base_frame_from_theta2_sweep(full, centre)


def test_disc_depth_window_has_no_selection_bias_at_5m():
    """The disc depth is unbiased against the mean raw depth of the true disc pixels.

    At 5 m (35 cm per pixel) whether a rim pixel joins the grown region depends
    on its own noise; a depth window bounded by the region's moment ellipse read
    about +0.4 cm too far (paired with the same frames, so the comparison is
    precise to about 0.05 cm). The disc's whole image circle does not.
    """
    rng = np.random.default_rng(24)
    T = camera_pose(rng, 5.0)
    p = sweep([rng.uniform(0, 180)])[0]
    c = transform_points(invert_transform(T), p)
    uv = project(T, p)
    truth = render_depth(rng, T, [p], noise=False)
    on = np.abs(truth - c[2]) < 0.3
    err = {"disc": [], "ellipse": []}
    oracle = []
    for _ in range(100):
        d = render_depth(rng, T, [p])
        oracle.append(np.mean(d[on] - truth[on]))
        for w in err:
            o = observe_disc(d, K, uv, DiscOptions(depth_model=CM_NOISE, disc_radius_m=DISC_RADIUS, depth_window=w))
            err[w].append(o.centroid_cam[2] - c[2])
    bias = {w: float(np.mean(np.array(e) - oracle)) for w, e in err.items()}
    assert abs(bias["disc"]) < 0.0012
    assert bias["ellipse"] > 0.002          # the earlier window: the test can tell the two apart
    with pytest.raises(ValueError, match="depth_window"):
        DiscOptions(depth_model=CM_NOISE, depth_window="box")


def test_virtual_lab_disc_scene_has_no_tracking_spheres():
    """The net holds the disc: no tracking sphere stands in front of it (one did, 3 cm too near at 5 m)."""
    import importlib

    from tudorvision.sim.scenes_rgbd import wall_disc

    record = importlib.import_module("tudorvision.lab.record")
    th = np.radians([0.0, 40.0, 0.0])
    state = record.static_arm_state(th, record.Payload.from_parts(PARAMS), PARAMS)
    geom = record.elastic_arm_geometry(th, *state, PARAMS)
    names = set(wall_disc([0.8, 0.0, 0.9], np.random.default_rng(0), arm=geom).scene.object_ids(0.0))
    assert "disc" in names and "link3_0" in names
    assert not names & {"red_sphere", "green_sphere", "ee_bar"}
    drawn = set(wall_disc([0.8, 0.0, 0.9], np.random.default_rng(0), arm=geom, draw_spheres=True).scene.object_ids(0.0))
    assert {"red_sphere", "green_sphere"} <= drawn


def test_refine_sweep_in_plane_recovers_a_tilted_frame_and_drops_an_outlier():
    """A calibration off by a rotation about base y and a shift is pulled back onto the model's
    end-effector positions; a disc centre 10 cm off is dropped; the circle plane is untouched."""
    from tudorvision.rgbd.base_calib import refine_sweep_in_plane

    rng = np.random.default_rng(7)
    th = np.radians([[0.0, a, 0.0] for a in np.arange(10.0, 171.0, 10.0)])

    def model(t23, m):          # reach and height of a sagging arm (any smooth curve will do)
        return np.stack([0.8 * np.cos(t23[:, 0]), 0.3 + 0.8 * np.sin(t23[:, 0]) - 0.01 * np.cos(t23[:, 0]) ** 2],
                        axis=1)

    rz = model(th[:, 1:], 0.0)
    p_base = np.stack([rz[:, 0], np.zeros(len(rz)), rz[:, 1]], axis=1) + rng.normal(0.0, 0.001, (len(rz), 3))
    p_base[4] += [0.1, 0.0, 0.0]                                   # one bad disc centre
    T_base_cam = np.eye(4)                                         # camera frame = base frame
    c, s = np.cos(np.radians(0.8)), np.sin(np.radians(0.8))
    T_off = np.eye(4)
    T_off[:3, :3] = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
    T_off[:3, 3] = [0.01, 0.0, -0.02]
    T_ref, info = refine_sweep_in_plane(T_off @ T_base_cam, p_base, th, model)
    assert info["points"] == len(rz) - 1
    assert abs(abs(info["in_plane_rotation_deg"]) - 0.8) < 0.05
    assert np.allclose(T_ref[:3, :3], np.eye(3), atol=1e-3)
    assert np.allclose(T_ref[:3, 3], 0.0, atol=2e-3)
    assert info["in_plane_rmse_m"] < 0.003
    with pytest.raises(ValueError, match="centres_cam"):
        refine_sweep_in_plane(T_off, np.full((5, 3), np.nan), th[:5], model)
