"""How the lab's depth noise is correlated between pixels, against a real Kinect frame.

The peer is a real sensor: the flat desk top of the TUM RGB-D frame
``../shared/realdata/rgbd_tum_desk/1_depth.png`` (rows 330-380, columns
90-200, about 1.23 m away, Kinect, depth in 1/5000 m). The lab renders the
same surface (the smooth fit of the real patch, the same intrinsics) through
its depth sensor (:func:`tudorvision.sim.depth_sensor.depth_mm_from_gbuffer`)
with independent pixels (``noise_corr_px = (0, 0)``, the lab before
2026-11-27) and with the default correlated noise, ``--draws`` times each.

Per patch: the residual of a smooth fit (``1/z`` quadratic in the pixel
coordinates; ``--degree 1``: a plane), its standard deviation, its
correlation at 1, 2 and 4 px along rows (u) and columns (v), and how much of
the variance the means of k x k blocks keep (``var(block mean) / (var / k^2)``:
1 for independent pixels, k^2 for fully correlated ones: the pixels per
independent sample that the RGB-D ball detector's ``noise_correlation_px``
stands for). The lab's rows print the ratio to the real one.

Edge section: where a real Kinect puts a straight depth edge. The left and
right sides of the monitor in the same frame (rows 105-204, columns 215-409,
the monitor 1.35-1.7 m away): per row the first / last column inside that
range, the residual from a fitted line, its standard deviation (px) and its
correlation at 1, 2, 4 and 8 rows. The lab renders a straight step edge
(1.5 m in front of 2.5 m, a slope of 0.03 px per row, ``--draws`` sub-pixel
positions) with no edge jitter and with the default
(:data:`tudorvision.sim.depth_sensor.KINECT_EDGE_JITTER_PX`), measured the same way.

Run::

    .venv/bin/python benchmarks/bench_depth_noise_real.py [--draws 20] [--degree 2]
"""
from __future__ import annotations

import argparse
import platform
import sys
from pathlib import Path

import cv2
import numpy as np

from tudorvision.sim.depth_sensor import (KINECT_EDGE_JITTER_PX, KINECT_NOISE_CORR_PX, DepthSensorModel,
                                         depth_mm_from_gbuffer)
from tudorvision.sim.raycast import GBuffer

REAL = Path(__file__).resolve().parents[1] / ".." / "shared" / "realdata" / "rgbd_tum_desk" / "1_depth.png"
FX, FY, CX, CY = 520.9, 521.0, 325.1, 249.7            # TUM freiburg2 (SOURCES.md)
ROWS, COLS = (330, 380), (90, 200)
LAGS = (1, 2, 4)
BLOCKS = (4, 8)
EDGE_ROWS, EDGE_COLS, EDGE_RANGE_M = (105, 205), (215, 410), (1.35, 1.7)
EDGE_LAGS = (1, 2, 4, 8)


def smooth_fit(depth_m: np.ndarray, degree: int):
    """Fit ``1/z`` as a polynomial of (u, v) over the valid pixels of the patch; returns (fit, residual)."""
    vv, uu = np.mgrid[ROWS[0]:ROWS[1], COLS[0]:COLS[1]].astype(float)
    ok = depth_m > 0
    cols = [np.ones(uu.shape), uu, vv] + ([uu * uu, uu * vv, vv * vv] if degree == 2 else [])
    M = np.stack([c[ok] for c in cols], 1)
    coef, *_ = np.linalg.lstsq(M, 1.0 / depth_m[ok], rcond=None)
    fit = 1.0 / (np.stack(cols, -1) @ coef)
    res = np.where(ok, depth_m - fit, np.nan)
    return fit, res


def correlation(res: np.ndarray, du: int, dv: int) -> float:
    a, b = res[:res.shape[0] - dv, :res.shape[1] - du], res[dv:, du:]
    m = np.isfinite(a) & np.isfinite(b)
    a, b = a[m] - a[m].mean(), b[m] - b[m].mean()
    return float((a * b).mean() / np.sqrt((a * a).mean() * (b * b).mean()))


