"""The stereo tracking loop end to end on small virtual-lab recordings.

Ground truth is read here to make the picks and to score; the pipeline never
reads it.
"""
from __future__ import annotations

import shutil

import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
from tudorvision.io import open_sequence
from tudorvision.io.frames import StereoFrame
from tudorvision.lab import RecordOptions, record
from tudorvision.stereo import (ColorModelSet, PipelineOptions, StereoPipeline, fit_color_model_set,
                                iter_stereo, track_mono, track_stereo)

SPHERE_RADIUS_M = 0.035


# ----------------------------------------------------------------------------- helpers (also used by the CLI tests)
def gt_transform(seq, row: int = 0) -> np.ndarray:
    """Row of groundtruth/transforms.csv as a 4x4 (0: T_base_left, 1: T_base_right)."""
    tr = seq.groundtruth("transforms")
    return np.array([[tr[f"m{i}{j}"][row] for j in range(4)] for i in range(4)])


def gt_picks(seq, k: int = 0, radius_factor: float = 0.9) -> list[str]:
    """``--pick`` strings at the true silhouette centroids of frame k, edge at 0.9 of the true radius."""
    gt = seq.groundtruth("ee")
    T_base = {"left": gt_transform(seq, 0), "right": gt_transform(seq, 1)}
    picks = []
    for cam in ("left", "right"):
        fx = seq.calibration.camera(cam).fx
        for s in ("red", "green"):
            p_base = np.array([gt[f"{s}_x_m"][k], gt[f"{s}_y_m"][k], gt[f"{s}_z_m"][k], 1.0])
            z = (np.linalg.inv(T_base[cam]) @ p_base)[2]
            r = radius_factor * fx * SPHERE_RADIUS_M / z
            u, v = gt[f"{cam}_{s}_u_px"][k], gt[f"{cam}_{s}_v_px"][k]
            picks.append(f"{cam}:{s}:{u:.3f},{v:.3f}:{u + r:.3f},{v:.3f}")
    return picks


def good_picks(seq, k: int = 0) -> list[str]:
    """Picks at the true centroids with the largest edge radius (0.9, 0.75, 0.6 of the true radius)
    whose circle is one colour, as a user would re-pick a circle that caught the arm or the shading."""
    from tudorvision.stereo import fit_color_model, parse_pick
    f = seq[k]
    chosen = []
    tries = [gt_picks(seq, k, fac) for fac in (0.9, 0.75, 0.6)]
    for i in range(4):
        for picks in tries:
            cam, _, c, e = parse_pick(picks[i])
            try:
                fit_color_model(getattr(f, cam), c, e)
            except TudorVisionError:
                continue
            chosen.append(picks[i])
            break
        else:
            chosen.append(tries[-1][i])
    return chosen


def gt_ee(seq) -> np.ndarray:
    gt = seq.groundtruth("ee")
    return np.column_stack([gt["ee_x_m"], gt["ee_y_m"], gt["ee_z_m"]])


def gt_uv(seq, cam: str, sphere: str) -> np.ndarray:
    gt = seq.groundtruth("ee")
    return np.column_stack([gt[f"{cam}_{sphere}_u_px"], gt[f"{cam}_{sphere}_v_px"]])


def models_for(seq, k: int = 0) -> ColorModelSet:
    f = seq[k]
    return fit_color_model_set({"left": f.left, "right": f.right}, good_picks(seq, k))


@pytest.fixture(scope="module")
def static_seq_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("stereo_static") / "seq"
    record("stereo-static", out, RecordOptions(seed=2, frames=5, image_ext=".png", show_progress=False))
    return out


@pytest.fixture(scope="module")
def static_run(static_seq_dir):
    seq = open_sequence(static_seq_dir)
    models = models_for(seq)
    res = track_stereo(seq, seq.calibration, models, T_base_left=gt_transform(seq), keep_results=True)
    return seq, models, res


# ----------------------------------------------------------------------------- accuracy
def test_static_end_to_end_accuracy(static_run):
    seq, _, res = static_run
    traj = res.trajectory
    assert traj.frame == "base"
    assert traj.valid.all()
    err = np.linalg.norm(traj.p - gt_ee(seq), axis=1)
    # measured on this recording (PNG, seed 2): 0.2-0.7 mm
    assert np.sqrt(np.mean(err ** 2)) < 1.5e-3, err
    assert err.max() < 3.0e-3, err


