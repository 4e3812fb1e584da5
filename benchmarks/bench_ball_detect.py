"""Benchmark: RGB-D ball detection speed, detection rate and 3D error on synthetic 640x480 frames.

Compares ``tudorvision.rgbd.ball.detect_balls`` (coarse block-averaged search,
local full-resolution refinement) with a straightforward full-resolution
OpenCV pipeline (absdiff, threshold, morphology, findContours,
minEnclosingCircle) on the same frames, both on one core
(``cv2.setNumThreads(1)``). Frames: Kinect optics, a slanted wall at
5.2-5.9 m and a box at 3 m (static), a 9 cm ball at 1.2-4.3 m, the seed's
depth noise sigma_z(z), mm rounding, invalid pixels at depth jumps.

Run::

    .venv/bin/python benchmarks/bench_ball_detect.py [--frames 200] [--repeat 3] [--lab DIR]

``--lab DIR`` also evaluates on a virtual-lab recording
(``tudorvision sim record rgbd-throws --out DIR``) against its ground truth:
detection rate over frames where the ball centre is in view and 0.6-4.5 m
away, 3D error there, and detections while no ball is in flight.
"""
from __future__ import annotations

import argparse
import os
import platform
import time
import warnings

os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2
import numpy as np

from tudorvision.rgbd.ball import DepthBackground, detect_balls
from tudorvision.rgbd.frames import Intrinsics

K = Intrinsics(525.0, 525.0, 319.5, 239.5, 640, 480)
R_BALL = 0.045
VV, UU = np.mgrid[: K.height, : K.width]
RAYS = np.stack([(UU - K.cx) / K.fx, (VV - K.cy) / K.fy, np.ones(K.shape)], axis=-1)


def seed_sigma_m(z):
    return np.maximum(0.51 * z ** 3 - 2.1 * z ** 2 + 5.12 * z - 2.18, 0.0) / 100.0


def static_scene():
    z = 5.2 + 0.7 * (UU / K.width)
    return np.where((UU > 60) & (UU < 200) & (VV > 300), 3.0, z)


def add_sphere(z_static, c):
    a = np.einsum("hwk,hwk->hw", RAYS, RAYS)
    b = RAYS @ c
    disc = b * b - a * (c @ c - R_BALL ** 2)
    hit = disc >= 0
    t = np.where(hit, (b - np.sqrt(np.where(hit, disc, 0.0))) / a, np.inf)
    return np.where(t < z_static, t, z_static)


def sense(rng, z):
    jump = np.zeros(z.shape, bool)
    dv = np.abs(np.diff(z, axis=0)) > 0.03 * np.minimum(z[1:], z[:-1])
    du = np.abs(np.diff(z, axis=1)) > 0.03 * np.minimum(z[:, 1:], z[:, :-1])
    jump[1:] |= dv
    jump[:-1] |= dv
    jump[:, 1:] |= du
    jump[:, :-1] |= du
    out = np.rint((z + seed_sigma_m(z) * rng.standard_normal(z.shape)) * 1000) / 1000
    out[jump | (z > 6.0)] = np.nan
    return out.astype(np.float32)


def random_ball(rng):
    while True:
        z = rng.uniform(1.2, 4.3)
        u, v = rng.uniform(40, K.width - 40), rng.uniform(40, K.height - 40)
        if not (z > 2.7 and 30 < u < 230 and v > 270):
            return np.array([(u - K.cx) / K.fx * z, (v - K.cy) / K.fy * z, z])


