"""A real Kinect's fixed depth pattern, and the lab's sensor measured the same way.

The peer is a real sensor: the floor of the five Kinect frames in
``../shared/realdata/rgbd_kinect_room/`` (registered depth in millimetres,
fx 518.0, fy 519.0, cx 325.5, cy 253.5; the camera moves about 1.5 m and
turns over the five). Per frame the floor (a region of rows and columns,
then the largest plane of it) is fitted as a plane in inverse depth, which
is exactly affine in the pixel coordinates for a plane: ``1/z = a + b u + c v``
(the package's fit, :func:`tudorvision.rgbd.depth_pattern.plane_residual_inv_depth`:
a three-point consensus, then trimmed least squares on the pixels within 3 cm). Its residual in inverse depth, times ``f b``
(:data:`tudorvision.sim.depth_sensor.KINECT_FOCAL_BASELINE_PX_M`), is a
disparity residual in pixels, averaged over 16 x 16 px blocks (the per-pixel
noise then averages to about 0.01 px).

A floor that is not flat, or things lying on it, show up where they lie in
the room; the camera moves between the frames, so they move in the image.
What the sensor adds stays at the same pixels. Printed: per frame the
blocks' RMS; per pair of frames the correlation of their blocks on common
pixels; the shared part (blocks seen in at least two of frames 2-5, their
mean) with its RMS and its correlation at 16-64 px lags along u and v;
every frame's RMS difference from the mean of the others.

Leave one out (the remedy on real data): for each of frames 2-5, the pattern is calibrated
(:func:`tudorvision.rgbd.depth_pattern.calibrate_depth_pattern`, the user's ``calib rgbd-pattern``) from
the floors of the other three (each frame's floor plane's pixels only, the rest set invalid) and removed
from the held-out frame; printed: its floor's block RMS before and after, where the three cover it.

The lab: the same fitted floor planes, the same valid pixels, rendered
through :func:`tudorvision.sim.depth_sensor.depth_mm_from_gbuffer` with the
default noise and ``--pattern-px`` (default
:data:`tudorvision.sim.depth_sensor.KINECT_PATTERN_DISPARITY_PX`), measured by
the same code; ``--pattern-px 0`` shows the lab before the pattern.

Run::

    .venv/bin/python benchmarks/bench_depth_pattern_real.py [--pattern-px 0.05] [--seeds 0 1 2]
"""
from __future__ import annotations

import argparse
import dataclasses
import platform
import sys
import warnings
from pathlib import Path

import cv2
import numpy as np

from tudorvision.lab.depth_wall import depth_frames_mm
from tudorvision.rgbd.depth_pattern import calibrate_depth_pattern, plane_residual_inv_depth
from tudorvision.sim.depth_sensor import (KINECT_FOCAL_BASELINE_PX_M, KINECT_PATTERN_CORR_PX,
                                         KINECT_PATTERN_DISPARITY_PX, DepthSensorModel)

ROOT = Path(__file__).resolve().parents[1] / ".." / "shared" / "realdata" / "rgbd_kinect_room" / "depth"
H, W, B = 480, 640, 16
#: the floor's region per frame: rows, columns (the lower part of the image, where the floor is)
REGIONS = {1: (300, 470, 40, 600), 2: (300, 470, 40, 600), 3: (300, 470, 40, 600),
           4: (330, 470, 40, 560), 5: (330, 470, 40, 600)}
SHARED = (2, 3, 4, 5)
LAGS = (1, 2, 3, 4)


def floor_plane(depth_m: np.ndarray, region) -> tuple:
    """The largest plane in ``region`` (the package's fit, :func:`plane_residual_inv_depth`, 3 cm):
    (its inverse-depth residual, 1/m, NaN off it; mask of its pixels)."""
    r0, r1, c0, c1 = region
    z = np.zeros((H, W))
    z[r0:r1, c0:c1] = depth_m[r0:r1, c0:c1]
    res, _ = plane_residual_inv_depth(z, max_dev_m=0.03)
    return res, np.isfinite(res)


