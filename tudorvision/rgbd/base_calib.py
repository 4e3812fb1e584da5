"""Wall camera to robot base calibration from a theta2 sweep (section 9.3).

With theta1 = theta3 = 0 the robot sweeps theta2; the disc in the net moves on
a circle about the joint-2 axis. The seed builds the base frame from the fitted
circle and the end effector in the vertical posture [0, 90, 0] deg:

- origin = circle centre;
- z = unit vector from the centre to the vertical-posture end effector;
- initial y = circle-plane normal; x = y x z; y = z x x.

Normal sign: the robot's base y axis is the joint-2 axis direction for which
increasing theta2 turns the arm from +x (theta2 = 0, zero configuration)
toward +z, i.e. increasing theta2 is a rotation about -y. The normal is
oriented accordingly (from the sweep order, or from the given theta2 values),
so x points toward the end effector at theta2 = 0.

Frame origin: the circle centre lies on the joint-2 axis, which is
``link1_height_m`` above the base plate origin of :mod:`tudorvision.robot`.
By default (``origin="base"``) the returned ``T_base_cam`` is shifted down
along z by ``link1_height_m`` so that it matches ``tudorvision.robot.fk_ee``;
``origin="joint2"`` gives the seed's frame (origin at the circle centre).

:func:`refine_sweep_in_plane` and :func:`refine_sweep_mirror` refine the
frame's angle in the sweep plane (the direction of gravity in it, which a
ball's predicted crossing is sensitive to): the first against a learnt
deflection model, the second without any model, from the sweep's mirror
symmetry about the vertical.
"""
from __future__ import annotations

import numpy as np

from .._checks import TudorVisionError, check_array, check_points
from ..geometry import fit_circle_3d, fit_rigid_transform, invert_transform

__all__ = ["base_frame_from_theta2_sweep", "refine_sweep_in_plane", "refine_sweep_mirror"]


def _rotation_axis(points: np.ndarray, centre: np.ndarray, normal: np.ndarray, theta2) -> np.ndarray:
    """Normal oriented as the rotation axis of increasing theta2."""
    d = points - centre
    cr = np.cross(d[:-1], d[1:]) @ normal
    if theta2 is None:
        step = np.ones(len(cr))
    else:
        step = np.diff(theta2)
    s = float(np.sum(np.sign(step) * cr))
    if s == 0.0:
        raise TudorVisionError("cannot tell the sweep direction: the points do not progress along the circle")
    return normal if s > 0 else -normal


def _inliers(pts: np.ndarray, fit, k: float) -> tuple[np.ndarray, np.ndarray]:
    """Inliers by the normalised residual with separate robust scales out of plane and radially.

    Depth noise makes the out-of-plane scatter much larger than the in-plane one
    when the camera faces the sweep plane, so one pooled scale would reject
    good points.
    """
    d = pts - fit.centre
    h = d @ fit.normal
    dr = np.linalg.norm(d - h[:, None] * fit.normal, axis=1) - fit.radius
    floor = 1e-6 * max(fit.radius, 1e-9)
    sh = max(1.4826 * float(np.median(np.abs(h))), floor)
    sr = max(1.4826 * float(np.median(np.abs(dr))), floor)
    return (h / sh) ** 2 + (dr / sr) ** 2 <= k * k, np.hypot(h, dr)


def _measured_weight(pts: np.ndarray, centre: np.ndarray, normal: np.ndarray, pv: np.ndarray, m: int) -> float:
    """Weight of the measured out-of-plane offset of the vertical point against the plane's prediction."""
    a = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(normal, a)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    d = pts - centre
    A = np.column_stack([np.ones(len(d)), d @ e1, d @ e2])
    h = d @ normal
    s2 = (1.4826 * float(np.median(np.abs(h - np.median(h))))) ** 2
    if not s2 > 0:
        return 0.0
    q = np.array([1.0, (pv - centre) @ e1, (pv - centre) @ e2])
    var_plane = s2 * float(q @ np.linalg.solve(A.T @ A, q))
    var_meas = s2 / max(m, 1)
    return var_plane / (var_plane + var_meas)


