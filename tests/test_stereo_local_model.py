"""Local colour models: a sphere on a frame that holds its colour elsewhere (issue 15).

Oracle scenes: a supersampled, shaded red sphere (exact centre known) on a
grey frame whose far parts are covered by patches of the sphere's own
shades. The global model (background over the whole frame) cannot single the
sphere out there and refuses the pick; the local fallback (background
sampled around the pick) accepts it, says so (``is_local``), finds the
sphere within half a pixel, and searches only its window, so a look-alike
elsewhere is never taken. A sphere whose colour runs on into its
surroundings, and a pick on a patch, are still refused.
"""
from __future__ import annotations

import numpy as np
import pytest

from test_stereo_segment_scenes import RED_BGR, sphere_patch
from tudorvision._checks import TudorVisionError
from tudorvision.stereo import ColorModelSet, SegmentParams, detect_sphere
from tudorvision.stereo.colormodel import fit_color_model, load_color_models, save_color_models
from tudorvision.stereo.tracker2d import SphereTracker

W, H, R = 640, 480, 9.0
SPHERE_UV = (200.3, 150.7)


def red_patches(img, rng, keep_out, n=40):
    """Rectangles in shades of the sphere's red (0.35 to 1.0 of its colour) away from ``keep_out`` (u, v, r)."""
    placed = 0
    while placed < n:
        w, h = rng.integers(20, 60, 2)
        x, y = rng.integers(0, W - w), rng.integers(0, H - h)
        u, v, r = keep_out
        if x - r < u < x + w + r and y - r < v < y + h + r:
            continue
        img[y:y + h, x:x + w] = rng.uniform(0.35, 1.0) * np.float32(RED_BGR)
        placed += 1


def scene(rng, *, uv=SPHERE_UV, keep=4.5 * R, lookalike=None, extra=None):
    """uint8 frame: grey, red patches farther than ``keep`` from the sphere, the shaded sphere, noise."""
    img = np.full((H, W, 3), 90.0, np.float32)
    red_patches(img, np.random.default_rng(3), (uv[0], uv[1], keep))
    if extra is not None:
        extra(img)
    sphere_patch(uv, R, RED_BGR, img)
    if lookalike is not None:
        sphere_patch(lookalike, R, RED_BGR, img)
    img += rng.normal(0.0, 2.0, img.shape).astype(np.float32)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


PICK = ((200, 151), (207, 151))   # centre, and an edge pixel at about 80 % of the radius


def test_global_model_refuses_and_local_model_finds_the_sphere():
    img = scene(np.random.default_rng(0))
    with pytest.raises(TudorVisionError, match="does not single out the picked sphere"):
        fit_color_model(img, *PICK, local_fallback=False)
    m = fit_color_model(img, *PICK)
    assert m.is_local and m.local_radius_px == pytest.approx(max(4 * 7.0, 7.0 + 12))
    # the global search would be lost among the patches; the local one covers the window around the pick
    frame = scene(np.random.default_rng(1))
    det = detect_sphere(frame, m)
    assert det.valid
    assert np.hypot(det.uv[0] - SPHERE_UV[0], det.uv[1] - SPHERE_UV[1]) < 0.5
    x, y, w, h = m.local_roi(None, W, H)
    assert (x, y, w, h) == (200 - 28, 151 - 28, 57, 57)


def test_a_global_model_is_not_local():
    img = scene(np.random.default_rng(0), extra=None)
    clean = np.full_like(img, 90)
    sphere = np.full((H, W, 3), 90.0, np.float32)
    sphere_patch(SPHERE_UV, R, RED_BGR, sphere)
    clean[:] = np.clip(np.rint(sphere + np.random.default_rng(2).normal(0, 2, sphere.shape)), 0, 255)
    m = fit_color_model(clean, *PICK)
    assert not m.is_local and m.local_roi(None, W, H) is None


def test_tracker_follows_the_sphere_and_ignores_a_lookalike_outside_the_window():
    m = fit_color_model(scene(np.random.default_rng(0)), *PICK)
    assert m.is_local
    trk = SphereTracker(m)
    rng = np.random.default_rng(4)
    lookalike = (520.4, 380.2)
    for k in range(6):           # the sphere moves 4 px per frame; a same-coloured sphere sits far away
        uv = (SPHERE_UV[0] + 4.0 * k, SPHERE_UV[1] + 1.5 * k)
        det = trk.update(scene(rng, uv=uv, lookalike=lookalike))
        assert det.valid, det.reason
        assert np.hypot(det.uv[0] - uv[0], det.uv[1] - uv[1]) < 0.5
    assert trk.anchor == pytest.approx(det.uv)
    # lost (the sphere leaves): the look-alike, outside the window around the last position, is not taken
    last = trk.anchor
    for _ in range(2):
        det = trk.update(scene(rng, uv=(-50.0, -50.0), lookalike=lookalike))
        assert not det.valid and "local colour model" in det.reason
        assert trk.mode == "full" and trk.anchor == last


