"""``rgbd.base_calib.refine_sweep_mirror``: the sweep's mirror symmetry fixes the in-plane angle, model-free.

Oracle: the lab's elastic arm (static end-effector positions of a theta2
sweep with its sag and backlash) seen through a known camera pose; the
refinement must recover the true frame's angle from a frame turned about y.
"""
from __future__ import annotations

import numpy as np
import pytest

from tudorvision.geometry import invert_transform
from tudorvision.rgbd.base_calib import refine_sweep_mirror
from tudorvision.sim.arm import ElasticArm, Payload, PlantConfig


def _rot_y(deg):
    c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
    T = np.eye(4)
    T[:3, :3] = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
    return T


def _sweep(theta2_deg, payload_kg=0.1):
    th = np.stack([np.zeros(len(theta2_deg)), np.radians(theta2_deg), np.zeros(len(theta2_deg))], axis=1)
    pts = np.array([ElasticArm(t, payload=Payload(mass_kg=payload_kg), config=PlantConfig()).ee_position()
                    for t in th])
    return th, pts


# camera 6.8 m in front of the base, 2 m up, looking along base +y (p_base = T_base_cam @ p_cam)
T_BASE_CAM = np.array([[1.0, 0, 0, 0.0], [0, 0, 1, -6.8], [0, -1, 0, 2.0], [0, 0, 0, 1]])


def _angle_about_y(T):
    return float(np.degrees(np.arctan2(T[0, 2], T[0, 0])))


@pytest.mark.parametrize("tilt_deg, shift_m", [(0.4, 0.0), (-0.25, 0.004), (0.1, -0.003)])
def test_recovers_the_angle_of_a_sagging_sweep(tilt_deg, shift_m):
    th, p_base = _sweep(np.arange(10.0, 170.1, 10.0))
    assert np.ptp([p[2] for p in p_base[[0, -1]]]) < 1e-9           # the lab's sag is mirrored (oracle's premise)
    p_cam = (np.c_[p_base, np.ones(len(p_base))] @ invert_transform(T_BASE_CAM).T)[:, :3]
    pert = _rot_y(tilt_deg)
    pert[0, 3] = shift_m
    T0 = pert @ T_BASE_CAM
    T, info = refine_sweep_mirror(T0, p_cam, th)
    assert info["pairs"] == 8
    assert abs(_angle_about_y(T @ invert_transform(T_BASE_CAM))) < 1e-6
    assert abs((T @ invert_transform(T_BASE_CAM))[0, 3]) < 1e-6     # x shift back as well
    assert abs(info["mirror_rotation_deg"] - tilt_deg) < 1e-6   # _rot_y(t) turns x away from z by t: undone by +t


def test_continuous_sweep_with_unmatched_angles_and_noise():
    """Frames every 0.37 deg (no exact mirror angles), 2 mm noise: the delta / 2 correction and the medians."""
    rng = np.random.default_rng(7)
    deg = np.arange(12.0, 168.0, 0.37)
    th, p_base = _sweep(deg)
    p_cam = (np.c_[p_base, np.ones(len(p_base))] @ invert_transform(T_BASE_CAM).T)[:, :3]
    p_cam = p_cam + rng.normal(0, 0.002, p_cam.shape)
    T0 = _rot_y(0.3) @ T_BASE_CAM
    T, info = refine_sweep_mirror(T0, p_cam, th)
    assert info["pairs"] > 100
    assert abs(_angle_about_y(T @ invert_transform(T_BASE_CAM))) < 0.02
    # without the correction the unmatched partners would bias it: the correction is doing work
    T_bad, _ = refine_sweep_mirror(T0, p_cam, th + np.array([0.0, np.radians(0.3), 0.0]) * (deg > 90)[:, None])
    assert abs(_angle_about_y(T_bad @ invert_transform(T_BASE_CAM))) > 0.1


def test_no_mirrored_poses_is_a_clear_error():
    th, p_base = _sweep(np.array([10.0, 30.0, 50.0]))
    with pytest.raises(ValueError, match="mirror"):
        refine_sweep_mirror(np.eye(4), p_base, th)
