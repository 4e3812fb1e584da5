"""The catch demo's wall-camera calibration cache: a cache entry from other code is computed again; the shipped
calibration is this code's, and the code hash covers every file whose code runs in a calibration.

The shipped file itself is computed again (the full 2400-frame sweep, about 3 min on one core) by
``benchmarks/check_shipped_calibration.py``, not here: this file checks what makes that comparison needed.
"""
import cProfile
import json
from pathlib import Path

import numpy as np

from tudorvision.lab.catch_demo import DemoOptions


def _short_calibration(tmp_path, profile=None, **kw):
    """A one-frame-per-pose calibration of the default placement (75 frames), its transform and report;
    ``profile``: a :class:`cProfile.Profile` enabled around the calibration alone."""
    import tudorvision.lab.catch.calibration as cal
    from tudorvision.lab.catch.run import demo_kinematics
    from tudorvision.lab.catch.scenario import CatchScenario
    from tudorvision.robot import load_robot_params

    p = load_robot_params()
    o = DemoOptions(throws=1, render=False, cache_dir=str(tmp_path), calibration_frames_per_pose=1, **kw)
    world = CatchScenario(o, p, np.deg2rad([0.0, 90.0, 0.0]))
    deflection = demo_kinematics(o, p)[0].deflection
    if profile is None:
        return cal.calibrate_wall_camera(o, p, world.T_base_cam, deflection=deflection)
    profile.enable()
    try:
        return cal.calibrate_wall_camera(o, p, world.T_base_cam, deflection=deflection)
    finally:
        profile.disable()


def test_a_cached_calibration_from_other_code_is_computed_again(tmp_path):
    """The cache_dir entry names the code that wrote it: read when it matches, computed again (and replaced)
    when it does not. The short sweep (one frame per pose) has its own key; the logic is the same."""
    import tudorvision.lab.catch.calibration as cal

    cal._MEMORY.clear()
    try:
        T1, rep1 = _short_calibration(tmp_path)
        assert not rep1["cached"] and rep1["frames"] == 75
        (path,) = tmp_path.glob("wall_calibration_*.json")
        entry = json.loads(path.read_text())
        assert entry["code"] == cal.calibration_code_hash()
        forged = dict(entry, T_base_cam=np.eye(4).tolist())
        path.write_text(json.dumps(forged))
        cal._MEMORY.clear()
        T2, rep2 = _short_calibration(tmp_path)
        assert rep2["cached"] and np.allclose(T2, np.eye(4))  # same code: the cache is read as it is
        path.write_text(json.dumps(dict(forged, code="0123456789abcdef")))
        cal._MEMORY.clear()
        T3, rep3 = _short_calibration(tmp_path)
        assert not rep3["cached"]
        np.testing.assert_allclose(T3, T1, atol=1e-9)
        assert json.loads(path.read_text())["code"] == cal.calibration_code_hash()   # replaced
        # this code's entry, damaged (not a rigid 4x4 transform, no report): computed again, not read
        path.write_text(json.dumps(dict(entry, T_base_cam=[[1.0, 2.0], [3.0, 4.0]])))
        cal._MEMORY.clear()
        T4, rep4 = _short_calibration(tmp_path)
        assert not rep4["cached"]
        np.testing.assert_allclose(T4, T1, atol=1e-9)
        assert cal._entry_ok(entry) and cal._entry_ok(json.loads(path.read_text()))
        for damaged in (dict(entry, T_base_cam_seed="x"), dict(entry, T_base_cam=(2 * np.eye(4)).tolist()),
                        dict(entry, T_base_cam=np.full((4, 4), np.nan).tolist()),
                        {k: v for k, v in entry.items() if k != "report"}, [entry], None):
            assert not cal._entry_ok(damaged)
    finally:
        cal._MEMORY.clear()


