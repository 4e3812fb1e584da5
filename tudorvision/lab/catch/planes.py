"""The plane the arm catches in: the net's inverse kinematics in a working plane, and that plane chosen per throw.

The seed catches in one vertical working plane (joint 1 fixed, facing the thrower). A ball whose crossing of
that plane lies low at the side of the reach needs a long joint-2 swing that the arm cannot finish in time;
turned by joint 1, the plane meets the same flight elsewhere, sooner and higher on the side the plane turns
towards the thrower. :func:`choose_plane` picks the smallest turn that leaves the move a margin before its
deadline (``DemoOptions.yaw_max_rad``); the ring then faces the ball at that angle, which narrows its
clearance (``R - r / cos a``), so the fixed plane is kept whenever it is in time.
"""
from __future__ import annotations

import numpy as np

__all__ = ["CatchIK", "plane_candidates", "choose_plane"]


def plane_candidates(max_rad: float, step_rad: float) -> np.ndarray:
    """Working-plane angles to weigh, rad: 0, then +-step, +-2 step, ... up to ``max_rad``, smallest turn first.

    Parameters
    ----------
    max_rad : float
        Largest turn of joint 1 from the fixed plane, rad (>= 0).
    step_rad : float
        Step, rad (> 0).

    Returns
    -------
    ndarray, shape (1 + 2 K,)
        The angles, ``0.0`` first.

    Examples
    --------
    >>> np.degrees(plane_candidates(np.radians(4.0), np.radians(2.0))).round(6).tolist()
    [0.0, 2.0, -2.0, 4.0, -4.0]
    """
    if not (np.isfinite(max_rad) and max_rad >= 0 and np.isfinite(step_rad) and step_rad > 0):
        raise ValueError(f"plane_candidates: expected max_rad >= 0 and step_rad > 0, got {max_rad}, {step_rad}")
    k = int(np.floor(max_rad / step_rad + 1e-9))
    return np.array([0.0] + [s * i * step_rad for i in range(1, k + 1) for s in (1.0, -1.0)])


def choose_plane(candidates_rad, slack_s, margin_s: float, min_gain_s: float = 0.0):
    """The working plane for a throw: the first candidate whose move ends in time, else the roomiest.

    The first candidate (the fixed plane) is kept when its slack reaches ``margin_s``; else, among the others
    that beat it by ``min_gain_s``, the first that reaches ``margin_s`` or, failing that, the one with the most
    slack; else the first.

    Parameters
    ----------
    candidates_rad : array_like, shape (K,)
        Plane angles in order of preference (:func:`plane_candidates`: the fixed plane, then the smallest
        turns), rad.
    slack_s : callable
        ``slack_s(theta1_rad)``: time from the end of the arm's move to that plane's intercept until its
        deadline, s, or None where the flight does not cross that plane within reach.
    margin_s : float
        Slack that is enough, s.
    min_gain_s : float
        Least gain in slack over the first candidate for which another plane is taken, s.

    Returns
    -------
    tuple or None
        ``(theta1_rad, slack_s)`` of the choice; None when no candidate is within reach.

    Examples
    --------
    >>> slack = {0.0: -0.2, 0.1: -0.05, -0.1: 0.08, 0.2: 0.3}
    >>> choose_plane([0.0, 0.1, -0.1, 0.2], slack.get, 0.05)           # the first with 0.05 s to spare
    (-0.1, 0.08)
    >>> choose_plane([0.0, 0.1], slack.get, 0.05, min_gain_s=0.1)      # none: the roomiest, 0.15 s better
    (0.1, -0.05)
    >>> choose_plane([0.0, 0.1, 0.2], slack.get, -0.1, min_gain_s=0.2)  # -0.05 is in time but gains too little
    (0.2, 0.3)
    >>> choose_plane([0.0, 0.1], slack.get, 0.05, min_gain_s=0.2)      # not better enough: the fixed plane
    (0.0, -0.2)
    >>> choose_plane([0.0, 0.1], slack.get, -0.3)                       # the fixed plane is in time
    (0.0, -0.2)
    """
    cands = np.asarray(candidates_rad, float).reshape(-1)
    if cands.size == 0:
        return None
    first = slack_s(float(cands[0]))
    if first is not None and first >= margin_s:
        return float(cands[0]), float(first)
    best = None
    for th1 in cands[1:]:
        s = slack_s(float(th1))
        if s is None or (first is not None and s < first + min_gain_s):
            continue
        if s >= margin_s:
            return float(th1), float(s)
        if best is None or s > best[1]:
            best = (float(th1), float(s))
    if best is None:
        return None if first is None else (float(cands[0]), float(first))
    return best


class CatchIK:
    """Inverse kinematics of the net: compensated (data-based deflection model) or rigid.

    Parameters
    ----------
    inverse : InverseKinematics
        The compensated inverse kinematics (:class:`~tudorvision.catch.kinematics.InverseKinematics`).
    params : RobotParams
        The robot's parameters (rigid IK).
    compensate : bool
        Use the deflection model (else rigid IK).
    theta1_rad : float
        Angle of the working plane, rad (the agent turns it for a throw with ``DemoOptions.yaw_max_rad``).
    """

    def __init__(self, inverse, params, *, compensate: bool, theta1_rad: float):
        self.inverse, self.params, self.compensate, self.theta1_rad = inverse, params, compensate, theta1_rad

    def __call__(self, p_base, payload_kg: float, *, near=None, elbow: str | None = None) -> np.ndarray:
        """Joint angles (3,) that put the net at ``p_base`` (m, base frame) carrying ``payload_kg`` (kg)."""
        if self.compensate:
            return self.inverse(p_base, self.theta1_rad, payload_kg, near=near, elbow=elbow)
        from ...robot import ik

        return ik(p_base, self.params, elbow=elbow, near=near)

    def nearest_on_branch(self, p_base, payload_kg: float, *, elbow: str, lower_rad, upper_rad):
        """Joint angles (3,) on one elbow branch within the bounds (rad) that bring the net nearest ``p_base``.

        Returns ``(theta, distance_m)`` (:meth:`~tudorvision.catch.kinematics.InverseKinematics.nearest_on_branch`;
        the rigid arm when not ``compensate``).
        """
        from ...catch.kinematics import DeflectionModel, InverseKinematics

        inverse = self.inverse if self.compensate else \
            InverseKinematics(DeflectionModel(D=np.zeros((30, 2)), params=self.params), self.params)
        return inverse.nearest_on_branch(p_base, self.theta1_rad, payload_kg, elbow=elbow, lower_rad=lower_rad,
                                         upper_rad=upper_rad)
