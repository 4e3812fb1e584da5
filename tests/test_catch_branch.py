"""An intercept setpoint stays on the arm's elbow branch unless the other branch's swing arrives in time.

A crossing low on the right is out of the elbow-up branch's reach within joint 2's setpoint margin; the
compensated IK then returns the elbow-down solution, a swing of joint 3 through the stretched arm that
takes over a second: late for the throw, and the arm is still away when the next ball comes. The agent
now sends the nearest point of its own branch instead (:meth:`InverseKinematics.nearest_on_branch`).
"""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from _catch_stubs import LayerStub, identity_ik_agent
from tudorvision.catch.kinematics import DeflectionModel, InverseKinematics
from tudorvision.robot import load_robot_params, planar_from_joints

PARAMS = load_robot_params()


def _grid_nearest(model, target_rz, lo, hi, payload, n=401):
    """Brute-force oracle: the grid point of the bounded (theta2, theta3) box nearest the target."""
    t2, t3 = np.meshgrid(np.linspace(lo[0], hi[0], n), np.linspace(lo[1], hi[1], n))
    th = np.stack([t2.ravel(), t3.ravel()], axis=1)
    d = np.linalg.norm(model(th, payload) - target_rz, axis=1)
    i = int(np.argmin(d))
    return th[i], float(d[i])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_nearest_on_branch_matches_a_brute_force_search(seed):
    rng = np.random.default_rng(seed)
    # a smooth made-up deflection of a few centimetres under load (the learnt model's form)
    model = DeflectionModel(D=rng.normal(0.0, 0.004, (30, 2)), params=PARAMS)
    ikm = InverseKinematics(model, PARAMS)
    lo3, hi3 = np.deg2rad([-170.0, -4.0, 3.0]), np.deg2rad([180.0, 182.0, 99.0])   # the elbow-up half
    payload = float(rng.uniform(0.0, 0.3))
    for target in ([0.44, 0.0, 0.62], [0.50, 0.0, 0.55], [0.30, 0.0, 1.00], [-0.2, 0.0, 1.3]):
        th, d = ikm.nearest_on_branch(np.array(target), 0.0, payload, elbow="up", lower_rad=lo3, upper_rad=hi3)
        assert th[2] > 0 and np.all(th[1:] >= lo3[1:] - 1e-12) and np.all(th[1:] <= hi3[1:] + 1e-12)
        target_rz = np.array([target[0], target[2]])
        assert d == pytest.approx(float(np.linalg.norm(model(th[None, 1:], payload)[0] - target_rz)), abs=1e-12)
        _, d_grid = _grid_nearest(model, target_rz, lo3[1:], hi3[1:], payload)
        assert d <= d_grid + 1e-6                      # no grid point of the box is nearer
        assert d_grid - d < 2e-3                       # and the grid's best is next to it


def test_a_target_the_branch_reaches_gives_its_exact_solution():
    model = DeflectionModel(D=np.zeros((30, 2)), params=PARAMS)
    ikm = InverseKinematics(model, PARAMS)
    theta = np.deg2rad([0.0, 35.0, 70.0])
    r, z = planar_from_joints(np.array([theta[1]]), np.array([theta[2]]), PARAMS)
    lo, hi = np.deg2rad([-170.0, -4.0, -99.0]), np.deg2rad([180.0, 182.0, 99.0])
    th, d = ikm.nearest_on_branch(np.array([r[0], 0.0, z[0]]), 0.0, 0.0, elbow="up", lower_rad=lo, upper_rad=hi)
    assert d < 1e-8 and np.allclose(th, theta, atol=1e-6)
    # low on the right the elbow-up branch ends at joint 2's bound: the nearest point has joint 2 there
    th, d = ikm.nearest_on_branch(np.array([0.44, 0.0, 0.62]), 0.0, 0.0, elbow="up", lower_rad=lo, upper_rad=hi)
    assert th[1] == pytest.approx(lo[1]) and 0.05 < d < 0.15         # 11 cm: the branch cannot get nearer
    with pytest.raises(ValueError, match="elbow"):
        ikm.nearest_on_branch(np.array([0.44, 0.0, 0.62]), 0.0, 0.0, elbow="left", lower_rad=lo, upper_rad=hi)


OTHER_BRANCH = np.deg2rad([0.0, 85.0, -98.0])      # what the IK returns (elbow down)
OWN_BRANCH = np.deg2rad([0.0, -4.0, 90.0])          # what the arm's own branch gets nearest


def _agent(layer, monkeypatch, **options):
    agent = identity_ik_agent(layer, monkeypatch, (0.0, 57.0, 57.0), overshoot_lead_m=0.0, **options)
    calls = []

    def nearest_on_branch(p, payload, *, elbow, lower_rad, upper_rad):
        calls.append(elbow)
        return OWN_BRANCH, 0.05

    agent.ik.nearest_on_branch = nearest_on_branch
    return agent, calls


@pytest.mark.parametrize("lead_s, keep, expected, kept", [
    (0.6, True, OWN_BRANCH, 1),          # the swing cannot arrive: the arm's own branch
    (10.0, True, OTHER_BRANCH, 0),       # plenty of time: the swing is made
    (0.6, False, OTHER_BRANCH, 0),       # the behaviour before: always the swing
])
def test_the_other_branch_only_when_its_swing_arrives_in_time(monkeypatch, lead_s, keep, expected, kept):
    layer = LayerStub(theta_deg=(0.0, 60.0, 60.0))         # elbow up
    agent, calls = _agent(layer, monkeypatch, keep_elbow_branch=keep)
    agent.begin_throw(0)
    agent._intercept(0.0, SimpleNamespace(p_base=OTHER_BRANCH, t_cross=lead_s), layer.theta)
    assert len(layer.sent) == 1 and np.allclose(layer.sent[-1], expected)
    assert agent.log.kept_branch == kept and calls == (["up"] if kept else [])


def test_a_solution_on_the_arms_own_branch_is_sent_as_before(monkeypatch):
    layer = LayerStub(theta_deg=(0.0, 60.0, 60.0))
    agent, calls = _agent(layer, monkeypatch)
    agent.begin_throw(0)
    same = np.deg2rad([0.0, 20.0, 80.0])
    agent._intercept(0.0, SimpleNamespace(p_base=same, t_cross=0.6), layer.theta)
    assert np.allclose(layer.sent[-1], same) and calls == [] and agent.log.kept_branch == 0
