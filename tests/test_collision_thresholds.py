"""Payload-scheduled collision thresholds and the collision runs' plants (issue 18 follow-up).

* ``payload_thresholds``: pooled 6 sigma of all collision-free residuals, per payload the larger of
  its own 6 sigma and the pooled value (a noisy heavy payload gets its own, a quiet one the floor);
* ``CollisionSetup``: the soft default plant runs with the collision gains at the joint layer's
  scaled position loop, ``plant="stiff"`` with the stiff plant's gains and payload schedule.
"""
from __future__ import annotations

import numpy as np
import pytest

from tudorvision.joint.collision_thresholds import payload_thresholds
from tudorvision.joint.damping_gains import PD_SCALES, SOFT_GAINS
from tudorvision.lab.collision_experiments import SOFT_COLLISION_K_EPS, CollisionSetup, make_arm


def test_payload_thresholds_take_the_larger_of_own_and_pooled():
    rng = np.random.default_rng(1)
    sig = np.array([[1.0, 0.5], [2.0, 1.0], [6.0, 2.0]]) * 1e-5
    runs = [rng.normal(0.0, s, size=(40000, 2)) for s in sig]
    pooled, per = payload_thresholds(runs)
    assert per.shape == (3, 2)
    allr = np.concatenate(runs)
    np.testing.assert_allclose(pooled, 6.0 * allr.std(axis=0))
    # the light payloads sit on the pooled floor, the heavy one has its own 6 sigma (above the pool)
    np.testing.assert_allclose(per[0], pooled)
    np.testing.assert_allclose(per[2], 6.0 * runs[2].std(axis=0))
    assert np.all(per[2] > pooled) and np.all(per >= pooled)
    # n_sigma scales everything
    p3, per3 = payload_thresholds(runs, n_sigma=3.0)
    np.testing.assert_allclose(p3, pooled / 2)
    np.testing.assert_allclose(per3, per / 2)


def test_payload_thresholds_refuse_bad_input():
    with pytest.raises(ValueError):
        payload_thresholds([])
    with pytest.raises(ValueError):
        payload_thresholds([np.zeros((10, 3))])


def test_collision_setup_plants_and_their_damping():
    soft = CollisionSetup()
    assert soft.plant == "soft" and soft.soft_k_eps == SOFT_COLLISION_K_EPS
    arm, ca = make_arm(soft, 3, np.array([0.0, 1.0, 0.0]), seed=0)
    assert arm.gain_set == "soft" and arm.hub.active and arm.two_way
    assert ca.damper.config.k_eps == SOFT_COLLISION_K_EPS
    assert ca.damper.pd_scale == pytest.approx(PD_SCALES["soft"]["proportional"])
    # () keeps the joint layer's own soft gains
    _, ca0 = make_arm(CollisionSetup(soft_k_eps=()), 3, np.array([0.0, 1.0, 0.0]), seed=0)
    assert ca0.damper.config.k_eps == SOFT_GAINS["proportional"]
    stiff = CollisionSetup(plant="stiff")
    arm, ca = make_arm(stiff, 3, np.array([0.0, 1.0, 0.0]), seed=0)
    assert not arm.hub.active and arm.two_way and arm.gain_set == "two-way"
    assert ca.damper.config.k_eps == stiff.k_eps and ca.damper.pd_scale == 1.0
    _, ca4 = make_arm(stiff, 4, np.array([0.0, 1.0, 0.0]), seed=0)      # heavy-payload schedule
    assert ca4.damper.config.k_eps == stiff.heavy_k_eps
    with pytest.raises(ValueError):
        CollisionSetup(plant="rubber")
    with pytest.raises(ValueError):
        CollisionSetup(soft_k_eps=(1.0, 2.0))
