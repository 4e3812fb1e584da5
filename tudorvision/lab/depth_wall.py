"""Frames of a flat wall through the lab's depth sensor: the recording a depth pattern calibration needs.

A user points the depth camera at a flat wall from a few distances and
angles (:func:`tudorvision.rgbd.depth_pattern.calibrate_depth_pattern`); the
lab renders the same: a plane filling the view at each distance, tilted by a
random angle up to ``max_tilt_deg`` about a random axis in the image plane,
seen through the sensor model (its noise, range and fixed pattern,
:func:`tudorvision.sim.depth_sensor.depth_mm_from_gbuffer`).
"""
from __future__ import annotations

import numpy as np

from ..sim.depth_sensor import DepthSensorModel, depth_mm_from_gbuffer
from ..sim.raycast import GBuffer

__all__ = ["wall_depth_m", "depth_frames_mm", "render_wall_frames", "record_rgbd_wall", "WALL_DISTANCES_M"]

#: Wall distances of the ``rgbd-wall`` recording, metres (one sequence each).
WALL_DISTANCES_M = (2.5, 3.5, 4.5)


def wall_depth_m(K, width: int, height: int, distance_m: float, normal_cam) -> np.ndarray:
    """True depth (z, metres) of the plane ``normal_cam . X = distance_m`` seen by a pinhole camera.

    Parameters
    ----------
    K : array_like, shape (3, 3)
        Intrinsics, pixels.
    width, height : int
        Image size, pixels.
    distance_m : float
        The plane's distance from the optical centre, metres.
    normal_cam : array_like, shape (3,)
        Its unit normal in the camera frame, pointing away from the camera (z > 0).

    Returns
    -------
    ndarray, shape (height, width)
        z per pixel; ``inf`` where the ray misses the plane.

    Examples
    --------
    >>> K = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    >>> z = wall_depth_m(K, 640, 480, 3.0, [0, 0, 1])
    >>> float(z.min()), float(z.max())
    (3.0, 3.0)
    """
    K = np.asarray(K, dtype=np.float64)
    n = np.asarray(normal_cam, dtype=np.float64)
    n = n / np.linalg.norm(n)
    vv, uu = np.mgrid[0:height, 0:width].astype(np.float64)
    dot = n[0] * (uu - K[0, 2]) / K[0, 0] + n[1] * (vv - K[1, 2]) / K[1, 1] + n[2]
    with np.errstate(divide="ignore"):
        return np.where(dot > 1e-6, float(distance_m) / np.where(dot > 1e-6, dot, 1.0), np.inf)


def render_wall_frames(K, width: int, height: int, sensor: DepthSensorModel, rng: np.random.Generator, *,
                       distances_m=WALL_DISTANCES_M, frames_per_distance: int = 10,
                       max_tilt_deg: float = 15.0) -> np.ndarray:
    """Depth frames of a flat wall at each distance, one random tilt per distance, noise drawn per frame.

    Parameters
    ----------
    K : array_like, shape (3, 3)
        Intrinsics, pixels.
    width, height : int
        Image size, pixels.
    sensor : DepthSensorModel
        The depth camera (its pattern is the one to calibrate).
    rng : numpy.random.Generator
        Tilts and noise.
    distances_m : sequence of float
        Wall distances, metres.
    frames_per_distance : int
        Frames at each.
    max_tilt_deg : float
        Largest tilt of the wall from facing the camera, degrees.

    Returns
    -------
    ndarray, shape (len(distances_m) * frames_per_distance, height, width), float32
        Depth in metres, NaN invalid.
    """
    out = []
    for d in distances_m:
        z = wall_depth_m(K, width, height, float(d), _tilted_normal(rng, max_tilt_deg))
        for raw in depth_frames_mm(z, sensor, rng, frames_per_distance):
            f = raw.astype(np.float32) / np.float32(sensor.units_per_m)
            f[raw == 0] = np.nan
            out.append(f)
    return np.stack(out)


