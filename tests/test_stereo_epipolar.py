"""Epipolar-consistent centres: the weighted correction against a constrained-minimisation oracle,
distortion round trips, and the pipeline's use of it (parallel rig, one view moved off its row)."""
import cv2
import numpy as np
import pytest
from scipy.optimize import least_squares

from tudorvision.geometry import invert_transform, make_frame, transform_points
from tudorvision.io import Calibration, CameraModel, StereoExtrinsics
from tudorvision.io.frames import StereoFrame
from tudorvision.stereo import ColorModelSet, PipelineOptions, StereoPipeline, fit_color_model
from tudorvision.stereo.epipolar import consistent_centres, normalised_to_pixels, epipolar_correction
from tudorvision.stereo.triangulate import StereoRig, triangulate_stereo

K = np.array([[900.0, 0.0, 319.5], [0.0, 880.0, 239.5], [0.0, 0.0, 1.0]])
DIST_L = np.array([-0.2, 0.06, 3e-4, -2e-4, 0.0])
DIST_R = np.array([-0.18, 0.05, -1e-4, 4e-4, 0.0])


def _pose(pos, target=(0.0, 0.0, 0.5)):
    z = np.asarray(target, float) - np.asarray(pos, float)
    return make_frame(np.asarray(pos, float), z, np.cross(z, [0.0, 0.0, 1.0]))


T_BASE_L, T_BASE_R = _pose([-1.2, -2.5, 2.0]), _pose([1.0, -2.7, 2.3])


def _rig():
    T_rl = invert_transform(T_BASE_R) @ T_BASE_L
    cal = Calibration(cameras={"left": CameraModel(K=K, dist=DIST_L, width=640, height=480),
                               "right": CameraModel(K=K, dist=DIST_R, width=640, height=480)},
                      stereo=StereoExtrinsics(R=T_rl[:3, :3], T=T_rl[:3, 3]))
    return cal, StereoRig(cal)


def _project(p_base, T_base_cam, dist):
    p = transform_points(invert_transform(T_base_cam), p_base)
    uv, _ = cv2.projectPoints(p.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, dist)
    return uv.reshape(-1, 2)


def _views(rng, n):
    """``n`` random workspace points (base frame) and their exact raw pixels in both cameras."""
    X = rng.uniform([-0.4, -0.4, 0.2], [0.4, 0.4, 1.0], size=(n, 3))
    return X, _project(X, T_BASE_L, DIST_L), _project(X, T_BASE_R, DIST_R)


def _skew(t):
    return np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])


@pytest.mark.parametrize("seed", range(4))
def test_weighted_correction_matches_a_constrained_minimisation_oracle(seed):
    rng = np.random.default_rng(seed)
    R = cv2.Rodrigues(rng.normal(scale=0.3, size=3))[0]
    T = rng.normal(size=3)
    E = _skew(T) @ R
    fl, fr = rng.uniform(500, 1500, 2)
    X = rng.uniform([-0.5, -0.5, 2.0], [0.5, 0.5, 4.0], size=(6, 3))
    xl = X[:, :2] / X[:, 2:] + rng.normal(scale=1.5 / fl, size=(6, 2))
    Xr = X @ R.T + T
    xr = Xr[:, :2] / Xr[:, 2:] + rng.normal(scale=1.5 / fr, size=(6, 2))
    sl, sr = rng.uniform(0.5, 3.0, 6), rng.uniform(0.5, 3.0, 6)
    cl, cr = epipolar_correction(xl, xr, E, fl, fr, sl, sr)
    for i in range(6):
        # oracle: the 3D point of least weighted reprojection error (unconstrained, scipy); its two
        # projections are the optimal consistent pair
        def resid(P, i=i):
            pr = R @ P + T
            return np.r_[(P[:2] / P[2] - xl[i]) * fl / sl[i], (pr[:2] / pr[2] - xr[i]) * fr / sr[i]]
        P = least_squares(resid, X[i], xtol=1e-15, ftol=1e-15, gtol=1e-15).x
        pr = R @ P + T
        np.testing.assert_allclose(fl * cl[i], fl * P[:2] / P[2], atol=1e-6)
        np.testing.assert_allclose(fr * cr[i], fr * pr[:2] / pr[2], atol=1e-6)
    res = np.einsum("ij,jk,ik->i", np.c_[cr, np.ones(6)], E, np.c_[cl, np.ones(6)])
    assert np.abs(res).max() < 1e-12
    assert np.abs(fl * (cl - xl)).max() > 0.05      # the noise really needed a correction


