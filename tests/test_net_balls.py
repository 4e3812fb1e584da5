"""Caught balls swinging in the net (sim.net_balls): statics, the pendulum's frequency and damping, the arm."""
from __future__ import annotations

import math

import numpy as np
import pytest

from tudorvision.sim.net_balls import SwingingBalls

DT = 0.0005


def _hang(balls: SwingingBalls, p, seconds: float, v=(0.0, 0.0, 0.0)):
    """Forces on a fixed ring at ``p`` over ``seconds``, shape (N, 3), and the balls' path, shape (N, 3)."""
    f, q = [], []
    for _ in range(int(round(seconds / DT))):
        f.append(balls.force(p, v))
        q.append(balls.bob_base.copy())
    return np.array(f), np.array(q)


def test_at_rest_the_bag_carries_the_weight_below_the_ring():
    balls = SwingingBalls(DT, length_m=0.1, axial_hz=8.0)
    balls.set_mass(0.09)
    f, q = _hang(balls, np.array([0.3, 0.1, 1.2]), 2.0)
    np.testing.assert_allclose(f[-1], [0.0, 0.0, -0.09 * 9.81], atol=1e-9)
    stretch = 9.81 / (2 * math.pi * 8.0) ** 2
    np.testing.assert_allclose(q[-1], [0.3, 0.1, 1.2 - 0.1 - stretch], atol=1e-9)


def test_no_balls_no_force_and_an_emptied_net_starts_again_at_rest():
    balls = SwingingBalls(DT)
    np.testing.assert_array_equal(balls.force([0, 0, 1], [1, 0, 0]), np.zeros(3))
    balls.set_mass(0.03)
    _hang(balls, np.zeros(3), 0.1, v=(0.5, 0.0, 0.0))
    balls.set_mass(0.0)
    assert balls.bob_base is None
    balls.set_mass(0.03)
    np.testing.assert_allclose(balls.force([1.0, 0.0, 0.0], [0.0, 0.0, 0.0]), [0.0, 0.0, -0.03 * 9.81], atol=1e-12)


@pytest.mark.parametrize("length_m", [0.06, 0.1, 0.2])
def test_small_swing_is_a_pendulum_of_the_stretched_length(length_m):
    """Oracle: the period 2 pi sqrt(L / g) of the stretched bag, and the log decrement of the swing's damping."""
    zeta = 0.05
    balls = SwingingBalls(DT, length_m=length_m, axial_hz=12.0, swing_zeta=zeta)
    balls.set_mass(0.06)
    ring = np.zeros(3)
    balls.force(ring, np.zeros(3))
    balls._v_bob = np.array([0.02, 0.0, 0.0])         # a small push sideways
    _, q = _hang(balls, ring, 6.0)
    x = q[:, 0]
    up = np.nonzero((x[:-1] < 0) & (x[1:] >= 0))[0]
    t_up = (up + (-x[up]) / (x[up + 1] - x[up])) * DT  # zero crossings upwards, interpolated
    f_measured = 1.0 / np.mean(np.diff(t_up))
    assert f_measured == pytest.approx(balls.swing_hz, rel=0.01)
    peaks = [np.max(np.abs(x[a:b])) for a, b in zip(up[:-1], up[1:])]
    decay = -np.polyfit(t_up[:-1], np.log(peaks), 1)[0]
    assert decay == pytest.approx(zeta * 2 * math.pi * f_measured, rel=0.15)


def test_a_ring_moved_sideways_drags_the_balls_and_they_lag():
    """The ring accelerated sideways: the bag tilts back, its pull on the ring points against the motion."""
    balls = SwingingBalls(DT, length_m=0.1)
    balls.set_mass(0.1)
    p, v = np.zeros(3), np.zeros(3)
    balls.force(p, v)
    for _ in range(200):                                # 0.1 s at 3 m/s^2
        v = v + np.array([3.0, 0.0, 0.0]) * DT
        p = p + v * DT
        f = balls.force(p, v)
    assert f[0] < -0.1 * 3.0 * 0.5                      # at least half of m a back against the motion
    assert balls.bob_base[0] < p[0]


def test_a_slack_bag_pulls_nothing():
    balls = SwingingBalls(DT, length_m=0.1)
    balls.set_mass(0.05)
    balls.force(np.zeros(3), np.zeros(3))
    # the ring drops 5 cm at once: the balls are now within the bag's length of it
    np.testing.assert_array_equal(balls.force(np.array([0.0, 0.0, -0.05]), np.zeros(3)), np.zeros(3))


def test_bad_arguments_are_refused():
    with pytest.raises(ValueError, match="length_m"):
        SwingingBalls(DT, length_m=0.0)
    with pytest.raises(ValueError, match="mass_kg"):
        SwingingBalls(DT).set_mass(float("nan"))


def test_the_arm_at_rest_feels_the_balls_as_point_masses():
    """Integration: the held arm's mean strains with three swinging balls equal those with three point-mass balls.

    Both arms start settled with the bare mount; at t = 0 three balls are added, as point masses to the one and
    hung in the bag of the other; the strains are averaged over the last 4 s of 10 s (the links still ring).
    """
    from tudorvision.lab.simulation import SimCore
    from tudorvision.robot import load_robot_params
    from tudorvision.sim.arm import Payload
    from tudorvision.sim.model import PlantConfig

    params = load_robot_params()
    pose = np.deg2rad([0.0, 20.0, 30.0])
    config = PlantConfig()
    strains = []
    for swing in (False, True):
        balls = SwingingBalls(config.dt) if swing else None
        sim = SimCore(pose, payload=Payload.from_parts(params), params=params, config=config,
                      obstacles=(balls,) if swing else ())
        if swing:
            balls.set_mass(3 * params.ball_mass_kg)
        else:
            sim.arm.set_payload(Payload.from_parts(params, balls=3))
        n = int(round(10.0 / config.dt))
        s = []
        for k in range(n):
            sim.step(config.dt)
            if k >= n - int(round(4.0 / config.dt)):
                s.append(sim.arm.measured_strain())
        strains.append(np.mean(np.asarray(s, float), axis=0))
    bare = SimCore(pose, payload=Payload.from_parts(params), params=params, config=config).arm.measured_strain()
    change = strains[0] - np.asarray(bare, float)
    assert np.max(np.abs(change)) > 1e-5                   # three balls do strain the links
    np.testing.assert_allclose(strains[1], strains[0], atol=0.05 * np.max(np.abs(change)))