def base_frame_from_theta2_sweep(points_cam, vertical_cam, *, theta2_rad=None, link1_height_m: float | None = None,
                          origin: str = "base", vertical: str = "combined", min_points: int = 6,
                          loss: str = "soft_l1", inlier_sigma: float = 3.5, max_rejected_fraction: float = 0.3):
    """Robot base frame in the camera frame from disc centroids of a theta2 sweep.

    Parameters
    ----------
    points_cam : array_like, shape (N, 3)
        Disc centroids per sweep step, metres, camera optical frame, in sweep
        order. Rows with NaN (lost samples) are skipped and reported.
    vertical_cam : array_like, shape (3,) or (M, 3)
        End-effector (disc) position(s) in the vertical posture [0, 90, 0] deg;
        several rows are averaged (NaN rows skipped). Average many frames: the
        depth noise of this point tilts z.
    theta2_rad : array_like, shape (N,), optional
        theta2 per sample; gives the sweep direction. Without it the samples
        are taken to be in increasing theta2.
    link1_height_m : float, optional
        Height of the joint-2 axis above the base plate (default: the robot
        parameter file). Only used with ``origin="base"``.
    origin : {"base", "joint2"}
        ``"base"``: base-plate origin of :mod:`tudorvision.robot`;
        ``"joint2"``: the circle centre (the seed's origin).
    vertical : {"combined", "seed", "plane"}
        Estimate of the vertical-posture point whose direction from the centre
        is z. ``"seed"``: the measured mean point. ``"plane"``: its offset out
        of the fitted circle plane removed (the vertical posture lies on the
        sweep circle). ``"combined"`` (default): the out-of-plane offset is the
        variance-weighted mean of the measured offset (variance ``s^2 / M`` for
        M vertical frames) and zero (the plane's variance at that spot from the
        plane fit of the sweep), with ``s`` the robust out-of-plane scatter of
        the sweep samples. Depth noise acts mostly out of the plane when the
        camera faces the sweep, so few vertical frames tilt a raw z by degrees.
    min_points : int
        Minimum number of valid inlier samples.
    loss : str
        Robust loss of the circle refinement (see :func:`tudorvision.geometry.fit_circle_3d`).
    inlier_sigma : float
        A sample is an outlier when its residual, normalised by robust scales
        taken separately out of the circle plane and radially, exceeds this.
    max_rejected_fraction : float
        Raise when more of the valid samples than this are outliers.

    Returns
    -------
    T_base_cam : ndarray, shape (4, 4)
        Maps camera-frame points into the base frame (``p_base = T_base_cam @ p_cam``).
    report : dict
        ``circle_rmse_m`` (inliers), ``circle_rmse_all_m``, ``circle_radius_m``,
        ``circle_centre_cam``, ``normal_cam`` (the oriented base y axis),
        ``vertical_cam``, ``points_used`` (indices), ``rejected`` (list of
        ``{"index", "reason"}``), ``origin``, ``link1_height_m``,
        ``z_tilt_from_plane_deg`` (how far the measured z leaves the circle plane).

    Raises
    ------
    TudorVisionError
        Too few valid points, too many outliers, degenerate sweep or a vertical
        point at the circle centre.
    """
    if origin not in ("base", "joint2"):
        raise ValueError(f"origin: expected 'base' or 'joint2', got {origin!r}")
    pts_all = check_points(points_cam, "points_cam", finite=False)
    n_all = len(pts_all)
    th_all = None
    if theta2_rad is not None:
        th_all = check_array(theta2_rad, "theta2_rad", (n_all,), finite=False)
    finite = np.all(np.isfinite(pts_all), axis=1)
    if th_all is not None:
        finite &= np.isfinite(th_all)
    rejected = [{"index": int(i), "reason": "invalid (lost disc or missing value)"} for i in np.nonzero(~finite)[0]]
    idx = np.nonzero(finite)[0]
    if len(idx) < max(3, min_points):
        raise TudorVisionError(f"circle fit needs at least {max(3, min_points)} valid points, got {len(idx)} "
                               f"of {n_all}")
    pts = pts_all[idx]
    try:
        fit = fit_circle_3d(pts, loss=loss)
    except ValueError as exc:
        raise TudorVisionError(f"circle fit failed: {exc}") from None
    inl, dist = _inliers(pts, fit, inlier_sigma)
    for i in np.nonzero(~inl)[0]:
        rejected.append({"index": int(idx[i]), "reason": "outlier", "distance_m": float(dist[i])})
    if (~inl).sum() > max_rejected_fraction * len(idx):
        raise TudorVisionError(f"{int((~inl).sum())} of {len(idx)} sweep points are circle outliers "
                               f"(more than {max_rejected_fraction:.0%}): check the disc segmentation")
    if inl.sum() < max(3, min_points):
        raise TudorVisionError(f"circle fit needs at least {max(3, min_points)} inlier points, got {int(inl.sum())}")
    if not np.all(inl):
        fit = fit_circle_3d(pts[inl], loss="linear")
        used = idx[inl]
    else:
        used = idx
    pts_used = pts_all[used]
    th_used = None if th_all is None else th_all[used]
    omega = _rotation_axis(pts_used, fit.centre, fit.normal, th_used)
    y_hat = -omega
    c = fit.centre

    pv_all = check_points(vertical_cam, "vertical_cam", finite=False)
    pv_ok = np.all(np.isfinite(pv_all), axis=1)
    if not np.any(pv_ok):
        raise TudorVisionError("vertical_cam: no valid vertical-posture point (disc lost in every vertical frame)")
    pv = pv_all[pv_ok].mean(axis=0)
    if vertical not in ("combined", "seed", "plane"):
        raise ValueError(f"vertical: expected 'combined', 'seed' or 'plane', got {vertical!r}")
    h_v = float((pv - c) @ omega)
    w_meas = 1.0
    if vertical != "seed":
        w_meas = 0.0 if vertical == "plane" else _measured_weight(pts_used, fit.centre, omega, pv,
                                                                  int(pv_ok.sum()))
        pv = pv - (1.0 - w_meas) * h_v * omega
    dz = pv - c
    nz = float(np.linalg.norm(dz))
    if nz < 0.1 * fit.radius:
        raise TudorVisionError(f"vertical_cam: the vertical-posture point is {nz:.3f} m from the circle centre "
                               f"(radius {fit.radius:.3f} m); expected about one radius")
    z = dz / nz
    x = np.cross(y_hat, z)
    nx = np.linalg.norm(x)
    if nx < 1e-6:
        raise TudorVisionError("vertical_cam: the direction to the vertical point is parallel to the circle normal")
    x /= nx
    y = np.cross(z, x)

    if link1_height_m is None:
        from ..robot import load_robot_params
        link1_height_m = load_robot_params().link1_height_m
    h = float(link1_height_m) if origin == "base" else 0.0
    T_cam_base = np.eye(4)
    T_cam_base[:3, 0], T_cam_base[:3, 1], T_cam_base[:3, 2] = x, y, z
    T_cam_base[:3, 3] = c - h * z
    T_base_cam = invert_transform(T_cam_base)
    rejected.sort(key=lambda r: r["index"])
    report = {
        "circle_rmse_m": float(fit.rmse),
        "circle_rmse_all_m": float(fit.rmse_all),
        "circle_radius_m": float(fit.radius),
        "circle_centre_cam": c.tolist(),
        "normal_cam": y_hat.tolist(),
        "vertical_cam": pv.tolist(),
        "n_vertical": int(pv_ok.sum()),
        "vertical_mode": vertical,
        "vertical_offset_from_plane_m": h_v,
        "vertical_measured_weight": float(w_meas),
        "vertical_distance_m": nz,
        "z_tilt_from_plane_deg": float(np.degrees(np.arcsin(np.clip(abs(z @ y_hat), 0.0, 1.0)))),
        "n_samples": n_all,
        "points_used": [int(i) for i in used],
        "rejected": rejected,
        "origin": ("base plate: link1_height_m below the circle centre along z" if origin == "base"
                   else "joint 2: the circle centre"),
        "link1_height_m": h,
        "T_base_cam": T_base_cam.tolist(),
    }
    return T_base_cam, report