def block_ratio(res: np.ndarray, k: int) -> float:
    h, w = (res.shape[0] // k) * k, (res.shape[1] // k) * k
    means = np.nanmean(res[:h, :w].reshape(h // k, k, w // k, k), axis=(1, 3))
    return float(np.nanvar(means) / (np.nanvar(res) / k ** 2))


def stats(depth_m: np.ndarray, degree: int) -> dict:
    _, res = smooth_fit(depth_m, degree)
    out = {"std_mm": float(np.nanstd(res) * 1e3)}
    for lag in LAGS:
        out[f"u{lag}"] = correlation(res, lag, 0)
        out[f"v{lag}"] = correlation(res, 0, lag)
    for k in BLOCKS:
        out[f"block{k}"] = block_ratio(res, k)
    return out


def lab_patch(surface_m: np.ndarray, corr_px, rng) -> np.ndarray:
    """The lab's depth sensor on the fitted surface (a full 640 x 480 frame, the patch cut out), metres."""
    z = np.full((480, 640), np.inf)
    # the surface's fit extended a few pixels keeps the filter's border away from the patch
    z[ROWS[0] - 20:ROWS[1] + 20, COLS[0] - 20:COLS[1] + 20] = np.pad(surface_m, 20, mode="edge")
    gb = GBuffer(distance_m=z, depth_m=z, normal_world=np.zeros((480, 640, 3), np.float32),
                 object_id=np.ones((480, 640), np.int32), albedo_rgb=np.full((480, 640, 3), 0.5, np.float32))
    raw = depth_mm_from_gbuffer(gb, DepthSensorModel(noise_corr_px=corr_px, edge_jump_rel=1.0), rng)
    return raw[ROWS[0]:ROWS[1], COLS[0]:COLS[1]].astype(float) / 1000.0


def edge_columns(depth_m: np.ndarray, side: str) -> np.ndarray:
    """Per row of ``EDGE_ROWS``: the first (``side="left"``) or last column whose depth is in ``EDGE_RANGE_M``."""
    out = []
    for r in range(*EDGE_ROWS):
        seg = depth_m[r, EDGE_COLS[0]:EDGE_COLS[1]]
        idx = np.nonzero((seg > EDGE_RANGE_M[0]) & (seg < EDGE_RANGE_M[1]))[0]
        out.append(np.nan if len(idx) == 0 else EDGE_COLS[0] + (idx[0] if side == "left" else idx[-1]))
    return np.array(out, float)


def edge_stats(cols: np.ndarray) -> list:
    """Residual of the edge columns from a line: [sd (px), correlation at each of ``EDGE_LAGS`` rows]."""
    rows = np.arange(*EDGE_ROWS, dtype=float)
    m = np.isfinite(cols)
    res = cols[m] - np.polyval(np.polyfit(rows[m], cols[m], 1), rows[m])
    return [float(res.std())] + [float(np.corrcoef(res[:-k], res[k:])[0, 1]) for k in EDGE_LAGS]


def lab_edge(jitter_px, c0: float, rng) -> np.ndarray:
    """The lab's sensor on a straight step edge (1.5 m right of it, 2.5 m left), a 640 x 480 frame, metres."""
    vv, uu = np.mgrid[0:480, 0:640].astype(float)
    z = np.where(uu >= c0 + 0.03 * (vv - 240.0), 1.5, 2.5)
    gb = GBuffer(distance_m=z, depth_m=z, normal_world=np.zeros((480, 640, 3), np.float32),
                 object_id=np.ones((480, 640), np.int32), albedo_rgb=np.full((480, 640, 3), 0.5, np.float32))
    return depth_mm_from_gbuffer(gb, DepthSensorModel(edge_jitter_px=jitter_px), rng).astype(float) / 1000.0


def edge_section(real_full: np.ndarray, draws: int, rng) -> None:
    """Print the edge comparison (see the module docstring)."""
    head = f"{'depth edge':34s}{'sd_px':>9s}" + "".join(f"{'r' + str(k):>9s}" for k in EDGE_LAGS)
    print("\n" + head)
    for side in ("left", "right"):
        st = edge_stats(edge_columns(real_full, side))
        print(f"{'real Kinect, monitor ' + side:34s}" + "".join(f"{v:9.2f}" for v in st))
    for name, jit in (("lab, no edge jitter", (0.0, 0.0)), (f"lab, edge_jitter_px {KINECT_EDGE_JITTER_PX}",
                                                           KINECT_EDGE_JITTER_PX)):
        runs = [edge_stats(edge_columns(lab_edge(jit, 300.3 + 0.37 * i, rng), "left")) for i in range(draws)]
        print(f"{name:34s}" + "".join(f"{v:9.2f}" for v in np.mean(runs, axis=0)))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--draws", type=int, default=20, help="lab frames per setting (default 20)")
    ap.add_argument("--degree", type=int, choices=(1, 2), default=2, help="smooth fit: 1 plane, 2 quadratic 1/z")
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args(argv)
    if not REAL.exists():
        print(f"{REAL}: the real TUM frame is not here (../shared/realdata); nothing to compare with")
        return 2
    real_full = cv2.imread(str(REAL), cv2.IMREAD_UNCHANGED).astype(float) / 5000.0
    real = real_full[ROWS[0]:ROWS[1], COLS[0]:COLS[1]]
    surface, _ = smooth_fit(real, a.degree)
    keys = ["std_mm"] + [f"{ax}{lag}" for lag in LAGS for ax in "uv"] + [f"block{k}" for k in BLOCKS]
    print(f"machine: {platform.machine()}, {platform.python_version()}; patch rows {ROWS}, columns {COLS}, "
          f"1/z fit of degree {a.degree}, {a.draws} lab draws per setting\n")
    print(f"{'depth noise':34s}" + "".join(f"{k:>9s}" for k in keys))
    ref = stats(real, a.degree)
    print(f"{'real Kinect (TUM desk), the peer':34s}" + "".join(f"{ref[k]:9.2f}" for k in keys))
    rng = np.random.default_rng(a.seed)
    for name, corr in (("lab, independent pixels", (0.0, 0.0)), (f"lab, noise_corr_px {KINECT_NOISE_CORR_PX}",
                                                                   KINECT_NOISE_CORR_PX)):
        runs = [stats(lab_patch(surface, corr, rng), a.degree) for _ in range(a.draws)]
        mean = {k: float(np.mean([r[k] for r in runs])) for k in keys}
        print(f"{name:34s}" + "".join(f"{mean[k]:9.2f}" for k in keys))
        print(f"{'  / real':34s}" + "".join(f"{mean[k] / ref[k]:9.2f}" if abs(ref[k]) > 0.05 else f"{'-':>9s}"
                                             for k in keys))
    print("\n(std_mm: residual standard deviation; u1..v4: correlation at 1 / 2 / 4 px along rows (u) and columns"
          " (v); block4 / block8: variance kept by 4x4 / 8x8 block means, in units of independent pixels')")
    edge_section(real_full, a.draws, rng)
    print("(sd_px: the edge column's residual from a line; r1..r8: its correlation at 1 / 2 / 4 / 8 rows)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
