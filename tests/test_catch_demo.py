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
    # seed 5: its first throw crosses the workspace and the arm arrives in time (seed 0's arrives 85 ms late
    # and the ring's rim meets the ball 5.3 cm off centre: a catch only under the lenient criterion)
    s = run_demo(tmp_path / "demo", DemoOptions(throws=1, seed=5, rerun=True, plots=True,
                                                cache_dir=str(tmp_path / "cache")))
    row = s["per_throw"][0]
    assert row["crossing_workspace"] == 1
    # the whole 9 cm ball through the 18 cm ring (issue 18), not only its centre
    assert row["caught"] == 1 and row["caught_centre"] == 1 and row["ring_offset_m"] <= 0.045
    assert row["rim_contact"] == 0 and row["rim_clearance_m"] >= 0.0 and row["miss_m"] < 0.045
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
    # the joint layer runs in lockstep with the simulation: the outcome does not depend on the machine's load;
    # on the seed-measured plant (the default since issue 18) not every crossing ball goes through the ring
    # (here the balls pass a few mm from the rim: which of them touch it depends on the last bits of the
    # calibration), but the net is there
    assert s["crossing_workspace"] >= 2 and s["caught_centre_in_workspace"] >= 1
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


def test_simulated_detection_covariance_along_and_across_the_ray():
    K = Intrinsics(525.0, 525.0, 319.5, 239.5, 640, 480)
    rng = np.random.default_rng(0)
    p, C = simulated_detection([0.2, -0.1, 3.0], K, rng)
    ray = np.array([0.2, -0.1, 3.0]) / np.linalg.norm([0.2, -0.1, 3.0])
    # by hand: sigma_z(3 m) = 8.05 mm (the seed's fit in mm) over sqrt(n), n = 0.8 pi (525 * 0.045 / 3)^2
    # silhouette pixels, divided by the ray's z component; across: 0.5 px at 3 m = 1.5 / 525 m (the detector's
    # centroid on ragged, real-Kinect-like depth edges), silhouette pixels over the 14 pixels per independent
    # sample of a real Kinect's correlated noise
    n = 0.8 * np.pi * (525.0 * 0.045 / 3.0) ** 2 / 14.0
    s_along = 8.05e-3 / np.sqrt(n) / ray[2]
    np.testing.assert_allclose(C @ ray, s_along ** 2 * ray, rtol=1e-9, atol=1e-15)
    across = np.cross(ray, [1.0, 0.0, 0.0])
    across /= np.linalg.norm(across)
    np.testing.assert_allclose(across @ C @ across, (1.5 / 525.0) ** 2, rtol=1e-9)
    # with millimetre depth noise the silhouette's depth fixes the range a little better than the centroid the
    # bearing (2.4 mm against 2.9 mm at 3 m)
    assert s_along < 1.5 / 525.0
    assert simulated_detection([0.0, 0.0, 6.0], K, rng) is None        # beyond 4.5 m
    assert simulated_detection([5.0, 0.0, 1.0], K, rng) is None        # outside the image
    # cut by the top border (11.8 px radius at 2 m): dropped, as the detector drops it; wholly inside: kept
    assert simulated_detection([0.0, (5.0 - 239.5) * 2.0 / 525.0, 2.0], K, rng) is None
    assert simulated_detection([0.0, (15.0 - 239.5) * 2.0 / 525.0, 2.0], K, rng) is not None


def test_demo_options_reject_bad_values():
    with pytest.raises(ValueError, match="throws"):
        DemoOptions(throws=0)
    with pytest.raises(ValueError, match="damping"):
        DemoOptions(damping="strong")
    with pytest.raises(ValueError, match="ball_radius_m"):
        DemoOptions(ball_radius_m=0.09)                  # as wide as the ring: it never fits through