@pytest.mark.parametrize("gap", [2.0, 2.6])
def test_twin_sphere_beside_it_is_refused(gap):
    """A sphere of the same colour touching or close beside it: its shades are the background near the pick."""
    twin = (SPHERE_UV[0] + gap * R, SPHERE_UV[1] + 0.3)
    img = scene(np.random.default_rng(0), lookalike=twin)
    with pytest.raises(TudorVisionError, match="does not single out the picked sphere .*nor in its neighbourhood"):
        fit_color_model(img, *PICK)


def test_patch_of_another_shade_beside_the_sphere_is_left_out():
    """A patch of one of the sphere's shades touching it: sampled as background, it does not pull the centre."""
    def touching_patch(img):
        img[130:175, 208:250] = 0.7 * np.float32(RED_BGR)

    img = scene(np.random.default_rng(0), extra=touching_patch)
    m = fit_color_model(img, *PICK)
    det = detect_sphere(scene(np.random.default_rng(1), extra=touching_patch), m)
    assert m.is_local and det.valid
    assert np.hypot(det.uv[0] - SPHERE_UV[0], det.uv[1] - SPHERE_UV[1]) < 0.5


def test_pick_on_a_patch_is_refused():
    img = scene(np.random.default_rng(0))
    ys, xs = np.nonzero(np.all(img > 0, axis=2))   # any pixel: find one inside a large flat red patch
    hsv_red = (img[..., 2].astype(int) - img[..., 1]) > 80
    far = (np.hypot(xs - SPHERE_UV[0], ys - SPHERE_UV[1]) > 6 * R) & hsv_red[ys, xs]
    u, v = int(xs[far][0]), int(ys[far][0])
    # pick inside the patch, clear of its border where possible
    for du in range(0, 60):
        if all(hsv_red[v + dv, min(u + du + d, W - 1)] for d in (-8, 0, 8) for dv in (-8, 0, 8) if 0 <= v + dv < H):
            u = u + du
            break
    with pytest.raises(TudorVisionError, match="is the pick on the sphere"):
        fit_color_model(img, (u, v), (u + 7, v))


def test_local_model_survives_a_file_round_trip(tmp_path):
    m = fit_color_model(scene(np.random.default_rng(0)), *PICK)
    save_color_models(ColorModelSet({"mono": {"red": m}}), tmp_path / "m.yaml")
    back = load_color_models(tmp_path / "m.yaml").get("mono", "red")
    assert back.is_local and back.local_radius_px == pytest.approx(m.local_radius_px)
    frame = scene(np.random.default_rng(7))
    a, b = detect_sphere(frame, m, params=SegmentParams()), detect_sphere(frame, back, params=SegmentParams())
    assert a.valid and b.valid and np.allclose(a.uv, b.uv, atol=1e-3)


def test_local_radius_is_checked():
    m = fit_color_model(scene(np.random.default_rng(0)), *PICK)
    d = m.to_dict()
    d["local_radius_px"] = 0.2
    with pytest.raises(TudorVisionError, match="local_radius_px"):
        type(m).from_dict(d)


def test_cli_warns_about_a_local_model(tmp_path, capsys):
    import cv2

    from tudorvision.cli import main

    for k in range(2):
        cv2.imwrite(str(tmp_path / f"frame_{k:06d}.png"), scene(np.random.default_rng(k)))
    out = tmp_path / "m.yaml"
    assert main(["colormodel", str(tmp_path), "--frame", "0", "--pick", "mono:red:200,151:207,151",
                 "--out", str(out)]) == 0
    lines = [x for x in capsys.readouterr().out.splitlines() if x.startswith("warning:")]
    assert len(lines) == 1 and "mono/red: local colour model" in lines[0] and "within 28 px" in lines[0]
    assert load_color_models(out).get("mono", "red").is_local


def test_reset_with_an_anchor_moves_the_local_window():
    """The stereo pipeline re-pairs a lost view along the epipolar line and resets its tracker there."""
    m = fit_color_model(scene(np.random.default_rng(0)), *PICK)
    far = (450.2, 330.6)

    def clear_pick_window(img):
        img[110:195, 160:245] = 90.0

    frame = scene(np.random.default_rng(5), uv=far, extra=clear_pick_window)
    trk = SphereTracker(m)
    assert not trk.update(frame).valid          # the sphere jumped out of the window around the pick
    trk.reset(anchor_uv=(446.0, 333.0))
    assert trk.anchor == (446.0, 333.0)
    det = trk.update(frame)
    assert det.valid and np.hypot(det.uv[0] - far[0], det.uv[1] - far[1]) < 0.5
    trk.reset()
    assert trk.anchor == pytest.approx(m.center_uv)
