"""Catching perception: base-frame ball detections in, filtered flight and intercept out.

:class:`CatchPerception` runs the ball EKF (:mod:`tudorvision.catch.ekf`),
the intercept planner (:mod:`tudorvision.catch.intercept`) and, for
comparison only, the drag-free ballistic peer on a stream of detections
(e.g. from :class:`tudorvision.rgbd.ball.BallDetector` moved into the base
frame with :func:`detection_to_base`).
"""
from __future__ import annotations

import time

import numpy as np

from .ballistic import BallisticPredictor
from .ekf import BallEKF, EKFOptions
from .intercept import InterceptOptions, InterceptPlanner, working_plane_normal

__all__ = ["CatchPerception", "detection_to_base"]


def detection_to_base(p_cam, cov_cam, T_base_cam):
    """Ball centre and covariance from the camera optical frame to the base frame.

    Parameters
    ----------
    p_cam : array_like, shape (3,)
        Ball centre, metres, camera optical frame (x right, y down, z forward).
    cov_cam : array_like, shape (3, 3)
        Its covariance, m^2, camera optical frame.
    T_base_cam : array_like, shape (4, 4)
        Camera pose: ``p_base = T_base_cam @ p_cam`` (homogeneous).

    Returns
    -------
    p_base : ndarray, shape (3,)
        Ball centre, metres, base frame.
    cov_base : ndarray, shape (3, 3)
        Its covariance ``R cov_cam R^T``, m^2, base frame.

    Examples
    --------
    >>> T = np.eye(4); T[:3, 3] = [1.0, 2.0, 3.0]
    >>> detection_to_base([0.0, 0.0, 1.0], np.eye(3), T)[0].tolist()
    [1.0, 2.0, 4.0]
    """
    R = np.asarray(T_base_cam, float)[:3, :3]
    return R @ np.asarray(p_cam, float) + np.asarray(T_base_cam, float)[:3, 3], R @ np.asarray(cov_cam, float) @ R.T


class CatchPerception:
    """Filter, intercept and peer predictor for a stream of base-frame ball detections.

    Parameters
    ----------
    ekf : EKFOptions
        Options of the ball EKF (flight model, process noise, gating).
    intercept : InterceptOptions
        Working plane and release policy of the intercept planner.
    params : RobotParams, optional
        Robot parameters for reachability; default the packaged ``tudor.yaml``.
    peer : bool
        Also run the drag-free ballistic peer (for comparison only).
    min_sigma_m : float
        Isotropic floor added to the detector's covariance (near the sensor it
        claims sub-millimetre depth accuracy that partial silhouettes at the
        image border do not have), metres.
    """

    def __init__(self, ekf: EKFOptions = EKFOptions(), intercept: InterceptOptions = InterceptOptions(),
                 params=None, *, min_sigma_m: float = 0.003, peer: bool = True):
        self.min_sigma_m = float(min_sigma_m)
        self.peer = bool(peer)
        self.ekf = BallEKF(ekf)
        self.planner = InterceptPlanner(intercept, model=ekf.model, q_m2_s3=ekf.q_m2_s3, params=params)
        self.ballistic = BallisticPredictor(working_plane_normal(intercept.theta1_rad))
        self._throw = -1

    def step(self, t: float, p_base, cov_base) -> dict:
        """Fuse one detection; returns a record (status, state, intercept, peer prediction).

        ``rec["peer_s"]`` is the time spent on the peer (not part of the catching pipeline).

        Parameters
        ----------
        t : float
            Detection time, seconds.
        p_base : array_like, shape (3,)
            Detected ball centre, metres, base frame (z up).
        cov_base : array_like, shape (3, 3)
            Its covariance, m^2, base frame (``min_sigma_m ** 2`` is added on
            the diagonal).

        Returns
        -------
        rec : dict
            ``"t"`` (s), ``"status"`` (the EKF status: ``"buffered"``,
            ``"initialised"``, ``"accepted"``, ``"rejected"`` or
            ``"restarted"``), ``"throw"`` (throw id), ``"intercept"``
            (:class:`Intercept` or None), ``"ballistic"`` (the peer's
            ``(t_cross, p_base)``, ``(None, None)`` when unknown),
            ``"peer_s"`` (s) and, once the filter is initialised, ``"x"``
            (state ``[x, y, z, vx, vy, vz]``, base frame).

        Raises
        ------
        ValueError
            If ``p_base`` or ``cov_base`` has the wrong shape.
        """
        cov = np.asarray(cov_base, float) + self.min_sigma_m ** 2 * np.eye(3)
        status = self.ekf.step(t, p_base, cov)
        if self.ekf.throw_id != self._throw or status == "restarted":
            if self.ekf.throw_id != self._throw:
                self._throw = self.ekf.throw_id
            self.planner.reset()
            self.ballistic.reset()
        rec = {"t": float(t), "status": status, "throw": self.ekf.throw_id, "intercept": None,
               "ballistic": (None, None), "peer_s": 0.0}
        if self.ekf.initialised:
            rec["x"] = self.ekf.x
            rec["intercept"] = self.planner.update(t, self.ekf.x, self.ekf.P)
        if self.peer:
            t0 = time.perf_counter()
            if status != "rejected":
                self.ballistic.add(t, p_base)
            if self.ekf.initialised:
                rec["ballistic"] = self.ballistic.predict()
            rec["peer_s"] = time.perf_counter() - t0
        return rec

    def on_plane(self, t: float, theta1_rad: float):
        """The filter's latest state crossing another working plane (:meth:`InterceptPlanner.on_plane`).

        The planner is unchanged; :meth:`use_plane` takes the plane for the throw.

        Parameters
        ----------
        t : float
            Time of the filter's latest state, seconds.
        theta1_rad : float
            Azimuth of the plane (joint 1's angle), rad.

        Returns
        -------
        Intercept or None
            That plane's crossing; None before the filter starts or when the flight does not cross it.
        """
        return self.planner.on_plane(t, self.ekf.x, self.ekf.P, theta1_rad) if self.ekf.initialised else None

    def use_plane(self, theta1_rad: float, released) -> None:
        """Estimate and refine this throw on another plane (:meth:`InterceptPlanner.use_plane`).

        Parameters
        ----------
        theta1_rad : float
            The plane's azimuth, rad.
        released : Intercept
            The estimate on that plane (:meth:`on_plane`) that was sent.
        """
        self.planner.use_plane(theta1_rad, released)

    def due(self, t: float, *, tol_m: float = 0.0):
        """A refinement due at ``t`` (s) without a detection (:meth:`InterceptPlanner.due`), or None.

        Parameters
        ----------
        t : float
            Time of a frame without a detection, seconds.
        tol_m : float
            The refinement's least change, metres, if larger than the planner's own tolerance.

        Returns
        -------
        Intercept or None
            The filter's latest intercept, marked ``send``, when the planner's refinement rule releases it now.
        """
        return self.planner.due(t, tol_m=tol_m) if self.ekf.initialised else None
