"""Rigid-equivalent kinematics of TUDOR (section 2.1, appendix A).

Conventions
-----------
Base frame ``base``: origin on the joint-1 axis at the base plate, z up.
theta1 rotates the arm about the base z axis. theta2 and theta3 have
horizontal axes; the arm moves in the vertical plane selected by theta1.
Zero configuration: arm stretched out horizontally along base x.
theta2 lifts link 2 (theta2 = 90 deg is vertical); link 3's elevation above the
horizontal is theta2 + theta3. With ``r`` the horizontal reach and ``h`` the
height::

    r = l2 cos(t2) + l3 cos(t2 + t3)
    z = h1 + l2 sin(t2) + l3 sin(t2 + t3)
    p_base = [r cos(t1), r sin(t1), z]

End-effector frame ``ee``: x along link 3, y in the arm plane (x rotated by
+90 deg upward), z along the joint-3 axis ``[sin t1, -cos t1, 0]``.

Elbow naming follows the seed (section 9.2): ``"up"`` means theta3 >= 0,
``"down"`` means theta3 < 0.
"""
from __future__ import annotations

import numpy as np

from .._checks import check_array
from .params import RobotParams, load_robot_params

__all__ = [
    "fk_ee", "fk_spheres", "T_base_ee", "jacobian_ee", "ik", "ik_all",
    "within_limits", "clip_to_limits", "planar_from_joints",
]

_DEFAULT: RobotParams | None = None


def _params(params: RobotParams | None) -> RobotParams:
    global _DEFAULT
    if params is not None:
        return params
    if _DEFAULT is None:
        _DEFAULT = load_robot_params()
    return _DEFAULT


def _theta(theta) -> tuple[np.ndarray, bool]:
    arr = np.asarray(theta, dtype=np.float64)
    single = arr.ndim == 1
    arr = check_array(arr[None] if single else arr, "theta", (None, 3))
    return arr, single


def planar_from_joints(theta2, theta3, params: RobotParams | None = None):
    """Reach ``r`` and height ``z`` of the end effector in the arm plane.

    Parameters
    ----------
    theta2, theta3 : array_like
        Joint angles in radians (broadcastable).
    params : RobotParams, optional
        Robot parameters; default the packaged ``tudor.yaml`` (:func:`load_robot_params`).

    Returns
    -------
    r, z : ndarray
        Horizontal reach and height above the base plate, metres.

    Examples
    --------
    >>> r, z = planar_from_joints(0.0, 0.0)
    >>> round(float(r), 3), round(float(z), 3)
    (0.84, 0.35)
    """
    p = _params(params)
    t2 = np.asarray(theta2, dtype=np.float64)
    t23 = t2 + np.asarray(theta3, dtype=np.float64)
    r = p.link2_length_m * np.cos(t2) + p.link3_length_m * np.cos(t23)
    z = p.link1_height_m + p.link2_length_m * np.sin(t2) + p.link3_length_m * np.sin(t23)
    return r, z


def fk_ee(theta, params: RobotParams | None = None) -> np.ndarray:
    """End-effector position in the base frame.

    Parameters
    ----------
    theta : array_like, shape (3,) or (N, 3)
        Joint angles, radians.
    params : RobotParams, optional
        Robot parameters; default the packaged ``tudor.yaml`` (:func:`load_robot_params`).

    Returns
    -------
    p_base : ndarray, shape (3,) or (N, 3)
        Metres, base frame.

    Examples
    --------
    >>> np.round(fk_ee([0.0, np.pi / 2, 0.0]), 3)
    array([0.  , 0.  , 1.19])
    """
    th, single = _theta(theta)
    r, z = planar_from_joints(th[:, 1], th[:, 2], params)
    p = np.stack([r * np.cos(th[:, 0]), r * np.sin(th[:, 0]), z], axis=1)
    return p[0] if single else p


def T_base_ee(theta, params: RobotParams | None = None) -> np.ndarray:
    """Rigid pose of the end-effector frame, shape (4, 4) or (N, 4, 4).

    Parameters
    ----------
    theta : array_like, shape (3,) or (N, 3)
        Joint angles ``[theta1, theta2, theta3]`` in radians.
    params : RobotParams, optional
        Robot parameters; default the packaged ``tudor.yaml`` (:func:`load_robot_params`).

    Returns
    -------
    T_base_ee : ndarray, shape (4, 4) or (N, 4, 4)
        Rigid transform mapping end-effector-frame points into the base frame
        (``p_base = T_base_ee @ p_ee``), translation in metres.

    Examples
    --------
    >>> T = T_base_ee([0.0, 0.0, 0.0])
    >>> (np.round(T[:3, :3], 6) + 0.0).tolist()
    [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]
    """
    th, single = _theta(theta)
    c1, s1 = np.cos(th[:, 0]), np.sin(th[:, 0])
    c23, s23 = np.cos(th[:, 1] + th[:, 2]), np.sin(th[:, 1] + th[:, 2])
    n = th.shape[0]
    T = np.zeros((n, 4, 4))
    T[:, :3, 0] = np.stack([c23 * c1, c23 * s1, s23], axis=1)
    T[:, :3, 1] = np.stack([-s23 * c1, -s23 * s1, c23], axis=1)
    T[:, :3, 2] = np.stack([s1, -c1, np.zeros(n)], axis=1)
    T[:, :3, 3] = fk_ee(th, params)
    T[:, 3, 3] = 1.0
    return T[0] if single else T