def _tilted_normal(rng: np.random.Generator, max_tilt_deg: float) -> np.ndarray:
    """A wall's unit normal, tilted from the optical axis by up to ``max_tilt_deg`` about a random axis."""
    tilt = np.radians(float(max_tilt_deg)) * np.sqrt(rng.uniform())
    axis = rng.uniform(0.0, 2 * np.pi)
    return np.array([np.sin(tilt) * np.cos(axis), np.sin(tilt) * np.sin(axis), np.cos(tilt)])


def depth_frames_mm(z_m, sensor: DepthSensorModel, rng: np.random.Generator, n: int) -> list:
    """``n`` raw frames of the sensor seeing a known true depth map (one surface, no edges inside it).

    Parameters
    ----------
    z_m : ndarray, shape (H, W)
        True depth (z), metres; ``inf`` where nothing is seen.
    sensor : DepthSensorModel
        Range, noise, fixed pattern, output scale.
    rng : numpy.random.Generator
        Noise, drawn per frame.
    n : int
        Frames.

    Returns
    -------
    list of ndarray, shape (H, W), uint16
        Depth in ``1 / sensor.units_per_m`` metres, 0 invalid.
    """
    h, w = z_m.shape
    gb = GBuffer(distance_m=z_m, depth_m=z_m, normal_world=np.zeros((h, w, 3), np.float32),
                 object_id=np.ones((h, w), np.int32), albedo_rgb=np.full((h, w, 3), 0.5, np.float32))
    return [depth_mm_from_gbuffer(gb, sensor, rng) for _ in range(int(n))]


def record_rgbd_wall(out, opts, *, calibration):
    """``tudorvision sim record rgbd-wall``: the lab's Kinect before a flat wall, one sequence per distance.

    What ``tudorvision calib rgbd-pattern`` needs: :data:`WALL_DISTANCES_M`, a random tilt (up to 15 deg)
    each, ``opts.frames`` frames per distance (default 10; 4 with ``opts.small``), the camera of
    ``calibration`` (the Kinect of the other RGB-D kinds) and the lab's depth sensor (its noise and its
    fixed pattern, unit 0 like every recording of the lab), depth only (the colour image is grey).

    Parameters
    ----------
    out : str or Path
        Folder to write (``wall_2.50m`` ... under it).
    opts : RecordOptions
        ``seed``, ``frames``, ``small``, the image format and ``force``.
    calibration : tudorvision.io.Calibration
        What the recordings' ``calibration.yaml`` holds; its ``rgbd`` camera is the one rendered.

    Returns
    -------
    Path
        ``out``.
    """
    from pathlib import Path

    from ..io import SequenceWriter
    from ..sim.scenes import KINECT_RATE_HZ

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    cam = calibration.cameras["rgbd"]
    sensor = DepthSensorModel()
    n = int(opts.frames or (4 if opts.small else 10))
    rng = np.random.default_rng([int(opts.seed), 17])
    grey = np.full((cam.height, cam.width, 3), 128, np.uint8)
    for d in WALL_DISTANCES_M:
        z = wall_depth_m(cam.K, cam.width, cam.height, d, _tilted_normal(rng, 15.0))
        with SequenceWriter(out / f"wall_{d:.2f}m", kind="rgbd", rate_hz=KINECT_RATE_HZ,
                            depth_scale=sensor.units_per_m, calibration=calibration,
                            image_ext=opts.image_ext, jpeg_quality=opts.jpeg_quality,
                            description=f"flat wall about {d:.2f} m away, tilted up to 15 deg",
                            meta={"generator": "tudorvision sim record", "seed": int(opts.seed)},
                            overwrite=opts.force) as w:
            for k, raw in enumerate(depth_frames_mm(z, sensor, rng, n)):
                w.add_rgbd(k / KINECT_RATE_HZ, grey, raw)
    return out