@pytest.mark.skipif(not SAMPLE.exists(), reason="sample data not present")
def test_cli_open_loop_on_recorded_throws(tmp_path, capsys):
    from tudorvision.io import load_calibration, save_calibration

    cal = load_calibration(SAMPLE / "calibration.yaml")
    # the test (not perception) may use ground truth: the recording's true extrinsics as a calibration
    T = np.loadtxt(SAMPLE / "groundtruth" / "T_base_cam.csv", delimiter=",", skiprows=2).reshape(4, 4)
    calib = save_calibration(cal.with_updates(transforms={"T_base_cam": T}), tmp_path / "calib.yaml")
    assert main(["catch", str(SAMPLE), "--calib", str(calib), "--out", str(tmp_path / "ol")]) == 0
    rows = list(csv.DictReader((tmp_path / "ol" / "predictions.csv").open()))
    assert len(rows) >= 6                   # the ball within the camera's 4.5 m detection range: 8 frames
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
    from tudorvision.lab.catch_demo import WEIGH_REST_SPEED_RAD_S, pause_and_weigh
    t, strains = pause_and_weigh(_FakeLayer(lambda t: 0.0), 0.0, 1.0, 30.0)
    assert t == pytest.approx(1.0) and len(strains) == 18                 # the last 0.6 s at 30 Hz
    np.testing.assert_allclose(np.mean(strains, axis=0), [1e-4, 2e-4, 3e-4, 4e-4])
    # still arriving at the ready pose during the window: no weighing
    _, strains = pause_and_weigh(_FakeLayer(lambda t: 0.5 if t < 0.7 else 0.0), 0.0, 1.0, 30.0)
    assert strains == []
    # moving before the window only: weighed
    _, strains = pause_and_weigh(_FakeLayer(lambda t: 0.5 if t < 0.3 else 0.5 * WEIGH_REST_SPEED_RAD_S), 0.0, 1.0,
                                 30.0)
    assert len(strains) == 18


# ----------------------------------------------------------------------------- the parts of the demo
# throws.csv as written before the split into scenario / agent / scorer / writers (benchmarks read it)
HISTORIC_COLUMNS = ["throw", "t_release_s", "crosses_plane", "crossing_workspace", "t_cross_true_s",
                    "x_cross_true_m", "z_cross_true_m", "detections", "released", "t_first_setpoint_s",
                    "lead_time_s", "x_pred_m", "z_pred_m", "pred_error_m", "ballistic_pred_error_m",
                    "x_net_m", "z_net_m", "miss_m", "time_margin_s", "payload_true_kg", "payload_est_kg",
                    "caught", "t_move_min_s", "in_time", "reason"]


# columns added by issue 18 (the strict catch criterion), after the historic ones
RING_COLUMNS = ["caught_centre", "ring_offset_m", "rim_clearance_m", "rim_contact"]
# and the working plane the agent turned to for the throw (DemoOptions.yaw_max_rad)
YAW_COLUMNS = ["yaw_deg"]


def test_throw_result_fields_are_the_csv_columns_in_order():
    import dataclasses

    from tudorvision.lab.catch_demo import PER_THROW_COLUMNS, ThrowResult

    assert PER_THROW_COLUMNS == HISTORIC_COLUMNS + RING_COLUMNS + YAW_COLUMNS
    assert [f.name for f in dataclasses.fields(ThrowResult)] == HISTORIC_COLUMNS + RING_COLUMNS + YAW_COLUMNS
    r = _result(miss_m=0.05)
    with pytest.raises(dataclasses.FrozenInstanceError):
        r.caught = False
    assert r.as_row()[PER_THROW_COLUMNS.index("miss_m")] == 0.05


def _result(**kw):
    from tudorvision.lab.catch.score import ThrowResult

    values = dict(throw=0, t_release_s=1.0, crosses_plane=True, crossing_workspace=True, t_cross_true_s=0.9,
                  x_cross_true_m=0.1, z_cross_true_m=1.0, detections=20, released=True, t_first_setpoint_s=0.3,
                  lead_time_s=0.6, x_pred_m=0.11, z_pred_m=1.0, pred_error_m=0.01, ballistic_pred_error_m=0.02,
                  x_net_m=0.12, z_net_m=1.0, miss_m=0.02, time_margin_s=0.2, payload_true_kg=0.0,
                  payload_est_kg=0.0, caught=True, t_move_min_s=0.4, in_time=True, reason="", caught_centre=True,
                  ring_offset_m=0.02, rim_clearance_m=0.025, rim_contact=False)
    return ThrowResult(**{**values, **kw})


