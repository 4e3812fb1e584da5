"""The catch demo's wall-camera calibration cache: the shipped calibration is what the code computes, a cache
entry from other code is computed again.

In a file of its own: the full sweep it renders (2400 frames, about 3 min on one core) would otherwise add to
``tests/test_catch_demo.py`` on one worker (``make test`` distributes whole files).
"""
import json

import numpy as np

from tudorvision.lab.catch_demo import DemoOptions


def test_a_cached_calibration_from_other_code_is_computed_again(tmp_path):
    """The cache_dir entry names the code that wrote it: read when it matches, computed again (and replaced)
    when it does not; the shipped calibration of the default placement is what the code computes now."""
    import tudorvision.lab.catch.calibration as cal
    from tudorvision.lab.catch.run import demo_kinematics
    from tudorvision.lab.catch.scenario import CatchScenario
    from tudorvision.robot import load_robot_params

    p = load_robot_params()
    o = DemoOptions(throws=1, render=False, cache_dir=str(tmp_path))
    world = CatchScenario(o, p, np.deg2rad([0.0, 90.0, 0.0]))
    deflection = demo_kinematics(o, p)[0].deflection
    shipped, rep = cal.calibrate_wall_camera(o, p, world.T_base_cam, deflection=deflection)
    assert rep["cached"]                                  # the default placement is shipped
    packaged = cal._packaged
    try:
        cal._packaged = lambda key: None
        cal._MEMORY.clear()
        T, rep = cal.calibrate_wall_camera(o, p, world.T_base_cam, deflection=deflection)
        assert not rep["cached"]
        np.testing.assert_allclose(T, shipped, atol=1e-9)     # the shipped file is not stale
        (path,) = tmp_path.glob("wall_calibration_*.json")
        assert json.loads(path.read_text())["code"] == cal.calibration_code_hash()
        # the cache's code check on a short sweep (one frame per pose, its own key): same logic, a 75-frame render
        from dataclasses import replace
        small = replace(o, calibration_frames_per_pose=1, cache_dir=str(tmp_path / "small"))
        cal._MEMORY.clear()
        T1, rep1 = cal.calibrate_wall_camera(small, p, world.T_base_cam, deflection=deflection)
        assert not rep1["cached"] and rep1["frames"] == 75
        (path,) = (tmp_path / "small").glob("wall_calibration_*.json")
        entry = json.loads(path.read_text())
        assert entry["code"] == cal.calibration_code_hash()
        forged = dict(entry, T_base_cam=np.eye(4).tolist())
        path.write_text(json.dumps(forged))
        cal._MEMORY.clear()
        T2, rep2 = cal.calibrate_wall_camera(small, p, world.T_base_cam, deflection=deflection)
        assert rep2["cached"] and np.allclose(T2, np.eye(4))  # same code: the cache is read as it is
        path.write_text(json.dumps(dict(forged, code="0123456789abcdef")))
        cal._MEMORY.clear()
        T3, rep3 = cal.calibrate_wall_camera(small, p, world.T_base_cam, deflection=deflection)
        assert not rep3["cached"]
        np.testing.assert_allclose(T3, T1, atol=1e-9)
        assert json.loads(path.read_text())["code"] == cal.calibration_code_hash()   # replaced
    finally:
        cal._packaged = packaged
        cal._MEMORY.clear()


def test_the_depth_pattern_is_read_back_from_the_cache_dir(tmp_path, monkeypatch):
    """A worker process that has not calibrated the wall camera's depth pattern reads it from ``cache_dir``
    (the same numbers: the YAML keeps every bit) instead of rendering 30 wall frames again; a damaged file is
    computed again and replaced, whole."""
    import tudorvision.lab.catch.calibration as cal
    import tudorvision.lab.depth_wall as depth_wall
    from tudorvision.lab.catch.scenario import CatchScenario
    from tudorvision.robot import load_robot_params

    p = load_robot_params()
    o = DemoOptions(throws=1, render=False, cache_dir=str(tmp_path), calibration_seed=3)
    cam = CatchScenario(o, p, np.deg2rad([0.0, 90.0, 0.0])).camera
    cal._MEMORY.clear()
    try:
        first = cal.wall_depth_pattern(o, cam.K, cam.width, cam.height)
        (path,) = tmp_path.glob("depth_pattern_*.yaml")
        assert not list(tmp_path.glob(".*tmp*"))                     # no partial file left beside it
        renders = []
        real = depth_wall.render_wall_frames
        monkeypatch.setattr(depth_wall, "render_wall_frames", lambda *a, **k: renders.append(1) or real(*a, **k))
        cal._MEMORY.clear()                                           # a fresh worker process
        again = cal.wall_depth_pattern(o, cam.K, cam.width, cam.height)
        assert not renders and again is not first
        np.testing.assert_array_equal(again.grid_inv_m, first.grid_inv_m)
        assert (again.step_px, tuple(again.image_size), again.n_frames) == \
            (first.step_px, tuple(first.image_size), first.n_frames)
        path.write_text(path.read_text()[:200])                       # cut short
        cal._MEMORY.clear()
        third = cal.wall_depth_pattern(o, cam.K, cam.width, cam.height)
        assert renders == [1]
        np.testing.assert_array_equal(third.grid_inv_m, first.grid_inv_m)
        cal._MEMORY.clear()
        from tudorvision.rgbd.depth_pattern import read_depth_pattern
        np.testing.assert_array_equal(read_depth_pattern(path).grid_inv_m, first.grid_inv_m)   # replaced
    finally:
        cal._MEMORY.clear()
