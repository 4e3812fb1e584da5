"""The fast paths of the catching pipeline against their plain references (oracle tests)."""
import numpy as np
import pytest

from tudorvision.catch import BallModel, net_target, propagate, reachable_solutions
from tudorvision.catch.ball_model import _propagate_reference
from tudorvision.catch.intercept import InterceptOptions, InterceptPlanner
from tudorvision.robot import load_robot_params


@pytest.mark.parametrize("k", [0.0, 0.012, 0.08])
def test_float_transition_matches_the_numpy_variational_rk4(k):
    rng = np.random.default_rng(11)
    m = BallModel(drag_k_per_m=k)
    for _ in range(25):
        x = rng.normal(size=6) * [1, 1, 1, 6, 6, 4]
        dt = rng.uniform(-0.4, 1.2)
        x1, F = propagate(x, dt, m)
        x2, G = _propagate_reference(x, dt, m)
        np.testing.assert_allclose(x1, x2, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(F, G, rtol=1e-10, atol=1e-12)
        # the structure the fast path relies on: position columns are the identity, rows below zero
        np.testing.assert_array_equal(F[:, :3], np.vstack([np.eye(3), np.zeros((3, 3))]))


def test_drag_free_transition_is_the_constant_velocity_matrix():
    F_exact = np.block([[np.eye(3), 0.7 * np.eye(3)], [np.zeros((3, 3)), np.eye(3)]])
    _, F = propagate([0.1, 0.2, 1.0, 3.0, -1.0, 2.0], 0.7, BallModel(drag_k_per_m=0.0))
    np.testing.assert_allclose(F, F_exact, atol=1e-14)


@pytest.mark.parametrize("theta1", [0.0, 0.8, -2.2, 3.05])
def test_planner_reachability_agrees_with_the_rigid_ik(theta1):
    rng = np.random.default_rng(5)
    planner = InterceptPlanner(InterceptOptions(theta1_rad=theta1))
    agree, reach = 0, 0
    for _ in range(1500):
        r, z = rng.uniform(-1.0, 1.0), rng.uniform(-0.6, 1.3)
        p = np.array([r * np.cos(theta1), r * np.sin(theta1), z])
        ref = len(reachable_solutions(p, theta1, margin_rad=planner.options.margin_rad)) > 0
        agree += planner._reachable(p) == ref
        reach += ref
    assert agree == 1500 and 200 < reach < 1300


def test_net_target_pulls_in_from_full_stretch_only():
    p = load_robot_params()
    reach = p.link2_length_m + p.link3_length_m
    rng = np.random.default_rng(2)
    for _ in range(200):
        t1 = rng.uniform(-np.pi, np.pi)
        ang, d = rng.uniform(-np.pi, np.pi), rng.uniform(0.0, reach)
        q = np.array([d * np.cos(ang) * np.cos(t1), d * np.cos(ang) * np.sin(t1),
                      p.link1_height_m + d * np.sin(ang)])
        out = net_target(q, t1, p, reach_margin_m=0.05)
        shoulder = np.array([0.0, 0.0, p.link1_height_m])
        if d <= reach - 0.05:
            np.testing.assert_array_equal(out, q)
        else:
            assert np.linalg.norm(out - shoulder) == pytest.approx(reach - 0.05, abs=1e-12)
            # moved radially, by less than the margin
            np.testing.assert_allclose(np.cross(out - shoulder, q - shoulder), 0.0, atol=1e-12)
            assert np.linalg.norm(out - q) <= 0.05 + 1e-12


def test_refinement_needs_a_change_beyond_the_sigma_factor():
    # the same states through two planners: a sideways move of the intercept of 1.5 sigma (> 2 cm) is
    # refined with the plain 2 cm rule, not when it must exceed 2 sigma; a 3 sigma move is refined by both
    x0 = np.array([0.1, -2.0, 1.3, 0.0, 6.0, 1.0])
    P = np.diag([4e-4, 4e-4, 4e-4, 1e-6, 1e-6, 1e-6])
    plain = InterceptPlanner(InterceptOptions(release_sigma_m=0.05))
    strict = InterceptPlanner(InterceptOptions(release_sigma_m=0.05, refine_sigma_factor=2.0))
    first = [pl.update(0.0, x0, P) for pl in (plain, strict)]
    assert all(it.send and it.reachable for it in first)
    sigma = first[1].sigma_m
    assert 0.0134 < sigma < 0.05
    x1 = x0.copy(); x1[0] += 1.5 * sigma
    a, b = plain.update(0.3, x1, P), strict.update(0.3, x1, P)
    assert a.send and not b.send
    x2 = x0.copy(); x2[0] += 3.0 * sigma
    assert strict.update(0.6, x2, P).send
