"""Colour and Kinect-like RGB-D frames of the virtual lab (the rendering front end).

The work is split by concept: :mod:`~tudorvision.sim.shapes` (analytic shapes
and the :class:`Scene`), :mod:`~tudorvision.sim.raycast` (one ray per pixel
centre, distortion included, each shape intersected only inside its projected
bounding box; the G-buffer), :mod:`~tudorvision.sim.lighting` (light terms and
the sensor) and :mod:`~tudorvision.sim.depth_sensor` (Kinect depth noise).
This module shades frames over an exposure and re-exports the public names of
the others, so ``from tudorvision.sim.render import Scene`` keeps working.

A :class:`Scene` has *static* shapes (rendered once per camera and cached) and
optional *dynamic* shapes given as a function of time ``t -> [shapes]``. A
colour frame integrates the dynamic shapes over the exposure (motion blur from
``n_subframes`` sub-frames) and, with a rolling shutter, exposes row ``r`` from
``t + r * line_time_s``. Only the dynamic shapes are re-cast per sub-frame.

Object ids: 0 is "no hit", static shape ``i`` has id ``i + 1`` and dynamic shape
``j`` (in the order the time function returns them) has id ``n_static + 1 + j``.

Assumptions: Lambertian surfaces, no shadows or inter-reflections, lighting
evaluated at the middle of the exposure, pinhole rays through pixel centres
(no anti-aliasing).
"""
from __future__ import annotations

import numpy as np

from .camera import PinholeCamera
from .depth_sensor import DepthModel, depth_mm_from_gbuffer, depth_sigma_m
from .lighting import SensorModel, apply_sensor, intensity_at, light_terms, weighted_sum
from .raycast import (GBuffer, cast_rays, dynamic_hits, pixel_bbox, pixel_bboxes, render_gbuffer, static_cast,
                      surface_at)
from .shapes import Box, Capsule, Cylinder, Disc, Rectangle, Scene, Sphere

__all__ = [
    "Sphere", "Rectangle", "Disc", "Box", "Capsule", "Cylinder", "Scene", "GBuffer",
    "render_gbuffer", "render_radiance", "render_bgr", "DepthModel", "depth_sigma_m",
    "depth_mm_from_gbuffer", "render_rgbd", "exposure_times", "cast_rays", "pixel_bbox", "pixel_bboxes",
    "SensorModel",
]


def _check_timing(exposure_s, n_subframes, line_time_s, band_rows):
    if not exposure_s >= 0:
        raise ValueError(f"exposure_s: expected >= 0, got {exposure_s!r}")
    if int(n_subframes) != n_subframes or n_subframes < 1:
        raise ValueError(f"n_subframes: expected a positive integer, got {n_subframes!r}")
    if not line_time_s >= 0:
        raise ValueError(f"line_time_s: expected >= 0, got {line_time_s!r}")
    if int(band_rows) != band_rows or band_rows < 1:
        raise ValueError(f"band_rows: expected a positive integer, got {band_rows!r}")


def exposure_times(t: float, *, exposure_s: float = 0.0, n_subframes: int = 1, row: int = 0,
                   line_time_s: float = 0.0) -> np.ndarray:
    """Times at which :func:`render_radiance` samples the dynamic shapes for image row ``row``.

    Average ground truth (e.g. a sphere's silhouette centroid) over these
    times to match a blurred frame. With a rolling shutter the renderer
    rounds them to its band grid (see :func:`render_radiance`).

    Examples
    --------
    >>> exposure_times(1.0, exposure_s=0.02, n_subframes=4).round(4).tolist()
    [1.0025, 1.0075, 1.0125, 1.0175]
    """
    _check_timing(exposure_s, n_subframes, line_time_s, 1)
    start = t + row * line_time_s
    if exposure_s == 0:
        return np.array([start])
    K = int(n_subframes)
    return start + exposure_s * (np.arange(K) + 0.5) / K


