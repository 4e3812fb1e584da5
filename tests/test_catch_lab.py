"""The demo's lockstep joint layer and the stereo-measured kinematics data (sections 9.2, 9.3)."""
import numpy as np
import pytest

from tudorvision.lab.data_collection import CollectionOptions, collect_settled_poses
from tudorvision.lab.lockstep import LockstepLayer
from tudorvision.joint import Ack, Damping, Mode
from tudorvision.robot import load_robot_params
from tudorvision.sim.arm import Payload
from tudorvision.lab.simulation import SimCore


def _layer(params):
    sim = SimCore(np.deg2rad([0.0, 60.0, 60.0]), payload=Payload.from_parts(params, balls=2), params=params)
    return sim, LockstepLayer(sim)


def test_lockstep_layer_is_deterministic_and_installs_the_damper():
    p = load_robot_params()
    goal = np.deg2rad([0.0, 80.0, 20.0])
    runs = []
    for _ in range(2):
        sim, layer = _layer(p)
        assert isinstance(layer.adapter.set_mode(Mode.SETPOINT, damping=Damping.PROPORTIONAL), Ack)
        assert sim.controlled.damper is not None
        assert isinstance(layer.adapter.send_setpoint(goal, max_speed=1.2, max_accel=5.0), Ack)
        layer.advance_to(1.2)
        assert layer.t == pytest.approx(1.2, abs=1e-9) and sim.arm.t == pytest.approx(1.2, abs=1e-9)
        runs.append((np.array(sim.arm.theta), np.array(sim.arm.strain)))
        layer.adapter.set_mode(Mode.SETPOINT, damping=Damping.OFF)
        assert sim.controlled.damper is None
        layer.close()
    np.testing.assert_array_equal(runs[0][0], runs[1][0])
    np.testing.assert_array_equal(runs[0][1], runs[1][1])
    np.testing.assert_allclose(runs[0][0], goal, atol=np.deg2rad(1.0))     # it got there


def test_lockstep_layer_rejects_a_bad_rate():
    p = load_robot_params()
    sim = SimCore(np.deg2rad([0.0, 90.0, 0.0]), params=p)
    with pytest.raises(ValueError, match="rate_hz"):
        LockstepLayer(sim, rate_hz=0.0)


def test_stereo_measured_poses_come_from_the_tracker_and_the_lab_calibration():
    from tudorvision.lab.record import T_WORLD_BASE
    from tudorvision.sim.scenes import stereo_lab

    opts = CollectionOptions(theta2_deg=(40.0, 100.0, 60.0), theta3_deg=(-30.0, 30.0, 60.0), payloads_kg=(0.2,),
                             measure="stereo")
    d = collect_settled_poses(opts)
    assert d["theta"].shape == (4, 3) and d["valid"].sum() >= 3
    err = np.linalg.norm(d["p_meas_base"] - d["p_true_base"], axis=1)[d["valid"]]
    # measured (not the truth copied), and within the tracker's few-millimetre accuracy
    assert np.all(err > 1e-5) and np.all(err < 0.006)
    # the base frame is the lab's own sweep calibration, close to (but not) the true pose
    left = stereo_lab(np.random.default_rng([opts.seed, 7]), T_world_base=T_WORLD_BASE).cameras["left"]
    T_true = np.linalg.inv(T_WORLD_BASE) @ left.T_world_cam
    T = d["T_base_left"]
    assert 0 < np.linalg.norm(T[:3, 3] - T_true[:3, 3]) < 0.01
    ang = np.arccos(np.clip((np.trace(T[:3, :3].T @ T_true[:3, :3]) - 1) / 2, -1, 1))
    assert ang < np.deg2rad(1.0)


def test_collection_options_reject_an_unknown_measurement():
    with pytest.raises(ValueError, match="measure"):
        CollectionOptions(measure="laser")
