"""Luma-edge rim refinement (:mod:`tudorvision.stereo.rim_edge`) and its use by the segmentation.

Oracles: supersampled discs and directionally lit spheres whose true image
centre is known; JPEG frames made with OpenCV's encoder (4:2:0 chroma
subsampling, the codec's default), so the colour planes are smeared while the
luma stays sharp.
"""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from tudorvision.stereo import SegmentParams, detect_sphere
from tudorvision.stereo.colormodel import fit_color_model
from tudorvision.stereo.rim_edge import luma_rim_points, refine_circle_on_luma
from tudorvision.stereo.segment import log_odds_image

SS = 8
COLOUR_RIM = SegmentParams()                      # the default: colour rim only
EDGE = SegmentParams(edge_refine=True)


def _coverage(h, w, cu, cv_, r):
    """Pixel coverage of the disc (supersampled SS x SS), float64 (h, w)."""
    xs = -0.5 + (np.arange(w * SS) + 0.5) / SS
    ys = -0.5 + (np.arange(h * SS) + 0.5) / SS
    X, Y = np.meshgrid(xs, ys)
    return cv2.resize(((X - cu) ** 2 + (Y - cv_) ** 2 <= r * r).astype(np.float32), (w, h),
                      interpolation=cv2.INTER_AREA).astype(np.float64)


def _lit_sphere(img, cu, cv_, r, colour_bgr, light=(-0.5, -0.6, 0.62), ambient=0.3):
    """Draw a Lambertian sphere lit from the upper left onto ``img`` (float, HxWx3) in place."""
    h, w = img.shape[:2]
    xs = -0.5 + (np.arange(w * SS) + 0.5) / SS
    ys = -0.5 + (np.arange(h * SS) + 0.5) / SS
    X, Y = np.meshgrid(xs, ys)
    dx, dy = (X - cu) / r, (Y - cv_) / r
    d2 = dx * dx + dy * dy
    inside = d2 <= 1.0
    nz = np.sqrt(np.clip(1.0 - d2, 0.0, 1.0))
    lx, ly, lz = np.asarray(light) / np.linalg.norm(light)
    shade = inside * (ambient + (1 - ambient) * np.clip(dx * lx + dy * ly + nz * lz, 0.0, None))
    shade = cv2.resize(shade.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA)[..., None]
    cover = cv2.resize(inside.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA)[..., None]
    img[:] = shade * np.float32(colour_bgr) * 1.25 + (1.0 - cover) * img


def _scene(rng, r=7.0, colour=(60.0, 170.0, 50.0)):
    """A 64 x 64 frame with a lit sphere at a random sub-pixel centre on a light ground."""
    h = w = 64
    v, u = np.mgrid[0:h, 0:w].astype(np.float32)
    img = np.repeat((150 + 20 * u / w + 10 * v / h)[..., None], 3, axis=2) * np.float32([1.0, 0.98, 0.95])
    c = (32.0 + rng.uniform(-2, 2), 32.0 + rng.uniform(-2, 2))
    _lit_sphere(img, *c, r, colour)
    img += rng.normal(0, 1.5, img.shape)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8), c


def _jpeg(img, quality=92):
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, quality])
    assert ok
    return cv2.imdecode(buf, cv2.IMREAD_COLOR)


@pytest.mark.parametrize("polarity", [-1.0, 1.0])
def test_rim_points_and_circle_on_antialiased_discs(polarity):
    rng = np.random.default_rng(7)
    errs = []
    for _ in range(10):
        cu, cv_, r = 30 + rng.uniform(-1, 1), 30 + rng.uniform(-1, 1), rng.uniform(5, 12)
        gray = 120.0 + polarity * 60.0 * _coverage(60, 60, cu, cv_, r)
        # start 1 px off in centre and radius, as a JPEG-biased colour rim may be
        start, r0 = (cu + rng.uniform(-1, 1) / np.sqrt(2), cv_ + rng.uniform(-1, 1) / np.sqrt(2)), r + 0.8
        pts, n = luma_rim_points(gray, None, start, r0)
        assert n % 4 == 0 and len(pts) == n
        assert np.abs(np.hypot(pts[:, 0] - cu, pts[:, 1] - cv_) - r).max() < 0.3
        u, v, rr, frac, rms = refine_circle_on_luma(gray, None, start, r0)
        errs.append(np.hypot(u - cu, v - cv_))
        assert errs[-1] < 0.1 and abs(rr - r) < 0.1 and frac > 0.9
    assert np.sqrt(np.mean(np.square(errs))) < 0.04


def test_low_contrast_gives_none_and_the_colour_rim_stands():
    gray = 120.0 + 4.0 * _coverage(40, 40, 20.2, 19.7, 8.0)       # 4 grey levels: below min_contrast
    assert len(luma_rim_points(gray, None, (20.0, 20.0), 8.0)[0]) == 0
    assert refine_circle_on_luma(gray, None, (20.0, 20.0), 8.0) is None
    # a red whose luma equals the ground's: the detection keeps the colour-rim circle
    img = np.full((60, 80, 3), 90, np.uint8)
    cv2.circle(img, (40, 30), 10, (40, 40, 200), -1, lineType=cv2.LINE_AA)   # Y = 88
    det = detect_sphere(img, fit_color_model(img, (40, 30), (47, 30)), params=EDGE)
    assert det.valid and det.method == "shape"


