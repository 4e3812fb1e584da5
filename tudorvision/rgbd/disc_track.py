"""Tracking the calibration disc through a theta2 sweep (issue 15); the measurement is :mod:`.disc3d`."""
from __future__ import annotations

import numpy as np

from .._checks import TudorVisionError, check_array
from ..geometry import fit_circle_3d
from .disc3d import Disc3DOptions, DiscMeasurement, measure_disc_3d, skip_measurement, unit_vector
from .disc_search import acquire_disc
from .frames import Intrinsics, check_depth

__all__ = ["DiscSweepTracker", "track_disc_sweep"]


class DiscSweepTracker:
    """Follow the disc through a theta2 sweep, predicting each centre from the previous frames.

    In the first frame the disc is the disc-shaped surface nearest the seed
    pixel's ray (a wide candidate search, :func:`tudorvision.rgbd.disc_search.acquire_disc`;
    a wall behind it is no candidate). With joint angles, after one pose the
    disc lies one chord ``2 arm_radius_m sin(dtheta / 2)`` from the previous
    centre in an unknown direction (candidates scored by that distance: 20-30
    degree steps work); after two a linear step in theta2 with a margin for
    the chord's turn; from three centres over at least ``circle_min_span_deg``
    (radius within 30 % of ``arm_radius_m`` while fewer than eight, RMSE under
    3 cm) the circle fitted to the centres at the frame's theta2 (the disc
    turns about the joint-2 axis, so the jump back to the vertical posture is
    predicted too), and the normal prior turned with it. When the disc is not
    found at the prediction, the candidates near it, then those one chord
    from the centre measured at the nearest theta2, are tried. Without joint
    angles a constant-velocity step per frame (margin for the step's turn on
    a circle of ``arm_radius_m``); a disc not found there is searched for on
    the circle of the centres so far (from five; the jump back to the
    vertical posture), else within 0.6 arm radii of the last centre. The search margin follows the
    prediction's recent errors, within the options' bounds.

    Parameters
    ----------
    intrinsics : Intrinsics
        Pinhole intrinsics of the depth camera (pixels).
    seed_uv : array_like, shape (2,)
        A pixel on the disc in the first frame (u right, v down).
    options : Disc3DOptions
        Disc radius, tolerances, margins.
    circle_min_span_deg : float
        theta2 span of the measurements before the circle prediction is used.

    Raises
    ------
    TudorVisionError
        If ``seed_uv`` lies outside the image.

    Examples
    --------
    >>> K = Intrinsics(525.0, 525.0, 40.0, 30.0, 80, 60)
    >>> d = np.zeros((60, 80)); vv, uu = np.mgrid[:60, :80]
    >>> d[(uu - 40) ** 2 + (vv - 30) ** 2 <= 15 ** 2] = 3.0       # a 9 cm disc 3 m away, nothing behind
    >>> m = DiscSweepTracker(K, (44, 28)).update(d)
    >>> m.valid, (np.round(m.centre_cam, 3) + 0.0).tolist()
    (True, [0.0, 0.0, 3.0])
    """

    def __init__(self, intrinsics: Intrinsics, seed_uv, options: Disc3DOptions = Disc3DOptions(), *,
                 circle_min_span_deg: float = 30.0):
        self.intrinsics = intrinsics
        self.options = options
        s = check_array(seed_uv, "seed_uv", (2,))
        if not (0 <= s[0] < intrinsics.width and 0 <= s[1] < intrinsics.height):
            raise TudorVisionError(f"seed_uv: ({s[0]:.0f}, {s[1]:.0f}) lies outside the "
                                   f"{intrinsics.width}x{intrinsics.height} image")
        self.seed_uv = (float(s[0]), float(s[1]))
        self.circle_min_span_rad = np.radians(circle_min_span_deg)
        self.centres: list = []
        self.theta2: list = []
        self.normals: list = []
        self.normal_theta2: list = []   # theta2 of each fitted normal (None without joint angles)
        self.errors: list = []          # |measured - predicted| of recent frames
        self.n_frames = 0
        self.skipped: dict = {}         # frame number -> reason
        self._rng = np.random.default_rng(options.random_seed)
        self._circle = None
        self._circle_n = 0
        self._clicked = None            # (point, theta2) where the first frame's click put the disc

    def _seed_prediction(self, d):
        u, v = int(round(self.seed_uv[0])), int(round(self.seed_uv[1]))
        for r in (2, 4, 8, 16, 32):
            patch = d[max(0, v - r):v + r + 1, max(0, u - r):u + r + 1]
            zs = patch[np.isfinite(patch)]
            if len(zs) >= 5:
                z = float(np.median(zs))
                K = self.intrinsics
                return np.array([(self.seed_uv[0] - K.cx) / K.fx * z, (self.seed_uv[1] - K.cy) / K.fy * z, z])
        return None

    def _fit_circle(self):
        n = len(self.centres)
        if self._circle is not None and n - self._circle_n < max(1, n // 10):
            return self._circle
        th = np.array(self.theta2)
        if n < 3 or np.ptp(th) < self.circle_min_span_rad:
            return None
        pts = np.array(self.centres)
        try:
            fit = fit_circle_3d(pts, loss="soft_l1")
        except ValueError:
            return None
        if not (fit.rmse < 0.03 and fit.radius < 3.0):
            return None                      # too few or too scattered centres yet: keep the linear step
        if n < 8 and abs(fit.radius - self.options.arm_radius_m) > 0.3 * self.options.arm_radius_m:
            return None                      # a circle through a few noisy centres that does not fit the arm
        e1 = unit_vector(pts[0] - fit.centre - ((pts[0] - fit.centre) @ fit.normal) * fit.normal)
        e2 = np.cross(fit.normal, e1)
        a = np.arctan2((pts - fit.centre) @ e2, (pts - fit.centre) @ e1)
        best = None
        for s in (1.0, -1.0):
            phi = float(np.angle(np.mean(np.exp(1j * (a - s * th)))))
            res = float(np.mean(np.abs(np.angle(np.exp(1j * (a - s * th - phi))))))
            if best is None or res < best[0]:
                best = (res, s, phi)
        self._circle = (fit.centre, fit.radius, e1, e2, best[1], best[2])
        self._circle_n = n
        return self._circle

    def predict(self, theta2_rad=None):
        """Predicted disc centre (camera frame, metres) and search margin (metres), or None before any measurement.

        Parameters
        ----------
        theta2_rad : float, optional
            Joint-2 angle of the frame to predict, rad.

        Returns
        -------
        tuple of (ndarray, shape (3,), float) or None
            Predicted centre and the margin to search around it.
        """
        p = self._predict(theta2_rad)
        return None if p is None else (p[0], p[1])

    def _predict(self, theta2_rad):
        """(centre, margin, mode): mode "step1" when only one pose was seen (the direction is unknown)."""
        o = self.options
        if not self.centres:
            return None
        recent = float(np.max(self.errors[-5:])) if self.errors else o.acquire_margin_m
        margin = float(np.clip(3.0 * recent + 0.02, o.min_margin_m, o.max_margin_m))
        if theta2_rad is not None and self.theta2 and self.theta2[-1] is not None:
            circ = self._fit_circle()
            if circ is not None:
                c, r, e1, e2, s, phi = circ
                a = s * theta2_rad + phi
                return c + r * (np.cos(a) * e1 + np.sin(a) * e2), margin, "circle"
            th = np.array(self.theta2)
            pts = np.array(self.centres)
            same = np.abs(th - theta2_rad) < np.radians(0.5)
            if same.any():                                   # the same pose again
                return pts[same].mean(axis=0), 2 * o.min_margin_m, "same"
            far = np.nonzero(np.abs(th - th[-1]) > np.radians(0.5))[0]
            if len(far):
                k = far[-1]
                v = (pts[-1] - pts[k]) / (th[-1] - th[k])
                dth = abs(theta2_rad - th[-1])
                # a linear step along a circle of the arm's radius misses by about r (1 - cos(dtheta)) per
                # step length (the chord turns); plus the noise of the two centres
                curve = o.arm_radius_m * 2.0 * (1.0 - np.cos(max(dth, abs(th[-1] - th[k]))))
                return pts[-1] + v * (theta2_rad - th[-1]), float(max(o.min_margin_m, 1.3 * curve + 0.05)), "step"
            # one pose seen so far: the disc turned by the step on a circle of the arm's radius
            return pts[-1], 2.0 * o.arm_radius_m * np.sin(abs(theta2_rad - th[-1]) / 2.0), "step1"
        if len(self.centres) < 2:
            return self.centres[-1], o.acquire_margin_m, "still"
        # the step turns by about its length / arm radius per frame: a constant-velocity step misses by the turn
        turn = min(float(np.linalg.norm(self.centres[-1] - self.centres[-2])) / o.arm_radius_m, np.pi / 2)
        curve = 2.0 * o.arm_radius_m * (1.0 - np.cos(turn))
        return (2 * self.centres[-1] - self.centres[-2], max(margin, 0.5 * o.acquire_margin_m, 1.3 * curve + 0.05),
                "velocity")

    def _normal_prior(self, theta2_rad):
        """The disc normal expected at ``theta2_rad``: the disc turns with the arm, so a normal fitted at
        another theta2 is turned about the sweep circle's axis by the difference (None when unknown)."""
        if not self.normals:
            return None
        if theta2_rad is None or self.normal_theta2[-1] is None:
            return np.median(np.array(self.normals[-10:]), axis=0)
        th = np.array(self.normal_theta2, float)
        near = np.abs(th - theta2_rad) <= np.radians(2.0)
        if near.any():                                   # fitted at (about) this pose already
            return unit_vector(np.median(np.array(self.normals)[near][-10:], axis=0))
        circ = self._fit_circle() if len(self.centres) >= 3 else None
        if circ is None:
            k = int(np.argmin(np.abs(th - theta2_rad)))
            return self.normals[k] if abs(th[k] - theta2_rad) <= np.radians(10.0) else None
        axis, s = unit_vector(np.cross(circ[2], circ[3])), circ[4]
        out = []
        for n, t in list(zip(self.normals, th))[-5:]:
            a = s * (theta2_rad - t)                       # Rodrigues: n turned by a about the axis
            out.append(n * np.cos(a) + np.cross(axis, n) * np.sin(a) + axis * (axis @ n) * (1 - np.cos(a)))
        return unit_vector(np.median(np.array(out), axis=0))

    def _search_without_joints(self, d, prior):
        """Without joint angles: the disc-shaped surface nearest the circle of the centres so far (from five),
        else the one nearest the last centre within a step of up to 0.6 arm radii (about 40 deg of theta2)."""
        o, R = self.options, self.options.disc_radius_m
        if len(self.centres) >= 5:
            try:
                fit = fit_circle_3d(np.array(self.centres), loss="soft_l1")
            except ValueError:
                fit = None
            if fit is not None and fit.rmse < 0.03 and abs(fit.radius - o.arm_radius_m) < 0.3 * o.arm_radius_m:
                def off_circle(m, c=fit.centre, n=fit.normal, r=fit.radius):
                    v = m.centre_cam - c
                    out = float(v @ n)
                    return float(np.hypot(out, np.linalg.norm(v - out * n) - r))
                m = self._acquire(d, fit.centre, fit.radius + R + 0.1, off_circle, 0.06, prior)
                if m.valid:
                    return m
        last = self.centres[-1]
        return self._acquire(d, last, 0.6 * o.arm_radius_m + R, lambda m: float(np.linalg.norm(m.centre_cam - last)),
                             0.6 * o.arm_radius_m, prior)

    def _acquire(self, d, around, reach, score, max_score, prior):
        return acquire_disc(d, self.intrinsics, around, reach, score, max_score, self.options,
                            normal_prior=prior, rng=self._rng)

    def update(self, depth_m, theta2_rad: float | None = None) -> DiscMeasurement:
        """Measure the disc in the next frame.

        Parameters
        ----------
        depth_m : array_like, shape (H, W)
            Depth (z) in metres, NaN or 0 = invalid; the intrinsics' shape.
        theta2_rad : float, optional
            Joint-2 angle of this frame, rad (enables the circle prediction).

        Returns
        -------
        DiscMeasurement
            The disc centre (metres, camera frame); when it cannot be measured,
            ``valid=False`` with the reason (also kept in ``skipped``).

        Raises
        ------
        ValueError
            If ``depth_m`` does not have the intrinsics' shape.
        """
        d = check_depth(depth_m, intrinsics=self.intrinsics, require_valid=False)
        o, R = self.options, self.options.disc_radius_m
        frame = self.n_frames
        self.n_frames += 1
        pred = self._predict(theta2_rad)
        prior = self._normal_prior(theta2_rad)
        if pred is None and self._clicked is not None and self._clicked[1] is not None and theta2_rad is not None:
            # the first frames were lost (the disc against the floor or a wall in depth): it turned by theta2 on a
            # circle of the arm's radius from where the click put it, one chord away in some direction
            p_click, th_click = self._clicked
            chord = 2.0 * o.arm_radius_m * np.sin(abs(theta2_rad - th_click) / 2.0)
            m = self._acquire(d, p_click, chord + R + 0.1,
                              lambda m: abs(float(np.linalg.norm(m.centre_cam - p_click)) - chord),
                              0.08 + 0.3 * chord + 0.5 * R, prior)
        elif pred is None:
            p0 = self._seed_prediction(d)
            if p0 is None:
                m = skip_measurement("no valid depth around the seed pixel")
                self.skipped[frame] = m.reason
                return m
            if frame == 0:
                self._clicked = (p0, theta2_rad)
            ray = unit_vector(p0)
            # the disc-shaped surface nearest the seed pixel's ray (front-most on ties); a wall behind it runs
            # on beyond the disc and is no candidate
            m = self._acquire(d, p0, R + o.acquire_margin_m,
                              lambda m: float(np.linalg.norm(np.cross(m.centre_cam, ray))), R + 0.5 * o.acquire_margin_m,
                              prior)
            if not m.valid:
                m = measure_disc_3d(d, self.intrinsics, p0, o.acquire_margin_m, o, normal_prior=prior, rng=self._rng)
        elif pred[2] == "step1":
            # the disc turned by theta2 on a circle of the arm's radius about an unknown axis: it lies about one
            # chord from the previous centre, in any direction
            prev, chord = pred[0], pred[1]
            m = self._acquire(d, prev, chord + R + 0.1, lambda m: abs(float(np.linalg.norm(m.centre_cam - prev)) - chord),
                              0.08 + 0.3 * chord, prior)
        else:
            m = measure_disc_3d(d, self.intrinsics, pred[0], pred[1], o, normal_prior=prior, rng=self._rng)
            if not m.valid:
                # a poor prediction (an early step, a jump): the disc-shaped surface nearest to it
                centre, margin = pred[0], pred[1]
                m2 = self._acquire(d, centre, margin + R,
                                   lambda m: float(np.linalg.norm(m.centre_cam - centre)), margin + 0.5 * R, prior)
                if m2.valid:
                    m = m2
                elif theta2_rad is not None and self.theta2[-1] is not None:
                    # the prediction is off (a circle through a few noisy centres): the disc lies one chord of the
                    # arm's radius from the centre measured at the nearest theta2
                    th = np.array(self.theta2)
                    k = int(np.argmin(np.abs(th - theta2_rad)))
                    prev = self.centres[k]
                    chord = 2.0 * o.arm_radius_m * np.sin(abs(theta2_rad - th[k]) / 2.0)
                    m3 = self._acquire(d, prev, chord + R + 0.1,
                                       lambda m: abs(float(np.linalg.norm(m.centre_cam - prev)) - chord),
                                       0.08 + 0.3 * chord, prior)
                    if m3.valid:
                        m = m3
                elif theta2_rad is None:
                    m3 = self._search_without_joints(d, prior)
                    if m3.valid:
                        m = m3
        if not m.valid:
            self.skipped[frame] = m.reason
            return m
        if self.centres and pred is not None and pred[2] != "step1":
            self.errors.append(float(np.linalg.norm(m.centre_cam - pred[0])))
        self.centres.append(m.centre_cam)
        self.theta2.append(None if theta2_rad is None else float(theta2_rad))
        if m.normal_from == "fit":
            self.normals.append(m.normal_cam)
            self.normal_theta2.append(None if theta2_rad is None else float(theta2_rad))
        if theta2_rad is None:
            self.theta2 = [None] * len(self.centres)
        return m


def track_disc_sweep(depth_frames, intrinsics: Intrinsics, seed_uv, theta2_rad=None,
                     options: Disc3DOptions = Disc3DOptions()):
    """Measure the disc in every frame of a sweep (see :class:`DiscSweepTracker`).

    Parameters
    ----------
    depth_frames : iterable of array_like, each shape (H, W)
        Depth (z) in metres, NaN or 0 = invalid.
    intrinsics : Intrinsics
        Pinhole intrinsics of the depth camera (pixels).
    seed_uv : array_like, shape (2,)
        A pixel on the disc in the first frame.
    theta2_rad : array_like, shape (N,), optional
        Joint-2 angle per frame, rad.
    options : Disc3DOptions
        Disc radius, tolerances, margins.

    Returns
    -------
    centres_cam : ndarray, shape (N, 3)
        Disc centres, metres, camera frame; NaN rows for skipped frames.
    skipped : dict
        Frame index -> reason, for the frames where the disc was not measurable.

    Raises
    ------
    TudorVisionError
        If ``seed_uv`` lies outside the image.
    """
    tr = DiscSweepTracker(intrinsics, seed_uv, options)
    out = []
    for i, dm in enumerate(depth_frames):
        th = None if theta2_rad is None else float(theta2_rad[i])
        out.append(tr.update(dm, th).centre_cam)
    return np.array(out).reshape(-1, 3), dict(tr.skipped)
