"""A theta1 ("yaw") sweep corrects the base frame's tilt towards the camera.

The seed's construction (:func:`tudorvision.rgbd.base_calib.base_frame_from_theta2_sweep`)
takes the base z axis from a theta2 sweep: the disc moves in a vertical
plane that faces the camera, so the tilt of z towards the camera (a rotation
about the base x axis) rests on the disc's depth, the noisiest coordinate of
an RGB-D camera, extrapolated from the upper half circle to its centre. With
the seed's Kinect noise correlated as a real Kinect's, a wall camera 6.8 m
away tilts that z by 0.3-0.6 deg (the catching demo), which puts a ball
seen 3 m from the arm 15-30 mm too high or low.

Turning joint 1 at one theta2 moves the disc on a horizontal circle about the
base z axis: near and far poses differ in depth by up to
``2 r sin(theta1_max)``, and the tilt of that circle's plane towards the
camera rests on heights, which the image measures laterally. The static sag
of the elastic arm is the same at every theta1 (its posture against gravity
does not change), so the circle stays horizontal whatever the payload.

:func:`measure_yaw_sweep` finds the disc in the yaw frames from the first
estimate of the base frame and the rigid kinematics (no seed pixel needed);
:func:`refine_tilt_from_yaw` turns the base frame about its x axis so that
its z axis is the normal of the yaw points' plane. With the joint angles,
each point keeps its viewing ray and takes its distance along it from the
arc (the rigid kinematics, its horizontal radius and offset fitted to the
points: the elastic links bend the disc outwards): a camera looking down
turns depth noise along the rays into height, and a plane fitted to the
measured depths leans towards the rays' slope. The roll about y (poorly
determined by a yaw arc in front of the base) stays the sweep's.
The heading (about z) is not taken from the yaw sweep: a disc seen 45 deg
off its face is measured 6-10 mm off its centre within its plane, towards
the camera's side (noise-free lab frames), which at the arc's two ends reads
as a 0.4-0.5 deg heading error; the tilt is not affected (the shift is
horizontal). A catch does not need it: a turn about the vertical keeps
gravity vertical (the lab's catch is the same with 0.14 deg of heading).
"""
from __future__ import annotations

import numpy as np

from .._checks import TudorVisionError, check_array, check_transform
from ..geometry import fit_plane, invert_transform, transform_points
from ..robot import load_robot_params
from ..robot.kinematics import T_base_ee
from .disc3d import Disc3DOptions, measure_disc_3d, unit_vector
from .frames import Intrinsics

__all__ = ["measure_yaw_sweep", "refine_tilt_from_yaw"]


def measure_yaw_sweep(depth_frames, intrinsics: Intrinsics, T_base_cam, theta_rad,
                      options: Disc3DOptions = Disc3DOptions(), *, robot=None, margin_m: float = 0.15):
    """Measure the disc in the frames of a theta1 sweep, predicted from a first base frame and the kinematics.

    The first frame of each pose is searched within ``margin_m`` of the rigid
    end-effector position (the elastic arm sags a few centimetres; a first
    base frame is off by millimetres); later frames of the same pose within
    ``options.min_margin_m`` (at least 3 cm) of the pose's mean so far, with
    their mean normal as the prior.

    Parameters
    ----------
    depth_frames : array_like, shape (N, H, W)
        Depth (z) in metres, NaN or 0 = invalid.
    intrinsics : Intrinsics
        Pinhole intrinsics of the depth camera (pixels).
    T_base_cam : array_like, shape (4, 4)
        A first estimate of the camera pose in the base frame (``p_base = T_base_cam @ p_cam``).
    theta_rad : array_like, shape (N, 3)
        Joint angles per frame, rad.
    options : Disc3DOptions
        Disc radius, tolerances.
    robot : RobotParams, optional
        Link lengths for the prediction; default the packaged ``tudor.yaml``.
    margin_m : float
        How far the disc may be from the rigid prediction in a pose's first frame, metres.

    Returns
    -------
    centres_cam : ndarray, shape (N, 3)
        Disc centres, metres, camera frame; NaN rows where the disc was not measured.
    skipped : dict
        Frame index -> reason.

    Raises
    ------
    ValueError
        On arrays of the wrong shape or a non-positive margin.
    """
    T = check_transform(T_base_cam, "T_base_cam")
    th = check_array(theta_rad, "theta_rad", (None, 3))
    frames = np.asarray(depth_frames)
    if frames.ndim != 3 or len(frames) != len(th):
        raise ValueError(f"depth_frames: expected shape (N, H, W) with N = {len(th)} (theta_rad), "
                         f"got {frames.shape}")
    if not margin_m > 0:
        raise ValueError(f"margin_m: expected > 0, got {margin_m}")
    T_cam_base = invert_transform(T)
    prm = robot if robot is not None else load_robot_params()
    pred_all = transform_points(T_cam_base, T_base_ee(th, prm)[:, :3, 3])
    out = np.full((len(th), 3), np.nan)
    normals = np.full((len(th), 3), np.nan)
    skipped = {}
    for i in range(len(th)):
        same = np.all(np.abs(th[:i] - th[i]) < np.radians(0.5), axis=1) & np.all(np.isfinite(out[:i]), axis=1)
        if same.any():
            pred, margin = out[:i][same].mean(axis=0), max(float(options.min_margin_m), 0.03)
            prior = unit_vector(normals[:i][same].mean(axis=0))
        else:
            pred, margin, prior = pred_all[i], float(margin_m), None
        m = measure_disc_3d(frames[i], intrinsics, pred, margin, options, normal_prior=prior)
        if m.valid:
            out[i], normals[i] = m.centre_cam, m.normal_cam
        else:
            skipped[i] = m.reason
    return out, skipped