def test_an_occluding_bar_does_not_pull_the_edge_circle():
    # a dark bar crosses the lower part of a dark green sphere and runs on over the ground: the
    # bar/ground edge near the rim is off the circle, so the trimmed fit leaves it out; the inside
    # gate (optional) drops those rays before the fit
    rng = np.random.default_rng(3)
    img = np.full((80, 80, 3), 165.0, np.float32)
    c = (40.3, 39.6)
    _lit_sphere(img, *c, 9.0, (40.0, 120.0, 30.0))   # darker than the ground all round
    v, u = np.mgrid[0:80, 0:80]
    bar = np.clip(2.0 - np.abs((v - 46.0) - 0.15 * (u - 40.0)), 0, 1)  # a 3 px bar 6 px below the centre
    img[:] = bar[..., None] * np.float32((70, 70, 75)) + (1 - bar[..., None]) * img
    img = np.clip(np.rint(img + rng.normal(0, 1.5, img.shape)), 0, 255).astype(np.uint8)
    model = fit_color_model(img, (40, 37), (46, 37))
    det = detect_sphere(img, model, params=EDGE)
    assert det.valid and det.method == "edge"
    assert np.hypot(det.uv[0] - c[0], det.uv[1] - c[1]) < 0.3
    gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.float64)
    lo = log_odds_image(img, model).astype(np.float64)
    gated, n = luma_rim_points(gray, lo, c, 9.0, inside_gate=True)
    default, _ = luma_rim_points(gray, lo, c, 9.0)
    assert len(gated) < len(default)          # rays over the bar are dropped by the inside gate


def test_the_shaded_limb_is_not_dropped_so_the_circle_does_not_lean_to_the_light():
    """A hard-lit sphere whose shaded limb has negative colour log-odds: the inside gate drops that
    side's rays and the circle leans towards the light; without it the rim is found all round."""
    rng = np.random.default_rng(5)
    lean = {True: [], False: []}
    for _ in range(12):
        h = w = 64
        img = np.full((h, w, 3), 150.0, np.float32)
        c = (32.0 + rng.uniform(-2, 2), 32.0 + rng.uniform(-2, 2))
        _lit_sphere(img, *c, 7.0, (50.0, 60.0, 190.0), light=(-0.8, -0.5, 0.35), ambient=0.08)
        img = np.clip(np.rint(img + rng.normal(0, 1.5, img.shape)), 0, 255).astype(np.uint8)
        model = fit_color_model(img, (round(c[0] - 2), round(c[1] - 1)), (round(c[0] + 2), round(c[1] - 1)))
        gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY).astype(np.float64)
        lo = log_odds_image(img, model).astype(np.float64)
        light = -np.array([-0.8, -0.5]) / np.hypot(0.8, 0.5)          # from the centre to the dark side
        for gate in (True, False):
            pts, n = luma_rim_points(gray, lo, c, 7.0, inside_gate=gate)
            dark = (pts - c) @ light > 0.5 * 7.0                          # rim points on the shaded side
            lean[gate].append(int(dark.sum()))
            if not gate:
                fit = refine_circle_on_luma(gray, lo, c, 7.0)
                assert fit is not None and np.hypot(fit[0] - c[0], fit[1] - c[1]) < 0.2
    assert np.mean(lean[False]) > np.mean(lean[True]) + 2      # the shaded side keeps its rays


def test_jpeg_chroma_smear_is_undone_by_the_luma_edge():
    rng = np.random.default_rng(11)
    err = {"colour-rim png": [], "edge png": [], "colour-rim jpg": [], "edge jpg": []}
    for _ in range(12):
        png, c = _scene(rng)
        jpg = _jpeg(png)
        for name, img in (("png", png), ("jpg", jpg)):
            model = fit_color_model(img, (round(c[0]), round(c[1])), (round(c[0]) + 5, round(c[1])))
            for label, params in (("colour-rim", COLOUR_RIM), ("edge", EDGE)):
                det = detect_sphere(img, model, params=params)
                assert det.valid, det.reason
                err[f"{label} {name}"].append(np.hypot(det.uv[0] - c[0], det.uv[1] - c[1]))
    rms = {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in err.items()}
    assert rms["edge png"] < 0.17, rms
    assert rms["edge jpg"] < 0.17, rms
    # on the JPEG frames the colour rim is clearly worse than the luma edge
    assert rms["colour-rim jpg"] > 1.5 * rms["edge jpg"], rms


def test_chroma_subsampled_source(tmp_path):
    from tudorvision.stereo.rim_edge import chroma_subsampled_source
    (tmp_path / "jpg" / "left").mkdir(parents=True)
    (tmp_path / "jpg" / "left" / "000000.jpg").write_bytes(b"x")
    (tmp_path / "png" / "left").mkdir(parents=True)
    (tmp_path / "png" / "left" / "000000.png").write_bytes(b"x")
    (tmp_path / "png" / "sequence.yaml").write_text("kind: stereo\n")
    assert chroma_subsampled_source(tmp_path / "jpg")
    assert not chroma_subsampled_source(tmp_path / "png")
    assert chroma_subsampled_source(tmp_path / "clip.MP4") and not chroma_subsampled_source(tmp_path / "none")
