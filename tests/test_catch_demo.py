"""Catching demo end to end and the catch CLI."""
import csv
import json
from pathlib import Path

import numpy as np
import pytest

from tudorvision.lab.catch_demo import DemoOptions, run_demo, simulated_detection
from tudorvision.cli import main
from tudorvision.rgbd.frames import Intrinsics

SAMPLE = Path(__file__).resolve().parents[1] / "sample_data" / "rgbd-throws"


def test_rendered_demo_catches_a_ball_that_crosses_the_workspace(tmp_path):
    s = run_demo(tmp_path / "demo", DemoOptions(throws=1, seed=0, rerun=True, plots=True,
                                                cache_dir=str(tmp_path / "cache")))
    row = s["per_throw"][0]
    assert row["crossing_workspace"] == 1
    assert row["caught"] == 1 and row["miss_m"] < 0.09
    assert row["pred_error_m"] < 0.03
    assert s["success_rate"] == 1.0 and s["balls_in_net"] == 1
    summary = json.loads((tmp_path / "demo" / "summary.json").read_text())
    assert {"throws", "crossing_workspace", "caught", "success_rate"} <= set(summary)
    for name in ("throws.csv", "predictions.csv", "setpoints.csv", "catch.png", "catch.rrd"):
        assert (tmp_path / "demo" / name).stat().st_size > 0
    with (tmp_path / "demo" / "setpoints.csv").open() as fh:
        assert len(list(csv.reader(fh))) >= 2


def test_modelled_detections_several_throws_add_payload_and_weigh_it(tmp_path):
    s = run_demo(tmp_path / "c", DemoOptions(throws=6, seed=3, render=False, rerun=False, plots=False,
                                             cache_dir=str(tmp_path / "cache")))
    rows = s["per_throw"]
    # the joint layer runs in lockstep with the simulation: the outcome does not depend on the machine's load
    assert s["crossing_workspace"] >= 2 and s["caught_in_workspace"] == s["crossing_workspace"]
    assert s["balls_in_net"] == s["caught"]
    assert s["kinematics"]["n_unmeasured"] > 0      # the stereo-measured collection (some poses hide a sphere)
    again = run_demo(tmp_path / "c2", DemoOptions(throws=2, seed=3, render=False, rerun=False, plots=False,
                                                  cache_dir=str(tmp_path / "cache")))["per_throw"]
    for a, b in zip(again, rows[:2]):
        assert a["miss_m"] == b["miss_m"] and a["x_net_m"] == b["x_net_m"]   # deterministic
    # caught balls add 30 g each; the strain-based estimate made at the ready pose follows it (within
    # about two balls: the caught balls still swing when it is made)
    caught_before = np.cumsum([0] + [r["caught"] for r in rows])[:-1]
    np.testing.assert_allclose([r["payload_true_kg"] for r in rows], 0.03 * caught_before, atol=1e-9)
    assert max(abs(r["payload_est_kg"] - r["payload_true_kg"]) for r in rows) < 0.07
    for r in rows:
        if r["crossing_workspace"]:
            assert r["pred_error_m"] < 0.03 and r["pred_error_m"] < r["ballistic_pred_error_m"]


def test_simulated_detection_covariance_is_elongated_along_the_ray():
    K = Intrinsics(525.0, 525.0, 319.5, 239.5, 640, 480)
    rng = np.random.default_rng(0)
    p, C = simulated_detection([0.2, -0.1, 3.0], K, rng)
    w, V = np.linalg.eigh(C)
    ray = np.array([0.2, -0.1, 3.0]) / np.linalg.norm([0.2, -0.1, 3.0])
    assert abs(V[:, -1] @ ray) > 0.999 and w[-1] > 1.2 * w[0]
    assert simulated_detection([0.0, 0.0, 6.0], K, rng) is None        # beyond 4.5 m
    assert simulated_detection([5.0, 0.0, 1.0], K, rng) is None        # outside the image


def test_demo_options_reject_bad_values():
    with pytest.raises(ValueError, match="throws"):
        DemoOptions(throws=0)
    with pytest.raises(ValueError, match="damping"):
        DemoOptions(damping="strong")


@pytest.mark.skipif(not SAMPLE.exists(), reason="sample data not present")
def test_cli_open_loop_on_recorded_throws(tmp_path, capsys):
    from tudorvision.io import load_calibration, save_calibration

    cal = load_calibration(SAMPLE / "calibration.yaml")
    # the test (not perception) may use ground truth: the recording's true extrinsics as a calibration
    T = np.loadtxt(SAMPLE / "groundtruth" / "T_base_cam.csv", delimiter=",", skiprows=2).reshape(4, 4)
    calib = save_calibration(cal.with_updates(transforms={"T_base_cam": T}), tmp_path / "calib.yaml")
    assert main(["catch", str(SAMPLE), "--calib", str(calib), "--out", str(tmp_path / "ol")]) == 0
    rows = list(csv.DictReader((tmp_path / "ol" / "predictions.csv").open()))
    assert len(rows) >= 10
    truth = np.loadtxt(SAMPLE / "groundtruth" / "ball.csv", delimiter=",", skiprows=2)
    last = rows[-1]
    t = float(last["t_s"])
    k = int(np.argmin(np.abs(truth[:, 1] - t)))
    est = np.array([float(last[c]) for c in ("x_m", "y_m", "z_m")])
    assert np.linalg.norm(est - truth[k, 6:9]) < 0.05
    assert (tmp_path / "ol" / "setpoints.csv").exists()
    # without T_base_cam: one clear line, exit 2
    assert main(["catch", str(SAMPLE), "--out", str(tmp_path / "ol2")]) == 2
    assert "T_base_cam" in capsys.readouterr().err


class _FakeLayer:
    """Layer stand-in: joint speed ``speed(t)``, constant strains."""

    def __init__(self, speed):
        self.t, self.speed = 0.0, speed

    def advance_to(self, t):
        self.t = t

    def state(self):
        from types import SimpleNamespace
        return SimpleNamespace(strains=(1e-4, 2e-4, 3e-4, 4e-4), theta_dot=(0.0, self.speed(self.t), 0.0))


def test_payload_is_weighed_only_with_the_arm_at_rest():
    from tudorvision.lab.catch_demo import WEIGH_REST_SPEED_RAD_S, _pause
    t, strains = _pause(_FakeLayer(lambda t: 0.0), 0.0, 1.0, 30.0)
    assert t == pytest.approx(1.0) and len(strains) == 18                 # the last 0.6 s at 30 Hz
    np.testing.assert_allclose(np.mean(strains, axis=0), [1e-4, 2e-4, 3e-4, 4e-4])
    # still arriving at the ready pose during the window: no weighing
    _, strains = _pause(_FakeLayer(lambda t: 0.5 if t < 0.7 else 0.0), 0.0, 1.0, 30.0)
    assert strains == []
    # moving before the window only: weighed
    _, strains = _pause(_FakeLayer(lambda t: 0.5 if t < 0.3 else 0.5 * WEIGH_REST_SPEED_RAD_S), 0.0, 1.0, 30.0)
    assert len(strains) == 18
