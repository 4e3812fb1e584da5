"""Virtual-lab recordings: determinism, readability, and ground truth consistent with the rendered images."""
import hashlib

import numpy as np
import pytest

from tudorvision.io import open_sequence
from tudorvision.robot import load_robot_params
from tudorvision.lab.record import KINDS, RecordOptions, elastic_arm_geometry, record, static_arm_state, \
    throw_trajectory
from tudorvision.sim.arm import Payload, fk_elastic


def _digest(root):
    h = hashlib.sha256()
    for f in sorted(p for p in root.rglob("*") if p.is_file()):
        h.update(f.relative_to(root).as_posix().encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def test_same_seed_same_files_other_seed_other_files(tmp_path):
    a = record("servo-views", tmp_path / "a", RecordOptions(seed=3, frames=2))
    b = record("servo-views", tmp_path / "b", RecordOptions(seed=3, frames=2))
    c = record("servo-views", tmp_path / "c", RecordOptions(seed=4, frames=2))
    assert _digest(a) == _digest(b)
    assert _digest(a) != _digest(c)


def test_stereo_static_truth_matches_rendered_spheres(tmp_path):
    out = record("stereo-static", tmp_path / "s", RecordOptions(seed=1, frames=3, image_ext=".png"))
    seq = open_sequence(out)
    assert seq.kind == "stereo" and len(seq) == 3
    gt = seq.groundtruth("ee")
    cal = seq.calibration
    assert cal.stereo is not None and abs(cal.stereo.baseline_m - 3.0) < 0.1
    for i, frame in enumerate(seq):
        for cam, img in (("left", frame.left), ("right", frame.right)):
            u, v = gt[f"{cam}_red_u_px"][i], gt[f"{cam}_red_v_px"][i]
            if not (5 < u < 635 and 5 < v < 475):
                continue
            b, g, r = (img[int(round(v)), int(round(u))].astype(int))
            assert r > g + 30 and r > b + 30, f"frame {i} {cam}: no red sphere at the true centroid"
    # joints and the end-effector truth agree with the plant's static deflection
    j = seq.joints()
    p = load_robot_params()
    th = j.theta_rad[0]
    tip2, tip3 = static_arm_state(th, Payload.from_parts(p, camera=True), p)
    ee = fk_elastic(th, tip2, tip3, p)[:3, 3]
    assert np.allclose(ee, [gt["ee_x_m"][0], gt["ee_y_m"][0], gt["ee_z_m"][0]], atol=1e-9)


def test_rgbd_plane_depth_is_the_true_distance(tmp_path):
    out = record("rgbd-plane", tmp_path / "p", RecordOptions(seed=2, frames=3, small=True))
    subs = sorted(p for p in out.iterdir() if p.is_dir())
    assert len(subs) == 4
    seq = open_sequence(subs[1])
    d = seq.groundtruth("target")["distance_m"][0]
    fr = seq[0]
    h, w = fr.depth_m.shape
    centre = fr.depth_m[h // 2 - 20:h // 2 + 20, w // 2 - 20:w // 2 + 20]
    assert abs(np.nanmedian(centre) - d) < 0.02


def test_elastic_geometry_ends_at_the_deflected_end_effector():
    p = load_robot_params()
    th = np.deg2rad([20.0, 30.0, 40.0])
    tip2, tip3 = static_arm_state(th, Payload.from_parts(p, plates=3), p)
    g = elastic_arm_geometry(th, tip2, tip3, p)
    assert np.allclose(g.link_points_base[1][-1], fk_elastic(th, tip2, tip3, p)[:3, 3])
    assert np.allclose(g.link_points_base[0][-1], g.link_points_base[1][0])
    # gravity pulls the elbow down relative to the rigid arm
    rigid_elbow_z = p.link1_height_m + p.link2_length_m * np.sin(th[1])
    assert g.link_points_base[0][-1][2] < rigid_elbow_z


def test_throw_trajectory_matches_drag_free_parabola_and_slows_with_drag():
    t, pos, v = throw_trajectory([0, 0, 1.5], [0.0, 6.0, 3.0], drag_k_per_m=0.0, duration_s=1.0)
    expect = np.column_stack([0 * t, 6.0 * t, 1.5 + 3.0 * t - 0.5 * 9.81 * t ** 2])
    assert np.allclose(pos, expect, atol=1e-9)
    _, pos_d, v_d = throw_trajectory([0, 0, 1.5], [0.0, 6.0, 3.0], drag_k_per_m=0.012, duration_s=1.0)
    assert pos_d[-1, 1] < pos[-1, 1] and np.linalg.norm(v_d[-1]) < np.linalg.norm(v[-1])


def test_unknown_kind_is_a_clear_error(tmp_path):
    from tudorvision.cli import main
    with pytest.raises(ValueError, match="unknown recording kind"):
        record("stereo-dance", tmp_path / "x")
    assert main(["sim", "record", "stereo-dance", "--out", str(tmp_path / "x")]) == 2
    assert set(KINDS) >= {"stereo-step", "stereo-sweep", "stereo-checkerboard", "rgbd-plane", "rgbd-disc",
                          "rgbd-throws", "servo-views"}
