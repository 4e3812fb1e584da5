"""Synthetic sphere frames with analytically known centres (and tests of the generator).

Spheres are drawn supersampled (``SS`` x ``SS`` samples per pixel, reduced with
``cv2.resize(..., INTER_AREA)``) as shaded discs lit head-on, so the shading
is point-symmetric and the true image position is exactly the disc centre;
motion blur averages the sphere over positions along a segment, so the true
position of a streak is the segment's midpoint (the mean over the exposure).
The background is a gradient with neutral clutter and red/green distractors
of other shades (orange, pink, maroon, brown, magenta; olive, teal, dark
green, pale green, yellow-green), partly disc-shaped, plus Gaussian noise.

Pixel convention: pixel centres at integer coordinates (OpenCV), so the
supersample ``s`` of pixel ``i`` sits at ``i - 0.5 + (s + 0.5) / SS``.

The benchmark (``benchmarks/bench_segment.py``) imports this module too.
"""
from __future__ import annotations

import cv2
import numpy as np

SS = 8
WIDTH, HEIGHT = 640, 480
# BGR; the red's hue is about 178 of OpenCV's 0..179, so noise wraps it over 0
RED_BGR = (40.0, 30.0, 210.0)
GREEN_BGR = (60.0, 190.0, 50.0)
REDDISH = [(0, 120, 230), (170, 150, 230), (25, 20, 100), (40, 70, 140), (150, 40, 200)]
GREENISH = [(40, 140, 130), (140, 150, 30), (20, 80, 15), (160, 210, 150), (30, 200, 170)]
NEUTRAL = [(90, 90, 90), (150, 150, 150), (60, 60, 70), (200, 200, 190), (120, 110, 100)]


def sphere_patch(center_uv, radius, color_bgr, background, *, blur_uv=(0.0, 0.0), n_time=1,
                 ambient=0.35, ss=SS):
    """Draw a shaded sphere (optionally blurred) onto ``background`` (float32 HxWx3) in place."""
    h, w = background.shape[:2]
    cu, cv_ = float(center_uv[0]), float(center_uv[1])
    bu, bv = float(blur_uv[0]), float(blur_uv[1])
    ext = radius + 0.5 * max(abs(bu), abs(bv)) + 2
    x0, x1 = max(int(np.floor(cu - ext)), 0), min(int(np.ceil(cu + ext)) + 1, w)
    y0, y1 = max(int(np.floor(cv_ - ext)), 0), min(int(np.ceil(cv_ + ext)) + 1, h)
    if x1 <= x0 or y1 <= y0:
        return
    xs = x0 - 0.5 + (np.arange((x1 - x0) * ss) + 0.5) / ss
    ys = y0 - 0.5 + (np.arange((y1 - y0) * ss) + 0.5) / ss
    X, Y = np.meshgrid(xs, ys)
    shade_acc = np.zeros_like(X)
    cover_acc = np.zeros_like(X)
    ts = [0.0] if n_time <= 1 else np.linspace(-0.5, 0.5, n_time)
    for t in ts:
        d2 = ((X - cu - t * bu) ** 2 + (Y - cv_ - t * bv) ** 2) / radius ** 2
        inside = d2 <= 1.0
        shade_acc += inside * (ambient + (1 - ambient) * np.sqrt(np.clip(1 - d2, 0, 1)))
        cover_acc += inside
    shade_acc /= len(ts)
    cover_acc /= len(ts)
    size = (x1 - x0, y1 - y0)
    shade = cv2.resize(shade_acc.astype(np.float32), size, interpolation=cv2.INTER_AREA)
    cover = cv2.resize(cover_acc.astype(np.float32), size, interpolation=cv2.INTER_AREA)
    patch = background[y0:y1, x0:x1]
    patch[:] = shade[..., None] * np.float32(color_bgr) + (1 - cover[..., None]) * patch