def block_residual(res_inv: np.ndarray, mask=None) -> np.ndarray:
    """A plane fit's inverse-depth residual as disparity (px), mean per 16 x 16 block (only ``mask``'s pixels);
    NaN where under half the block is in."""
    res = res_inv * KINECT_FOCAL_BASELINE_PX_M
    if mask is not None:
        res = np.where(mask, res, np.nan)
    blocks = res.reshape(H // B, B, W // B, B).transpose(0, 2, 1, 3).reshape(H // B, W // B, -1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        out = np.nanmean(blocks, axis=2)
    out[np.isfinite(blocks).sum(axis=2) < B * B // 2] = np.nan
    return out


def corr(a: np.ndarray, b: np.ndarray) -> tuple:
    ok = np.isfinite(a) & np.isfinite(b)
    if ok.sum() < 10:
        return float("nan"), int(ok.sum())
    x, y = a[ok] - a[ok].mean(), b[ok] - b[ok].mean()
    return float(x @ y / np.sqrt((x @ x) * (y @ y))), int(ok.sum())


def summary(maps: dict) -> dict:
    """The numbers printed for one set of per-frame block maps."""
    rms = {i: float(np.sqrt(np.nanmean(m ** 2))) for i, m in maps.items()}
    pairs = {(i, j): corr(maps[i], maps[j]) for i in maps for j in maps if i < j}
    stack = np.stack([maps[i] for i in SHARED])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        shared = np.where(np.isfinite(stack).sum(0) >= 2, np.nanmean(stack, 0), np.nan)
        loo = {i: np.nanmean(np.stack([maps[j] for j in SHARED if j != i]), 0) for i in SHARED}
    sc = shared - np.nanmean(shared)
    lag_u = [corr(sc[:, k:], sc[:, :-k])[0] for k in LAGS]
    lag_v = [corr(sc[k:, :], sc[:-k, :])[0] for k in LAGS]
    diff = {}
    for i in SHARED:
        ok = np.isfinite(loo[i]) & np.isfinite(maps[i])
        diff[i] = float(np.sqrt(np.mean((maps[i][ok] - loo[i][ok]) ** 2)))
    return {"rms": rms, "pairs": pairs, "shared_rms": float(np.sqrt(np.nanmean(sc ** 2))),
            "shared_n": int(np.isfinite(shared).sum()), "lag_u": lag_u, "lag_v": lag_v, "diff": diff}


def lab_frame(plane_m: np.ndarray, model: DepthSensorModel, rng) -> np.ndarray:
    """The lab's sensor on the fitted plane (valid where the real floor was), metres (0 invalid)."""
    raw = depth_frames_mm(plane_m, dataclasses.replace(model, edge_jump_rel=1.0), rng, 1)[0]
    return raw.astype(float) / model.units_per_m


def print_summary(name: str, s: dict) -> None:
    print(f"\n{name}")
    print("  per frame, blocks' RMS (px): " + ", ".join(f"{i}: {v:.3f}" for i, v in s["rms"].items()))
    print("  pairs, correlation (common blocks): "
          + ", ".join(f"{i}-{j}: {c:+.2f} ({n})" for (i, j), (c, n) in s["pairs"].items()))
    print(f"  shared part (frames {SHARED}, >= 2 per block): {s['shared_n']} blocks, RMS {s['shared_rms']:.3f} px")
    print("  its correlation at lag " + ", ".join(f"{k * B}" for k in LAGS) + " px: along u "
          + " ".join(f"{c:.2f}" for c in s["lag_u"]) + "; along v " + " ".join(f"{c:.2f}" for c in s["lag_v"]))
    print("  every frame against the mean of the others, RMS difference (px): "
          + ", ".join(f"{i}: {v:.3f}" for i, v in s["diff"].items()))


def leave_one_out(planes: dict) -> None:
    """Calibrate from three floors, correct the fourth (frames 2-5); print its blocks' RMS before and after."""
    floors = {}
    for i in SHARED:
        d = cv2.imread(str(ROOT / f"{i}.pgm"), cv2.IMREAD_UNCHANGED).astype(float) / 1000.0
        floors[i] = np.where(planes[i][1], d, 0.0)
    print("\nleave one out (real frames): the pattern from the other three floors removed from one")
    rms_b, rms_a = [], []
    for i in SHARED:
        corr = calibrate_depth_pattern([floors[j] for j in SHARED if j != i], step_px=B, min_plane_fraction=0.05,
                                       min_samples=B * B // 4)
        seen = np.zeros((H, W), bool)
        for j in SHARED:
            if j != i:
                seen |= planes[j][1]
        mask = planes[i][1] & seen
        before = block_residual(floor_plane(floors[i], REGIONS[i])[0], mask)
        after = block_residual(floor_plane(corr.apply(floors[i]), REGIONS[i])[0], mask)
        both = np.isfinite(before) & np.isfinite(after)
        b, a = float(np.sqrt(np.mean(before[both] ** 2))), float(np.sqrt(np.mean(after[both] ** 2)))
        rms_b.append(b)
        rms_a.append(a)
        print(f"  frame {i}: {both.sum()} blocks, RMS {b:.3f} -> {a:.3f} px ({100 * (1 - a / b):.0f} % less)")
    print(f"  mean RMS {np.mean(rms_b):.3f} -> {np.mean(rms_a):.3f} px")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--pattern-px", type=float, default=KINECT_PATTERN_DISPARITY_PX,
                    help="the lab's pattern RMS, disparity px (default the measured Kinect's)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2], help="the lab's pattern seeds (units)")
    args = ap.parse_args(argv)
    if not ROOT.is_dir():
        print(f"skipped: {ROOT} is not here (the real frames)")
        return 0
    print(f"# {platform.node()} {platform.processor() or platform.machine()}, python {sys.version.split()[0]}")
    real, planes = {}, {}
    for i, region in REGIONS.items():
        d = cv2.imread(str(ROOT / f"{i}.pgm"), cv2.IMREAD_UNCHANGED).astype(float) / 1000.0
        res, mask = floor_plane(d, region)
        with np.errstate(divide="ignore"):
            plane_m = np.where(mask, 1.0 / (1.0 / d - res), np.inf)       # the fitted plane on the floor's pixels
        planes[i] = (plane_m, mask)
        real[i] = block_residual(res)
        print(f"frame {i}: floor {mask.sum()} px, median depth {np.median(plane_m[mask]):.2f} m")
    s = summary(real)
    print_summary("real Kinect (rgbd_kinect_room)", s)
    leave_one_out(planes)
    z_ref = 2.6
    print(f"  shared RMS as depth at {z_ref} m: {s['shared_rms'] / KINECT_FOCAL_BASELINE_PX_M * z_ref ** 2 * 1e3:.1f} mm "
          f"({s['shared_rms'] / KINECT_FOCAL_BASELINE_PX_M * z_ref * 100:.2f} %)")
    for seed in args.seeds:
        model = DepthSensorModel(pattern_disparity_px=args.pattern_px, pattern_seed=seed)
        lab = {}
        for i in REGIONS:
            d = lab_frame(planes[i][0], model, np.random.default_rng([seed, i]))
            lab[i] = block_residual(floor_plane(d, REGIONS[i])[0])
        ls = summary(lab)
        print_summary(f"lab, pattern {args.pattern_px} px, corr {KINECT_PATTERN_CORR_PX} px, unit {seed}", ls)
        print(f"  ratio lab / real: shared RMS {ls['shared_rms'] / s['shared_rms']:.2f}, "
              f"32 px lag u {ls['lag_u'][1] / s['lag_u'][1]:.2f}, v {ls['lag_v'][1] / s['lag_v'][1]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