def _scored(miss_m, net_radius_m, *, released=True):
    """A synthetic throw crossing at (-0.27, 0, 0.96) m and a net ``miss_m`` beside it, scored."""
    from types import SimpleNamespace

    from tudorvision.lab.catch.agent import ThrowLog
    from tudorvision.lab.catch.scenario import Throw
    from tudorvision.lab.catch.score import score_throw
    from tudorvision.robot import load_robot_params

    p = load_robot_params()
    p_cross = np.array([-0.27, 0.0, 0.96])
    throw = Throw(index=4, t_release_s=2.0, times_s=np.zeros(1), points_base=np.zeros((1, 3)), t_cross_rel_s=0.9,
                  p_cross_base=p_cross, t_cross_s=2.9)
    it = SimpleNamespace(p_base=p_cross + [0.005, 0.0, 0.0])
    log = ThrowLog(detections=20, last_intercept=it, t_first_setpoint_s=2.4 if released else None,
                   t_arrived_s=2.7 if released else None, payload_est_kg=0.03)
    return score_throw(throw, log, net_at_cross=p_cross + [0.0, 0.0, miss_m], theta_at_release=np.deg2rad([0, 60, 60]),
                       payload_true_kg=0.03, options=DemoOptions(net_radius_m=net_radius_m), params=p,
                       theta1_rad=0.0, max_speed=1.0, max_accel=5.0, frame_rate_hz=30.0)


def test_caught_means_the_whole_ball_inside_the_net_radius_option():
    r = _scored(0.15, 0.09)
    assert r.crossing_workspace and not r.caught and r.miss_m == pytest.approx(0.15)
    assert not r.caught_centre and not r.rim_contact       # 15 cm off a 9 cm ring: the 4.5 cm ball passes it
    assert r.reason == "deflection or vibration"          # released, predicted well, arrived: the net was off
    r = _scored(0.10, 0.09)                                # 10 cm off: the ball's edge hits the rim from outside
    assert not r.caught and not r.caught_centre and r.rim_contact and r.reason == "ball hit the rim"
    assert _scored(0.10, 0.16).caught                      # a larger net catches the same throw (0.10 <= 0.16 - 0.045)
    r = _scored(0.10, 0.12)                                # centre inside, ball on the rim: bounces off
    assert r.caught_centre and not r.caught and r.rim_contact and r.reason == "ball hit the rim"
    r = _scored(0.02, 0.09)
    assert r.caught and r.reason == "" and r.lead_time_s == pytest.approx(0.5) and r.time_margin_s == pytest.approx(0.2)
    assert r.x_pred_m == pytest.approx(-0.265) and r.pred_error_m == pytest.approx(0.005)
    assert np.isnan(r.ballistic_pred_error_m)              # no peer prediction
    r = _scored(0.3, 0.09, released=False)
    assert not r.released and r.reason.startswith("not released") and np.isnan(r.t_first_setpoint_s)
    # a prediction error beyond what the net can take (net radius less the ball's) is named before the arm:
    # 5 mm off, a 4.9 cm ring leaves a 4.5 cm ball 4 mm
    assert _scored(0.3, 0.049).reason == "prediction error"
    assert _scored(0.3, 0.051).reason == "deflection or vibration"


def test_summary_counts_come_from_the_results():
    from tudorvision.lab.catch.score import summarize_throws

    rows = [_result(), _result(throw=1, caught=False, reason="arm late", in_time=False),
            _result(throw=2, crosses_plane=False, crossing_workspace=False, caught=False, in_time=False,
                    pred_error_m=np.nan, reason="does not reach the working plane", caught_centre=False),
            _result(throw=3, caught=False, reason="arm late", pred_error_m=0.03)]
    s = summarize_throws(rows)
    assert (s["crossing_workspace"], s["caught_in_workspace"], s["caught"]) == (3, 1, 1)
    assert s["success_rate"] == pytest.approx(1 / 3)
    # the lenient count follows caught_centre (here still True for throws 1 and 3)
    assert (s["caught_centre_in_workspace"], s["caught_centre"]) == (3, 3)
    assert s["success_rate_centre"] == pytest.approx(1.0) and s["rim_contacts_in_workspace"] == 0
    assert (s["crossing_in_time"], s["caught_in_time"]) == (2, 1)
    assert s["median_pred_error_m"] == pytest.approx(0.01)
    assert s["misses"] == {"arm late": 2, "does not reach the working plane": 1}


