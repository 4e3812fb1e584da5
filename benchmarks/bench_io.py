"""Write and read back RGB-D sequences at 640x480: frames per second and bytes per frame.

Run: ``.venv/bin/python benchmarks/bench_io.py [--frames N]``. Not a test.
"""
from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from tudorvision.io import SequenceWriter, open_sequence


def _scene(rng, k):
    """A smooth synthetic colour image and depth map (compressible like rendered frames)."""
    v, u = np.mgrid[0:480, 0:640]
    bgr = np.stack([(u + 3 * k) % 256, (v + k) % 256, ((u + v) // 2) % 256], axis=-1).astype(np.uint8)
    bgr = cv2.add(bgr, rng.integers(0, 8, bgr.shape, dtype=np.uint8))
    depth_m = 1.5 + 0.5 * np.sin(u / 80.0 + k / 10) + rng.normal(0, 0.005, u.shape)
    depth_m[:, :20] = np.nan
    return bgr, depth_m


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, default=60)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    frames = [_scene(rng, k) for k in range(args.frames)]
    for ext in (".png", ".jpg"):
        with tempfile.TemporaryDirectory() as d:
            out = Path(d) / "seq"
            t0 = time.perf_counter()
            with SequenceWriter(out, kind="rgbd", rate_hz=30.0, depth_scale=1000.0, image_ext=ext) as w:
                for k, (bgr, depth) in enumerate(frames):
                    w.add_rgbd(k / 30.0, bgr, depth)
            t_write = time.perf_counter() - t0
            size = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())
            t0 = time.perf_counter()
            n = sum(1 for _ in open_sequence(out))
            t_read = time.perf_counter() - t0
            print(f"{ext}: write {n / t_write:6.1f} frames/s, read {n / t_read:6.1f} frames/s, "
                  f"{size / n / 1e3:7.1f} kB/frame")


if __name__ == "__main__":
    main()