def test_consistent_centres_meet_through_the_distortion_and_follow_the_weights():
    cal, rig = _rig()
    rng = np.random.default_rng(7)
    _, uv_l, uv_r = _views(rng, 20)
    noisy_r = uv_r + rng.normal(scale=1.0, size=uv_r.shape)
    assert np.median(rig.epipolar_px(uv_l, noisy_r)) > 0.3
    # a near-certain left view: the right one alone moves, onto the left's epipolar line
    cl, cr, moved = consistent_centres(rig, uv_l, noisy_r, 1e-4, 1.0)
    assert moved.all()
    assert rig.epipolar_px(cl, cr).max() < 1e-6
    assert np.abs(cl - uv_l).max() < 1e-4
    # the move takes out the error across the line, so the right centres come nearer the truth
    assert np.linalg.norm(cr - uv_r, axis=1).mean() < 0.85 * np.linalg.norm(noisy_r - uv_r, axis=1).mean()
    # the triangulated points of an already consistent pair do not move
    cl2, cr2, _ = consistent_centres(rig, uv_l, uv_r, 1.0, 2.0)
    np.testing.assert_allclose(cl2, uv_l, atol=1e-6)
    np.testing.assert_allclose(cr2, uv_r, atol=1e-6)
    np.testing.assert_allclose(triangulate_stereo(cl2, cr2, cal), triangulate_stereo(uv_l, uv_r, cal), atol=1e-9)
    # pairs beyond the tolerance are left as measured
    far_r = noisy_r.copy()
    far_r[:5, 1] += 12.0                      # far off the epipolar lines (the rig is not parallel)
    cl3, cr3, moved3 = consistent_centres(rig, uv_l, far_r, 1.0, 1.0, max_epipolar_px=6.0)
    epi = rig.epipolar_px(uv_l, far_r)
    np.testing.assert_array_equal(moved3, epi <= 6.0)
    assert not moved3[:5].all() and moved3[5:].all()
    np.testing.assert_array_equal(cr3[~moved3], far_r[~moved3])


def test_weighted_centres_are_nearer_the_truth_on_average():
    """Seeded property: with one view twice as noisy, the corrected centres and points beat the raw ones."""
    cal, rig = _rig()
    rng = np.random.default_rng(8)
    X, uv_l, uv_r = _views(rng, 400)
    nl = uv_l + rng.normal(scale=0.25, size=uv_l.shape)
    nr = uv_r + rng.normal(scale=0.5, size=uv_r.shape)
    cl, cr, _ = consistent_centres(rig, nl, nr, 1.0, 2.0)
    raw_err = np.r_[np.linalg.norm(nl - uv_l, axis=1), np.linalg.norm(nr - uv_r, axis=1)]
    new_err = np.r_[np.linalg.norm(cl - uv_l, axis=1), np.linalg.norm(cr - uv_r, axis=1)]
    assert np.median(new_err) < 0.9 * np.median(raw_err)
    truth = transform_points(invert_transform(T_BASE_L), X)
    e_raw = np.linalg.norm(triangulate_stereo(nl, nr, cal) - truth, axis=1)
    e_new = np.linalg.norm(triangulate_stereo(cl, cr, cal) - truth, axis=1)
    assert np.sqrt(np.mean(e_new ** 2)) < np.sqrt(np.mean(e_raw ** 2))


