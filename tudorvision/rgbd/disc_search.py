"""Finding the calibration disc in a wide window, without a close prediction (issue 15).

The sweep tracker (:mod:`tudorvision.rgbd.disc_track`) measures the disc near
a predicted centre (:func:`tudorvision.rgbd.disc3d.measure_disc_3d`). Before
a circle can be fitted to the centres the prediction is poor: in the first
frame only the user's seed pixel is known, and after one pose a theta2 step
of 20-30 degrees moves the disc by 0.3-0.45 m in an unknown direction. Here
every disc-like surface in a wide window becomes a candidate:

1. the depth is median-filtered (5 x 5, 3 x 3 for a disc under 8 px in radius; invalid pixels
   read as far);
2. pixels next to a depth jump larger than ``max(3 cm, 2.5 sigma_z)`` over one or two
   pixels are cut,
   so a surface in front of a wall or of nothing is its own region;
3. an opening of about a third of the disc's image radius removes the thin
   links and the net's edge;
4. each connected region of disc-like size gives a predicted centre (its
   centroid pixel at its median depth), measured in 3D by
   ``measure_disc_3d``, which rejects planes that run on beyond the disc
   (walls, floor, table tops) and patches that are not round.

The caller chooses among the measured candidates (nearest the seed ray,
nearest the expected step, front-most on ties).
"""
from __future__ import annotations

import numpy as np

from .disc3d import Disc3DOptions, DiscMeasurement, measure_disc_3d, skip_measurement
from .frames import Intrinsics

__all__ = ["disc_candidates", "acquire_disc"]


def disc_candidates(depth_m, intrinsics: Intrinsics, around_cam, reach_m: float,
                    options: Disc3DOptions = Disc3DOptions()) -> list:
    """Predicted centres of the disc-sized surfaces within ``reach_m`` of a point (see the module notes).

    Parameters
    ----------
    depth_m : ndarray, shape (H, W)
        Depth (z) in metres, NaN = invalid.
    intrinsics : Intrinsics
        Pinhole intrinsics (pixels).
    around_cam : array_like, shape (3,)
        Centre of the search, metres, camera frame (its depth sets the disc's
        image size).
    reach_m : float
        Search radius across the view, metres.
    options : Disc3DOptions
        Disc radius and depth noise.

    Returns
    -------
    list of ndarray, shape (3,)
        Candidate centres, metres, camera frame, largest regions first.
    """
    import cv2

    K, R = intrinsics, options.disc_radius_m
    c = np.asarray(around_cam, float)
    z0 = float(c[2])
    if not z0 > 0.1:
        return []
    f = float(np.sqrt(K.fx * K.fy))
    half = int(np.ceil(f * reach_m / z0)) + 2
    uc, vc = K.fx * c[0] / z0 + K.cx, K.fy * c[1] / z0 + K.cy
    u0, u1 = max(0, int(uc) - half), min(K.width, int(uc) + half + 1)
    v0, v1 = max(0, int(vc) - half), min(K.height, int(vc) + half + 1)
    if u1 - u0 < 3 or v1 - v0 < 3:
        return []
    sub = np.asarray(depth_m, dtype=np.float32)[v0:v1, u0:u1]
    valid = np.isfinite(sub) & (sub > 0)
    r_px = f * R / z0
    zs = cv2.medianBlur(np.where(valid, sub, np.float32(1e3)).astype(np.float32), 5 if r_px >= 8 else 3)
    ok = zs < 100.0
    tau = np.maximum(0.03, 2.5 * options.depth_model.sigma_m(np.clip(zs, 0.3, 8.0)))
    for step in (1, 2):             # the median blurs a jump over a pixel or two: cut across both
        jump_u = np.abs(zs[:, step:] - zs[:, :-step]) > tau[:, step:]
        jump_v = np.abs(zs[step:, :] - zs[:-step, :]) > tau[step:, :]
        for a in ((0, 1) if step == 1 else (1,)):        # a gradual jump: only the pixel across it
            ok[:, a:ok.shape[1] - step + a] &= ~jump_u
            ok[a:ok.shape[0] - step + a, :] &= ~jump_v
    ro = max(1, int(round(0.3 * r_px)))
    kern = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * ro + 1, 2 * ro + 1))
    mask = cv2.morphologyEx(ok.astype(np.uint8), cv2.MORPH_OPEN, kern)
    n_lab, labels, stats, cents = cv2.connectedComponentsWithStats(mask, connectivity=8)
    disc_px = np.pi * r_px * r_px
    out = []
    for k in np.argsort(-stats[1:, cv2.CC_STAT_AREA]) + 1:
        area = stats[k, cv2.CC_STAT_AREA]
        if not 0.15 * disc_px <= area <= 4.0 * disc_px:
            continue
        reg = (labels == k) & valid
        if reg.sum() < options.min_points:
            continue
        z = float(np.median(sub[reg]))
        u, v = cents[k][0] + u0, cents[k][1] + v0
        out.append(np.array([(u - K.cx) / K.fx * z, (v - K.cy) / K.fy * z, z]))
    return out


def acquire_disc(depth_m, intrinsics: Intrinsics, around_cam, reach_m: float, score, max_score: float,
                 options: Disc3DOptions = Disc3DOptions(), *, normal_prior=None,
                 rng: np.random.Generator | None = None) -> DiscMeasurement:
    """The best-scoring disc among the candidates within ``reach_m`` of a point.

    Parameters
    ----------
    depth_m : ndarray, shape (H, W)
        Depth (z) in metres, NaN = invalid.
    intrinsics : Intrinsics
        Pinhole intrinsics (pixels).
    around_cam : array_like, shape (3,)
        Centre of the search, metres, camera frame.
    reach_m : float
        Search radius across the view, metres.
    score : callable DiscMeasurement -> float
        Lower is better (e.g. distance from the expected position, metres).
    max_score : float
        Candidates scoring above this are not the disc.
    options : Disc3DOptions
        Radius, tolerances and checks.
    normal_prior : array_like, shape (3,), optional
        Disc normal of the previous frames, camera frame.
    rng : numpy.random.Generator, optional
        RANSAC sampling.

    Returns
    -------
    DiscMeasurement
        The chosen disc; ``valid=False`` with the reason when no candidate
        fits. Among candidates scoring within ``disc_radius_m`` of the best,
        the front-most is taken.
    """
    rng = rng if rng is not None else np.random.default_rng(options.random_seed)
    cands = disc_candidates(depth_m, intrinsics, around_cam, reach_m, options)
    found, reasons = [], []
    for guess in cands:
        m = measure_disc_3d(depth_m, intrinsics, guess, 0.5 * options.disc_radius_m, options,
                            normal_prior=normal_prior, rng=rng)
        if not m.valid:
            reasons.append(m.reason)
            continue
        if any(np.linalg.norm(m.centre_cam - o.centre_cam) < options.disc_radius_m for _, o in found):
            continue
        s = float(score(m))
        if s <= max_score:
            found.append((s, m))
        else:
            reasons.append(f"a disc-shaped patch {s:.2f} off the expected position")
    if not found:
        why = reasons[0] if reasons else "no disc-sized surface apart from its background"
        return skip_measurement(f"no disc within {reach_m:.2f} m of the expected position ({len(cands)} "
                                f"candidates; {why})")
    best = min(s for s, _ in found)
    close = [m for s, m in found if s <= best + options.disc_radius_m]
    return min(close, key=lambda m: float(m.centre_cam[2]))