def refine_sweep_in_plane(T_base_cam, centres_cam, theta_rad, deflection, payload_kg: float = 0.0):
    """Refine a sweep calibration's in-plane angle and origin with the arm's learnt deflection model.

    The seed's construction (:func:`base_frame_from_theta2_sweep`) takes z
    from the circle centre to the disc in the vertical posture [0, 90, 0] deg. The elastic arm does not
    stand exactly vertical there (the lab's arm leans 6.5 mm, 0.45 deg, at the disc), so that z leans with
    it, and over the 2-6 m a ball is extrapolated a 0.45 deg tilt of gravity moves the predicted crossing
    by centimetres. Here the disc centres, mapped into the base frame by ``T_base_cam``, are fitted in the
    sweep plane (a rotation about base y and a shift in x and z, Kabsch on the in-plane points, points
    beyond three robust sigmas dropped) to the end-effector positions the arm's own data-based kinematics
    predict at the sweep's joint angles (e.g. :class:`tudorvision.catch.kinematics.DeflectionModel`, the
    model the catch's inverse kinematics use; any callable of that signature). The circle plane (base y)
    is kept from ``T_base_cam``. Used by the catch demo after :func:`base_frame_from_theta2_sweep`.

    Parameters
    ----------
    T_base_cam : array_like, shape (4, 4)
        The sweep calibration (``p_base = T_base_cam @ p_cam``), base-plate origin.
    centres_cam : array_like, shape (N, 3)
        Measured disc centres, metres, camera frame; NaN rows are skipped.
    theta_rad : array_like, shape (N, 3)
        Joint angles per frame, rad (theta1 = 0 in the sweep).
    deflection : callable
        ``deflection(theta23 (N, 2), payload_kg) -> (N, 2)`` reach and height of the deflected end
        effector, metres (a :class:`~tudorvision.catch.kinematics.DeflectionModel`).
    payload_kg : float
        Payload added to the end-effector mount during the sweep, kg.

    Returns
    -------
    T_base_cam : ndarray, shape (4, 4)
        The refined transform.
    info : dict
        ``in_plane_rotation_deg`` (the correction), ``in_plane_rmse_m`` (residual against the model),
        ``points`` used.

    Raises
    ------
    ValueError
        Fewer than three measured centres.

    Examples
    --------
    >>> th = np.radians([[0, a, 0] for a in (0.0, 45.0, 90.0, 135.0, 180.0)])
    >>> model = lambda t23, m: np.stack([0.8 * np.cos(t23[:, 0]), 0.3 + 0.8 * np.sin(t23[:, 0])], axis=1)
    >>> rz = model(th[:, 1:], 0.0)
    >>> pts = np.stack([rz[:, 0], np.zeros(5), rz[:, 1]], axis=1)       # camera frame = base frame here
    >>> c, s = np.cos(np.radians(0.5)), np.sin(np.radians(0.5))
    >>> T0 = np.eye(4); T0[:3, :3] = [[c, 0, s], [0, 1, 0], [-s, 0, c]]  # a calibration 0.5 deg off about y
    >>> T, info = refine_sweep_in_plane(T0, pts, th, model)
    >>> bool(np.allclose(T, np.eye(4), atol=1e-9)), round(abs(info["in_plane_rotation_deg"]), 3)
    (True, 0.5)
    """
    T0 = check_array(T_base_cam, "T_base_cam", (4, 4))
    pc = check_array(centres_cam, "centres_cam", (None, 3), finite=False)
    th = check_array(theta_rad, "theta_rad", (len(pc), 3))
    ok = np.all(np.isfinite(pc), axis=1)
    if ok.sum() < 3:
        raise ValueError(f"centres_cam: expected at least 3 measured disc centres, got {int(ok.sum())}")
    pb = pc[ok] @ T0[:3, :3].T + T0[:3, 3]
    rz = np.asarray(deflection(th[ok, 1:], payload_kg), float)
    a = np.stack([pb[:, 0], np.zeros(len(pb)), pb[:, 2]], axis=1)     # measured, in the sweep plane y = 0
    b = np.stack([rz[:, 0], np.zeros(len(rz)), rz[:, 1]], axis=1)     # predicted by the kinematics model
    def fit(use):
        C = fit_rigid_transform(a[use], b[use])
        return C, np.linalg.norm(a @ C[:3, :3].T + C[:3, 3] - b, axis=1)

    use = np.ones(len(a), bool)
    for _ in range(2):                       # drop points beyond three robust sigmas, twice
        C, res = fit(use)
        use = res <= 3.0 * (1.4826 * float(np.median(res[use])) + 1e-9)
    C, res = fit(use)
    return C @ T0, {"in_plane_rotation_deg": float(np.degrees(np.arctan2(C[2, 0], C[0, 0]))),
                    "in_plane_rmse_m": float(np.sqrt(np.mean(res[use] ** 2))), "points": int(use.sum())}


