"""Triangulation benchmark: throughput and accuracy on a synthetic lab stereo rig.

Rig: two 640x480 cameras (f = 700 px, wide-angle distortion k1 ~ -0.2) under
the ceiling, 3 m baseline, convergent toward the robot base, as in section
2.4. Points are drawn uniformly in TUDOR's workspace.

Compared, on one core (OpenCV and BLAS limited to one thread):

* ``ours``: :func:`tudorvision.stereo.triangulate.triangulate_stereo`
  (vectorised undistortion to normalised coordinates + one
  ``cv2.triangulatePoints`` call on float64 2xN arrays), both routes;
* ``numpy DLT``: undistortion + the pure-numpy oracle :func:`triangulate_dlt`;
* ``per-point cv2``: the tutorial pattern, one ``undistortPoints`` and one
  ``triangulatePoints`` call per point;
* ``tutorial raw``: the other tutorial shortcut, raw (distorted) pixels with
  ``K[I|0]`` / ``K[R|T]`` and float32, vectorised (accuracy only).

Accuracy is the RMS 3D error against the synthetic truth with Gaussian pixel
noise of 0.1 and 0.25 px. The rolling-shutter section triangulates a point
moving at 5.5 m/s (peak end-effector speed of figure 2.7) with and without
:func:`compensate_rolling_shutter`.

Run::

    .venv/bin/python benchmarks/bench_triangulate.py [--n 100000] [--repeat 5]
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from tudorvision.geometry import invert_transform, make_frame, transform_points  # noqa: E402
from tudorvision.io.calibration import Calibration, CameraModel, StereoExtrinsics  # noqa: E402
from tudorvision.stereo.triangulate import (compensate_rolling_shutter, projection_matrices,  # noqa: E402
                                            triangulate_dlt, triangulate_spheres, triangulate_stereo,
                                            undistort_points)

K = np.array([[700.0, 0.0, 319.5], [0.0, 700.0, 239.5], [0.0, 0.0, 1.0]])
DIST_L = np.array([-0.21, 0.07, 4e-4, -3e-4, -0.01])
DIST_R = np.array([-0.19, 0.05, -2e-4, 5e-4, 0.0])
LINE_TIME = 0.018 / 480


def _pose(pos):
    pos = np.asarray(pos, float)
    z = np.array([0.0, 0.0, 0.6]) - pos
    return make_frame(pos, z, np.cross(z, [0.0, 0.0, 1.0]))


T_BASE_LEFT = _pose([-1.5, -2.4, 2.7])
T_BASE_RIGHT = _pose([1.5, -2.4, 2.7])
T_RIGHT_LEFT = invert_transform(T_BASE_RIGHT) @ T_BASE_LEFT
CAL = Calibration(
    cameras={"left": CameraModel(K=K, dist=DIST_L, width=640, height=480, line_time_s=LINE_TIME),
             "right": CameraModel(K=K, dist=DIST_R, width=640, height=480, line_time_s=LINE_TIME)},
    stereo=StereoExtrinsics(R=T_RIGHT_LEFT[:3, :3], T=T_RIGHT_LEFT[:3, 3]))


def project(points_base, T_base_cam, dist):
    p = transform_points(invert_transform(T_base_cam), points_base)
    uv, _ = cv2.projectPoints(p.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), K, dist)
    return uv.reshape(-1, 2)


def workspace(rng, n):
    r = rng.uniform(0.1, 0.84, n)
    a = rng.uniform(-np.pi, np.pi, n)
    return np.column_stack([r * np.cos(a), r * np.sin(a), rng.uniform(0.0, 1.2, n)])


def numpy_dlt(uv_l, uv_r):
    na, nb = undistort_points(uv_l, K, DIST_L), undistort_points(uv_r, K, DIST_R)
    P1, P2 = projection_matrices(np.eye(3), np.eye(3), T_RIGHT_LEFT[:3, :3], T_RIGHT_LEFT[:3, 3])
    return triangulate_dlt(na, nb, P1, P2)


def per_point_cv2(uv_l, uv_r):
    P1, P2 = projection_matrices(np.eye(3), np.eye(3), T_RIGHT_LEFT[:3, :3], T_RIGHT_LEFT[:3, 3])
    out = np.empty((len(uv_l), 3))
    for i in range(len(uv_l)):
        a = cv2.undistortPoints(uv_l[i].reshape(1, 1, 2), K, DIST_L)
        b = cv2.undistortPoints(uv_r[i].reshape(1, 1, 2), K, DIST_R)
        X = cv2.triangulatePoints(P1, P2, a.reshape(2, 1), b.reshape(2, 1))
        out[i] = X[:3, 0] / X[3, 0]
    return out


def tutorial_raw(uv_l, uv_r):
    P1, P2 = projection_matrices(K, K, T_RIGHT_LEFT[:3, :3], T_RIGHT_LEFT[:3, 3])
    X = cv2.triangulatePoints(P1.astype(np.float32), P2.astype(np.float32),
                              uv_l.T.astype(np.float32), uv_r.T.astype(np.float32))
    return (X[:3] / X[3]).T.astype(np.float64)


def best_time(fn, repeat):
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def rms_error(points_left, truth_base):
    p = transform_points(T_BASE_LEFT, points_left)
    return float(np.sqrt(np.mean(np.sum((p - truth_base) ** 2, axis=1))))


def moving_point(t):
    w = 5.5 / 0.84
    return np.stack([0.84 * np.cos(w * t), 0.84 * np.sin(w * t), 0.7 + 0.3 * np.sin(3.0 * t)], axis=-1)


def rolling_capture(t_frame, T_base_cam, dist):
    tc = np.array(t_frame, float)
    for _ in range(30):
        uv = project(moving_point(tc), T_base_cam, dist)
        tc = t_frame + uv[:, 1] * LINE_TIME
    return project(moving_point(tc), T_base_cam, dist)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, default=100_000, help="points for the vectorised runs")
    ap.add_argument("--n-loop", type=int, default=5_000, help="points for the per-point loop")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    rng = np.random.default_rng(args.seed)
    print(f"machine: {platform.processor() or platform.machine()}, {platform.system()}, "
          f"python {platform.python_version()}, numpy {np.__version__}, opencv {cv2.__version__}, "
          f"1 thread")

    X = workspace(rng, args.n)
    uv_l, uv_r = project(X, T_BASE_LEFT, DIST_L), project(X, T_BASE_RIGHT, DIST_R)
    print(f"\n== throughput, N = {args.n} points (per-point loop on {args.n_loop}) ==")
    rates = {}
    for name, fn in (("ours normalized", lambda: triangulate_stereo(uv_l, uv_r, CAL)),
                     ("ours rectified", lambda: triangulate_stereo(uv_l, uv_r, CAL, method="rectified")),
                     ("numpy DLT oracle", lambda: numpy_dlt(uv_l, uv_r))):
        t = best_time(fn, args.repeat)
        rates[name] = args.n / t
        print(f"{name:22s} {t * 1e3:9.2f} ms   {rates[name] / 1e6:8.3f} M points/s")
    m = min(args.n_loop, args.n)
    t = best_time(lambda: per_point_cv2(uv_l[:m], uv_r[:m]), max(1, args.repeat // 2))
    rates["per-point cv2"] = m / t
    print(f"{'per-point cv2':22s} {t * 1e3 * args.n / m:9.2f} ms*  {rates['per-point cv2'] / 1e6:8.3f} M points/s"
          "   (*extrapolated)")
    base = rates["ours normalized"]
    print(f"ratio ours/numpy DLT: {base / rates['numpy DLT oracle']:.1f}x, "
          f"ours/per-point cv2: {base / rates['per-point cv2']:.0f}x")
    # per-frame use: two spheres per stereo pair, one call per frame
    one = {"red": uv_l[:1], "green": uv_l[1:2]}
    two = {"red": uv_r[:1], "green": uv_r[1:2]}
    reps = 2000
    t0 = time.perf_counter()
    for _ in range(reps):
        triangulate_spheres(one, two, CAL, T_base_left=T_BASE_LEFT)
    per_frame = (time.perf_counter() - t0) / reps
    print(f"per-frame triangulate_spheres (2 spheres, base frame): {per_frame * 1e6:.0f} us "
          f"= {1 / per_frame:.0f} frames/s")

    print("\n== accuracy, RMS 3D error vs synthetic truth (workspace, 3 m baseline) ==")
    n_acc = min(args.n, 20_000)
    Xa = X[:n_acc]
    print("(per-point column on the first 2000 points; 'tut. raw' skips undistortion)")
    print(f"{'noise':>8s} {'ours':>10s} {'rectified':>10s} {'numpy DLT':>10s} {'per-point':>10s} "
          f"{'tut. raw':>10s}  ratio raw/ours")
    for sigma in (0.0, 0.1, 0.25):
        nl = uv_l[:n_acc] + rng.normal(scale=sigma, size=(n_acc, 2))
        nr = uv_r[:n_acc] + rng.normal(scale=sigma, size=(n_acc, 2))
        e = [rms_error(triangulate_stereo(nl, nr, CAL), Xa),
             rms_error(triangulate_stereo(nl, nr, CAL, method="rectified"), Xa),
             rms_error(numpy_dlt(nl, nr), Xa),
             rms_error(per_point_cv2(nl[:2000], nr[:2000]), Xa[:2000]),
             rms_error(tutorial_raw(nl, nr), Xa)]
        ratio = f"  {e[4] / e[0]:10.1f}x" if sigma > 0 else ""
        print(f"{sigma:6.2f}px " + " ".join(f"{v * 1e3:8.3f}mm" for v in e) + ratio)

    print("\n== rolling shutter: point at 5.5 m/s, 50 Hz, 18 ms read-out ==")
    t = np.arange(250) * 0.02
    ul, ur = rolling_capture(t, T_BASE_LEFT, DIST_L), rolling_capture(t, T_BASE_RIGHT, DIST_R)
    truth = moving_point(t)
    raw = rms_error(triangulate_stereo(ul, ur, CAL), truth)
    comp = {}
    for order in (1, 2, 3):
        cl, _ = compensate_rolling_shutter(t, ul, LINE_TIME, order=order)
        cr, _ = compensate_rolling_shutter(t, ur, LINE_TIME, order=order)
        comp[order] = rms_error(triangulate_stereo(cl, cr, CAL), truth)
    print(f"uncompensated {raw * 1e3:.3f} mm; compensated linear {comp[1] * 1e3:.3f} mm, "
          f"quadratic {comp[2] * 1e3:.3f} mm, cubic {comp[3] * 1e3:.4f} mm "
          f"(cubic: {raw / comp[3]:.0f}x smaller)")
    t0 = time.perf_counter()
    compensate_rolling_shutter(t, ul, LINE_TIME)
    print(f"compensation cost: {(time.perf_counter() - t0) / len(t) * 1e6:.1f} us per sample")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
