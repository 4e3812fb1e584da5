"""Sphere segmentation throughput and accuracy on synthetic stereo pairs (one core).

Renders ``--pairs`` synthetic 640x480 stereo pairs (a red and a green sphere
on either side of a moving end effector, static cluttered background per
camera with red/green distractors of other shades, noise; centres known to
sub-pixel accuracy from supersampled drawing, see
``tests/test_stereo_segment_scenes.py``), fits one colour model per camera
and sphere from picks on the first pair, then times on one core
(``cv2.setNumThreads(1)``):

- full-frame mode (``detect_spheres``, coarse to fine, and at full resolution),
- tracking mode (``FrameTracker``),
- the tutorial-style peer baseline (``peer_hsv.py``),

and prints pairs/s, the speed ratio to the peer and the centroid RMS error of
each against the known centres.

Run::

    .venv/bin/python benchmarks/bench_segment.py --pairs 200
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tests"))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, ".."))

from peer_hsv import detect_peer  # noqa: E402
from test_stereo_segment_scenes import GREEN_BGR, RED_BGR, clutter_background, sphere_patch  # noqa: E402
from tudorvision.stereo.colormodel import fit_color_model  # noqa: E402
from tudorvision.stereo.segment import SegmentParams, detect_spheres  # noqa: E402
from tudorvision.stereo.tracker2d import FrameTracker  # noqa: E402

COLORS = {"red": RED_BGR, "green": GREEN_BGR}


def make_sequence(n: int, seed: int, radius: float, blur: bool):
    """Truth ``{camera: {sphere: (n, 2)}}`` and frames ``{camera: [uint8 BGR]}``."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 50.0  # 50 fps
    frames, truth = {}, {}
    for cam, (cx, cy, sx) in {"left": (300.0, 250.0, 1.0), "right": (340.0, 230.0, -1.0)}.items():
        # end-effector image path: a Lissajous figure, up to ~8 px/frame
        mid = np.c_[cx + sx * 180 * np.sin(2 * np.pi * 0.35 * t), cy + 120 * np.sin(2 * np.pi * 0.5 * t + 0.4)]
        ang = 0.3 * np.sin(2 * np.pi * 0.2 * t)
        off = 24.0 * np.c_[np.cos(ang), np.sin(ang)]
        paths = {"red": mid - off, "green": mid + off}
        vel = {k: np.gradient(p, axis=0) for k, p in paths.items()}
        keep = [(u, v, radius + 12) for p in paths.values() for u, v in p[::3]]
        bg = clutter_background(rng, keep_out=keep)
        frames[cam] = []
        for k in range(n):
            img = bg.copy()
            for name, p in paths.items():
                b = tuple(vel[name][k]) if blur else (0.0, 0.0)
                sphere_patch(p[k], radius, COLORS[name], img, blur_uv=b, n_time=12 if blur else 1)
            img += rng.normal(0.0, 3.0, img.shape).astype(np.float32)
            frames[cam].append(np.clip(np.rint(img), 0, 255).astype(np.uint8))
        truth[cam] = paths
    return frames, truth


def fit_models(frames, truth, radius):
    models = {}
    for cam in frames:
        models[cam] = {}
        for name in ("red", "green"):
            c = truth[cam][name][0]
            models[cam][name] = fit_color_model(frames[cam][0], np.rint(c), np.rint(c) + [round(radius), 0])
    return models


def run(method, frames, n):
    """Call ``method(camera, frame)`` for every pair; returns (wall s, CPU s, results[cam][k])."""
    out = {cam: [None] * n for cam in frames}
    t0, c0 = time.perf_counter(), time.process_time()
    for k in range(n):
        for cam in ("left", "right"):
            out[cam][k] = method(cam, frames[cam][k])
    return time.perf_counter() - t0, time.process_time() - c0, out


def errors(results, truth, n, to_uv):
    errs, found = [], 0
    for cam in results:
        for k in range(n):
            for name in ("red", "green"):
                uv = to_uv(results[cam][k], name)
                if uv is None:
                    continue
                found += 1
                errs.append(np.subtract(uv, truth[cam][name][k]))
    e = np.array(errs)
    rms = float(np.sqrt(np.mean(np.sum(e ** 2, axis=1)))) if len(e) else float("nan")
    return rms, found / (4 * n)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pairs", type=int, default=200)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--radius", type=float, default=7.0, help="sphere radius in pixels")
    ap.add_argument("--blur", action="store_true", help="streaks as long as the frame-to-frame motion")
    ap.add_argument("--repeat", type=int, default=3, help="timing runs per method (best is reported)")
    ap.add_argument("--json", help="also write the results to this file")
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    n = args.pairs
    print(f"rendering {n} synthetic 640x480 stereo pairs (seed {args.seed}, radius {args.radius} px, "
          f"blur {'on' if args.blur else 'off'}) ...", flush=True)
    frames, truth = make_sequence(n, args.seed, args.radius, args.blur)
    models = fit_models(frames, truth, args.radius)

    def uv_ours(res, name):
        d = res[name]
        return d.uv if d.valid else None

    def uv_peer(res, name):
        return res[name]

    full = SegmentParams()
    fullres = SegmentParams(coarse_step=1)
    methods = {
        "full frame (coarse to fine)": (lambda: (lambda cam, f: detect_spheres(f, models[cam], params=full)), uv_ours),
        "full frame (full resolution)": (lambda: (lambda cam, f: detect_spheres(f, models[cam], params=fullres)),
                                         uv_ours),
        "tracking": (lambda: _tracking(models), uv_ours),
        "peer (HSV inRange + contours)": (lambda: (lambda cam, f: detect_peer(f)), uv_peer),
    }
    rows = {}
    for label, (factory, to_uv) in methods.items():
        best, best_cpu, res = np.inf, np.inf, None
        for _ in range(args.repeat):
            dt, cpu, res = run(factory(), frames, n)  # a fresh tracker per run
            best, best_cpu = min(best, dt), min(best_cpu, cpu)
        rms, rate = errors(res, truth, n, to_uv)
        rows[label] = {"pairs_per_s": n / best, "ms_per_pair": 1e3 * best / n, "cpu_pairs_per_s": n / best_cpu,
                       "rms_px": rms, "found": rate}
    peer = rows["peer (HSV inRange + contours)"]
    print(f"\n{'method':32s} {'pairs/s':>9s} {'ms/pair':>8s} {'x peer':>7s} {'CPU pairs/s':>12s} "
          f"{'RMS px':>8s} {'found':>6s}")
    for label, r in rows.items():
        print(f"{label:32s} {r['pairs_per_s']:9.1f} {r['ms_per_pair']:8.2f} "
              f"{r['pairs_per_s'] / peer['pairs_per_s']:7.2f} {r['cpu_pairs_per_s']:12.1f} "
              f"{r['rms_px']:8.3f} {100 * r['found']:5.1f}%")
    print("(pairs/s from wall-clock time, best of --repeat runs; CPU pairs/s from process CPU time)")
    ours = rows["full frame (coarse to fine)"]
    print(f"\naccuracy ratio (peer RMS / ours, full frame): {peer['rms_px'] / ours['rms_px']:.1f}")
    print(f"one core: cv2.getNumThreads() = {cv2.getNumThreads()}; targets: >= 100 pairs/s full frame, "
          f">= 500 pairs/s tracking")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"args": vars(args), "results": rows}, fh, indent=1)
    return 0


def _tracking(models):
    trackers = {cam: FrameTracker(m) for cam, m in models.items()}
    return lambda cam, f: trackers[cam].update(f)


if __name__ == "__main__":
    raise SystemExit(main())