def refine_tilt_from_yaw(T_base_cam, yaw_points_cam, *, pivot_cam=None, theta_rad=None, robot=None,
                         inlier_sigma: float = 3.5, min_points: int = 6, min_spread_m: float = 0.15,
                         iterations: int = 3):
    """Turn a base frame about its x axis so that its z axis is normal to the yaw sweep's plane.

    Parameters
    ----------
    T_base_cam : array_like, shape (4, 4)
        The base frame to refine (``p_base = T_base_cam @ p_cam``), e.g. the seed's construction.
    yaw_points_cam : array_like, shape (N, 3)
        Disc centres of the yaw frames, metres, camera frame; NaN rows are skipped.
    pivot_cam : array_like, shape (3,), optional
        The point the frame turns about, camera frame: where the first estimate is best known (the
        theta2 sweep's points' mean); default the base origin.
    theta_rad : array_like, shape (N, 3), optional
        Joint angles of the yaw frames, rad. Given, each disc centre keeps its viewing ray (what the image
        measures) but takes its distance along the ray from the arc (the rigid end-effector positions, their
        horizontal radius and offset fitted to the points, through the current base frame), re-predicted
        after each turn: the depth noise no longer
        tilts the plane (the camera looks down, so a point moved along its ray also moves in height, and
        the scatter of the depths pulls a least-squares plane towards the rays' slope). Without it the
        measured depths are used.
    robot : RobotParams, optional
        Link lengths for ``theta_rad``; default the packaged ``tudor.yaml``.
    inlier_sigma : float
        Points farther from the plane than this many robust standard deviations are left out (once).
    min_points : int
        Fewest valid inlier points.
    min_spread_m : float
        Fewest metres the points must spread along the base y axis (towards the camera): the tilt's lever.
    iterations : int
        Turns applied in sequence with ``theta_rad`` (each from the depths the previous frame predicts).

    Returns
    -------
    T_base_cam : ndarray, shape (4, 4)
        The refined frame.
    info : dict
        ``yaw_tilt_correction_deg`` (the turn about base x applied), ``yaw_tilt_std_deg`` (its standard
        error from the plane residuals), ``yaw_roll_deg`` (the plane's tilt about base y, not applied),
        ``yaw_plane_rmse_m``, ``yaw_points_used``, ``yaw_spread_m``, ``yaw_depth_from`` (``"measured"`` or
        ``"kinematics"``) and, with ``theta_rad``, ``yaw_radius_scale`` (the arc's radius over the rigid one).

    Raises
    ------
    TudorVisionError
        Too few valid points or too little spread along base y.

    Examples
    --------
    >>> a = np.radians(np.arange(-45.0, 45.1, 15.0))
    >>> ring = np.c_[0.6 * np.cos(a), 0.6 * np.sin(a), np.full_like(a, 0.9)]    # base frame
    >>> tilt = np.radians(0.5)                                                      # the first estimate's error
    >>> R = np.array([[1, 0, 0], [0, np.cos(tilt), -np.sin(tilt)], [0, np.sin(tilt), np.cos(tilt)]])
    >>> T = np.eye(4); T[:3, :3] = R                           # takes the points (as camera points) to R @ p
    >>> T2, info = refine_tilt_from_yaw(T, ring)
    >>> round(info["yaw_tilt_correction_deg"], 3), bool(np.allclose(T2[:3, :3], np.eye(3)))
    (-0.5, True)
    """
    T = check_transform(T_base_cam, "T_base_cam")
    P = check_array(yaw_points_cam, "yaw_points_cam", (None, 3), finite=False)
    ok = np.all(np.isfinite(P), axis=1)
    if ok.sum() < min_points:
        raise TudorVisionError(f"yaw sweep: {int(ok.sum())} valid disc centres, at least {min_points} needed")
    if theta_rad is None:
        return _turn_to_plane(T, P[ok], pivot_cam, inlier_sigma, min_points, min_spread_m)
    th = check_array(theta_rad, "theta_rad", (len(P), 3))
    prm = robot if robot is not None else load_robot_params()
    rays = P[ok] / np.linalg.norm(P[ok], axis=1, keepdims=True)
    ee_base = T_base_ee(th[ok], prm)[:, :3, 3]
    T0 = T
    for _ in range(max(1, int(iterations))):
        pred, scale = _arc_prediction(transform_points(T, P[ok]), ee_base)
        along = np.sum(rays * transform_points(invert_transform(T), pred), axis=1)
        T, info = _turn_to_plane(T, rays * along[:, None], pivot_cam, inlier_sigma, min_points, min_spread_m)
    R = T[:3, :3] @ T0[:3, :3].T                        # the turns compose to one about base x
    info["yaw_tilt_correction_deg"] = float(np.degrees(np.arctan2(R[2, 1], R[1, 1])))
    info.update(yaw_depth_from="kinematics", yaw_radius_scale=scale)
    return T, info


