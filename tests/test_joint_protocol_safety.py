"""Safety pure functions: clamping, refusal reasons, braking, ramps."""
import numpy as np
import pytest

from tudorvision.joint.protocol import Reason
from tudorvision.joint.safety import (SafetyLimits, SafetyPolicy, brake_velocity,
                                      check_setpoint, check_velocity_command, ramp_velocity,
                                      stopping_time, within_range)

LIM = SafetyLimits.from_params()
REFUSE = SafetyPolicy(velocity_over_speed="refuse", setpoint_out_of_range="refuse",
                      setpoint_over_limits="refuse")
CLAMP = SafetyPolicy(velocity_over_speed="clamp", setpoint_out_of_range="clamp",
                     setpoint_over_limits="clamp")


def test_velocity_within_limits_passes_unchanged():
    rng = np.random.default_rng(0)
    for _ in range(200):
        v = rng.uniform(-1, 1, 3) * LIM.max_speed_rad_s
        out = check_velocity_command(v, LIM)
        assert out.code == Reason.OK and np.array_equal(out.value, v)


def test_velocity_over_speed_is_scaled_keeping_direction():
    rng = np.random.default_rng(1)
    for _ in range(200):
        v = rng.uniform(-3, 3, 3) * LIM.max_speed_rad_s
        if np.all(np.abs(v) <= LIM.max_speed_rad_s):
            continue
        out = check_velocity_command(v, LIM, policy=CLAMP)
        assert out.code == Reason.CLAMPED_SPEED and out.clamped
        assert np.all(np.abs(out.value) <= LIM.max_speed_rad_s)
        assert np.isclose(np.max(np.abs(out.value) / LIM.max_speed_rad_s), 1.0)
        # same direction: parallel and same sign
        cos = out.value @ v / np.linalg.norm(out.value) / np.linalg.norm(v)
        assert cos == pytest.approx(1.0)


def test_velocity_refusals():
    over = check_velocity_command([0.0, 10.0, 0.0], LIM, policy=REFUSE)
    nan = check_velocity_command([0.0, np.nan, 0.0], LIM)
    assert (over.code, over.value) == (Reason.OVER_SPEED, None)
    assert "joint 2 speed 10 rad/s" in over.text
    assert (nan.code, nan.accepted) == (Reason.NON_FINITE, False)
    with pytest.raises(ValueError, match=r"theta_dot: expected shape \(3\)"):
        check_velocity_command([1.0, 2.0], LIM)


def test_setpoint_range_refused_or_clamped():
    soft = LIM.soft_limits_rad
    outside = np.array([0.0, soft[1, 1] + 0.2, soft[2, 0] - 0.1])
    ref = check_setpoint(outside, LIM, policy=REFUSE)
    assert ref.code == Reason.OUT_OF_RANGE and not ref.accepted
    assert "joint 2 setpoint" in ref.text
    cl = check_setpoint(outside, LIM, policy=CLAMP)
    assert cl.code == Reason.CLAMPED_RANGE
    assert np.allclose(cl.value, [0.0, soft[1, 1], soft[2, 0]])
    inside = check_setpoint([0.1, 1.0, -0.3], LIM)
    assert inside.code == Reason.OK and np.allclose(inside.value, [0.1, 1.0, -0.3])
    assert np.allclose(inside.max_speed_rad_s, LIM.default_speed_rad_s)
    assert np.allclose(inside.max_accel_rad_s2, LIM.default_accel_rad_s2)