def render_radiance(camera: PinholeCamera, scene: Scene, t: float, *, exposure_s: float = 0.0,
                    n_subframes: int = 1, line_time_s: float = 0.0, band_rows: int = 4) -> np.ndarray:
    """Linear RGB radiance of a frame whose exposure starts at ``t``.

    Row ``r`` integrates ``[t + r line_time_s, t + r line_time_s + exposure_s]``
    with ``n_subframes`` samples at the sub-interval midpoints (one sample at
    the start when ``exposure_s`` is 0). With a rolling shutter
    (``line_time_s > 0``) the dynamic shapes are evaluated on a time grid of
    ``band_rows`` line times: each band of ``band_rows`` rows takes the time
    of its middle row and sub-frame offsets are rounded to the grid, so the
    timing error is at most about ``band_rows / 2`` line times.

    Returns
    -------
    ndarray, shape (H, W, 3), float32
    """
    _check_timing(exposure_s, n_subframes, line_time_s, band_rows)
    H = camera.height
    st = static_cast(camera, scene)
    t_light = t + 0.5 * exposure_s + 0.5 * (H - 1) * line_time_s
    gains = np.array([intensity_at(light, t_light) for light in scene.lights], np.float32)
    base = weighted_sum(gains, st.terms)
    if scene.dynamic is None:
        return base
    K = int(n_subframes) if exposure_s > 0 else 1
    offsets = exposure_s * (np.arange(K) + 0.5) / K if exposure_s > 0 else np.zeros(1)
    if line_time_s > 0:
        # time grid of one band: shapes evaluated once per grid time and shared by the bands
        step = band_rows * line_time_s
        bands = _rolling_bands(camera, scene, t, exposure_s, line_time_s, int(band_rows))
        jobs = [((r0, r1), (r0 // band_rows) + int(round(off / step))) for r0, r1 in bands for off in offsets]

        def time_of(k):
            return t + (k * band_rows + 0.5 * (band_rows - 1)) * line_time_s
    else:
        jobs = [((0, H), k) for k in range(K)]

        def time_of(k):
            return t + offsets[k]
    cache = {}
    out = base.copy()
    for rows, k in jobs:
        if k not in cache:
            shapes = list(scene.dynamic(time_of(k)))
            cache[k] = (shapes, pixel_bboxes(camera, [sh.corners() for sh in shapes]))
        shapes, boxes = cache[k]
        for j, shape, rr, cc, tj in dynamic_hits(camera, shapes, boxes, st, rows):
            p, n, a = surface_at(camera, shape, rr, cc, tj)
            rad = weighted_sum(gains, light_terms(scene.lights, p, n, a))
            out[rr, cc] += (rad - base[rr, cc]) / K
    return out


def _rolling_bands(camera, scene, t, exposure_s, line_time_s, band_rows):
    """Row bands that a dynamic shape can touch during the rolling read-out."""
    H = camera.height
    times = t + np.linspace(0.0, (H - 1) * line_time_s + exposure_s, 9)
    rows = []
    for tt in times:
        boxes = pixel_bboxes(camera, [shape.corners() for shape in scene.dynamic(tt)])
        rows.append([(b[0], b[1]) if b is not None else (np.nan, np.nan) for b in boxes])
    rows = np.array(rows, dtype=float).reshape(len(times), -1, 2)
    if rows.size == 0 or np.all(np.isnan(rows)):
        return []
    # pad by the largest row motion of a shape between two samples
    pad = 4 + int(np.nan_to_num(np.abs(np.diff(rows, axis=0)), nan=0.0).max(initial=0))
    lo, hi = max(int(np.nanmin(rows[..., 0])) - pad, 0), min(int(np.nanmax(rows[..., 1])) + pad, H)
    start = (lo // band_rows) * band_rows
    return [(r0, min(r0 + band_rows, H)) for r0 in range(start, hi, band_rows)]


def render_bgr(camera: PinholeCamera, scene: Scene, t: float, *, rng: np.random.Generator | None = None,
               sensor: SensorModel = SensorModel(), exposure_s: float = 0.0, n_subframes: int = 1,
               line_time_s: float = 0.0, band_rows: int = 4) -> np.ndarray:
    """8-bit BGR colour frame (see :func:`render_radiance` for the timing options).

    Parameters
    ----------
    camera : PinholeCamera
        Intrinsics, distortion and pose ``T_world_cam`` of the camera.
    scene : Scene
        Shapes (world frame, metres) and lights.
    t : float
        Start of the exposure, seconds (scene time).
    rng : numpy.random.Generator, optional
        Sensor-noise source; None renders without noise.
    sensor : SensorModel, optional
        Gain, noise, ADC and gamma of the image sensor.
    exposure_s : float, optional
        Exposure time, seconds (>= 0; 0: one instant, no motion blur).
    n_subframes : int, optional
        Samples integrated over the exposure for motion blur (>= 1).
    line_time_s : float, optional
        Rolling-shutter delay between successive rows, seconds (0: global shutter).
    band_rows : int, optional
        Rows per time band of the rolling-shutter approximation (>= 1).

    Returns
    -------
    ndarray, shape (H, W, 3), uint8, BGR order
        The colour image (u right, v down).

    Raises
    ------
    ValueError
        If a timing option is out of range.
    """
    rad = render_radiance(camera, scene, t, exposure_s=exposure_s, n_subframes=n_subframes,
                          line_time_s=line_time_s, band_rows=band_rows)
    return apply_sensor(rad, sensor, rng)


def render_rgbd(camera: PinholeCamera, scene: Scene, t: float, *, rng: np.random.Generator | None = None,
                depth_model: DepthModel = DepthModel(), sensor: SensorModel = SensorModel(),
                exposure_s: float = 0.0, n_subframes: int = 1):
    """Kinect-like frame: colour and registered depth from the same viewpoint at time ``t``.

    Parameters
    ----------
    camera : PinholeCamera
        Intrinsics, distortion and pose ``T_world_cam`` of the RGB-D camera.
    scene : Scene
        Shapes (world frame, metres) and lights.
    t : float
        Frame time, seconds (scene time; start of the colour exposure).
    rng : numpy.random.Generator, optional
        Source of the sensor and depth noise; None renders without noise.
    depth_model : DepthModel, optional
        Depth noise, quantisation and range of the depth sensor.
    sensor : SensorModel, optional
        Gain, noise, ADC and gamma of the colour sensor.
    exposure_s : float, optional
        Colour exposure time, seconds (>= 0).
    n_subframes : int, optional
        Samples integrated over the colour exposure for motion blur (>= 1).

    Returns
    -------
    bgr : ndarray, shape (H, W, 3), uint8
        Colour image, BGR order.
    depth : ndarray, shape (H, W), uint16
        z in ``1 / depth_model.units_per_m`` metres (millimetres by default), 0 invalid.
    gbuffer : GBuffer
        The noise-free snapshot at ``t`` (ground truth).
    """
    gb = render_gbuffer(camera, scene, t)
    bgr = render_bgr(camera, scene, t, rng=rng, sensor=sensor, exposure_s=exposure_s, n_subframes=n_subframes)
    return bgr, depth_mm_from_gbuffer(gb, depth_model, rng), gb