def _arc_prediction(Pb, ee_base):
    """The rigid arc scaled and shifted horizontally to the measured points (base frame), and the scale.

    The elastic arm's disc runs on a wider circle than the rigid kinematics say (its links bend down and
    out), and a radius off by ``dr`` would tilt the plane by about ``0.15 dr / r`` through the rays'
    slope; so the horizontal radius ``k r`` and offset come from the points, each axis weighted by its
    scatter (base x lies across the view, y along it): ``Pb[:, :2] ~ k ee[:, :2] + c``; the height is the
    kinematics' shifted by the points' median sag.
    """
    A = ee_base[:, :2]
    rows, rhs = [], []
    for ax in (0, 1):                               # unknowns (k, cx, cy); each axis weighted by its own fit's scatter
        M = np.zeros((len(A), 3))
        M[:, 0], M[:, 1 + ax] = A[:, ax], 1.0
        r = Pb[:, ax] - M @ np.linalg.lstsq(M, Pb[:, ax], rcond=None)[0]
        w = 1.0 / max(1.4826 * float(np.median(np.abs(r - np.median(r)))), 1e-4)
        rows.append(w * M)
        rhs.append(w * Pb[:, ax])
    k, cx, cy = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0]
    pred = ee_base.copy()
    pred[:, 0], pred[:, 1] = k * A[:, 0] + cx, k * A[:, 1] + cy
    pred[:, 2] += float(np.median(Pb[:, 2] - ee_base[:, 2]))       # the sag: the rays' slope differs with depth
    return pred, float(k)


def _turn_to_plane(T, P, pivot_cam, inlier_sigma, min_points, min_spread_m):
    """One turn about base x that makes base z the normal of the points' plane (see refine_tilt_from_yaw)."""
    Pb = transform_points(T, P)                          # base frame of the first estimate
    keep = np.ones(len(Pb), bool)
    for rejection in (True, False):                      # fit, leave the outliers out once, fit again
        plane = fit_plane(Pb[keep], normal_hint=[0.0, 0.0, 1.0])
        n = plane.normal
        r = (Pb - plane.centroid) @ n
        s = 1.4826 * np.median(np.abs(r - np.median(r)))
        if rejection and s > 1e-9:
            keep = np.abs(r - np.median(r)) <= inlier_sigma * s
    if keep.sum() < min_points:
        raise TudorVisionError(f"yaw sweep: {int(keep.sum())} disc centres on the plane, at least {min_points} needed")
    y = Pb[keep, 1]
    spread = float(np.ptp(y))
    if spread < min_spread_m:
        raise TudorVisionError(f"yaw sweep: the disc spreads {100 * spread:.1f} cm towards the camera, at least "
                               f"{100 * min_spread_m:.0f} cm needed (turn joint 1 further)")
    phi = float(np.arctan2(n[1], n[2]))                  # the turn about base x that takes n's y-z part onto z
    Rc = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(phi), -np.sin(phi)], [0.0, np.sin(phi), np.cos(phi)]])
    q = np.zeros(3) if pivot_cam is None else transform_points(T, check_array(pivot_cam, "pivot_cam", (3,)))
    C = np.eye(4)
    C[:3, :3] = Rc
    C[:3, 3] = q - Rc @ q
    rmse = plane.rmse
    se = rmse / float(np.sqrt(np.sum((y - y.mean()) ** 2)))
    info = {"yaw_tilt_correction_deg": float(np.degrees(phi)), "yaw_tilt_std_deg": float(np.degrees(se)),
            "yaw_roll_deg": float(np.degrees(np.arctan2(n[0], n[2]))), "yaw_plane_rmse_m": rmse,
            "yaw_points_used": int(keep.sum()), "yaw_spread_m": spread, "yaw_depth_from": "measured"}
    return C @ T, info

