"""Test double for the joint-layer core, plus tests of the double itself.

``RigidTestCore`` is NOT the product: a rigid joint integrator that records
every call and every step so tests can check what the server made the arm
do. Other joint tests import it (``from test_joint_adapter_core import ...``).
"""
from __future__ import annotations

import threading
import time

import numpy as np
import pytest

from tudorvision.joint.server import CoreState, JointCore
from tudorvision.robot import load_robot_params

PARAMS = load_robot_params()
LIMITS = PARAMS.joint_limits_rad
VMAX = PARAMS.max_speed_rad_s
AMAX = PARAMS.max_accel_rad_s2


class RigidTestCore:
    """Rigid arm: velocity references are followed exactly, setpoints by an
    acceleration-limited approach, ``stop`` decelerates at ``AMAX``.

    Records ``history`` rows ``[t, theta(3), theta_dot(3)]`` after every step,
    and every ``apply_velocity`` / ``apply_setpoint`` / ``stop`` call.
    """

    def __init__(self, theta0=(0.0, np.pi / 2, 0.0)):
        self.theta = np.array(theta0, dtype=float)
        self.v = np.zeros(3)
        self.t = 0.0
        self.mode = "stop"
        self.v_cmd = np.zeros(3)
        self.target = self.theta.copy()
        self.vlim, self.alim = VMAX.copy(), AMAX.copy()
        self.velocity_calls: list[np.ndarray] = []
        self.setpoint_calls: list[tuple] = []
        self.stop_calls = 0
        self.modes = []
        self._rows = [[0.0, *self.theta, *self.v]]
        self._cond = threading.Condition()

    # -- JointCore interface
    def apply_velocity(self, theta_dot):
        with self._cond:
            self.mode, self.v_cmd = "velocity", np.array(theta_dot, dtype=float)
            self.velocity_calls.append(self.v_cmd.copy())

    def apply_setpoint(self, theta, *, max_speed_rad_s, max_accel_rad_s2):
        with self._cond:
            self.mode, self.target = "setpoint", np.array(theta, dtype=float)
            self.vlim = np.array(max_speed_rad_s, dtype=float)
            self.alim = np.array(max_accel_rad_s2, dtype=float)
            self.setpoint_calls.append((self.target.copy(), self.vlim.copy(), self.alim.copy()))

    def stop(self):
        with self._cond:
            self.mode, self.alim = "stop", AMAX.copy()
            self.stop_calls += 1

    def set_modes(self, *, damping, collision):
        self.modes.append((damping, collision))

    def step(self, dt):
        with self._cond:
            if self.mode == "velocity":
                new_v = self.v_cmd
            else:
                if self.mode == "setpoint":
                    e = self.target - self.theta
                    want = np.sign(e) * np.minimum(np.minimum(self.vlim, np.abs(e) / dt),
                                                   np.sqrt(1.8 * self.alim * np.abs(e)))
                else:
                    want = np.zeros(3)
                dv = np.clip(want - self.v, -self.alim * dt, self.alim * dt)
                new_v = self.v + dv
            self.theta = self.theta + 0.5 * (self.v + new_v) * dt
            self.v = new_v.copy()
            self.t += dt
            self._rows.append([self.t, *self.theta, *self.v])
            self._cond.notify_all()

    def state(self):
        with self._cond:
            reached = self.mode != "setpoint" or np.all(np.abs(self.target - self.theta) < 1e-5)
            at_rest = bool(np.all(self.v == 0.0)) or bool(np.all(np.abs(self.v) < 1e-7))
            return CoreState(t=self.t, theta=self.theta.copy(), theta_dot=self.v.copy(),
                             strains=np.full(4, 1e-6), residuals=np.zeros(3),
                             settled=bool(reached and at_rest and self.mode != "velocity"))

    # -- test helpers
    def history(self) -> np.ndarray:
        """Array (N, 7): t, theta(3), theta_dot(3)."""
        with self._cond:
            return np.array(self._rows)

    def wait_until(self, predicate, timeout: float) -> bool:
        """Wait (event-based, bounded) until ``predicate(core)`` holds after a step."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while not predicate(self):
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return False
                self._cond.wait(min(remaining, 0.1))
            return True


def assert_within_limits(hist: np.ndarray, *, accel: bool = True):
    """The recorded trajectory never leaves the joint ranges, speed or acceleration limits."""
    theta, v = hist[:, 1:4], hist[:, 4:7]
    assert np.all(theta >= LIMITS[:, 0] - 1e-9), np.rad2deg(theta.min(axis=0))
    assert np.all(theta <= LIMITS[:, 1] + 1e-9), np.rad2deg(theta.max(axis=0))
    assert np.all(np.abs(v) <= VMAX + 1e-9), np.abs(v).max(axis=0)
    if accel:
        dt = np.diff(hist[:, 0])
        a = np.abs(np.diff(v, axis=0)) / dt[:, None]
        assert np.all(a <= AMAX * (1 + 1e-6) + 1e-6), a.max(axis=0)


# ------------------------------------------------------------------ tests of the double
def test_test_core_implements_the_interface():
    assert isinstance(RigidTestCore(), JointCore)


def test_test_core_setpoint_respects_limits_and_settles():
    core = RigidTestCore(theta0=(0.0, 0.5, 0.0))
    core.apply_setpoint([1.0, 0.0, -0.5], max_speed_rad_s=np.full(3, 0.8),
                        max_accel_rad_s2=np.full(3, 3.0))
    for _ in range(3000):
        core.step(1e-3)
        if core.state().settled:
            break
    assert core.state().settled
    assert np.allclose(core.state().theta, [1.0, 0.0, -0.5], atol=1e-5)
    hist = core.history()
    assert np.abs(hist[:, 4:7]).max() <= 0.8 + 1e-12
    assert_within_limits(hist)


def test_limit_check_catches_a_violation():
    core = RigidTestCore()
    core.apply_velocity([0.0, 0.0, VMAX[2] * 1.5])
    core.step(1e-3)
    with pytest.raises(AssertionError):
        assert_within_limits(core.history(), accel=False)