def refine_sweep_mirror(T_base_cam, centres_cam, theta_rad, *, pair_tol_rad: float = float(np.radians(1.0))):
    """Refine a sweep calibration's in-plane angle and lateral origin from the sweep's mirror symmetry.

    With theta1 = theta3 = 0 an elastic arm under gravity bends alike at theta2 and 180 deg - theta2,
    mirrored about the vertical through joint 2 (the gravity moment changes sign with cos theta2,
    and the gear backlash settles on the mirrored side): whatever the static deflection, the chord
    from the disc at theta2 to the disc at 180 deg - theta2 is horizontal and its midpoint lies on
    the vertical through joint 2. No model of the arm is needed. Each such pair of poses (per-pose
    median of the measured centres, poses told apart to 0.1 deg of theta2; a partner ``delta`` off the
    mirrored angle is allowed up to ``pair_tol_rad`` and its chord's tilt corrected by ``delta / 2``)
    gives the chord's tilt in the sweep plane; the tilts are averaged
    with weights of the squared chord length, the frame is turned about base y by it (about the
    midpoints' mean, so the height there is kept) and shifted along x so that the midpoints' mean
    lies at x = 0. The circle plane (base y) and the height origin are kept from ``T_base_cam``.

    Parameters
    ----------
    T_base_cam : array_like, shape (4, 4)
        A sweep calibration (``p_base = T_base_cam @ p_cam``), e.g. of :func:`base_frame_from_theta2_sweep`
        or :func:`refine_sweep_in_plane`.
    centres_cam : array_like, shape (N, 3)
        Measured disc centres, metres, camera frame; NaN rows are skipped.
    theta_rad : array_like, shape (N, 3)
        Joint angles per frame, rad (theta1 = theta3 = 0).
    pair_tol_rad : float
        How far ``theta2_a + theta2_b`` may be from 180 deg for two poses to pair, rad (default 1 deg).

    Returns
    -------
    T_base_cam : ndarray, shape (4, 4)
        The refined transform.
    info : dict
        ``mirror_rotation_deg`` (the correction in the sweep plane, positive turning x toward z, as
        ``in_plane_rotation_deg`` of :func:`refine_sweep_in_plane`), ``mirror_shift_m`` (along base x),
        ``pairs`` used and ``mirror_tilt_sd_deg`` (weighted spread of the pairs' tilts).

    Raises
    ------
    ValueError
        No pair of measured poses mirrored about the vertical.

    Examples
    --------
    A sagging arm (the tip 3 cm low at horizontal, mirrored) seen through a frame 0.3 deg off:

    >>> a = np.radians([20.0, 45.0, 70.0, 110.0, 135.0, 160.0])
    >>> sag = 0.03 * np.cos(a) ** 2
    >>> pts = np.stack([0.84 * np.cos(a), np.zeros(6), 0.35 + 0.84 * np.sin(a) - sag], axis=1)
    >>> th = np.stack([np.zeros(6), a, np.zeros(6)], axis=1)
    >>> c, s = np.cos(np.radians(0.3)), np.sin(np.radians(0.3))
    >>> T0 = np.eye(4); T0[:3, :3] = [[c, 0, s], [0, 1, 0], [-s, 0, c]]   # camera frame = true base frame
    >>> T, info = refine_sweep_mirror(T0, pts, th)
    >>> info["pairs"], round(abs(info["mirror_rotation_deg"]), 3), bool(np.allclose(T[:3, :3], np.eye(3)))
    (3, 0.3, True)
    """
    T0 = check_array(T_base_cam, "T_base_cam", (4, 4))
    pc = check_array(centres_cam, "centres_cam", (None, 3), finite=False)
    th = check_array(theta_rad, "theta_rad", (len(pc), 3))
    ok = np.all(np.isfinite(pc), axis=1)
    pb = pc[ok] @ T0[:3, :3].T + T0[:3, 3]
    t2 = th[ok, 1]
    groups = np.round(np.degrees(t2), 1)                                    # poses: theta2 to 0.1 deg
    keys, poses = [], []
    for g in np.unique(groups):
        sel = groups == g
        keys.append(float(np.mean(t2[sel])))
        poses.append(np.median(pb[sel][:, [0, 2]], axis=0))                  # (x, z) in the sweep plane
    keys, poses = np.asarray(keys), np.asarray(poses)
    tilts, weights, mids = [], [], []
    for a in range(len(keys)):
        if keys[a] >= np.pi / 2 - pair_tol_rad:
            continue                                                         # each pair once, not 90 deg with itself
        b = int(np.argmin(np.abs(keys + keys[a] - np.pi)))
        delta = float(keys[a] + keys[b] - np.pi)
        if abs(delta) > pair_tol_rad:
            continue
        chord = poses[a] - poses[b]                                          # should point along +x
        # a partner delta further round the circle tilts the chord by delta / 2 (first order)
        tilts.append(float(np.arctan2(chord[1], chord[0])) - 0.5 * delta)
        weights.append(float(chord @ chord))
        mids.append(0.5 * (poses[a] + poses[b]))
    if not tilts:
        raise ValueError("centres_cam, theta_rad: no two measured poses mirror each other about the vertical "
                         "(theta2 and 180 deg - theta2)")
    w = np.asarray(weights) / np.sum(weights)
    tilt = float(w @ np.asarray(tilts))
    pivot = w @ np.asarray(mids)
    c, s = np.cos(-tilt), np.sin(-tilt)
    R2 = np.array([[c, -s], [s, c]])                                        # turns each chord onto +x
    mids_r = (np.asarray(mids) - pivot) @ R2.T + pivot
    shift = -float(w @ mids_r[:, 0])
    C = np.eye(4)
    C[np.ix_([0, 2], [0, 2])] = R2
    C[[0, 2], 3] = pivot - R2 @ pivot + np.array([shift, 0.0])
    spread = float(np.sqrt(w @ (np.asarray(tilts) - tilt) ** 2))
    return C @ T0, {"mirror_rotation_deg": float(np.degrees(-tilt)), "mirror_shift_m": shift,
                    "pairs": len(tilts), "mirror_tilt_sd_deg": float(np.degrees(spread))}