def test_static_centroids(static_run):
    seq, _, res = static_run
    errs = []
    for cam, uv in (("left", res.uv_left), ("right", res.uv_right)):
        for s in ("red", "green"):
            errs.append(np.linalg.norm(uv[s] - gt_uv(seq, cam, s), axis=1))
    errs = np.concatenate(errs)
    assert np.isfinite(errs).all()
    # measured: median 0.1 px, max 0.31 px; spheres partly hidden behind the arm reach about
    # 1 px on other seeds (the lab's truth is the unoccluded silhouette centroid)
    assert np.median(errs) < 0.25, errs
    assert errs.max() < 1.0, errs


def test_left_frame_without_base_transform(static_run):
    seq, models, res = static_run
    left = track_stereo(seq, seq.calibration, models)
    assert left.trajectory.frame == "left"
    T = gt_transform(seq)
    p_base = left.trajectory.p @ T[:3, :3].T + T[:3, 3]
    np.testing.assert_allclose(p_base, res.trajectory.p, atol=1e-9)
    # the left optical frame looks forward: z is the depth, about 3-4 m in the lab
    assert np.all((left.trajectory.p[:, 2] > 2.0) & (left.trajectory.p[:, 2] < 6.0))


def test_full_frame_mode_agrees_with_tracking(static_run):
    seq, models, res = static_run
    full = track_stereo(seq, seq.calibration, models, T_base_left=gt_transform(seq),
                        options=PipelineOptions(tracking=False))
    np.testing.assert_allclose(full.trajectory.p, res.trajectory.p, atol=1e-4)


def test_per_frame_results_and_stats(static_run):
    seq, _, res = static_run
    assert [r.index for r in res.results] == list(range(len(seq)))
    assert res.stats.processed == res.stats.valid == len(seq)
    assert res.stats.skipped == 0 and res.stats.fps > 0
    assert "100.0% valid" in res.stats.summary()
    assert set(res.stats.checks) == {"pairs off the epipolar line", "of them re-paired from other regions",
                                     "views measured again on their luma rim", "views measured again for their radius",
                                     "spheres refused for their radius"}
    assert all(isinstance(n, int) and n >= 0 for n in res.stats.checks.values())
    r0 = res.results[0]
    assert r0.valid and set(r0.detections) == {"left", "right"}
    np.testing.assert_allclose(r0.ee, 0.5 * (r0.spheres["red"] + r0.spheres["green"]))


# ----------------------------------------------------------------------------- missing data
class _Frames:
    """A minimal in-memory stereo sequence (what iter_stereo/track_stereo need)."""

    kind = "stereo"
    rate_hz = 50.0

    def __init__(self, frames):
        self.frames = frames
        self.timestamps = np.array([f.t for f in frames])

    def __len__(self):
        return len(self.frames)

    def load_or_report(self, i):
        return self.frames[i]

    def play(self, *, speed=1.0, clock=None, sleep=None):
        from tudorvision.io import Playback
        return Playback(self, speed=speed, clock=clock, sleep=sleep)


def _hide_sphere(img, uv, radius=14):
    import cv2
    out = img.copy()
    cv2.circle(out, (int(round(uv[0])), int(round(uv[1]))), radius, (128, 128, 128), -1)
    return out


def test_sphere_missing_in_one_camera_gives_nan_row(static_run):
    seq, models, _ = static_run
    frames = list(seq)
    k = 2
    right = _hide_sphere(frames[k].right, gt_uv(seq, "right", "red")[k])
    frames[k] = StereoFrame(t=frames[k].t, index=k, left=frames[k].left, right=right)
    res = track_stereo(_Frames(frames), seq.calibration, models, keep_results=True)
    valid = res.trajectory.valid
    assert not valid[k] and valid[np.arange(len(frames)) != k].all()
    assert np.isnan(res.trajectory.p[k]).all()
    # the red sphere is missing in the right image only: no 3D point from the left view alone
    tri = res.triangulation
    assert not tri.sphere_valid["red"][k] and tri.sphere_valid["green"][k]
    assert np.isnan(tri.spheres["red"][k]).all()
    assert not res.results[k].detections["right"]["red"].valid
    assert res.results[k].detections["left"]["red"].valid