def _parallel_scene(dv_right: float):
    """Parallel cameras 0.2 m apart; a red and a green disc 2 m ahead, the right image's red disc ``dv`` lower."""
    cam = CameraModel(K=[[500, 0, 160], [0, 500, 120], [0, 0, 1]], width=320, height=240)
    cal = Calibration(cameras={"left": cam, "right": cam}, stereo=StereoExtrinsics(R=np.eye(3), T=[-0.2, 0.0, 0.0]))
    imgs, models = {}, {}
    for name, du in (("left", 0), ("right", -50)):
        img = np.full((240, 320, 3), 90, np.uint8)
        shift = 16 if name == "right" else 0
        # drawn at 16x sub-pixel precision: a 2 px move of the red disc's centre in the right view
        cv2.circle(img, ((140 + du) * 16, 120 * 16 + int(round(dv_right * 16)) * (name == "right")), 10 * 16,
                   (40, 40, 200), -1, cv2.LINE_AA, shift=4)
        cv2.circle(img, ((180 + du) * 16, 120 * 16), 10 * 16, (50, 190, 40), -1, cv2.LINE_AA, shift=4)
        del shift
        models[name] = {"red": fit_color_model(img, (140 + du, 120), (149 + du, 120)),
                        "green": fit_color_model(img, (180 + du, 120), (189 + du, 120))}
        imgs[name] = img
    return cal, ColorModelSet(models), StereoFrame(t=0.0, index=0, left=imgs["left"], right=imgs["right"])


def test_pipeline_moves_both_views_onto_one_row_and_keeps_the_view_centres():
    cal, models, frame = _parallel_scene(2.0)
    raw = StereoPipeline(cal, models, options=PipelineOptions(tracking=False, epipolar_centres=False)).process(frame)
    got = StereoPipeline(cal, models, options=PipelineOptions(tracking=False)).process(frame)
    vl, vr = raw.detections["left"]["red"].uv, raw.detections["right"]["red"].uv
    assert vr[1] - vl[1] == pytest.approx(2.0, abs=0.1)            # the views disagree by 2 px across the rows
    dl, dr = got.detections["left"]["red"], got.detections["right"]["red"]
    assert dl.uv_view == pytest.approx(vl, abs=1e-9) and dr.uv_view == pytest.approx(vr, abs=1e-9)
    assert dl.uv[1] == pytest.approx(dr.uv[1], abs=1e-6)            # one row: parallel epipolar lines
    assert dl.uv[0] == pytest.approx(vl[0], abs=1e-6) and dr.uv[0] == pytest.approx(vr[0], abs=1e-6)
    # both on the colour, equal weights: each view moves half way
    assert dl.uv[1] == pytest.approx(0.5 * (vl[1] + vr[1]), abs=1e-6)
    assert np.isnan(raw.detections["left"]["red"].uv_view).all()
    # the green pair was consistent already: it stays where it was measured
    assert got.detections["right"]["green"].uv == pytest.approx(raw.detections["right"]["green"].uv, abs=1e-3)
    # the point is the triangulation of the moved centres
    np.testing.assert_allclose(got.spheres["red"], triangulate_stereo([dl.uv], [dr.uv], cal)[0], atol=1e-12)


@pytest.mark.parametrize("n_coef", [0, 4, 5, 8])
def test_distortion_matches_opencv_projection(n_coef):
    rng = np.random.default_rng(20 + n_coef)
    Kc = np.array([[910.0, 0.0, 322.0], [0.0, 890.0, 241.0], [0.0, 0.0, 1.0]])
    d = rng.normal(scale=[0.2, 0.05, 1e-3, 1e-3, 0.01, 0.05, 0.01, 0.005][:n_coef])
    x = rng.uniform(-0.4, 0.4, size=(50, 2))
    want, _ = cv2.projectPoints(np.c_[x, np.ones(50)].reshape(-1, 1, 3), np.zeros(3), np.zeros(3), Kc, d)
    np.testing.assert_allclose(normalised_to_pixels(x, Kc, d), want.reshape(-1, 2), atol=1e-9)
