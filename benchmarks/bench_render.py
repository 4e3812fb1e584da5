"""Rendering speed of the virtual lab's cameras.

Times, on the 640x480 stereo lab scene (about 30 static shapes, a moving arm
of 13 dynamic shapes):

* a stereo pair per frame with the static background cached (a recorded
  sequence: the usual case), without blur, with motion blur of K sub-frames,
  and with a rolling shutter;
* a stereo pair rendered from scratch (static background re-cast);
* the peer: a naive renderer that intersects every shape with every pixel ray
  (no bounding-box culling, no static cache), then shades per object;
* one Kinect-like RGB-D frame (colour + depth) of the ball-throw scene.

Run: ``.venv/bin/python benchmarks/bench_render.py [--repeats N]``
"""
from __future__ import annotations

import argparse
import platform
import time

import numpy as np

from tudorvision.sim.camera import ray_directions_world
from tudorvision.sim.lighting import apply_sensor, intensity_at, light_terms, weighted_sum
from tudorvision.sim.render import SensorModel, _surface, cast_rays, render_bgr, render_rgbd
from tudorvision.sim.scenes import arm_geometry_from_joints, stereo_lab
from tudorvision.sim.scenes_rgbd import ball_throw, ballistic
from tudorvision.robot import load_robot_params


def naive_bgr(camera, scene, t, rng):
    """Peer: every shape against every ray, no cache; same shading and sensor."""
    shapes = list(scene.static) + list(scene.dynamic(t) if scene.dynamic else [])
    dist, ids, _ = cast_rays(camera, shapes, cull=False)
    gains = np.array([intensity_at(light, t) for light in scene.lights], np.float32)
    rad = np.zeros((camera.height, camera.width, 3), np.float32)
    for i, shape in enumerate(shapes):
        rr, cc = np.nonzero(ids == i + 1)
        if rr.size:
            p, n, a = _surface(camera, shape, rr, cc, dist[rr, cc])
            rad[rr, cc] = weighted_sum(gains, light_terms(scene.lights, p, n, a))
    return apply_sensor(rad, SensorModel(), rng)


def timed(fn, repeats):
    best = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best.append(time.perf_counter() - t0)
    return float(np.median(best))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    rng = np.random.default_rng(0)
    params = load_robot_params()
    th0 = np.array([0.3, 0.8, 0.6])

    def arm(t):
        return arm_geometry_from_joints(th0 + np.array([0.5, 2.0, -1.0]) * t, params, n_points=5)

    setup = stereo_lab(rng, arm=arm)
    left, right = setup.cameras["left"], setup.cameras["right"]
    for cam in (left, right):
        ray_directions_world(cam)  # per-camera ray table, built once per camera
    n_static, n_dyn = setup.scene.n_static, len(setup.scene.dynamic(0.0))
    frame = iter(range(10 ** 9))

    def pair(**kw):
        t = next(frame) / 50.0
        render_bgr(left, setup.scene, t, rng=rng, **kw)
        render_bgr(right, setup.scene, t, rng=rng, **kw)

    def pair_cold():
        fresh = stereo_lab(np.random.default_rng(1), arm=arm)
        t = next(frame) / 50.0
        render_bgr(left, fresh.scene, t, rng=rng)
        render_bgr(right, fresh.scene, t, rng=rng)

    def pair_naive():
        t = next(frame) / 50.0
        naive_bgr(left, setup.scene, t, rng)
        naive_bgr(right, setup.scene, t, rng)

    pair()  # warm the static cache
    res = {
        "stereo pair, cached background, no blur": timed(pair, args.repeats),
        "stereo pair, cached background, blur K=4": timed(lambda: pair(exposure_s=0.01, n_subframes=4), args.repeats),
        "stereo pair, cached background, blur K=8": timed(lambda: pair(exposure_s=0.01, n_subframes=8), args.repeats),
        "stereo pair, rolling shutter 40 us/line": timed(lambda: pair(line_time_s=4e-5), args.repeats),
        "stereo pair, rolling shutter + blur K=8": timed(
            lambda: pair(line_time_s=4e-5, exposure_s=0.01, n_subframes=8), args.repeats),
        "stereo pair, from scratch (culling, no cache)": timed(pair_cold, args.repeats),
        "stereo pair, naive peer (no culling, no cache)": timed(pair_naive, max(2, args.repeats // 2)),
    }
    throw = ball_throw(ballistic([0.2, -5.0, 1.5], [0.0, 5.0, 2.5]), rng)
    cam = throw.cameras["rgbd"]
    ray_directions_world(cam)
    render_rgbd(cam, throw.scene, 0.0, rng=rng)
    res["RGB-D frame (colour + depth), ball throw"] = timed(
        lambda: render_rgbd(cam, throw.scene, next(frame) / 300.0, rng=rng), args.repeats)

    print(f"machine: {platform.processor() or platform.machine()}, numpy {np.__version__}, "
          f"python {platform.python_version()}")
    print(f"stereo lab: {n_static} static + {n_dyn} dynamic shapes, 640x480 per camera; median of "
          f"{args.repeats} runs")
    for name, sec in res.items():
        print(f"  {name:50s} {sec * 1000:8.1f} ms")
    naive = res["stereo pair, naive peer (no culling, no cache)"]
    print(f"  ratio naive / cached (no blur):      {naive / res['stereo pair, cached background, no blur']:6.1f}x")
    scratch = res["stereo pair, from scratch (culling, no cache)"]
    print(f"  ratio naive / from scratch (culling): {naive / scratch:6.1f}x")


if __name__ == "__main__":
    main()
