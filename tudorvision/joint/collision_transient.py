"""Threshold allowance for the inertial transient of soft links after a change of planned acceleration.

The momentum observer (:class:`~tudorvision.joint.collision.MomentumObserver`)
models the links as rigid: the inertial strain ``I_eps(theta) ddtheta`` is
expected at once. Soft links (hub springs, backlash, a 1.5-3 Hz first mode)
deliver it late, so whenever the planned acceleration jumps (a new setpoint
re-plans a move in progress: the layer's planner restarts the acceleration
from zero) or ramps to zero at the end of a move, the residual answers with a
transient of about the size of the change of inertial strain,
``|I_eps (a - a_lagged)|``, within 5-65 ms. On the soft lab plant these
transients were the collision detector's false positives (peaks 1.0-1.2 of
the 6-sigma thresholds).

The layer knows its planned acceleration, so it can widen the thresholds
while such a transient is due: per root strain the allowance is the
high-passed inertial strain demand ``u = I_eps a_ref`` (``u`` less its
first-order low-pass with time constant ``tau_s``), held at its peak with an
exponential decay of time constant ``hold_s``, times ``gain``; the detection
threshold is ``threshold + allowance``. It is zero during steady motion and at
rest, so a contact then is detected as before; a contact that coincides with
a re-plan is detected later by the time the allowance takes to decay.
"""
from __future__ import annotations

import math

__all__ = ["TransientAllowance", "TRANSIENT_TAU_S", "TRANSIENT_HOLD_S", "SOFT_TRANSIENT_GAIN"]

#: Low-pass time constant whose complement (high-pass) measures the change of inertial strain demand, s.
TRANSIENT_TAU_S = 0.1
#: Decay time constant of the held allowance, s.
TRANSIENT_HOLD_S = 0.1
#: Gain for the soft lab plant (benchmarks/bench_collision.py; docs/benchmarks.md, "Collision: the soft links'
#: inertial transient"): no false positive in 3 x 10 min of collision-free motion where fixed thresholds gave 0-4,
#: contacts 0.5-1.5 ms later than with fixed thresholds.
SOFT_TRANSIENT_GAIN = 1.0


class TransientAllowance:
    """Per root strain (links 2, 3) threshold allowance from the planned joint acceleration, m/m.

    Parameters
    ----------
    dt : float
        Sample time, s.
    gain : float
        Multiple of the held high-passed inertial strain demand (0: no allowance).
    tau_s : float
        Time constant of the low-pass the demand is compared with, s.
    hold_s : float
        Decay time constant of the held peak, s.

    Raises
    ------
    ValueError
        If ``dt``, ``tau_s`` or ``hold_s`` is not positive or ``gain`` is negative.

    Examples
    --------
    >>> ta = TransientAllowance(0.001, gain=1.0)
    >>> I = ((1e-4, 0.0), (0.0, 5e-5))                   # strain per rad/s^2
    >>> ta.step(I, (0.0, 0.0, 0.0))
    [0.0, 0.0]
    >>> a = ta.step(I, (0.0, 0.002, 0.0))                # joint 2's planned acceleration jumps to 2 rad/s^2
    >>> round(a[0] * 1e6, 1), a[1]
    (198.0, 0.0)
    >>> for _ in range(500):
    ...     a = ta.step(I, (0.0, 0.002, 0.0))            # the speed stays: the acceleration falls to 0
    >>> a[0] < 2e-6                                      # the allowance has decayed
    True
    """

    def __init__(self, dt: float, *, gain: float, tau_s: float = TRANSIENT_TAU_S, hold_s: float = TRANSIENT_HOLD_S):
        if not (dt > 0 and tau_s > 0 and hold_s > 0 and gain >= 0):
            raise ValueError(f"dt, tau_s, hold_s: expected > 0, gain >= 0; got {dt}, {tau_s}, {hold_s}, {gain}")
        self.dt, self.gain = float(dt), float(gain)
        self._alpha = self.dt / (float(tau_s) + self.dt)
        self._decay = math.exp(-self.dt / float(hold_s))
        self.reset()

    def reset(self) -> None:
        """Forget the history: the next sample's planned speed is the reference (no acceleration)."""
        self._dref = None
        self._lp = [0.0, 0.0]
        self.allowance = [0.0, 0.0]

    def step(self, inertia, dtheta_ref) -> list:
        """One sample: the allowance (2 floats, m/m) after the planned joint speeds ``dtheta_ref``.

        Parameters
        ----------
        inertia : array_like, shape (2, 2)
            Strain-referred inertia ``I_eps`` at the current pose and payload, m/m per rad/s^2.
        dtheta_ref : sequence of 3 floats
            Planned joint speeds (the cascade's velocity feed-forward), rad/s.

        Returns
        -------
        list of 2 floats
            Allowance for the link-2 and link-3 root residuals, m/m.
        """
        d2, d3 = float(dtheta_ref[1]), float(dtheta_ref[2])
        if self._dref is None:
            self._dref = (d2, d3)
        a2, a3 = (d2 - self._dref[0]) / self.dt, (d3 - self._dref[1]) / self.dt
        self._dref = (d2, d3)
        al, dec, out = self._alpha, self._decay, self.allowance
        for i in range(2):
            u = inertia[i][0] * a2 + inertia[i][1] * a3
            self._lp[i] += al * (u - self._lp[i])
            out[i] = max(out[i] * dec, self.gain * abs(u - self._lp[i]))
        return list(out)