def fk_spheres(theta, params: RobotParams | None = None) -> dict[str, np.ndarray]:
    """Centres of the tracking spheres in the base frame (rigid kinematics).

    Parameters
    ----------
    theta : array_like, shape (3,) or (N, 3)
        Joint angles ``[theta1, theta2, theta3]`` in radians.
    params : RobotParams, optional
        Robot parameters; default the packaged ``tudor.yaml`` (:func:`load_robot_params`).

    Returns
    -------
    dict
        ``{"red": p_base, "green": p_base}``, each shape (3,) or (N, 3), metres.

    Examples
    --------
    >>> s = fk_spheres([0.0, 0.0, 0.0])
    >>> bool(np.allclose((s["red"] + s["green"]) / 2, fk_ee([0.0, 0.0, 0.0])))
    True
    """
    p = _params(params)
    T = T_base_ee(theta, p)
    out = {}
    for name, off in p.sphere_offsets_ee_m.items():
        out[name] = T[..., :3, :3] @ off + T[..., :3, 3]
    return out


def jacobian_ee(theta, params: RobotParams | None = None) -> np.ndarray:
    """Analytic translational Jacobian d p_base / d theta.

    Parameters
    ----------
    theta : array_like, shape (3,) or (N, 3)
        Joint angles ``[theta1, theta2, theta3]`` in radians.
    params : RobotParams, optional
        Robot parameters; default the packaged ``tudor.yaml`` (:func:`load_robot_params`).

    Returns
    -------
    J : ndarray, shape (3, 3) or (N, 3, 3)
        Rows x, y, z (metres); columns theta1..3 (radians).

    Examples
    --------
    >>> J = jacobian_ee([0.1, 0.5, -0.3])
    >>> J.shape
    (3, 3)
    """
    p = _params(params)
    th, single = _theta(theta)
    t1, t2, t23 = th[:, 0], th[:, 1], th[:, 1] + th[:, 2]
    l2, l3 = p.link2_length_m, p.link3_length_m
    r = l2 * np.cos(t2) + l3 * np.cos(t23)
    dr2 = -l2 * np.sin(t2) - l3 * np.sin(t23)
    dr3 = -l3 * np.sin(t23)
    dz2 = l2 * np.cos(t2) + l3 * np.cos(t23)
    dz3 = l3 * np.cos(t23)
    c1, s1 = np.cos(t1), np.sin(t1)
    J = np.zeros((th.shape[0], 3, 3))
    J[:, 0] = np.stack([-r * s1, dr2 * c1, dr3 * c1], axis=1)
    J[:, 1] = np.stack([r * c1, dr2 * s1, dr3 * s1], axis=1)
    J[:, 2] = np.stack([np.zeros_like(r), dz2, dz3], axis=1)
    return J[0] if single else J


def within_limits(theta, params: RobotParams | None = None, *, margin_rad: float = 0.0) -> np.ndarray:
    """Whether each configuration lies inside the joint ranges (shrunk by ``margin_rad``).

    Parameters
    ----------
    theta : array_like, shape (3,) or (N, 3)
        Joint angles ``[theta1, theta2, theta3]`` in radians.
    params : RobotParams, optional
        Robot parameters; default the packaged ``tudor.yaml`` (:func:`load_robot_params`).
    margin_rad : float, optional
        Margin in radians by which every joint range is shrunk on both ends.

    Returns
    -------
    ok : bool or ndarray of bool, shape (N,)
        True where all three joints lie inside their (shrunk) ranges.

    Examples
    --------
    >>> bool(within_limits([0.0, 0.0, 2.0]))
    False
    """
    p = _params(params)
    th, single = _theta(theta)
    lo, hi = p.joint_limits_rad[:, 0] + margin_rad, p.joint_limits_rad[:, 1] - margin_rad
    ok = np.all((th >= lo) & (th <= hi), axis=1)
    return ok[0] if single else ok


