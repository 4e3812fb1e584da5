"""Appendix B.5 of the seed: stereo accuracy along a vertical rail.

The seed mounts the red and green tracking spheres on a slider of a vertical
rail (1.50 m long), placed at the centre of the robot workspace and 0.85 m
from it along the base x axis (tangent to the workspace), shifts the slider
in 50 mm steps from 300 to 1500 mm above the floor and records 100 images per
step. The triangulated positions should lie on a straight line; the seed
reports the mean and standard deviation of the deviation from the fitted
line per axis of the stereo camera frame and finds them within a 2 mm band
inside the workspace (figure B.3).

:func:`record_rail` renders that experiment in the virtual lab with the
ceiling stereo rig of :func:`tudorvision.sim.scenes.stereo_rig` (3 m
baseline, 700 px focal length, the seed's set-up) and writes an ordinary
stereo sequence (``docs/sequence_format.md``) that the normal tracking
pipeline reads; the truth (sphere centres, image centroids, the rail axis,
the slider height of every frame) is in ``groundtruth/`` only.
:func:`rail_deviation` is the evaluation: deviations of measured points from
their fitted straight line (and from the true line), per height and axis.

The rail is tilted by a small random angle per seed ("not perfectly aligned"),
the room, clutter and lighting are randomised per seed, and every frame has
its own sensor noise. The scene is static while the slider rests, so the
radiance is rendered once per height (at the time of the height's first
frame) and each of the ``frames_per_height`` images gets independent sensor
noise (and its own JPEG encoding). The robot arm is not drawn.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from .._checks import TudorVisionError
from .._progress import progress
from ..robot import load_robot_params
from ..sim.camera import PinholeCamera
from ..sim.lighting import SensorModel, apply_sensor
from ..sim.render import Box, Capsule, Scene, Sphere, render_radiance
from ..sim.scenes import GREEN_RGB, RED_RGB, SimSetup, StereoRigConfig, lab_room, sphere_image_truth, stereo_rig
from .record import calibration_from_cameras

__all__ = ["RAIL_HEIGHTS_M", "RAIL_POSITIONS_M", "RailOptions", "rail_lab", "record_rail", "fit_line",
           "rail_deviation", "RailDeviation", "heights_in_view",
           "user_pick_models"]

#: The seed's slider heights above the floor: 300 to 1500 mm in 50 mm steps (25 heights), metres.
RAIL_HEIGHTS_M = tuple(np.round(np.arange(0.30, 1.5001, 0.05), 3).tolist())

#: The seed's two rail places in the robot base frame (x, y), metres: the
#: workspace centre and 0.85 m from it along base x (tangent to the workspace).
RAIL_POSITIONS_M = {"centre": (0.0, 0.0), "border": (0.85, 0.0)}

RATE_HZ = 50.0


@dataclass(frozen=True, kw_only=True)
class RailOptions:
    """Set-up of one rail recording.

    Attributes
    ----------
    seed : int
        Seeds the room, clutter, lighting, rail tilt and sensor noise.
    rail_xy_m : tuple of 2 floats
        Where the sphere midpoint line meets the floor, base frame, metres
        (see :data:`RAIL_POSITIONS_M`).
    heights_m : tuple of floats
        Slider heights (sphere midpoint above the floor), metres.
    frames_per_height : int
        Images recorded at each height (the seed: 100).
    max_tilt_rad : float
        Largest random tilt of the rail from the vertical, radians.
    bar_yaw_rad : float
        Yaw of the bar carrying the spheres from the base x axis, radians
        (a random ±3 deg is added per seed).
    sphere_radius_m, sphere_separation_m : float or None
        Tracking spheres; None: the robot's (``load_robot_params``).
    rig : StereoRigConfig
        The ceiling stereo rig (default: the seed's, BRIEF).
    n_clutter, n_distractors : int
        Random boxes, and reddish and greenish look-alike objects, in the
        room (:func:`tudorvision.sim.scenes.lab_room`).
    image_ext, jpeg_quality : str, int
        Colour image format (the lab's default: JPEG, quality 92).
    sensor : SensorModel
        Image sensor noise model.
    skip_out_of_view : bool
        Leave out the heights at which a sphere is not wholly inside both
        images (listed in ``sequence.yaml`` as ``rail_heights_out_of_view_m``);
        False refuses them.
    show_progress : bool or None
        Progress bar on stderr (None: when stderr is a terminal).
    force : bool
        Replace a previous recording in a non-empty folder.
    """

    seed: int = 0
    rail_xy_m: tuple = RAIL_POSITIONS_M["centre"]
    heights_m: tuple = RAIL_HEIGHTS_M
    frames_per_height: int = 100
    max_tilt_rad: float = float(np.deg2rad(1.0))
    bar_yaw_rad: float = 0.0
    sphere_radius_m: float | None = None
    sphere_separation_m: float | None = None
    rig: StereoRigConfig = field(default_factory=StereoRigConfig)
    n_clutter: int = 8
    n_distractors: int = 4
    image_ext: str = ".jpg"
    jpeg_quality: int = 92
    sensor: SensorModel = field(default_factory=SensorModel)
    skip_out_of_view: bool = True
    show_progress: bool | None = False
    force: bool = False

    def __post_init__(self):
        h = np.asarray(self.heights_m, float)
        if h.ndim != 1 or h.size < 2 or not np.all(np.isfinite(h)) or np.any(h <= 0):
            raise ValueError(f"heights_m: expected at least two positive heights, got {self.heights_m!r}")
        if int(self.frames_per_height) != self.frames_per_height or self.frames_per_height < 1:
            raise ValueError(f"frames_per_height: expected an integer >= 1, got {self.frames_per_height!r}")
        if len(self.rail_xy_m) != 2:
            raise ValueError(f"rail_xy_m: expected (x, y), got {self.rail_xy_m!r}")


def _sphere_geometry(opts: RailOptions):
    p = load_robot_params()
    r = p.sphere_radius_m if opts.sphere_radius_m is None else float(opts.sphere_radius_m)
    sep = opts.sphere_separation_m
    if sep is None:
        off = p.sphere_offsets_ee_m
        sep = float(np.linalg.norm(np.subtract(off["red"], off["green"])))
    if not (r > 0 and sep > 2 * r):
        raise ValueError(f"spheres: need radius > 0 and separation > 2 radii, got {r!r}, {sep!r}")
    return r, float(sep)


def _rail_axis(rng, opts: RailOptions):
    """Unit rail direction (tilted from +z) and the bar direction (horizontal-ish, across the rail)."""
    tilt = rng.uniform(0.0, opts.max_tilt_rad)
    az = rng.uniform(0.0, 2 * np.pi)
    d = np.array([np.sin(tilt) * np.cos(az), np.sin(tilt) * np.sin(az), np.cos(tilt)])
    yaw = opts.bar_yaw_rad + rng.uniform(-1.0, 1.0) * np.deg2rad(3.0)
    b = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    b -= d * (b @ d)
    return d, b / np.linalg.norm(b)


def rail_lab(rng: np.random.Generator, opts: RailOptions = RailOptions()) -> SimSetup:
    """The B.5 scene: lab room, ceiling stereo rig, rail, slider with a red and a green sphere.

    The sphere midpoint moves along a straight line through
    ``(rail_xy_m, 0)`` with the (tilted) rail direction; at frame time ``t``
    it rests at height ``heights_m[k]`` with ``k = int(t * 50 Hz) //
    frames_per_height``. The rail stands 6 cm behind the spheres (away from
    the cameras) so that it never hides them.

    Parameters
    ----------
    rng : numpy.random.Generator
        Randomises the room, clutter, lighting, the rail tilt and the bar yaw.
    opts : RailOptions
        Rail place, heights, frames per height, spheres and rig.

    Returns
    -------
    SimSetup
        ``cameras = {"left", "right"}`` (world frame = robot base frame);
        ``meta``: ``rail_point_m`` (3,) (the midpoint line at the floor),
        ``rail_dir`` (3,) unit, ``bar_dir`` (3,) unit (red -> green),
        ``centres_at`` (callable ``k -> {"red", "green", "mid"}`` of (3,)
        world points for height index ``k``), ``height_index_at`` (callable
        ``t -> k``), ``sphere_radius_m``, ``rate_hz``.

    Raises
    ------
    ValueError
        If the sphere geometry is impossible.

    Examples
    --------
    >>> s = rail_lab(np.random.default_rng(0), RailOptions(heights_m=(0.5, 1.0), frames_per_height=2))
    >>> round(float(s.meta["centres_at"](1)["mid"][2]), 3), s.meta["height_index_at"](0.03)
    (1.0, 1)
    """
    radius, sep = _sphere_geometry(opts)
    heights = np.asarray(opts.heights_m, float)
    d, b = _rail_axis(rng, opts)
    p0 = np.array([opts.rail_xy_m[0], opts.rail_xy_m[1], 0.0])
    behind = np.array([0.0, 1.0, 0.0]) - d * d[1]
    behind /= np.linalg.norm(behind)
    left, right = stereo_rig(np.eye(4), config=opts.rig)
    keep = (0.5 * opts.rail_xy_m[0], 0.5 * opts.rail_xy_m[1])
    shapes, lights = lab_room(rng, center_xy=(0.0, 0.0), keepout_xy=keep, keepout_radius_m=1.5,
                              n_clutter=opts.n_clutter, n_distractors=opts.n_distractors,
                              size_m=(8.0, 7.0, opts.rig.height_m + 0.3), clutter_region_y=(-0.8, 3.4))
    # the rail: an aluminium profile from 0.15 m to 1.65 m on a post and a foot plate
    R_rail = np.column_stack([b, np.cross(d, b), d])
    axis0 = p0 + 0.06 * behind

    def along(z):
        return axis0 + (z / d[2]) * d

    shapes += [Box(center=along(0.90), half_extents=(0.02, 0.02, 0.75), R_world_box=R_rail, color_rgb=(0.7, 0.71, 0.73),
                   name="rail"),
               Box(center=along(0.075), half_extents=(0.015, 0.015, 0.075), R_world_box=R_rail,
                   color_rgb=(0.25, 0.25, 0.27), name="rail_post"),
               Box(center=(axis0[0], axis0[1], 0.01), half_extents=(0.25, 0.25, 0.01), R_world_box=np.eye(3),
                   color_rgb=(0.3, 0.3, 0.32), name="rail_foot")]
    fph = int(opts.frames_per_height)

    def index_at(t: float) -> int:
        return int(min(max(int(round(float(t) * RATE_HZ)) // fph, 0), len(heights) - 1))

    def centres(k: int) -> dict:
        mid = p0 + (heights[int(k)] / d[2]) * d
        return {"red": mid - 0.5 * sep * b, "green": mid + 0.5 * sep * b, "mid": mid}

    def dynamic(t):
        c = centres(index_at(t))
        slider = c["mid"] + 0.04 * behind
        return [Sphere(center=c["red"], radius=radius, color_rgb=RED_RGB, name="red_sphere"),
                Sphere(center=c["green"], radius=radius, color_rgb=GREEN_RGB, name="green_sphere"),
                Capsule(p0=c["red"], p1=c["green"], radius=0.005, color_rgb=(0.12, 0.12, 0.13), name="bar"),
                Box(center=slider, half_extents=(0.05, 0.012, 0.05), R_world_box=R_rail, color_rgb=(0.2, 0.2, 0.22),
                    name="slider")]

    scene = Scene(static=shapes, lights=lights, dynamic=dynamic)
    return SimSetup(scene=scene, cameras={"left": left, "right": right},
                    meta={"rail_point_m": p0, "rail_dir": d, "bar_dir": b, "centres_at": centres,
                          "height_index_at": index_at, "sphere_radius_m": radius, "rate_hz": RATE_HZ,
                          "object_ids": scene.object_ids(0.0)})


def _truth_rows(cams, setup, times):
    r = setup.meta["sphere_radius_m"]
    rows = []
    for t in times:
        k = setup.meta["height_index_at"](t)
        c = setup.meta["centres_at"](k)
        row = [t, *c["mid"], *c["red"], *c["green"]]
        for cam in cams:
            for name in ("red", "green"):
                try:
                    uv = sphere_image_truth(cam, lambda _t, p=c[name]: p, r, float(t))
                except ValueError:
                    uv = [np.nan, np.nan]
                row += list(uv)
        rows.append(row)
    names = ["t", "ee_x_m", "ee_y_m", "ee_z_m", "red_x_m", "red_y_m", "red_z_m", "green_x_m", "green_y_m",
             "green_z_m"]
    for cam in ("left", "right"):
        for name in ("red", "green"):
            names += [f"{cam}_{name}_u_px", f"{cam}_{name}_v_px"]
    return names, np.array(rows)


def heights_in_view(setup, heights_m, *, margin_px: float = 2.0) -> list:
    """Indices of the heights at which both spheres lie wholly inside both images.

    Parameters
    ----------
    setup : SimSetup
        A :func:`rail_lab` scene.
    heights_m : sequence of float
        Its heights, metres.
    margin_px : float
        Extra margin beyond the apparent sphere radius, pixels.

    Returns
    -------
    list of int
    """
    r = setup.meta["sphere_radius_m"]
    keep = []
    for k in range(len(heights_m)):
        c = setup.meta["centres_at"](k)
        ok = True
        for cam in setup.cameras.values():
            for name in ("red", "green"):
                try:
                    u, v = sphere_image_truth(cam, lambda _t, p=c[name]: p, r, 0.0)
                except ValueError:
                    ok = False
                    continue
                z = (np.linalg.inv(cam.T_world_cam) @ np.append(c[name], 1.0))[2]
                rad = float(cam.K[0, 0]) * r / z + margin_px if z > 0 else np.inf
                ok &= bool(rad <= u <= cam.width - 1 - rad and rad <= v <= cam.height - 1 - rad)
        if ok:
            keep.append(k)
    return keep


def record_rail(out, opts: RailOptions = RailOptions()) -> Path:
    """Render the B.5 rail experiment into a stereo sequence directory.

    Parameters
    ----------
    out : str or path-like
        Sequence directory to write (must be empty unless ``opts.force``).
    opts : RailOptions
        Seed, rail place, heights and frames per height.

    Returns
    -------
    pathlib.Path
        ``out``. Besides the images and ``calibration.yaml`` (the lab's
        nominal camera models), ``groundtruth/`` holds ``ee.csv`` (sphere
        centres and midpoint in the base frame, metres, and the exact image
        centroids, pixels, per frame, as the other stereo recordings),
        ``rail.csv`` (per frame: ``height_index``, ``height_m``),
        ``rail_axis.csv`` (one row: the midpoint line's floor point
        ``p0_*_m`` and unit direction ``d_*``, base frame) and
        ``transforms.csv`` (``T_base_left``, ``T_base_right``,
        ``T_world_base``).

    Raises
    ------
    TudorVisionError
        A non-empty ``out`` without ``force``; fewer than two heights with
        both spheres in view (or any out of view without
        ``skip_out_of_view``).
    ValueError
        Invalid options.
    """
    from ..io import SequenceWriter

    out = Path(out)
    rng = np.random.default_rng([int(opts.seed), 5])
    setup = rail_lab(rng, opts)
    left, right = setup.cameras["left"], setup.cameras["right"]
    visible = heights_in_view(setup, opts.heights_m)
    if len(visible) < 2:
        raise TudorVisionError(f"rail at {tuple(opts.rail_xy_m)} m: fewer than two heights have both spheres in "
                               "both images; choose other heights or rail_xy_m")
    if opts.skip_out_of_view:
        heights = tuple(opts.heights_m[k] for k in visible)
        skipped = [float(h) for k, h in enumerate(opts.heights_m) if k not in visible]
        if skipped:
            opts = replace(opts, heights_m=heights)
            rng = np.random.default_rng([int(opts.seed), 5])     # the same scene, the fewer heights
            setup = rail_lab(rng, opts)
            left, right = setup.cameras["left"], setup.cameras["right"]
    elif len(visible) < len(opts.heights_m):
        raise TudorVisionError(f"rail: {len(opts.heights_m) - len(visible)} heights have a sphere outside an "
                               "image; choose other heights or set skip_out_of_view")
    else:
        skipped = []
    n_h = len(opts.heights_m)
    cal = calibration_from_cameras({"left": left, "right": right}, stereo=("left", "right"),
                                   note="appendix B.5 rail")
    fph = int(opts.frames_per_height)
    times = np.arange(n_h * fph) / RATE_HZ
    desc = (f"appendix B.5 rail at base ({opts.rail_xy_m[0]:.3f}, {opts.rail_xy_m[1]:.3f}) m, {n_h} heights "
            f"{min(opts.heights_m):.2f}-{max(opts.heights_m):.2f} m, {fph} frames each")
    with SequenceWriter(out, kind="stereo", rate_hz=RATE_HZ, depth_scale=1000.0, calibration=cal,
                        image_ext=opts.image_ext, jpeg_quality=opts.jpeg_quality, description=desc,
                        meta={"generator": "tudorvision.lab.rail", "seed": int(opts.seed),
                              "rail_heights_out_of_view_m": skipped},
                        overwrite=opts.force) as w:
        for k in progress(range(n_h), desc="rail heights", enabled=opts.show_progress):
            t0 = float(times[k * fph])
            rad = {name: render_radiance(cam, setup.scene, t0) for name, cam in setup.cameras.items()}
            for j in range(fph):
                w.add_stereo(float(times[k * fph + j]), apply_sensor(rad["left"], opts.sensor, rng),
                             apply_sensor(rad["right"], opts.sensor, rng))
        names, rows = _truth_rows((left, right), setup, times)
        w.write_groundtruth("ee", (names, rows), comment="rail: sphere centres and their midpoint, robot base "
                            "frame (= world), metres; exact silhouette centroids in pixels")
        idx = np.repeat(np.arange(n_h), fph)
        w.write_groundtruth("rail", {"t": times, "height_index": idx,
                                     "height_m": np.asarray(opts.heights_m, float)[idx]},
                            comment="slider height (sphere midpoint above the floor) of every frame")
        p0, d = setup.meta["rail_point_m"], setup.meta["rail_dir"]
        w.write_groundtruth("rail_axis", {"p0_x_m": [p0[0]], "p0_y_m": [p0[1]], "p0_z_m": [p0[2]],
                                          "d_x": [d[0]], "d_y": [d[1]], "d_z": [d[2]]},
                            comment="the sphere-midpoint line: floor point and unit direction, base frame")
        mats = [np.asarray(left.T_world_cam, float), np.asarray(right.T_world_cam, float), np.eye(4)]
        table = {"index": np.arange(3), **{f"m{i}{j}": np.array([m[i, j] for m in mats])
                                           for i in range(4) for j in range(4)}}
        w.write_groundtruth("transforms", table, comment="rows: 0=T_base_left, 1=T_base_right, 2=T_world_base; "
                            "4x4 row-major, metres")
    return out


# --------------------------------------------------------------------------- the simulated user

def truth_transform(seq, row: int) -> np.ndarray:
    """The recorded true transform of row ``row`` (``transforms`` ground truth), shape (4, 4)."""
    tr = seq.groundtruth("transforms")
    return np.array([[tr[f"m{i}{j}"][row] for j in range(4)] for i in range(4)])


def user_pick_models(seq, *, verify_params=None, edge_factors=(0.8, 0.6), start_height_m=None):
    """Colour models from a simulated user's clicks, as ``tudorvision stereo colormodel --pick`` makes them.

    The user clicks, on one stereo pair, the pixel under each sphere's centre
    (the exact silhouette centroid rounded to a pixel) and a pixel
    ``edge_factor`` of the apparent radius to its right. When the colour
    model refuses a pick (it would single out another object), the user
    clicks a smaller circle, then tries the first frame of the next height,
    and so on. Only this stand-in for the user reads the truth
    (``groundtruth/ee.csv``); the models are what the pipeline gets.

    Parameters
    ----------
    seq : tudorvision.io.Sequence
        A :func:`record_rail` sequence.
    verify_params : tudorvision.stereo.SegmentParams, optional
        Segmentation the model is verified with (the CLI passes the tracking
        centre method).
    edge_factors : sequence of float
        Edge-pixel distances tried, in apparent sphere radii.
    start_height_m : float, optional
        Pick first on the first frame of the height nearest this (then the
        following heights, then the ones below); None: the first frame.

    Returns
    -------
    models : tudorvision.stereo.ColorModelSet
    frame : int
        Index of the stereo pair picked on.
    picks : list of str
        The accepted ``CAMERA:SPHERE:CU,CV:EU,EV`` picks.

    Raises
    ------
    TudorVisionError
        Every frame tried refuses a pick (the last refusal is named).
    """
    from ..stereo import ColorModelSet, fit_color_model

    gt = seq.groundtruth("ee")
    rail = seq.groundtruth("rail")
    h = np.asarray(rail["height_index"], int)
    ks = np.unique(h)
    firsts = [int(np.argmax(h == k)) for k in ks]
    if start_height_m is not None:
        hm = np.asarray(rail["height_m"], float)[firsts]
        j = int(np.argmin(np.abs(hm - float(start_height_m))))
        firsts = firsts[j:] + firsts[:j][::-1]
    r = load_robot_params().sphere_radius_m
    T_cam_base = {cam: np.linalg.inv(truth_transform(seq, row)) for row, cam in enumerate(("left", "right"))}
    last = ""
    for k in firsts:
        frame = seq[k]
        models, picks = {}, []
        for cam in ("left", "right"):
            fx = seq.calibration.camera(cam).fx
            for s in ("red", "green"):
                z = (T_cam_base[cam] @ [gt[f"{s}_x_m"][k], gt[f"{s}_y_m"][k], gt[f"{s}_z_m"][k], 1.0])[2]
                u, v = round(gt[f"{cam}_{s}_u_px"][k]), round(gt[f"{cam}_{s}_v_px"][k])
                for fac in edge_factors:
                    e = max(1, round(fac * fx * r / z))
                    try:
                        models.setdefault(cam, {})[s] = fit_color_model(getattr(frame, cam), (u, v), (u + e, v),
                                                                         verify_params=verify_params)
                    except TudorVisionError as exc:
                        last = f"frame {k} {cam}:{s}: {exc}"
                        continue
                    picks.append(f"{cam}:{s}:{u},{v}:{u + e},{v}")
                    break
        if len(picks) == 4:
            return ColorModelSet(models), k, picks
    raise TudorVisionError(f"rail: every pick was refused; last: {last}")


# --------------------------------------------------------------------------- evaluation

def fit_line(points) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares straight line through 3D points (total least squares).

    Parameters
    ----------
    points : array_like, shape (N, 3), N >= 2
        Points, metres; rows with a NaN are ignored.

    Returns
    -------
    point : ndarray, shape (3,)
        The points' mean (on the line).
    direction : ndarray, shape (3,)
        Unit direction (largest principal axis), sign such that its largest
        component is positive.

    Raises
    ------
    ValueError
        Fewer than two finite points.

    Examples
    --------
    >>> p, d = fit_line([[0, 0, 0], [0, 0, 1], [0, 0, 2]])
    >>> p.tolist(), (d.round(6) + 0.0).tolist()
    ([0.0, 0.0, 1.0], [0.0, 0.0, 1.0])
    """
    p = np.asarray(points, float).reshape(-1, 3)
    p = p[np.all(np.isfinite(p), axis=1)]
    if len(p) < 2:
        raise ValueError(f"points: need at least two finite points, got {len(p)}")
    c = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - c, full_matrices=False)
    d = vt[0]
    if d[np.argmax(np.abs(d))] < 0:
        d = -d
    return c, d


def _residuals(p, point, direction):
    q = p - point
    return q - np.outer(q @ direction, direction)


@dataclass(frozen=True)
class RailDeviation:
    """Deviations of measured rail points from a straight line, per height and axis (metres).

    Attributes
    ----------
    heights_m : ndarray, shape (H,)
        The heights with at least one measured point.
    mean_m, std_m : ndarray, shape (H, 3)
        Per height and axis, the mean and standard deviation of the residual
        (point minus its foot on the line).
    position_m : ndarray, shape (H, 3)
        Per height, the mean measured position.
    n : ndarray, shape (H,)
        Points per height.
    band_m : ndarray, shape (3,)
        Per axis, ``max - min`` of ``mean_m`` over the heights.
    band_std_m : ndarray, shape (3,)
        Per axis, ``max(mean + std) - min(mean - std)`` over the heights.
    rms_m : float
        RMS distance of all points from the line.
    point, direction : ndarray, shape (3,)
        The line.
    """

    heights_m: np.ndarray
    mean_m: np.ndarray
    std_m: np.ndarray
    position_m: np.ndarray
    n: np.ndarray
    band_m: np.ndarray
    band_std_m: np.ndarray
    rms_m: float
    point: np.ndarray
    direction: np.ndarray


def rail_deviation(points, heights_m, *, line=None, R=None) -> RailDeviation:
    """Deviation of measured rail positions from a straight line, per height and axis.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Measured positions, metres (NaN rows: frames without a measurement,
        ignored).
    heights_m : array_like, shape (N,)
        The slider height of each frame (groups the frames), metres.
    line : (point (3,), direction (3,)), optional
        The line to compare with (e.g. the true rail line in the same
        frame); None fits one to the points (:func:`fit_line`).
    R : array_like, shape (3, 3), optional
        Rotation applied to the residual vectors before they are split into
        axes (e.g. ``R_cam_base``); None keeps the points' frame.

    Returns
    -------
    RailDeviation

    Raises
    ------
    ValueError
        Shapes that do not match, or fewer than two measured points.

    Examples
    --------
    >>> z = np.repeat([0.5, 1.0, 1.5], 2)
    >>> p = np.column_stack([[0.001, 0.001, 0, 0, -0.001, -0.001], np.zeros(6), z])
    >>> dev = rail_deviation(p, z, line=(np.zeros(3), np.array([0.0, 0.0, 1.0])))
    >>> (1e3 * dev.band_m).round(3).tolist(), round(1e3 * dev.rms_m, 3)
    ([2.0, 0.0, 0.0], 0.816)
    """
    p = np.asarray(points, float).reshape(-1, 3)
    h = np.asarray(heights_m, float).reshape(-1)
    if len(h) != len(p):
        raise ValueError(f"heights_m: expected {len(p)} values (one per point), got {len(h)}")
    ok = np.all(np.isfinite(p), axis=1) & np.isfinite(h)
    p, h = p[ok], h[ok]
    if len(p) < 2:
        raise ValueError(f"points: need at least two measured points, got {len(p)}")
    point, direction = fit_line(p) if line is None else (np.asarray(line[0], float), np.asarray(line[1], float))
    direction = direction / np.linalg.norm(direction)
    res = _residuals(p, point, direction)
    if R is not None:
        res = res @ np.asarray(R, float).T
    hs = np.unique(h)
    mean = np.array([res[h == v].mean(axis=0) for v in hs])
    std = np.array([res[h == v].std(axis=0) for v in hs])
    pos = np.array([p[h == v].mean(axis=0) for v in hs])
    n = np.array([int(np.sum(h == v)) for v in hs])
    return RailDeviation(heights_m=hs, mean_m=mean, std_m=std, position_m=pos, n=n,
                         band_m=mean.max(axis=0) - mean.min(axis=0),
                         band_std_m=(mean + std).max(axis=0) - (mean - std).min(axis=0),
                         rms_m=float(np.sqrt(np.mean(np.sum(res ** 2, axis=1)))), point=point, direction=direction)