def test_corrupt_frame_skipped_and_counted(static_seq_dir, tmp_path):
    d = tmp_path / "seq"
    shutil.copytree(static_seq_dir, d)
    (d / "left" / "000001.png").write_bytes(b"not a png")
    seq = open_sequence(d, strict=False)
    ref = open_sequence(static_seq_dir)
    res = track_stereo(seq, seq.calibration, models_for(ref), T_base_left=gt_transform(ref))
    assert res.stats.skipped == 1 and res.stats.processed == len(seq) - 1
    assert list(res.index) == [0, 2, 3, 4]
    np.testing.assert_allclose(res.t, ref.timestamps[[0, 2, 3, 4]])
    assert res.trajectory.valid.all()
    assert len(seq.report) == 1 and "000001.png" in str(seq.report[0])
    strict = open_sequence(d)
    with pytest.raises(TudorVisionError, match="000001.png"):
        track_stereo(strict, strict.calibration, models_for(ref))


def test_live_playback_drops_frames_and_reports_latency(static_run):
    seq, models, _ = static_run
    frames = list(seq) * 4                       # 20 frames at 50 Hz
    frames = [StereoFrame(t=k / 50.0, index=k, left=f.left, right=f.right) for k, f in enumerate(frames)]
    now = [0.0]

    def clock():                                 # every look at the clock costs 15 ms: slower than 50 Hz
        now[0] += 0.015
        return now[0]

    res = track_stereo(_Frames(frames), seq.calibration, models, live=True, clock=clock,
                       sleep=lambda s: now.__setitem__(0, now[0] + s), keep_results=True)
    st = res.stats
    assert st.dropped > 0
    assert st.processed + st.dropped == len(frames)
    assert all(np.isfinite(r.latency_s) and r.latency_s >= 0 for r in res.results)
    assert sum(r.dropped for r in res.results) == st.dropped
    assert st.max_latency_s >= st.mean_latency_s > 0
    assert "dropped" in st.summary() and "latency" in st.summary()
    assert res.trajectory.valid.all()


# ----------------------------------------------------------------------------- bad input
def test_image_size_must_match_calibration(static_run):
    import cv2
    seq, models, _ = static_run
    pipe = StereoPipeline(seq.calibration, models)
    f = seq[0]
    small = StereoFrame(t=0.0, index=0, left=cv2.resize(f.left, (320, 240)), right=cv2.resize(f.right, (320, 240)))
    with pytest.raises(TudorVisionError, match="320x240.*calibration's left camera is 640x480"):
        pipe.process(small)


def test_models_need_both_cameras(static_run):
    seq, models, _ = static_run
    left_only = ColorModelSet({"left": dict(models.for_camera("left"))})
    with pytest.raises(TudorVisionError, match="no models for the right camera"):
        StereoPipeline(seq.calibration, left_only)
    with pytest.raises(TudorVisionError, match="stereo sequence"):
        list(iter_stereo(type("S", (), {"kind": "rgbd", "path": "x"})(), StereoPipeline(seq.calibration, models)))


def test_color_model_that_finds_nothing_flags_frames(static_run):
    import cv2
    from tudorvision.stereo import fit_color_model
    seq, _, _ = static_run
    img = np.full((480, 640, 3), 90, np.uint8)
    cv2.circle(img, (320, 240), 10, (230, 40, 200), -1)     # a magenta disc: nothing like it in the lab
    m = fit_color_model(img, (320, 240), (330, 240))
    models = ColorModelSet({"left": {"red": m, "green": m}, "right": {"red": m, "green": m}})
    res = track_stereo(seq, seq.calibration, models)
    assert res.stats.processed == len(seq) and res.stats.valid == 0
    assert not res.trajectory.valid.any() and np.isnan(res.trajectory.p).all()