def test_payload_estimate_is_clipped_to_the_trained_range():
    from types import SimpleNamespace

    from _catch_stubs import LayerStub
    from tudorvision.lab.catch.agent import CatchAgent
    from tudorvision.lab.catch.options import trained_payload_range_kg
    from tudorvision.lab.data_collection import CollectionOptions
    from tudorvision.robot import load_robot_params

    assert trained_payload_range_kg(CollectionOptions()) == (0.0, 0.4)       # training stops at 400 g
    assert trained_payload_range_kg(CollectionOptions(payloads_kg=(0.0, 0.25))) == (0.0, 0.25)

    p = load_robot_params()
    for m_est, expected in ((0.7, 0.4), (-0.05, 0.0), (0.12, 0.12)):
        strain = SimpleNamespace(payload=lambda theta23, eps, m=m_est: np.array([m]))
        layer = LayerStub()
        agent = CatchAgent(layer, None, strain, None, None, np.eye(4), params=p,
                           options=DemoOptions(payload_catch_prior=0.0),      # the last weighing, no belief
                           payload_range_kg=trained_payload_range_kg(CollectionOptions()))
        agent.weigh([np.zeros(4)])
        assert agent.payload_est_kg == pytest.approx(expected)
        assert layer.payloads[-1] == pytest.approx(p.end_effector_mount_mass_kg + expected)
        n = len(layer.payloads)
        agent.weigh([])                                  # not at rest: nothing weighed, nothing told
        assert len(layer.payloads) == n


def test_the_agent_never_reaches_the_simulation_or_the_truth():
    import ast

    import tudorvision.lab.catch.agent as agent_module
    import tudorvision.lab.catch.planes as planes_module
    import tudorvision.lab.catch.profile as profile_module

    # the agent, the profile model it uses (the layer's planner mirrored) and its IK / plane choice see no
    # simulation and no truth
    for module in (agent_module, profile_module, planes_module):
        tree = ast.parse(Path(module.__file__).read_text())
        imported = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom):
                imported.add(("." * node.level) + (node.module or ""))
            elif isinstance(node, ast.Import):
                imported |= {a.name for a in node.names}
        allowed = ("...catch.", "...joint", "...robot", "numpy", "time", "math", "dataclasses", "__future__",
                   ".profile", ".planes")
        assert imported and all(m.startswith(allowed) for m in imported), imported
        names = {n.attr for n in ast.walk(tree) if isinstance(n, ast.Attribute)} | \
            {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)}
        assert not names & {"sim", "arm", "ball_world", "net_position", "p_cross_base", "scenario"}


def test_the_plot_draws_on_a_figure_with_the_net_radius():
    from matplotlib.figure import Figure

    from tudorvision.lab.catch.writers import plot_catch
    from tudorvision.robot import load_robot_params

    preds = [[0, 1.5, "tracking", 0, 0, 0, 0, 0, 0, 1.9, 0.12, 0.0, 1.01, 0.01, 1, 1, np.nan, np.nan, np.nan]]
    fig = plot_catch([_result()], preds, net_radius_m=0.123, params=load_robot_params())
    assert isinstance(fig, Figure)
    radii = [patch.get_radius() for patch in fig.axes[0].patches]
    assert radii == [pytest.approx(0.123)]