class OpenCVPeer:
    """Straightforward full-resolution pipeline, the usual tutorial recipe on depth images."""

    def __init__(self, bg_frames, *, threshold_m=0.3, max_range_m=4.5):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)     # all-NaN pixels beyond range
            bg = np.nanmedian(np.stack(bg_frames), axis=0)
        self.bg = np.nan_to_num(bg, nan=10.0).astype(np.float32)
        self.threshold = threshold_m
        self.max_range = max_range_m
        self.kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (5, 5))

    def detect(self, depth):
        d = np.nan_to_num(depth, nan=0.0)
        diff = cv2.absdiff(self.bg, d)
        _, fg = cv2.threshold(diff, self.threshold, 255, cv2.THRESH_BINARY)
        fg = fg.astype(np.uint8) & cv2.inRange(d, 0.4, self.max_range)
        fg = cv2.morphologyEx(fg, cv2.MORPH_OPEN, self.kernel)
        contours, _ = cv2.findContours(fg, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        best, best_score = None, np.inf
        for c in contours:
            (u, v), r = cv2.minEnclosingCircle(c)
            if r < 2:
                continue
            m = np.zeros_like(fg)
            cv2.drawContours(m, [c], -1, 255, -1)
            z = float(np.median(d[(m > 0) & (d > 0)])) if np.any((m > 0) & (d > 0)) else np.nan
            if not np.isfinite(z):
                continue
            r_exp = K.fx * R_BALL / z
            score = abs(np.log(r / r_exp))
            if score < np.log(2.0) and score < best_score:
                ray = np.array([(u - K.cx) / K.fx, (v - K.cy) / K.fy, 1.0])
                best, best_score = ray * (z + R_BALL), score      # surface depth + radius
        return best


def evaluate(name, fn, frames, truths, repeat):
    for f in frames[:5]:
        fn(f)
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        outs = [fn(f) for f in frames]
        times.append(time.perf_counter() - t0)
    t = min(times)
    errs = [np.linalg.norm(p - c) for p, c in zip(outs, truths) if p is not None]
    rate = len(errs) / len(frames)
    fps = len(frames) / t
    med = float(np.median(errs)) if errs else float("nan")
    p95 = float(np.percentile(errs, 95)) if errs else float("nan")
    print(f"{name:<28s} {fps:9.1f} frames/s   detection rate {rate:6.1%}   3D error median "
          f"{med * 100:5.2f} cm  95% {p95 * 100:5.2f} cm")
    return fps


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=200)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--lab", help="also evaluate on a virtual-lab rgbd-throws recording")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    rng = np.random.default_rng(args.seed)
    static = static_scene()
    bg_frames = [sense(rng, static) for _ in range(10)]
    truths = [random_ball(rng) for _ in range(args.frames)]
    frames = [sense(rng, add_sphere(static, c)) for c in truths]
    background = DepthBackground(bg_frames, K)
    peer = OpenCVPeer(bg_frames)

    def ours(f):
        d = detect_balls(f, background)
        return d[0].p_cam if d else None

    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cpus, "
          f"cv2 {cv2.__version__}, numpy {np.__version__}, cv2 threads {cv2.getNumThreads()}")
    print(f"{args.frames} synthetic 640x480 depth frames, best of {args.repeat} runs")
    a = evaluate("tudorvision detect_balls", ours, frames, truths, args.repeat)
    b = evaluate("OpenCV full-res pipeline", peer.detect, frames, truths, args.repeat)
    print(f"speed ratio (ours / peer): {a / b:.2f}x; target >= 300 frames/s: {'met' if a >= 300 else 'NOT met'}")
    if args.lab:
        lab(args.lab)


def lab(path):
    from tudorvision.io import open_sequence

    seq = open_sequence(path)
    cam = seq.calibration.camera("rgbd")
    K_lab = Intrinsics.from_matrix(cam.K, cam.width, cam.height)
    gt = seq.groundtruth("ball")
    truth = np.column_stack([gt["x_cam_m"], gt["y_cam_m"], gt["z_cam_m"]])
    depth = [f.depth_m for f in seq]
    bg = DepthBackground(depth[:10], K_lab)
    t0 = time.perf_counter()
    dets = [detect_balls(d, bg) for d in depth[10:]]
    dt = time.perf_counter() - t0
    truth = truth[10:]
    with np.errstate(invalid="ignore"):
        u = K_lab.fx * truth[:, 0] / truth[:, 2] + K_lab.cx
        v = K_lab.fy * truth[:, 1] / truth[:, 2] + K_lab.cy
        visible = ((truth[:, 2] > 0.6) & (truth[:, 2] < 4.5) & (u >= 0) & (u < K_lab.width)
                   & (v >= 0) & (v < K_lab.height))
    errs, false = [], 0
    for d, c, vis in zip(dets, truth, visible):
        if d and vis:
            errs.append(np.linalg.norm(d[0].p_cam - c))
        elif d and not np.all(np.isfinite(c)):
            false += 1
    errs = np.array(errs)
    print(f"virtual lab {path}: {len(depth) - 10} frames at {(len(depth) - 10) / dt:.0f} frames/s; "
          f"ball in view within 4.5 m in {visible.sum()} frames, detected in {len(errs)} "
          f"({len(errs) / max(visible.sum(), 1):.1%}); 3D error median {np.median(errs) * 100:.2f} cm, "
          f"95% {np.percentile(errs, 95) * 100:.2f} cm, max {errs.max() * 100:.2f} cm; "
          f"detections while no ball is in flight: {false}")


if __name__ == "__main__":
    main()