def test_setpoint_profile_limits_clamped_per_joint_or_refused():
    fast = 5.0   # rad/s: above every joint's speed limit
    out = check_setpoint([0, 1, 0], LIM, max_speed=fast, max_accel=50.0, policy=CLAMP)
    assert out.code == Reason.CLAMPED_SPEED
    assert np.allclose(out.max_speed_rad_s, LIM.max_speed_rad_s)
    assert np.allclose(out.max_accel_rad_s2, LIM.max_accel_rad_s2)
    assert "profile acceleration" in out.text
    assert check_setpoint([0, 1, 0], LIM, max_speed=fast, policy=REFUSE).code == Reason.OVER_SPEED
    assert check_setpoint([0, 1, 0], LIM, max_accel=100.0,
                          policy=REFUSE).code == Reason.OVER_ACCEL
    assert check_setpoint([0, 1, 0], LIM, max_speed=-1.0).code == Reason.OVER_SPEED
    assert check_setpoint([0, 1, 0], LIM, max_accel=0.0).code == Reason.OVER_ACCEL
    assert check_setpoint([0, np.inf, 0], LIM).code == Reason.NON_FINITE
    assert check_setpoint([0, 1, 0], LIM, max_speed=np.nan).code == Reason.NON_FINITE


def test_brake_lets_every_joint_stop_inside_its_range():
    """Simulate the server's brake + ramp loop pushing into each limit at full speed."""
    dt = 2e-3
    soft = LIM.soft_limits_rad
    rng = np.random.default_rng(2)
    for _ in range(20):
        sign = rng.choice([-1.0, 1.0], 3)
        vmax, amax = LIM.max_speed_rad_s, LIM.max_accel_rad_s2
        d_stop = vmax**2 / (2 * amax) + 2 * vmax * dt     # closest start that can still stop
        theta = (np.where(sign > 0, soft[:, 1], soft[:, 0])
                 - sign * (d_stop + rng.uniform(0.0, 0.3, 3)))
        v_target = sign * vmax
        v = v_target.copy()            # already at full speed
        for _ in range(1500):
            braked = brake_velocity(theta, v_target, LIM, dt, theta_dot_now=v)
            v = ramp_velocity(v, braked, LIM.max_accel_rad_s2, dt)
            theta = theta + v * dt
            assert np.all(theta <= soft[:, 1]) and np.all(theta >= soft[:, 0])
            if not np.any(v):
                break
        assert np.allclose(v, 0.0, atol=1e-9)      # stopped against the limit
        for _ in range(20):                        # and stays there
            v = ramp_velocity(v, brake_velocity(theta, v_target, LIM, dt), LIM.max_accel_rad_s2, dt)
            assert not np.any(v)
        # stopped close to the soft limit, not far before it
        gap = np.where(sign > 0, soft[:, 1] - theta, theta - soft[:, 0])
        assert np.all(gap < np.deg2rad(1.0))


def test_brake_never_pushes_further_out_and_keeps_inward_motion():
    hard = LIM.joint_limits_rad
    theta = hard[:, 1] + 0.01     # beyond the upper limits
    out = brake_velocity(theta, [1.0, 1.0, -1.0], LIM, 1e-3)
    assert np.all(out[:2] == 0.0) and out[2] == -1.0


def test_ramp_and_stopping_time():
    a = LIM.max_accel_rad_s2
    v = np.array([1.0, -2.0, 0.5])
    n = 0
    while np.any(v != 0) and n < 10000:
        v = ramp_velocity(v, np.zeros(3), a, 1e-3)
        n += 1
    assert n * 1e-3 == pytest.approx(stopping_time([1.0, -2.0, 0.5], a), abs=1.5e-3)


def test_limits_validation_and_within_range():
    with pytest.raises(ValueError, match="max_speed_rad_s: limits must be positive"):
        SafetyLimits(joint_limits_rad=LIM.joint_limits_rad, max_speed_rad_s=[1, 0, 1],
                     max_accel_rad_s2=[1, 1, 1])
    with pytest.raises(ValueError, match=r"joint_limits_rad: expected shape \(3, 2\)"):
        SafetyLimits(joint_limits_rad=[[0, 1]], max_speed_rad_s=[1, 1, 1],
                     max_accel_rad_s2=[1, 1, 1])
    with pytest.raises(ValueError, match="velocity_over_speed"):
        SafetyPolicy(velocity_over_speed="ignore")
    assert within_range([0.0, 1.0, 0.0], LIM)
    assert not within_range([0.0, -1.0, 0.0], LIM)