def test_a_fault_stop_is_reset_and_the_last_setpoint_sent_again():
    from types import SimpleNamespace

    from tudorvision.joint import StateFlags
    from tudorvision.lab.catch.agent import CatchAgent
    from tudorvision.robot import load_robot_params

    calls = []

    class Adapter:
        def __getattr__(self, name):           # set_mode, reset_fault, send_setpoint, set_payload
            return lambda *a, **kw: calls.append(name)

    class Layer:
        adapter = Adapter()
        flags = StateFlags(0)

        def state(self):
            return SimpleNamespace(flags=self.flags, theta=np.zeros(3))

    layer = Layer()
    agent = CatchAgent(layer, None, None, None, None, np.eye(4), options=DemoOptions(), params=load_robot_params(),
                       payload_range_kg=(0.0, 0.4))
    agent.recover(0.0)                                      # nothing sent yet: nothing to recover
    agent.send(np.array([0.0, 1.0, 1.0]), 0.1)
    agent.recover(0.2)                                      # no fault: nothing happens
    assert calls == ["set_mode", "send_setpoint"] and agent.faults == []
    layer.flags = StateFlags.FAULT
    agent.recover(0.3)
    # a mode switch alone does not clear FAULT (protocol v2): the agent resets it, then resends
    assert calls[2:] == ["reset_fault", "set_mode", "send_setpoint"] and agent.faults == [0.3]