# ----------------------------------------------------------------------------- mono
def test_track_mono_on_left_stream(static_seq_dir, tmp_path):
    from tudorvision.io import SequenceWriter
    seq = open_sequence(static_seq_dir)
    models = models_for(seq)
    with SequenceWriter(tmp_path / "mono", kind="mono", rate_hz=50.0, image_ext=".png") as w:
        for f in seq:
            w.add_mono(f.t, f.left)
    mono = open_sequence(tmp_path / "mono")
    res = track_mono(mono, models.get("left", "green"))
    assert res.valid.all() and list(res.frame) == list(range(len(seq)))
    err = np.linalg.norm(res.uv - gt_uv(seq, "left", "green"), axis=1)
    assert np.median(err) < 0.3, err
    with pytest.raises(TudorVisionError, match="mono"):
        track_mono(seq, models.get("left", "green"))


# ----------------------------------------------------------------------------- stereo consistency
def _parallel_rig_scene(decoy: bool):
    import cv2
    from tudorvision.io import Calibration, CameraModel, StereoExtrinsics
    from tudorvision.stereo import fit_color_model
    cam = CameraModel(K=[[500, 0, 160], [0, 500, 120], [0, 0, 1]], width=320, height=240)
    cal = Calibration(cameras={"left": cam, "right": cam},
                      stereo=StereoExtrinsics(R=np.eye(3), T=[-0.2, 0.0, 0.0]))
    imgs, models = {}, {}
    for name, du in (("left", 0), ("right", -50)):
        img = np.full((240, 320, 3), 90, np.uint8)
        cv2.circle(img, (140 + du, 120), 8, (40, 40, 200), -1)
        cv2.circle(img, (180 + du, 120), 8, (50, 190, 40), -1)
        models[name] = {"red": fit_color_model(img, (140 + du, 120), (147 + du, 120)),
                        "green": fit_color_model(img, (180 + du, 120), (187 + du, 120))}
        if decoy and name == "right":      # a bigger green look-alike, far off the epipolar line
            cv2.circle(img, (250, 40), 11, (50, 190, 40), -1)
        imgs[name] = img
    return cal, ColorModelSet(models), StereoFrame(t=0.0, index=0, left=imgs["left"], right=imgs["right"])


def test_epipolar_check_rejects_a_look_alike():
    cal, models, frame = _parallel_rig_scene(decoy=True)
    naive = StereoPipeline(cal, models, options=PipelineOptions(max_epipolar_px=None, tracking=False))
    r = naive.process(frame)
    assert r.detections["right"]["green"].uv[1] == pytest.approx(40, abs=0.5)     # the decoy wins alone
    pipe = StereoPipeline(cal, models, options=PipelineOptions(tracking=False))
    r = pipe.process(frame)
    assert r.valid and pipe.n_inconsistent == 1 and pipe.n_repaired == 1
    np.testing.assert_allclose(r.spheres["green"], [0.08, 0.0, 2.0], atol=1e-6)
    np.testing.assert_allclose(r.ee, [0.0, 0.0, 2.0], atol=1e-6)
    assert pipe.epipolar_px([[180.0, 120.0]], [[250.0, 40.0]])[0] == pytest.approx(80.0, abs=0.5)


def test_sphere_separation_check_flags_the_frame():
    cal, models, frame = _parallel_rig_scene(decoy=False)
    ok = StereoPipeline(cal, models, options=PipelineOptions(sphere_separation_m=0.16)).process(frame)
    assert ok.valid
    bad = StereoPipeline(cal, models, options=PipelineOptions(sphere_separation_m=0.30)).process(frame)
    assert not bad.valid and np.isnan(bad.ee).all()
    assert "separation" in bad.detections["left"]["red"].reason
    with pytest.raises(TudorVisionError, match="sphere_separation_m"):
        PipelineOptions(sphere_separation_m=-1.0)


def test_summary_names_the_stereo_checks_that_did_something():
    from tudorvision.stereo.tracking import TrackStats
    st = TrackStats(frames_total=10, processed=10, valid=9, wall_s=1.0)
    assert "stereo checks" not in st.summary()
    st.checks = {"views measured again on their luma rim": 3, "spheres refused for their radius": 0}
    assert st.summary().endswith("; stereo checks: 3 views measured again on their luma rim")
