"""rerun logging of the joint-control layer's state: joint angles, speeds, strains and the setpoint over time.

Entity layout (rerun 0.41), on the ``time`` timeline (the layer core's
clock, s)::

    joints/theta_deg/<j>         rr.Scalars, joint angle j = 1..3, degrees
    joints/setpoint_deg/<j>      rr.Scalars, the commanded target, degrees
    joints/theta_dot_deg_s/<j>   rr.Scalars, joint speed, deg/s
    strains/<k>_um_m             rr.Scalars, strain gauge k = 1..4, micrometre per metre

Angles are logged in degrees because that is what ``joint move --to``
takes; the State itself is in radians. rerun is imported on first use.
"""
from __future__ import annotations

import numpy as np

__all__ = ["log_joint_state"]


def log_joint_state(recording, state, target_rad=None) -> None:
    """Log one :class:`~tudorvision.joint.messages.State` (and the setpoint it moves to).

    Parameters
    ----------
    recording : rerun.RecordingStream
        The stream to log to.
    state : State
        Layer state: ``t`` (s), ``theta`` (3,) rad, ``theta_dot`` (3,) rad/s,
        ``strains`` (4,) m/m.
    target_rad : array_like, shape (3,), optional
        The setpoint, rad.

    Returns
    -------
    None
    """
    import rerun as rr

    recording.set_time("time", duration=float(state.t))
    for j, (th, thd) in enumerate(zip(np.rad2deg(state.theta), np.rad2deg(state.theta_dot)), start=1):
        recording.log(f"joints/theta_deg/{j}", rr.Scalars(float(th)))
        recording.log(f"joints/theta_dot_deg_s/{j}", rr.Scalars(float(thd)))
    if target_rad is not None:
        for j, v in enumerate(np.rad2deg(np.asarray(target_rad, float).ravel()), start=1):
            recording.log(f"joints/setpoint_deg/{j}", rr.Scalars(float(v)))
    for k, s in enumerate(state.strains, start=1):
        recording.log(f"strains/{k}_um_m", rr.Scalars(float(s) * 1e6))