def test_open_loop_says_why_no_setpoint(tmp_path, capsys):
    """A wall calibration that puts the camera 5 m to the side: every crossing is out of reach, and the
    command says so instead of a bare '0 setpoint(s)'."""
    from tudorvision.cli import main

    text = (SAMPLE / "wall_calibration.yaml").read_text().replace("- [1.0, 0.0, 0.0, 0.0]", "- [1.0, 0.0, 0.0, 5.0]")
    assert "0.0, 5.0]" in text
    cal = tmp_path / "far.yaml"
    cal.write_text(text)
    assert main(["catch", str(SAMPLE), "--calib", str(cal), "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "0 setpoint(s)" in out
    assert "no setpoint: all" in out and "outside the arm's reachable workspace" in out


def test_demo_catches_with_the_wall_camera_calibrated_from_a_disc_sweep(tmp_path, capsys):
    """Issue 18: the agent gets T_base_cam from a simulated disc sweep (calib rgbd-base's perception) with the
    camera where it stands for the throws, not the true transform; it catches about as well as with the truth."""
    base = dict(throws=6, seed=3, render=False, rerun=False, plots=False, cache_dir=str(tmp_path / "cache"))
    s = run_demo(tmp_path / "cal", DemoOptions(**base))
    printed = capsys.readouterr().out
    assert "calibrated from the disc sweep" in printed and "error against the truth" in printed
    cal = s["calibration"]
    assert cal["source"] == "disc sweep" and cal["sweep_camera_offset_m"] < 1e-9
    # calibrated, not copied: a small but non-zero error against the truth (lab side)
    assert 0.0 < cal["position_error_m"] < 0.02 and 0.0 < cal["rotation_error_deg"] < 1.0
    assert 0.0 < cal["error_at_arm_m"] < 0.03
    assert abs(cal["circle_radius_m"] - 0.84) < 0.02
    t = run_demo(tmp_path / "true", DemoOptions(**base, true_calibration=True))
    assert t["calibration"] == {"source": "true"}
    assert s["crossing_workspace"] == t["crossing_workspace"] >= 2        # the same throws
    assert s["caught_in_workspace"] >= t["caught_in_workspace"] - 1
    summary = json.loads((tmp_path / "cal" / "summary.json").read_text())
    for key in ("success_rate", "success_rate_centre", "caught_centre_in_workspace", "rim_contacts_in_workspace",
                "calibration"):
        assert key in summary, key
    assert summary["caught_centre_in_workspace"] >= summary["caught_in_workspace"]
    # one calibration per camera placement: the second run reads it from the cache (memory or cache_dir)
    again = run_demo(tmp_path / "cal2", DemoOptions(**{**base, "throws": 1}))
    assert again["calibration"]["cached"] and again["calibration"]["position_error_m"] == cal["position_error_m"]


def test_calibration_sweep_camera_is_the_throw_camera(tmp_path):
    from tudorvision.lab.catch.calibration import calibrate_wall_camera, wall_camera_position_world
    from tudorvision.lab.catch.scenario import CatchScenario
    from tudorvision.robot import load_robot_params

    p = load_robot_params()
    o = DemoOptions(throws=1, render=False, cache_dir=str(tmp_path), camera_distance_m=5.0, calibration_seed=1,
                    calibration_method="seed+deflection+mirror", calibration_frames_per_pose=8)   # a quarter of the
    # demo's frames (the full sweep: 0.06 deg here; seeds 2 / 3 at 8 frames: 0.14 / 0.08 deg)
    world = CatchScenario(o, p, np.deg2rad([0.0, 90.0, 0.0]))
    np.testing.assert_allclose(world.camera.T_world_cam[:3, 3], wall_camera_position_world(o))
    from tudorvision.lab.catch.run import demo_kinematics

    deflection = demo_kinematics(o, p)[0].deflection
    T, rep = calibrate_wall_camera(o, p, world.T_base_cam, deflection=deflection)
    assert rep["sweep_camera_offset_m"] < 1e-9 and not rep["cached"]
    assert rep["position_error_m"] < 0.02 and rep["rotation_error_deg"] < 1.0
    assert list(tmp_path.glob("wall_calibration_*.json"))              # cached on disk
    # the in-plane refinement against the learnt deflection model removes the lean of the vertical posture
    # (about 0.45 deg) from the seed's construction
    assert rep["method"] == "seed+deflection+mirror"
    assert rep["rotation_error_deg"] < rep["seed_method"]["rotation_error_deg"]
    assert 0.2 < -rep["in_plane_rotation_deg"] < 0.7
    # the sweep's mirror symmetry then corrects what the model left (a few hundredths of a degree to 0.15)
    assert rep["pairs"] == 8 and abs(rep["mirror_rotation_deg"]) < 0.2
    # a camera elsewhere than the throws' is refused (the sweep would calibrate another camera)
    with pytest.raises(ValueError, match="not the throws' camera"):
        calibrate_wall_camera(DemoOptions(throws=1, cache_dir=str(tmp_path / "x"), camera_distance_m=5.2,
                                          calibration_frames_per_pose=1), p, world.T_base_cam, deflection=deflection)
    with pytest.raises(ValueError, match="needs the deflection model"):
        calibrate_wall_camera(o, p, world.T_base_cam)


def test_wall_camera_reaches_the_arm_from_behind_the_thrower(tmp_path):
    """Issue 18: the default wall camera stands behind the thrower's release (6.8 m, releases 5.7-6.3 m in
    front of the base); its depth sensor reaches 8 m with the seed's sigma_z cubic extrapolated (96 mm at
    6.8 m); the disc sweep is measured there (no frame skipped) and calibrates the camera to a few mm."""
    from tudorvision.lab.catch.calibration import wall_depth_sensor
    from tudorvision.lab.catch.run import wall_camera_transform
    from tudorvision.lab.catch.scenario import CatchScenario
    from tudorvision.robot import load_robot_params
    from tudorvision.sensors import KINECT_RANGE_M

    o = DemoOptions(throws=1, render=False, cache_dir=str(tmp_path))
    assert o.camera_distance_m == 6.8 and o.camera_distance_m > 6.3
    sensor = wall_depth_sensor(o)
    assert sensor.max_depth_m == 8.0 and KINECT_RANGE_M == (0.6, 6.0)           # package default unchanged
    assert sensor.noise.sigma_m(6.8) == pytest.approx(0.0959, abs=5e-4)
    p = load_robot_params()
    world = CatchScenario(o, p, np.deg2rad([0.0, 90.0, 0.0]))
    assert world.depth_sensor == sensor
    T, rep = wall_camera_transform(o, p, world.T_base_cam, verbose=False)
    assert rep["cached"]            # the default placement's calibration is shipped (package data), not rendered
    # theta2 10-170 deg 32 frames each, the vertical posture 192, the theta1 sweep 1664 (+-45 deg at theta2 = 45 deg)
    k = o.calibration_frames_per_pose
    assert k == 32 and rep["skipped_frames"] == 0 and rep["frames"] == 17 * k + 6 * k + 52 * k
    assert rep["yaw_frames"] == 52 * k and rep["yaw_skipped_frames"] <= k // 2 and rep["yaw_points_used"] >= 50 * k
    assert rep["yaw_depth_from"] == "kinematics" and 1.0 < rep["yaw_radius_scale"] < 1.1     # the links bend out
    # the depth noise correlated as a real Kinect's: 0.15 deg (0.12 cm at the base, 0.13 cm at the arm), what is left
    # is the heading (about z, harmless to the catch); the theta2 sweep alone (method seed) 0.61 deg
    assert rep["position_error_m"] < 0.01 and rep["rotation_error_deg"] < 0.25 and rep["error_at_arm_m"] < 0.01
    # (with the Kinect's fixed depth pattern calibrated and removed, this draw's theta2 sweep left 0.04 deg of tilt
    # for the theta1 sweep to take out; 0.2-1.0 deg before the pattern)
    assert abs(rep["yaw_tilt_correction_deg"]) < 1.0 and 0.02 < rep["yaw_tilt_std_deg"] < 0.1
    assert rep["rotation_error_deg"] < rep["seed_method"]["rotation_error_deg"] - 0.1     # the lean removed
    assert 0.003 < rep["circle_rmse_m"] < 0.025                 # the 10 cm depth noise at 6.9 m shows
    # the Kinect's fit range alone (6 m) loses the disc at the arm: the sweep cannot be measured there
    from dataclasses import replace
    with pytest.raises(ValueError):
        wall_camera_transform(replace(o, camera_max_depth_m=6.0, calibration_frames_per_pose=1,
                                      cache_dir=str(tmp_path / "b")), p, world.T_base_cam, verbose=False)


def test_cli_demo_plant_and_camera_distance(tmp_path, capsys):
    """``catch demo --plant stiff --camera-distance-m 6.5``: the options reach the demo (summary.json); bad
    values give a one-line error. The placement no calibration is shipped for is calibrated from one depth frame
    per sweep pose (``--calibration-frames 1``: 75 frames instead of 2400)."""
    out = tmp_path / "d"
    assert main(["catch", "demo", "--throws", "1", "--no-render", "--no-rerun", "--plant", "stiff",
                 "--camera-distance-m", "6.5", "--ball-swing-length-m", "0", "--calibration-frames", "1",
                 "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["plant"] == "stiff" and s["camera_position_world_m"][1] == pytest.approx(-6.5)
    assert s["ball_swing_length_m"] == 0.0
    assert s["calibration"]["source"] == "disc sweep" and s["calibration"]["frames"] == 75
    assert main(["catch", "demo", "--throws", "1", "--no-render", "--no-rerun", "--out", str(tmp_path / "e")]) == 0
    s = json.loads((tmp_path / "e" / "summary.json").read_text())
    assert s["plant"] == "seed_measured" and s["camera_position_world_m"][1] == pytest.approx(-6.8)  # defaults
    assert s["ball_swing_length_m"] == 0.1
    capsys.readouterr()
    assert main(["catch", "demo", "--camera-distance-m", "9", "--out", str(tmp_path / "f")]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--camera-distance-m" in err[0] and "1-7.8 m" in err[0]
    assert not (tmp_path / "f").exists()
    assert main(["catch", "demo", "--ball-swing-length-m", "0.9", "--out", str(tmp_path / "g")]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--ball-swing-length-m" in err[0] and "0-0.5 m" in err[0]
    assert not (tmp_path / "g").exists()
    assert main(["catch", "demo", "--yaw-max-deg", "nan", "--out", str(tmp_path / "h")]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--yaw-max-deg" in err[0] and "0-90 deg" in err[0]
    assert main(["catch", "demo", "--calibration-frames", "0", "--out", str(tmp_path / "i")]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--calibration-frames" in err[0] and "1-256" in err[0]
    assert not (tmp_path / "i").exists()
    with pytest.raises(SystemExit):
        main(["catch", "demo", "--plant", "soft"])
    assert "invalid choice: 'soft'" in capsys.readouterr().err
    assert main(["catch", str(tmp_path), "--plant", "stiff"]) != 0
    assert "only with 'catch demo'" in capsys.readouterr().err


def test_frames_reach_the_agent_late_filtered_at_exposure_and_acted_on_at_arrival(tmp_path, capsys):
    """``camera_latency_s``: every setpoint goes out when a frame arrives, ``latency`` after the exposure its
    estimate was filtered at (setpoints.csv against predictions.csv); with no latency they coincide. The CLI's
    ``--camera-latency-ms`` reaches summary.json; a bad value is a one-line error."""
    def times(out):
        pred = [(int(r["throw"]), float(r["t_s"])) for r in csv.DictReader(open(out / "predictions.csv"))]
        sent = [(int(r["throw"]), float(r["t_s"])) for r in csv.DictReader(open(out / "setpoints.csv"))]
        return pred, sent

    def exposed_at(pred, throw, t):     # the CSVs keep times to the microsecond
        return any(th == throw and abs(e - t) < 2e-6 for th, e in pred)

    for latency_ms in (0.0, 67.0):
        out = tmp_path / f"lat{latency_ms:g}"
        assert main(["catch", "demo", "--throws", "3", "--seed", "3", "--no-render", "--no-rerun",
                     "--camera-latency-ms", f"{latency_ms:g}", "--out", str(out)]) == 0
        assert json.loads((out / "summary.json").read_text())["camera_latency_s"] == pytest.approx(latency_ms / 1e3)
        pred, sent = times(out)
        assert sent
        for throw, t in sent:          # each setpoint answers an estimate exposed exactly one latency earlier
            assert exposed_at(pred, throw, t - latency_ms / 1e3)
            if latency_ms:
                assert not exposed_at(pred, throw, t)
    capsys.readouterr()
    assert main(["catch", "demo", "--camera-latency-ms", "-5", "--out", str(tmp_path / "bad")]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--camera-latency-ms" in err[0] and not (tmp_path / "bad").exists()
    with pytest.raises(ValueError, match="camera_latency_s"):
        DemoOptions(camera_latency_s=float("nan"))


def test_frames_late_by_a_jittered_delay_arrive_in_order_within_the_bounds(tmp_path, capsys):
    """``camera_latency_jitter_s``: each setpoint goes out between ``latency`` and ``latency + jitter`` after the
    exposure of the estimate it answers, the delays vary, the run repeats itself on the same seed, and a jitter
    that takes the latency past 0.5 s is a one-line CLI error naming the option."""
    lat_ms, jit_ms = 40.0, 25.0

    def delays(out):
        pred = sorted({(int(r["throw"]), float(r["t_s"])) for r in csv.DictReader(open(out / "predictions.csv"))})
        sent = [(int(r["throw"]), float(r["t_s"])) for r in csv.DictReader(open(out / "setpoints.csv"))]
        found = []
        for throw, t in sent:      # the newest exposure that can have arrived by t
            exposed = [e for th, e in pred if th == throw and e <= t - lat_ms / 1e3 + 1e-9]
            found.append(t - max(exposed))
        return np.array(found)

    runs = []
    for name in ("a", "b"):
        out = tmp_path / name
        assert main(["catch", "demo", "--throws", "6", "--seed", "3", "--no-render", "--no-rerun",
                     "--camera-latency-ms", f"{lat_ms:g}", "--camera-latency-jitter-ms", f"{jit_ms:g}",
                     "--out", str(out)]) == 0
        summary = json.loads((out / "summary.json").read_text())
        assert summary["camera_latency_jitter_s"] == pytest.approx(jit_ms / 1e3)
        runs.append(delays(out))
    d = runs[0]
    assert len(d) >= 3
    assert np.all(d >= lat_ms / 1e3 - 1e-9) and np.all(d <= (lat_ms + jit_ms) / 1e3 + 1e-9)
    assert np.ptp(d) > 1e-3                                    # the delays vary
    np.testing.assert_array_equal(runs[0], runs[1])           # seeded
    capsys.readouterr()
    assert main(["catch", "demo", "--camera-latency-ms", "300", "--camera-latency-jitter-ms", "300",
                 "--out", str(tmp_path / "bad")]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "camera_latency_jitter_s" in err[0] and not (tmp_path / "bad").exists()
