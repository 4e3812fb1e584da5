"""Rigid-equivalent kinematics: FK/IK round trips, Jacobian vs finite differences."""
import numpy as np
import pytest

from tudorvision.robot import (T_base_ee, fk_ee, fk_spheres, ik, ik_all, jacobian_ee,
                               load_robot_params, within_limits)

P = load_robot_params()


def _random_thetas(rng, n, margin=0.05):
    lo = P.joint_limits_rad[:, 0] + margin
    hi = P.joint_limits_rad[:, 1] - margin
    return rng.uniform(lo, hi, size=(n, 3))


def test_zero_and_vertical_configurations():
    assert np.allclose(fk_ee([0, 0, 0]), [P.link2_length_m + P.link3_length_m, 0, P.link1_height_m])
    top = P.link1_height_m + P.link2_length_m + P.link3_length_m
    assert np.allclose(fk_ee([0.7, np.pi / 2, 0]), [0, 0, top])
    # link 3 vertical when theta2 + theta3 = 90 deg
    p = fk_ee([0, np.deg2rad(30), np.deg2rad(60)])
    elbow_r = P.link2_length_m * np.cos(np.deg2rad(30))
    assert np.isclose(p[0], elbow_r)


def test_fk_ik_round_trip_over_joint_ranges():
    rng = np.random.default_rng(1)
    for th in _random_thetas(rng, 500):
        if abs(np.sin(th[2])) < 1e-3:
            continue
        sols = ik_all(fk_ee(th))
        assert len(sols) >= 1
        for s in sols:  # every returned solution reaches the point and respects limits
            assert np.allclose(fk_ee(s), fk_ee(th), atol=1e-9)
            assert within_limits(s)
        err = np.abs((sols - th + np.pi) % (2 * np.pi) - np.pi).max(axis=1)
        assert err.min() < 1e-8
        elbow = "up" if th[2] >= 0 else "down"
        assert np.allclose(ik(fk_ee(th), elbow=elbow, near=th), th, atol=1e-8)


def test_jacobian_matches_finite_differences():
    rng = np.random.default_rng(2)
    h = 1e-6
    for th in _random_thetas(rng, 50):
        J = jacobian_ee(th)
        Jn = np.column_stack([(fk_ee(th + h * e) - fk_ee(th - h * e)) / (2 * h) for e in np.eye(3)])
        assert np.allclose(J, Jn, atol=1e-8)
    thetas = _random_thetas(rng, 7)
    assert np.allclose(jacobian_ee(thetas)[3], jacobian_ee(thetas[3]))


def test_ee_frame_is_rotation_and_spheres_straddle_ee():
    rng = np.random.default_rng(3)
    th = _random_thetas(rng, 20)
    T = T_base_ee(th)
    R = T[:, :3, :3]
    assert np.allclose(R @ np.transpose(R, (0, 2, 1)), np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(R), 1.0)
    s = fk_spheres(th)
    assert np.allclose((s["red"] + s["green"]) / 2, fk_ee(th))
    d = np.linalg.norm(s["red"] - s["green"], axis=1)
    off = P.sphere_offsets_ee_m
    assert np.allclose(d, np.linalg.norm(off["red"] - off["green"]))
    # spheres sit on the joint axis direction: horizontal offset
    assert np.allclose(s["red"][:, 2], s["green"][:, 2])


def test_unreachable_and_bad_arguments():
    with pytest.raises(ValueError, match="not reachable"):
        ik([5.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="elbow"):
        ik(fk_ee([0, 1, 0.5]), elbow="sideways")
    with pytest.raises(ValueError, match=r"theta: expected shape \(N, 3\)"):
        fk_ee([0.0, 1.0])
    assert not within_limits([0.0, 0.0, np.deg2rad(110)])