def clutter_background(rng, *, width=WIDTH, height=HEIGHT, keep_out=(), n_distractors=14, n_neutral=25):
    """Gradient, neutral clutter and coloured distractors away from ``keep_out`` discs.

    ``keep_out`` : sequence of ``(u, v, r)`` discs no distractor may reach.
    """
    v, u = np.mgrid[0:height, 0:width].astype(np.float32)
    base = 70 + 50 * u / width + 30 * v / height
    img = np.repeat(base[..., None], 3, axis=2) * np.float32([1.0, 0.97, 0.93])

    def free(cu, cv_, r):
        return all(np.hypot(cu - ku, cv_ - kv) > r + kr + 6 for ku, kv, kr in keep_out)

    for _ in range(n_neutral):
        col = NEUTRAL[rng.integers(len(NEUTRAL))]
        cu, cv_ = rng.uniform(0, width), rng.uniform(0, height)
        a, b = rng.uniform(10, 60), rng.uniform(10, 60)
        if free(cu, cv_, max(a, b) * 1.5):
            cv2.rectangle(img, (int(cu - a), int(cv_ - b)), (int(cu + a), int(cv_ + b)), col, -1)
    placed = 0
    tries = 0
    while placed < n_distractors and tries < 500:
        tries += 1
        col = (REDDISH + GREENISH)[placed % 10]
        cu, cv_ = rng.uniform(20, width - 20), rng.uniform(20, height - 20)
        r = rng.uniform(6, 22)
        if not free(cu, cv_, r * 1.6):
            continue
        kind = placed % 3
        if kind == 0:  # a shaded disc of another shade: same shape as a sphere
            sphere_patch((cu, cv_), r, col, img, ss=2)
        elif kind == 1:
            cv2.ellipse(img, (int(cu), int(cv_)), (int(r * 1.5), int(r)), float(rng.uniform(0, 180)), 0, 360,
                        col, -1)
        else:
            cv2.rectangle(img, (int(cu - r), int(cv_ - r / 2)), (int(cu + r), int(cv_ + r / 2)), col, -1)
        placed += 1
    return img


def make_frame(rng, spheres, *, noise=3.0, clutter=True, width=WIDTH, height=HEIGHT):
    """A uint8 BGR frame with spheres.

    ``spheres`` : dict name -> dict(uv=(u, v), radius=r, color=BGR, blur=(du, dv), n_time=k).
    """
    keep = [(s["uv"][0], s["uv"][1], s["radius"] + 0.5 * np.hypot(*s.get("blur", (0, 0))))
            for s in spheres.values()]
    if clutter:
        img = clutter_background(rng, width=width, height=height, keep_out=keep)
    else:
        img = np.full((height, width, 3), 80.0, np.float32)
    for s in spheres.values():
        blur = s.get("blur", (0.0, 0.0))
        n_time = s.get("n_time", 1 if blur == (0.0, 0.0) else 24)
        sphere_patch(s["uv"], s["radius"], s["color"], img, blur_uv=blur, n_time=n_time)
    if noise > 0:
        img = img + rng.normal(0.0, noise, img.shape).astype(np.float32)
    return np.clip(np.rint(img), 0, 255).astype(np.uint8)


def two_spheres(red_uv, green_uv, radius=9.0, **extra):
    """The ``spheres`` argument of :func:`make_frame` for the red and the green sphere."""
    return {"red": dict(uv=tuple(red_uv), radius=radius, color=RED_BGR, **extra),
            "green": dict(uv=tuple(green_uv), radius=radius, color=GREEN_BGR, **extra)}


# ---------------------------------------------------------------- generator self-tests

def test_supersampled_disc_centroid_is_the_centre():
    """Oracle check of the generator: the coverage-weighted centroid equals the true centre."""
    rng = np.random.default_rng(1)
    for _ in range(5):
        uv = rng.uniform(30, 50, size=2)
        img = np.zeros((80, 80, 3), np.float32)
        sphere_patch(uv, 7.3, (255.0, 255.0, 255.0), img, ambient=1.0)  # flat: value = coverage
        cov = img[..., 0] / 255.0
        v, u = np.mgrid[0:80, 0:80]
        est = np.array([(cov * u).sum(), (cov * v).sum()]) / cov.sum()
        np.testing.assert_allclose(est, uv, atol=5e-3)
        np.testing.assert_allclose(cov.sum(), np.pi * 7.3 ** 2, rtol=2e-3)


def test_blur_streak_centroid_is_the_mean_position():
    img = np.zeros((80, 120, 3), np.float32)
    sphere_patch((60.3, 40.6), 6.0, (255.0, 255.0, 255.0), img, blur_uv=(20.0, 8.0), n_time=24, ambient=1.0)
    cov = img[..., 0] / 255.0
    v, u = np.mgrid[0:80, 0:120]
    est = np.array([(cov * u).sum(), (cov * v).sum()]) / cov.sum()
    np.testing.assert_allclose(est, (60.3, 40.6), atol=2e-3)


def test_red_sphere_hue_straddles_zero():
    rng = np.random.default_rng(2)
    img = make_frame(rng, two_spheres((100, 100), (300, 200)), clutter=False)
    hue = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)[95:106, 95:106, 0]
    assert (hue > 170).any() and (hue < 5).any()