def test_the_shipped_calibration_is_this_codes_and_read_for_the_default_placement(tmp_path):
    """Every shipped wall calibration names today's code hash (else: ``benchmarks/check_shipped_calibration.py
    --ship``); the default placement reads it instead of rendering the sweep."""
    import tudorvision.lab.catch.calibration as cal
    from tudorvision.lab.catch.run import demo_kinematics
    from tudorvision.lab.catch.scenario import CatchScenario
    from tudorvision.robot import load_robot_params

    codes = cal.shipped_calibration_codes()
    assert codes
    stale = {name: code for name, code in codes.items() if code != cal.calibration_code_hash()}
    assert not stale, (f"shipped calibrations computed by other code: {stale} (this code: "
                       f"{cal.calibration_code_hash()}); run benchmarks/check_shipped_calibration.py --ship")
    p = load_robot_params()
    o = DemoOptions(throws=1, render=False, cache_dir=str(tmp_path))
    world = CatchScenario(o, p, np.deg2rad([0.0, 90.0, 0.0]))
    cal._MEMORY.clear()
    try:
        T, rep = cal.calibrate_wall_camera(o, p, world.T_base_cam, deflection=demo_kinematics(o, p)[0].deflection)
    finally:
        cal._MEMORY.clear()
    assert rep["cached"] and rep["frames"] == 2400 and not list(tmp_path.glob("wall_calibration_*"))
    assert rep["error_at_arm_m"] < 0.01                    # the shipped calibration is a good one


def test_the_default_depth_pattern_is_shipped_for_this_code_and_read_without_rendering(tmp_path, monkeypatch):
    """The wall camera's depth-pattern calibration of the default placement is shipped under today's key (else:
    ``benchmarks/check_shipped_calibration.py --ship``): read from the package, nothing rendered or written."""
    import tudorvision.lab.catch.calibration as cal
    import tudorvision.lab.depth_wall as depth_wall
    from tudorvision.lab.catch.scenario import CatchScenario
    from tudorvision.robot import load_robot_params

    o = DemoOptions(throws=1, render=False, cache_dir=str(tmp_path))
    cam = CatchScenario(o, load_robot_params(), np.deg2rad([0.0, 90.0, 0.0])).camera

    def no_render(*a, **k):
        raise AssertionError("the shipped depth pattern was not read: run benchmarks/check_shipped_calibration.py "
                             "--ship")

    monkeypatch.setattr(depth_wall, "render_wall_frames", no_render)
    cal._MEMORY.clear()
    try:
        corr = cal.wall_depth_pattern(o, cam.K, cam.width, cam.height)
    finally:
        cal._MEMORY.clear()
    assert tuple(corr.image_size) == (cam.width, cam.height) and not list(tmp_path.iterdir())
    assert len(list(Path(cal.__file__).resolve().parents[2].joinpath("catch", "data").glob("depth_pattern_*"))) == 1


def test_the_code_hash_covers_every_file_that_runs_in_a_calibration(tmp_path):
    """A short calibration profiled: every package file with code that ran is in ``CODE_FILES`` (or exempt: checks
    and file writes), so a change to any of them names other code and the shipped file is checked again."""
    import tudorvision.lab.catch.calibration as cal
    from tudorvision.lab.code_hash import PACKAGE_ROOT, files_run

    cal._MEMORY.clear()
    prof = cProfile.Profile()
    try:
        _T, rep = _short_calibration(tmp_path, prof, calibration_seed=11)      # its own key: nothing cached
    finally:
        cal._MEMORY.clear()
    assert not rep["cached"]
    ran = files_run(prof)
    assert "rgbd/disc_track.py" in ran and "sim/raycast.py" in ran          # the profile saw the calibration
    missing = ran - set(cal.CODE_FILES) - set(cal.CODE_EXEMPT)
    assert not missing, f"files that run in a calibration but are not in CODE_FILES: {sorted(missing)}"
    assert all((PACKAGE_ROOT / rel).is_file() for rel in cal.CODE_FILES + cal.CODE_EXEMPT)


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
