"""The calibration disc found as what it is: a planar disc of known radius, in 3D on the depth points.

Issue 15. The seed segments the disc as "a region of uniform depth" grown from
a seed pixel (:mod:`tudorvision.rgbd.disc`). On a real arm the disc sits in a
net ring at the end of thin links, so in depth it is joined to the ring and
the links (the region leaks along them), and behind it there is either no
depth at all (a background out of range) or a wall a few decimetres away.
Here the disc is measured in 3D near where it is expected:

1. **Search window in 3D.** The valid pixels whose back-projected points lie
   within ``disc_radius_m + margin`` of the predicted centre laterally (across
   the viewing ray) and within that plus three depth-noise sigmas along it.
2. **Plane.** RANSAC on those points (triples drawn from the core, the points
   within one disc radius of the prediction), inlier band ``3 sigma_z``, then
   a least-squares refit in inverse depth (``1/z`` is linear in the pixel
   ray for a plane, and the depth noise lies along the rays: unbiased where a
   total least-squares plane tilts away from the view under Kinect noise at
   5 m). When depth noise leaves the plane's tilt undetermined
   (its standard error above ``max_normal_std_deg``), the normal of the
   previous frames is used, else the one facing the camera; so too when the
   fit is edge-on (it may be the noise's), but a patch that lies on the
   edge-on plane where that plane runs on beyond it is the floor or a wall
   seen at a grazing angle, not the disc.
3. **Disc in the plane.** The inlier pixels form a mask; a closing fills noise
   holes and an opening with a kernel of ``opening_fraction`` of the disc's
   smaller image radius removes the thin links and anything else narrower than
   the disc. Every pixel of the component under the prediction is then
   intersected with the plane (its ray, not its noisy depth), so the disc's
   points are metric positions in the plane.
4. **Circle of known radius.** The centre is the area-weighted centroid of the
   in-plane points inside a circle of the disc's radius about the current
   centre, iterated to its fixed point (a mean shift with a flat kernel of the
   disc's radius): the ring, link stubs and anything outside the disc do not
   pull it. The disc area found inside 1.5 radii (the equivalent radius) must
   fit the known radius, else the frame is skipped.

:class:`tudorvision.rgbd.disc_track.DiscSweepTracker` predicts the centre from the previous frames: with
joint angles, a circle fitted to the centres so far, parametrised by theta2
(the disc turns about the joint-2 axis), before that a step of the arm's
radius from the last centre, otherwise a constant-velocity step.
A frame where the disc cannot be measured (edge-on, out of range, occluded,
off the image) is skipped and counted with its reason, never fatal.

Only depth images, intrinsics and joint angles are used; no scene knowledge.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._checks import check_array
from ..sensors import KINECT_DEPTH_NOISE, DepthNoiseModel
from .frames import Intrinsics, check_depth

__all__ = ["Disc3DOptions", "DiscMeasurement", "measure_disc_3d", "plane_extent_ratio"]


@dataclass(frozen=True, kw_only=True)
class Disc3DOptions:
    """Options of the 3D disc measurement and of the sweep tracker.

    Parameters
    ----------
    disc_radius_m : float
        Radius of the calibration disc, metres (default 0.09: the 18 cm disc).
    acquire_margin_m : float
        Search margin around the prediction (beyond the disc radius) until the
        disc has been found twice, metres.
    min_margin_m, max_margin_m : float
        Bounds of the search margin while tracking, metres.
    plane_tol_sigma : float
        Plane inlier band, in depth-noise sigmas at the predicted depth.
    min_plane_tol_m : float
        Smallest plane inlier band, metres.
    ransac_iterations : int
        Plane hypotheses per plane.

    opening_fraction : float
        Radius of the opening kernel as a fraction of the disc's smaller image
        radius (the links are removed when thinner than twice that).
    area_ratio : tuple of float
        ``(low, high)`` accepted bounds of (disc area found within 1.5 radii of
        the centre) / (pi R^2); a ring around the disc adds to it. The low bound
        is 0.25 (was 0.45): a 9 px disc 5 m away with a real sensor's ragged
        depth edges (:data:`tudorvision.sim.depth_sensor.KINECT_EDGE_JITTER_PX`)
        keeps 0.27-0.45 of its area through the invalid edge band and the
        opening when seen 30-45 deg off its face.
    min_points : int
        Fewest valid depth points in the search window.
    min_minor_px : float
        The disc is skipped when its smaller image radius is below this (seen
        edge-on or too far), pixels.
    max_normal_std_deg : float
        Above this standard error of the fitted plane's normal, the plane keeps
        the previous frames' normal (or faces the camera), degrees.
    max_extent_ratio : float
        A plane patch is not the disc when its inlier pixels cover more than
        this fraction of the in-plane annulus between 1.7 and 2.6 disc radii
        around the centre found (a wall, the floor or a table top: the disc
        and its ring end at about 1.35 radii).
    min_roundness : float
        Smallest accepted axis ratio (square root of the in-plane second
        moments' eigenvalue ratio) of the patch within 1.5 radii: a disc (and
        its ring) is round, a strip of floor seen on a wrong plane is not.
    arm_radius_m : float
        Distance of the disc centre from the joint-2 axis, metres (link2 +
        link3 on the seed's arm): bounds how far one theta2 step moves the
        disc (``2 arm_radius_m sin(dtheta / 2)``) before a circle is fitted.
    depth_model : tudorvision.sensors.DepthNoiseModel
        ``sigma_z(z)`` in metres.
    random_seed : int
        Seed of the RANSAC sampling (results are reproducible).

    Raises
    ------
    ValueError
        On a non-positive radius or margin, inverted bounds or a bad fraction.
    """

    disc_radius_m: float = 0.09
    acquire_margin_m: float = 0.15
    min_margin_m: float = 0.04
    max_margin_m: float = 0.2
    plane_tol_sigma: float = 3.0
    min_plane_tol_m: float = 0.01
    ransac_iterations: int = 96
    opening_fraction: float = 0.4
    area_ratio: tuple = (0.25, 2.15)
    min_points: int = 20
    min_minor_px: float = 2.5
    max_normal_std_deg: float = 10.0
    max_extent_ratio: float = 0.35
    min_roundness: float = 0.55
    arm_radius_m: float = 0.84
    depth_model: DepthNoiseModel = field(default=KINECT_DEPTH_NOISE)
    random_seed: int = 0

    def __post_init__(self):
        if not self.disc_radius_m > 0:
            raise ValueError(f"disc_radius_m: expected > 0, got {self.disc_radius_m}")
        if not 0 < self.min_margin_m <= self.max_margin_m or not self.acquire_margin_m > 0:
            raise ValueError("min_margin_m, max_margin_m, acquire_margin_m: expected 0 < min <= max and acquire > 0")
        if not 0 < self.opening_fraction < 1:
            raise ValueError(f"opening_fraction: expected in (0, 1), got {self.opening_fraction}")
        if not 0 <= self.area_ratio[0] < self.area_ratio[1]:
            raise ValueError(f"area_ratio: expected 0 <= low < high, got {self.area_ratio}")
        if not 0 < self.max_extent_ratio <= 1 or not self.arm_radius_m > 0:
            raise ValueError("max_extent_ratio in (0, 1] and arm_radius_m > 0 expected")
        if self.ransac_iterations < 1 or self.min_points < 3:
            raise ValueError("ransac_iterations >= 1 and min_points >= 3 expected")


@dataclass(frozen=True)
class DiscMeasurement:
    """The disc in one depth frame.

    Parameters
    ----------
    valid : bool
        False when the disc could not be measured (``reason`` says why).
    centre_cam : ndarray, shape (3,)
        Disc centre, metres, camera optical frame (x right, y down, z
        forward); NaN when not valid.
    normal_cam : ndarray, shape (3,)
        Unit normal of the disc plane, facing the camera; NaN when not valid.
    radius_m : float
        Equivalent radius of the disc area found (``sqrt(A / pi)``), metres.
    n_points : int
        Disc pixels used for the centre.
    plane_rmse_m : float
        RMS distance of the plane inliers to the plane, metres.
    normal_from : str
        ``"fit"``, ``"prior"`` (previous frames) or ``"camera"`` (facing it).
    reason : str
        Why the frame was skipped; empty when ``valid``.
    """

    valid: bool
    centre_cam: np.ndarray
    normal_cam: np.ndarray
    radius_m: float = float("nan")
    n_points: int = 0
    plane_rmse_m: float = float("nan")
    normal_from: str = ""
    reason: str = ""


def skip_measurement(reason: str, n: int = 0) -> DiscMeasurement:
    """An invalid :class:`DiscMeasurement` with ``reason``.

    Parameters
    ----------
    reason : str
        Why the disc was not measurable.
    n : int
        Valid depth points seen.

    Returns
    -------
    DiscMeasurement
    """
    nan3 = np.full(3, np.nan)
    return DiscMeasurement(False, nan3, nan3.copy(), n_points=n, reason=reason)


def unit_vector(v):
    """``v / |v|``.

    Parameters
    ----------
    v : ndarray, shape (3,)

    Returns
    -------
    ndarray, shape (3,)
    """
    return v / np.linalg.norm(v)


def _ransac_plane(P, core, tol, iterations, rng, view, min_cos_view):
    """Plane (normal, offset) with the most inliers; triples drawn from the ``core`` points."""
    idx = np.nonzero(core)[0] if core.sum() >= 3 else np.arange(len(P))
    tri = idx[rng.integers(0, len(idx), size=(iterations, 3))]
    a, b, c = P[tri[:, 0]], P[tri[:, 1]], P[tri[:, 2]]
    n = np.cross(b - a, c - a)
    norm = np.linalg.norm(n, axis=1)
    ok = norm > 1e-12
    if not ok.any():
        return None
    n = n[ok] / norm[ok, None]
    a = a[ok]
    if min_cos_view > 0:                      # planes seen too edge-on cannot show the disc
        face = np.abs(n @ view) >= min_cos_view
        if not face.any():
            return None
        n, a = n[face], a[face]
    h = np.einsum("ij,ij->i", n, a)
    r = np.abs(P @ n.T - h)
    score = np.sum(np.minimum(r / tol, 1.0) ** 2, axis=0)       # MSAC: truncated squared residuals
    k = int(np.argmin(score))
    return n[k], float(h[k])


def _refit(P, normal, h, tol, sigma):
    """Least-squares plane of the inliers of (normal, h), fitted in inverse depth.

    A plane ``n . p = h`` seen along the rays ``r = (u', v', 1)`` is linear in
    inverse depth: ``1 / z = (n . r) / h``. The depth noise lies along the
    rays, so the regression of ``1 / z`` on ``(u', v', 1)`` is unbiased, where
    a total least-squares (SVD) plane tilts away from the view when the noise
    is not small against the patch (35 deg at 5.5 m on the 18 cm disc).

    Returns normal, h, inlier mask, rmse and the normal's standard error (rad)
    from the regression's covariance, the residual scale floored at the depth
    noise ``sigma``.
    """
    for _ in range(2):
        inl = np.abs(P @ normal - h) <= tol
        if inl.sum() < 4:
            break
        Q = P[inl]
        A = np.column_stack([Q[:, 0] / Q[:, 2], Q[:, 1] / Q[:, 2], np.ones(len(Q))])
        sol, *_ = np.linalg.lstsq(A, 1.0 / Q[:, 2], rcond=None)
        norm = float(np.linalg.norm(sol))
        if not norm > 0:
            break
        normal, h = sol / norm, 1.0 / norm
    inl = np.abs(P @ normal - h) <= tol
    Q = P[inl]
    if len(Q) < 4:
        return normal, h, inl, float("nan"), float("inf")
    rmse = float(np.sqrt(np.mean((Q @ normal - h) ** 2)))
    A = np.column_stack([Q[:, 0] / Q[:, 2], Q[:, 1] / Q[:, 2], np.ones(len(Q))])
    v = normal / h
    zres = Q[:, 2] - 1.0 / (A @ v)                                  # residuals along the rays
    zmed = float(np.median(Q[:, 2]))
    s_inv = max(float(np.sqrt(np.mean(zres ** 2))), sigma) / zmed ** 2      # noise of 1/z
    try:
        cov = s_inv ** 2 * np.linalg.inv(A.T @ A)
    except np.linalg.LinAlgError:
        return normal, h, inl, rmse, float("inf")
    perp = np.eye(3) - np.outer(normal, normal)
    std = float(np.sqrt(max(np.linalg.eigvalsh(perp @ cov @ perp)[-1], 0.0)) / np.linalg.norm(v))
    return normal, h, inl, rmse, std


def _mean_shift(Q, w, centre, R, edge):
    """Fixed point of: centre = area-weighted mean of the points within ``R`` (soft edge of +-``edge``)."""
    for _ in range(30):
        dist = np.linalg.norm(Q - centre, axis=1)
        wk = w * np.clip((R + edge - dist) / (2 * edge), 0.0, 1.0)
        if wk.sum() <= 0:
            return None
        new = np.average(Q, axis=0, weights=wk)
        moved = float(np.linalg.norm(new - centre))
        centre = new
        if moved < 1e-5:
            break
    return centre


def plane_extent_ratio(depth_m, intrinsics: Intrinsics, centre_cam, normal_cam, radius_m: float, tol_m: float,
                       inner: float = 1.7, outer: float = 2.6) -> float:
    """Fraction of the in-plane annulus around a disc centre covered by depth points on the plane.

    Each pixel's ray is intersected with the plane; the pixel counts (with
    its footprint on the plane) when its in-plane distance from the centre is
    between ``inner`` and ``outer`` radii and its measured depth lies within
    ``tol_m`` of the plane's. The disc and its ring leave this annulus
    nearly empty (thin links aside); a wall or the floor fills it.

    Parameters
    ----------
    depth_m : ndarray, shape (H, W)
        Depth (z) in metres, NaN = invalid.
    intrinsics : Intrinsics
        Pinhole intrinsics (pixels).
    centre_cam, normal_cam : array_like, shape (3,)
        Disc centre (metres) and unit normal, camera frame.
    radius_m : float
        Disc radius, metres.
    tol_m : float
        Depth band of the plane, metres.
    inner, outer : float
        Annulus bounds in disc radii.

    Returns
    -------
    float
        Covered area / annulus area (0 when the annulus is outside the image).
    """
    K = intrinsics
    c, n = np.asarray(centre_cam, float), np.asarray(normal_cam, float)
    zc = float(c[2])
    f = float(np.sqrt(K.fx * K.fy))
    half = int(np.ceil(f * outer * radius_m / zc)) + 2
    uc, vc = K.fx * c[0] / zc + K.cx, K.fy * c[1] / zc + K.cy
    u0, u1 = max(0, int(uc) - half), min(K.width, int(uc) + half + 1)
    v0, v1 = max(0, int(vc) - half), min(K.height, int(vc) + half + 1)
    if u0 >= u1 or v0 >= v1:
        return 0.0
    gu, gv = np.meshgrid((np.arange(u0, u1) - K.cx) / K.fx, (np.arange(v0, v1) - K.cy) / K.fy)
    ndotr = n[0] * gu + n[1] * gv + n[2]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = float(n @ c) / ndotr
        rho = np.sqrt((gu * t - c[0]) ** 2 + (gv * t - c[1]) ** 2 + (t - c[2]) ** 2)
        z = depth_m[v0:v1, u0:u1]
        on = (t > 0) & (rho >= inner * radius_m) & (rho <= outer * radius_m) & (np.abs(z - t) <= tol_m)
        w = t * t / (K.fx * K.fy * np.abs(ndotr))
    area = float(np.sum(w[on]))
    return area / (np.pi * (outer ** 2 - inner ** 2) * radius_m ** 2)


def _disc_kernel(r):
    import cv2

    r = max(int(round(r)), 1)
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))


def measure_disc_3d(depth_m, intrinsics: Intrinsics, predicted_cam, margin_m: float,
                    options: Disc3DOptions = Disc3DOptions(), *, normal_prior=None,
                    rng: np.random.Generator | None = None) -> DiscMeasurement:
    """Measure the disc near its predicted centre (plane fit and circle of known radius in 3D).

    Parameters
    ----------
    depth_m : array_like, shape (H, W)
        Depth (z) in metres; NaN or 0 = invalid.
    intrinsics : Intrinsics
        Pinhole intrinsics of the depth image (pixels).
    predicted_cam : array_like, shape (3,)
        Predicted disc centre, metres, camera optical frame.
    margin_m : float
        How far the true centre may be from the prediction, metres; the search
        window reaches ``disc_radius_m + margin_m`` around it.
    options : Disc3DOptions
        Radius, tolerances and checks.
    normal_prior : array_like, shape (3,), optional
        Disc normal of the previous frames (camera frame), used when the plane
        tilt is undetermined by the depth noise.
    rng : numpy.random.Generator, optional
        RANSAC sampling (default: seeded from ``options.random_seed``).

    Returns
    -------
    DiscMeasurement
        ``valid=False`` with the reason when the disc is not measurable in
        this frame.

    Raises
    ------
    ValueError
        If the depth image does not have the intrinsics' shape or the
        prediction is not three finite values.
    """
    d = check_depth(depth_m, intrinsics=intrinsics, require_valid=False)
    pred = check_array(predicted_cam, "predicted_cam", (3,))
    rng = rng if rng is not None else np.random.default_rng(options.random_seed)
    K, R = intrinsics, options.disc_radius_m
    zp = float(pred[2])
    if not zp > 0.1:
        return skip_measurement(f"predicted disc depth {zp:.2f} m is behind the camera")
    f = float(np.sqrt(K.fx * K.fy))
    reach = R + float(margin_m)
    up, vp = K.fx * pred[0] / zp + K.cx, K.fy * pred[1] / zp + K.cy
    half = int(np.ceil(f * reach / zp)) + 2
    u0, u1 = max(0, int(np.floor(up)) - half), min(K.width, int(np.ceil(up)) + half + 1)
    v0, v1 = max(0, int(np.floor(vp)) - half), min(K.height, int(np.ceil(vp)) + half + 1)
    if u0 >= u1 or v0 >= v1:
        return skip_measurement(f"predicted disc at pixel ({up:.0f}, {vp:.0f}) is outside the image")
    z = d[v0:v1, u0:u1]
    gu, gv = np.meshgrid((np.arange(u0, u1) - K.cx) / K.fx, (np.arange(v0, v1) - K.cy) / K.fy)
    lat = np.hypot(gu - pred[0] / zp, gv - pred[1] / zp) * zp          # lateral offset at the predicted depth
    sigma = float(options.depth_model.sigma_m(zp))
    with np.errstate(invalid="ignore"):
        sel = np.isfinite(z) & (lat <= reach) & (np.abs(z - zp) <= reach + 3.0 * sigma)
    n_sel = int(sel.sum())
    if n_sel < options.min_points:
        return skip_measurement(f"only {n_sel} valid depth points within {reach:.2f} m of the predicted disc", n_sel)
    P = np.column_stack([gu[sel] * z[sel], gv[sel] * z[sel], z[sel]])
    tol = max(options.min_plane_tol_m, options.plane_tol_sigma * sigma)
    geo = _Window(K, f, R, zp, pred, gu, gv, lat, sel, z.shape, sigma, d)
    # the disc is the front surface near the prediction: a wall behind it would give RANSAC a plane slanted
    # across both. Front = within the disc's depth extent (from the previous normal, else up to 60 deg of
    # tilt) plus 3 sigma behind the 10th percentile depth of the points within one radius of the prediction.
    zs, core = P[:, 2], lat[sel] <= R
    z_front = float(np.quantile(zs[core] if core.sum() >= options.min_points else zs, 0.1))
    tilt = np.radians(60.0)
    if normal_prior is not None and np.all(np.isfinite(normal_prior)):
        tilt = min(np.arccos(min(1.0, abs(float(unit_vector(np.asarray(normal_prior, float)) @ unit_vector(pred))))) +
                   np.radians(15.0), np.radians(75.0))
    front = zs <= z_front + 2.0 * R * np.sin(tilt) + 3.0 * sigma
    first_reason = ""
    for subset in (front, np.ones(len(P), bool)):
        idx = np.nonzero(subset)[0]
        if len(idx) < options.min_points:
            continue
        hyp = _ransac_plane(P[idx], core[idx], tol, options.ransac_iterations, rng, unit_vector(pred),
                            min(0.9, options.min_minor_px * zp / (f * R)))
        if hyp is None:
            continue
        normal, h, inl_sub, rmse, nstd = _refit(P[idx], *hyp, tol, sigma)
        inl = np.zeros(len(P), bool)
        inl[idx[inl_sub]] = True
        if inl.sum() < options.min_points:
            continue
        m = _disc_in_plane(geo, P, inl, normal, h, rmse, nstd, tol, options, normal_prior)
        if m.valid:
            return m
        first_reason = first_reason or m.reason
        if subset.all():
            break
    return skip_measurement(first_reason or "no plane through the points near the predicted disc", n_sel)


@dataclass(frozen=True)
class _Window:
    K: Intrinsics
    f: float
    R: float
    zp: float
    pred: np.ndarray
    gu: np.ndarray
    gv: np.ndarray
    lat: np.ndarray
    sel: np.ndarray
    shape: tuple
    sigma: float
    depth: np.ndarray


def _patch(g, P, inl, minor_px, options):
    """Pixels of the in-plane component under the prediction, after closing and opening (None if none)."""
    import cv2

    mask = np.zeros(g.shape, np.uint8)
    vv, uu = np.nonzero(g.sel)
    mask[vv[inl], uu[inl]] = 1
    mask = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, _disc_kernel(1))
    mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, _disc_kernel(options.opening_fraction * minor_px))
    n_lab, labels = cv2.connectedComponents(mask, connectivity=8)
    core = (g.lat <= g.R) & (labels > 0)
    counts = np.bincount(labels[core], minlength=n_lab) if core.any() else np.zeros(n_lab, int)
    if n_lab < 2:
        return None
    if counts[1:].max(initial=0) > 0:
        return labels == int(np.argmax(counts[1:]) + 1)
    # nothing under the prediction (it lags a large step): the disc-sized component nearest to it
    sizes = np.bincount(labels.ravel(), minlength=n_lab)
    big = [k for k in range(1, n_lab) if sizes[k] >= 0.3 * np.pi * minor_px * (g.f * g.R / g.zp)]
    if not big:
        return None
    return labels == min(big, key=lambda k: float(np.min(g.lat[labels == k])))


def _disc_in_plane(g, P, inl, normal, h, rmse, nstd, tol, options, normal_prior) -> DiscMeasurement:
    """The disc of known radius among the inliers of one plane (see the module notes, steps 3 and 4).

    Two passes: the second takes the plane again from the depth points of the
    disc found in the first only (a RANSAC plane may cut across the disc and a
    surface behind it), with its own inliers, patch and centre.
    """
    K, f, R, zp, pred = g.K, g.f, g.R, g.zp, g.pred
    index = np.full(g.shape, -1)
    index[g.sel] = np.arange(len(P))
    normal_from = "fit"
    centre = None
    edge = None                      # a determined fit seen edge-on (normal, offset), replaced by the fallback

    def fallback_plane():
        # the depth noise leaves the tilt undetermined: keep the previous frames' normal, or face the camera
        if normal_prior is not None and np.all(np.isfinite(normal_prior)):
            n, source = unit_vector(np.asarray(normal_prior, float)), "prior"
        else:
            n, source = -unit_vector(pred), "camera"
        hh = float(np.median(P[inl] @ n))
        return n, source, hh, np.abs(P @ n - hh) <= tol

    def facing(n, hh):
        # the normal toward the camera, the cosine of the view angle and the disc's smaller image radius
        if n @ pred > 0:
            n, hh = -n, -hh
        cos = abs(float(n @ unit_vector(pred)))
        return n, hh, cos, f * R / zp * cos

    for it in range(2):
        if not np.degrees(nstd) <= options.max_normal_std_deg or normal_from != "fit":
            normal, normal_from, h, inl = fallback_plane()
        normal, h, cos_view, minor_px = facing(normal, h)
        if minor_px < options.min_minor_px and normal_from == "fit":
            # an edge-on fit may be the noise's (depth scatter dwarfing the disc): try the fallback normal; a
            # truly edge-on disc then leaves too small a patch for the area check
            edge = (normal, h)
            nstd = np.inf
            normal, normal_from, h, inl = fallback_plane()
            normal, h, cos_view, minor_px = facing(normal, h)
        if minor_px < options.min_minor_px:
            return skip_measurement(f"disc seen edge-on: smaller image radius {minor_px:.1f} px (plane "
                         f"{np.degrees(np.arccos(cos_view)):.0f} deg from the view)")
        comp = _patch(g, P, inl, minor_px, options)
        if comp is None:
            return skip_measurement("nothing as wide as the disc in the plane under the prediction (links only?)")
        # every pixel of the patch on the plane: its ray, not its noisy depth
        ru, rv = g.gu[comp], g.gv[comp]
        ndotr = normal[0] * ru + normal[1] * rv + normal[2]
        if np.min(np.abs(ndotr)) < 1e-6:
            return skip_measurement("disc plane parallel to a viewing ray")
        t = h / ndotr
        Q = np.column_stack([ru * t, rv * t, t])
        w = t * t / (K.fx * K.fy * np.abs(ndotr))          # pixel footprint on the plane, m^2
        start = np.average(Q, axis=0, weights=w) if centre is None else centre
        centre = _mean_shift(Q, w, start, R, 0.5 * zp / f)
        if centre is None:
            return skip_measurement("the disc patch lies outside one radius of its own centre")
        if it == 1:
            break
        pidx = index[comp]
        on = (np.linalg.norm(Q - centre, axis=1) <= R) & (pidx >= 0)
        if on.sum() < options.min_points:
            break
        if normal_from == "fit":
            normal, h, _, rmse, nstd = _refit(P[pidx[on]], normal, h, tol, g.sigma)
        else:
            h = float(np.median(P[pidx[on]] @ normal))
        if normal @ pred > 0:
            normal, h = -normal, -h
        inl = np.abs(P @ normal - h) <= tol
    area = float(w[np.linalg.norm(Q - centre, axis=1) <= 1.5 * R].sum())
    ratio = area / (np.pi * R * R)
    r_eq = float(np.sqrt(area / np.pi))
    if not options.area_ratio[0] <= ratio <= options.area_ratio[1]:
        return skip_measurement(f"disc patch of equivalent radius {r_eq:.3f} m does not fit the {R:.3f} m disc "
                     f"(area ratio {ratio:.2f} outside {options.area_ratio[0]}..{options.area_ratio[1]})")
    inside = np.linalg.norm(Q - centre, axis=1) <= 1.5 * R
    if inside.sum() >= 3:
        ev = np.linalg.eigvalsh(np.cov((Q[inside] - centre).T, aweights=w[inside]))[1:]   # in-plane spread
        roundness = float(np.sqrt(max(ev[0], 0.0) / ev[1])) if ev[1] > 0 else 0.0
        if roundness < options.min_roundness:
            return skip_measurement(f"the plane patch is not round (axis ratio {roundness:.2f} < "
                                    f"{options.min_roundness}): a strip of floor or wall, a link, not the disc")
    extent = plane_extent_ratio(g.depth, K, centre, normal, R, tol)
    if extent > options.max_extent_ratio:
        return skip_measurement(f"the plane found runs on beyond the disc ({100 * extent:.0f} % of the annulus "
                                f"1.7-2.6 radii around it lies in it): a wall, the floor or a table, not the disc")
    if edge is not None and abs(float(edge[0] @ centre)) > 1e-9:
        # the floor (or a wall) seen at a grazing angle fits a determined plane edge-on; on the fallback plane facing
        # the camera, a band of it cut by the window passes for the disc. Not the disc when the centre found lies on
        # the edge-on plane and that plane runs on beyond it
        on_edge = centre * (edge[1] / float(edge[0] @ centre))
        if abs(float(on_edge[2] - centre[2])) <= tol:
            extent = plane_extent_ratio(g.depth, K, on_edge, edge[0], R, tol)
            if extent > options.max_extent_ratio:
                return skip_measurement(f"the patch lies on a plane seen edge-on that runs on beyond it "
                                        f"({100 * extent:.0f} % of the annulus 1.7-2.6 radii around it lies in it): "
                                        f"the floor or a wall at a grazing angle, not the disc")
    reach = float(np.max(g.lat[g.sel])) if g.sel.any() else R
    off = float(np.hypot(*(centre[:2] / centre[2] - pred[:2] / zp)) * zp)
    if off > reach:
        return skip_measurement(f"disc found {off:.2f} m across the view from the prediction")
    return DiscMeasurement(True, centre, normal.copy(), r_eq, int(comp.sum()), rmse, normal_from)

