"""A joint-layer core for another arm whose controller takes joint velocities (docs/own_hardware.md).

Many arms (UR's ``speedj``, Franka's joint-velocity mode, a ROS ``JointGroupVelocityController``,
a hobby servo board) accept joint velocities and report joint positions. This example wraps such an
interface as a :class:`tudorvision.joint.JointCore`, so the joint-control layer (safety limits,
watchdog, sessions, UDP) and everything that talks to it through :class:`tudorvision.joint.JointAdapter`
(visual servoing, catching) drive that arm unchanged.

``VendorArm`` stands in for the vendor's driver: degrees, a command latency of one cycle and a
first-order speed response; replace it with your driver's calls. ``VelocityArmCore`` is the part
you keep: SI units in and out, point-to-point setpoints turned into velocity commands by a
time-optimal profile, a controlled stop, and a :class:`~tudorvision.joint.cores.CoreState` per step.

Run it (about 3 s): ``.venv/bin/python examples/own_joint_core.py`` drives the core through the
layer in-process with the adapter, a setpoint then velocity commands, and prints what it did.
``.venv/bin/python examples/own_joint_core.py --serve 47130 --duration 10`` serves it on UDP
instead, for ``tudorvision joint status/move --port 47130`` from another shell.
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from tudorvision.cli import main as tudorvision_main
from tudorvision.joint import (CollisionStrategy, CoreState, Damping, InProcessTransport, JointAdapter,
                               JointLayerServer, Mode, SafetyLimits, register_core)


class VendorArm:
    """Stand-in for a vendor driver with a joint-velocity interface (degrees, one cycle of latency).

    Parameters
    ----------
    q0_deg : sequence of 3 float
        Initial joint positions in degrees.
    tau_s : float
        Time constant of the drives' speed response in s.
    """

    def __init__(self, q0_deg, tau_s: float = 0.02):
        self.q_deg = np.array(q0_deg, float)
        self.qd_deg_s = np.zeros(3)
        self._pending = np.zeros(3)      # the command sent last cycle (latency)
        self._active = np.zeros(3)
        self.tau_s = tau_s

    def send_joint_velocities(self, qd_deg_s) -> None:
        """What a driver call looks like: joint velocities in deg/s, applied from the next cycle."""
        self._pending = np.array(qd_deg_s, float)

    def read_joint_positions(self) -> np.ndarray:
        """Joint positions in degrees."""
        return self.q_deg.copy()

    def read_joint_velocities(self) -> np.ndarray:
        """Joint speeds in deg/s."""
        return self.qd_deg_s.copy()

    def cycle(self, dt: float) -> None:
        """Advance the (simulated) hardware by ``dt`` s; a real driver runs on its own clock."""
        self._active, self._pending = self._pending, self._pending
        self.qd_deg_s += (self._active - self.qd_deg_s) * min(1.0, dt / self.tau_s)
        self.q_deg += self.qd_deg_s * dt


class VelocityArmCore:
    """A :class:`tudorvision.joint.JointCore` over a joint-velocity interface (SI units inside).

    Parameters
    ----------
    arm : VendorArm
        The driver (anything with ``send_joint_velocities``, ``read_joint_positions``,
        ``read_joint_velocities`` and ``cycle``).
    limits : SafetyLimits, optional
        Speed and acceleration limits (default: from the robot description).
    position_gain_1_s : float
        Gain of the position loop that closes setpoints through the velocity interface, 1/s.
    """

    def __init__(self, arm: VendorArm, *, limits: SafetyLimits | None = None, position_gain_1_s: float = 8.0):
        self.arm = arm
        self.limits = limits or SafetyLimits.from_params()
        self.kp = position_gain_1_s
        self.t = 0.0
        self.mode = "hold"
        self.v_ref = np.zeros(3)            # rad/s, what we send
        self.target = np.deg2rad(arm.read_joint_positions())
        self.vmax = self.limits.max_speed_rad_s
        self.amax = self.limits.max_accel_rad_s2
        self.damping, self.collision = Damping.OFF, CollisionStrategy.NONE

    # --- the JointCore protocol -------------------------------------------------------------
    def apply_velocity(self, theta_dot) -> None:
        """Follow this joint velocity reference (rad/s; the layer already limited it)."""
        self.mode, self.v_ref = "velocity", np.asarray(theta_dot, float).copy()

    def apply_setpoint(self, theta, *, max_speed_rad_s, max_accel_rad_s2) -> None:
        """Go to ``theta`` (rad) within the per-joint speed (rad/s) and acceleration (rad/s^2) limits."""
        self.mode, self.target = "setpoint", np.asarray(theta, float).copy()
        self.vmax = np.asarray(max_speed_rad_s, float)
        self.amax = np.asarray(max_accel_rad_s2, float)

    def stop(self) -> None:
        """Controlled stop: ramp the commanded speed to zero at the acceleration limits, then hold."""
        self.mode = "stop"
        self.amax = self.limits.max_accel_rad_s2

    def set_modes(self, *, damping, collision) -> None:
        """A rigid arm has no strain damping or collision residual: record the choice only."""
        self.damping, self.collision = Damping(damping), CollisionStrategy(collision)

    def step(self, dt: float) -> None:
        """One control period: compute the velocity command, send it, let the arm run ``dt`` s."""
        theta = np.deg2rad(self.arm.read_joint_positions())
        if self.mode == "velocity":
            want = self.v_ref
        elif self.mode == "setpoint":
            e = self.target - theta
            # time-optimal approach (braking distance) blended with a position loop near the goal
            want = np.sign(e) * np.minimum.reduce([self.vmax, np.sqrt(2 * self.amax * np.abs(e)),
                                                   self.kp * np.abs(e)])
        else:
            want = np.zeros(3)
        step = self.amax * dt
        self.v_ref = self.v_ref + np.clip(want - self.v_ref, -step, step) if self.mode != "velocity" else want
        self.arm.send_joint_velocities(np.rad2deg(self.v_ref))
        self.arm.cycle(dt)
        self.t += dt

    def state(self) -> CoreState:
        """Joint angles (rad) and speeds (rad/s); no strain gauges on this arm (zeros)."""
        theta = np.deg2rad(self.arm.read_joint_positions())
        theta_dot = np.deg2rad(self.arm.read_joint_velocities())
        at_rest = bool(np.all(np.abs(theta_dot) < 1e-3))
        reached = self.mode != "setpoint" or bool(np.all(np.abs(self.target - theta) < 1e-3))
        return CoreState(t=self.t, theta=theta, theta_dot=theta_dot,
                         settled=at_rest and reached and self.mode != "velocity")


def make_vendor_core(**options) -> VelocityArmCore:
    """Factory for :func:`tudorvision.joint.register_core` (``joint serve --core vendor``)."""
    return VelocityArmCore(VendorArm(q0_deg=[0.0, 90.0, 0.0]), **options)


register_core("vendor", make_vendor_core)


def demo() -> int:
    """Drive the core through the layer with the adapter, in-process: a setpoint, then velocities."""
    client, end = InProcessTransport.pair()
    with JointLayerServer(end, make_vendor_core()), JointAdapter(client) as joints:
        goal = np.deg2rad([20.0, 70.0, -15.0])
        assert joints.set_mode(Mode.SETPOINT, timeout=2.0).code.name == "OK"
        assert joints.send_setpoint(goal, timeout=2.0).code.name == "OK"
        st = joints.wait_settled(goal, tol=np.deg2rad(0.2), timeout=10.0)
        if st is None:
            print("setpoint: did not settle", file=sys.stderr)
            return 1
        print("setpoint reached, theta_deg " + " ".join(f"{x:.2f}" for x in np.rad2deg(st.theta)))
        # visual servoing sends joint velocities at the camera rate; the layer's watchdog stops
        # the arm when they cease
        assert joints.set_mode(Mode.VELOCITY, timeout=2.0).code.name == "OK"
        t_end = time.monotonic() + 0.5
        while time.monotonic() < t_end:
            joints.send_velocity(np.deg2rad([10.0, 0.0, 0.0]))
            time.sleep(0.02)
        time.sleep(0.4)          # commands stopped: the watchdog ramps the arm down
        st = joints.request_state(timeout=1.0)
        print("after 0.5 s at 10 deg/s on joint 1 and the watchdog stop: theta_deg "
              + " ".join(f"{x:.2f}" for x in np.rad2deg(st.theta))
              + f", speed {np.rad2deg(abs(st.theta_dot[0])):.2f} deg/s")
    return 0


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--serve", type=int, metavar="PORT", help="serve the core on UDP (tudorvision joint serve)")
    ap.add_argument("--duration", type=float, default=10.0, help="with --serve: seconds (default 10)")
    args = ap.parse_args()
    if args.serve is not None:
        sys.exit(tudorvision_main(["joint", "serve", "--core", "vendor", "--port", str(args.serve),
                                   "--duration", str(args.duration)]))
    sys.exit(demo())
