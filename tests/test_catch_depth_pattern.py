"""The catching demo's wall camera has the lab Kinect's fixed depth pattern; the agent calibrates it from a flat
wall and removes it from every detection. Oracles: the lab's own pattern field (never shown to the agent) and the
base-frame transform of the corrected detection."""
from types import SimpleNamespace

import numpy as np
import pytest

from tudorvision.lab.catch.options import DemoOptions
from tudorvision.sim.depth_sensor import pattern_field


def test_modelled_detections_carry_the_units_pattern():
    from tudorvision.lab.catch.calibration import wall_depth_sensor
    from tudorvision.lab.catch.scenario import CatchScenario
    from tudorvision.robot import load_robot_params

    p = load_robot_params()
    world = CatchScenario(DemoOptions(render=False, calibration_seed=3), p, np.deg2rad([0.0, 90.0, 0.0]))
    K = world.intrinsics
    c = pattern_field(wall_depth_sensor(world.options), K.height, K.width)
    moved = []
    for q in ([0.2, -0.3, 6.5], [-0.5, 0.4, 4.0], [0.0, 0.0, 7.0]):
        q = np.asarray(q, float)
        s = world.pattern_moved(q)
        u, v = (int(round(K.fx * q[0] / q[2] + K.cx)), int(round(K.fy * q[1] / q[2] + K.cy)))
        assert abs(s[2] - 1.0 / (1.0 / q[2] + c[v, u])) < 1e-12              # the unit's pattern at that pixel
        np.testing.assert_allclose(s[:2] / s[2], q[:2] / q[2], atol=1e-12)     # along the ray
        moved.append(abs(s[2] - q[2]))
    assert max(moved) > 0.01                                                  # centimetres at 4-7 m
    flat = CatchScenario(DemoOptions(render=False, depth_pattern_px=0.0), p, np.deg2rad([0.0, 90.0, 0.0]))
    assert np.array_equal(flat.pattern_moved(np.array([0.2, -0.3, 6.5])), [0.2, -0.3, 6.5])
    with pytest.raises(ValueError, match="depth_pattern_px"):
        DemoOptions(depth_pattern_px=-1.0)


def test_the_agents_wall_calibration_removes_the_pattern_at_the_arm(tmp_path):
    from tudorvision.lab.catch.calibration import wall_depth_pattern, wall_depth_sensor
    from tudorvision.sim.scenes_rgbd import kinect_camera

    o = DemoOptions(cache_dir=str(tmp_path), calibration_seed=5)
    cam = kinect_camera(np.eye(4))
    corr = wall_depth_pattern(o, cam.K, cam.width, cam.height)
    assert wall_depth_pattern(o, cam.K, cam.width, cam.height) is corr            # cached
    assert list(tmp_path.glob("depth_pattern_*.yaml"))                           # written for the user to see
    c = pattern_field(wall_depth_sensor(o), cam.height, cam.width)
    z = 6.9                                                                       # the arm, from the wall camera
    before = np.sqrt(np.mean((1 / (1 / z + c) - z) ** 2))
    after = np.sqrt(np.mean((corr.apply(1 / (1 / z + c)) - z) ** 2))
    assert before > 0.05 and after < 0.15 * before
    assert wall_depth_pattern(DemoOptions(depth_pattern_correction=False), cam.K, cam.width, cam.height) is None


def test_the_agent_removes_the_pattern_before_the_filter():
    import tudorvision.lab.catch.agent as agent_mod
    from tudorvision.lab.catch.scenario import CameraFrame
    from tudorvision.rgbd.depth_pattern import DepthPatternCorrection
    from tudorvision.rgbd.frames import Intrinsics
    from tudorvision.robot import load_robot_params

    from _catch_stubs import LayerStub

    seen = []

    class Perception:
        def step(self, t, p_base, cov_base):
            seen.append(np.asarray(p_base, float))
            return {"peer_s": 0.0, "intercept": None}

    K = Intrinsics(525.0, 525.0, 319.5, 239.5, 640, 480)
    corr = DepthPatternCorrection(np.full((60, 80), 2e-3), 8, (640, 480))
    T = np.eye(4)
    T[:3, 3] = [0.1, -6.8, 1.0]
    agent = agent_mod.CatchAgent(LayerStub(), lambda *a, **k: np.zeros(3), None, Perception(), None, T,
                                 options=DemoOptions(), params=load_robot_params(), payload_range_kg=(0.0, 0.4),
                                 depth_correction=corr, intrinsics=K)
    p = np.array([0.3, -0.2, 6.0])
    agent.step(0.0, CameraFrame(t=0.0, detection_cam=(p, np.eye(3) * 1e-4)))
    z = 1.0 / (1.0 / 6.0 - 2e-3)                                  # the reported 6 m taken back by the pattern
    np.testing.assert_allclose(seen[0], (T @ np.r_[p * z / 6.0, 1.0])[:3], atol=1e-12)
    with pytest.raises(ValueError, match="intrinsics"):
        agent_mod.CatchAgent(LayerStub(), None, None, None, None, T, options=DemoOptions(),
                             params=load_robot_params(), payload_range_kg=(0.0, 0.4), depth_correction=corr)


def test_catch_cli_depth_pattern_arguments_are_checked(tmp_path, capsys):
    from tudorvision.cli import main

    assert main(["catch", "demo", "--depth-pattern-px", "3", "--out", str(tmp_path / "bad")]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--depth-pattern-px" in err[0] and not (tmp_path / "bad").exists()
    assert main(["catch", str(tmp_path), "--no-depth-pattern-correction"]) != 0
    assert "only with 'catch demo'" in capsys.readouterr().err