def clip_to_limits(theta, params: RobotParams | None = None) -> np.ndarray:
    """Clamp joint angles into the joint ranges.

    Parameters
    ----------
    theta : array_like, shape (3,) or (N, 3)
        Joint angles ``[theta1, theta2, theta3]`` in radians.
    params : RobotParams, optional
        Robot parameters; default the packaged ``tudor.yaml`` (:func:`load_robot_params`).

    Returns
    -------
    theta : ndarray, shape (3,) or (N, 3)
        Joint angles in radians, each clamped into its joint range.
    """
    p = _params(params)
    th, single = _theta(theta)
    out = np.clip(th, p.joint_limits_rad[:, 0], p.joint_limits_rad[:, 1])
    return out[0] if single else out


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def ik_all(p_base, params: RobotParams | None = None, *, respect_limits: bool = True) -> np.ndarray:
    """All analytic inverse-kinematics solutions for one end-effector position.

    Two choices of theta1 (facing the point, or facing away with the arm
    reaching over the top) times two elbow postures give up to four solutions.

    Parameters
    ----------
    p_base : array_like, shape (3,)
        Target position, metres, base frame.
    respect_limits : bool
        Drop solutions outside the joint ranges.
    params : RobotParams, optional
        Robot parameters; default the packaged ``tudor.yaml`` (:func:`load_robot_params`).

    Returns
    -------
    thetas : ndarray, shape (K, 3)
        K in 0..4 solutions, radians; empty when unreachable.

    Examples
    --------
    >>> sols = ik_all(fk_ee([0.3, 0.8, -0.6]))
    >>> bool(np.any(np.all(np.isclose(sols, [0.3, 0.8, -0.6]), axis=1)))
    True
    """
    p = _params(params)
    x, y, z = check_array(p_base, "p_base", (3,))
    l2, l3 = p.link2_length_m, p.link3_length_m
    rho = np.hypot(x, y)
    zz = z - p.link1_height_m
    phi = np.arctan2(y, x) if rho > 1e-12 else 0.0
    sols = []
    for t1, r in ((phi, rho), (_wrap(phi + np.pi), -rho)):
        d2 = r * r + zz * zz
        c3 = (d2 - l2 * l2 - l3 * l3) / (2 * l2 * l3)
        if c3 > 1.0 + 1e-12 or c3 < -1.0 - 1e-12:
            continue
        c3 = min(1.0, max(-1.0, c3))
        for sgn in (1.0, -1.0):
            t3 = sgn * np.arccos(c3)
            t2 = np.arctan2(zz, r) - np.arctan2(l3 * np.sin(t3), l2 + l3 * np.cos(t3))
            t2 = _wrap(t2)
            # theta2's range extends past 180 deg: prefer the representative inside it
            lo2, hi2 = p.joint_limits_rad[1]
            if t2 < lo2 and t2 + 2 * np.pi <= hi2:
                t2 += 2 * np.pi
            sols.append([t1, t2, t3])
    out = np.array(sols, dtype=np.float64).reshape(-1, 3)
    if respect_limits and len(out):
        out = out[within_limits(out, p)]
    # remove duplicates (elbow singular: t3 = 0 or pi)
    if len(out) > 1:
        keep = [0]
        for i in range(1, len(out)):
            if not any(np.allclose(out[i], out[j], atol=1e-9) for j in keep):
                keep.append(i)
        out = out[keep]
    return out


def ik(p_base, params: RobotParams | None = None, *, elbow: str | None = None,
       near=None) -> np.ndarray:
    """Inverse kinematics: one solution, chosen by elbow posture and nearness.

    Parameters
    ----------
    p_base : array_like, shape (3,)
        Target, metres, base frame.
    elbow : {"up", "down", None}
        ``"up"``: theta3 >= 0, ``"down"``: theta3 < 0; ``None`` accepts both.
    near : array_like, shape (3,), optional
        Current configuration; the valid solution nearest to it is returned.
        Default: the solution with theta1 facing the target.
    params : RobotParams, optional
        Robot parameters; default the packaged ``tudor.yaml`` (:func:`load_robot_params`).

    Returns
    -------
    theta : ndarray, shape (3,)

    Raises
    ------
    ValueError
        If ``elbow`` is invalid or no solution within the joint ranges exists.

    Examples
    --------
    >>> th = ik(fk_ee([0.0, 0.6, 0.5]), elbow="up")
    >>> np.round(th, 6).tolist()
    [0.0, 0.6, 0.5]
    """
    if elbow not in (None, "up", "down"):
        raise ValueError(f"elbow: expected 'up', 'down' or None, got {elbow!r}")
    sols = ik_all(p_base, params)
    if elbow == "up":
        sols = sols[sols[:, 2] >= 0]
    elif elbow == "down":
        sols = sols[sols[:, 2] < 0]
    if len(sols) == 0:
        raise ValueError(f"p_base: {np.round(np.asarray(p_base, float), 4).tolist()} is not reachable"
                         f" within the joint ranges (elbow={elbow})")
    if near is None:
        return sols[0]
    ref = check_array(near, "near", (3,))
    d = np.linalg.norm(_wrap(sols - ref), axis=1)
    return sols[int(np.argmin(d))]
