"""Training data for the data-based kinematics (section 9.2): settled poses of the simulated arm.

The seed sampled theta2 in 10 deg steps over [0, 180] deg and theta3 over
[-90, 90] deg with payloads 0-400 g in 100 g steps (1805 settled poses) and
recorded joint angles, settled strains and the end effector measured by its
stereo system. Here each pose is the simulated elastic arm
(:class:`tudorvision.sim.arm.ElasticArm`) at static equilibrium; the payload
adds to the end-effector mount. The end effector is measured in one of two
ways (``CollectionOptions.measure``):

``"stereo"``
    As the seed did: every settled pose is rendered by the virtual lab's
    ceiling stereo rig (:func:`tudorvision.sim.scenes.stereo_lab`) and tracked
    by the project's stereo tracker (:class:`tudorvision.stereo.StereoPipeline`,
    colour models fitted from one pick per camera and sphere on the first pair,
    as ``tudorvision track stereo --pick`` does). The base frame comes from the
    lab's own base calibration, a theta1 sweep tracked the same way
    (:func:`tudorvision.stereo.base_frame_from_theta1_sweep`); the camera models are
    the lab's calibration. Poses where a sphere is hidden are left out
    (``valid`` False). Rendering and tracking take about 0.2 s per pose, so
    the demo's collection (:data:`DEMO_COLLECTION`, the seed's full grid) is
    shipped with the package (:data:`PACKAGED_DIR`) instead of being
    collected on first use.
``"noise"``
    The true deflected end effector plus isotropic Gaussian noise of
    ``measurement_sigma_m`` (fast; for tests and quick runs).

Ground truth is kept beside it (``p_true_base``) for evaluation only. The
picks that seed the colour models are placed at the projected sphere
centres, as a user clicking on the first pair would (the tests and benchmarks
of the stereo tracker do the same).

Results are cached in an ``.npz`` file keyed by the options, so the demo does
not recollect.
"""
from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from .._progress import progress

__all__ = ["CollectionOptions", "DEMO_COLLECTION", "PLANTS", "plant_config", "PACKAGED_DIR",
           "collect_settled_poses", "load_or_collect", "robot_key", "remap_errors", "StereoLab"]

#: Simulated plants the catch demo and its data collection run on: the seed-measured, softer one
#: (hub springs, dampers and backlash of :meth:`tudorvision.sim.model.PlantConfig.seed_measured`) and
#: the earlier stiff one (rigid link clamping, one-way coupling: the default plant before issue 18).
PLANTS = ("seed_measured", "stiff")


def plant_config(plant: str):
    """The :class:`~tudorvision.sim.model.PlantConfig` of a plant name of :data:`PLANTS`.

    Parameters
    ----------
    plant : str
        ``"seed_measured"`` or ``"stiff"``.

    Returns
    -------
    PlantConfig
        ``PlantConfig.seed_measured()`` or the rigidly clamped ``PlantConfig(hub_stiffness_Nm_rad=(inf, inf))``
        (given explicitly, whatever ``PlantConfig``'s default is).

    Raises
    ------
    ValueError
        On an unknown name.

    Examples
    --------
    >>> plant_config("seed_measured").hub_stiffness_Nm_rad
    (1500.0, 800.0)
    """
    from ..sim.model import PlantConfig

    if plant == "seed_measured":
        return PlantConfig.seed_measured()
    if plant == "stiff":
        return PlantConfig(hub_stiffness_Nm_rad=(math.inf, math.inf), hub_damping_Nms_rad=(0.0, 0.0),
                           backlash_rad=(0.0, 0.0), two_way=None)
    raise ValueError(f"plant: expected one of {', '.join(PLANTS)}, got {plant!r}")


@dataclass(frozen=True, kw_only=True)
class CollectionOptions:
    """Grid and measurement of the data collection.

    Attributes
    ----------
    theta2_deg, theta3_deg : tuple (start, stop, step)
        Joint grids in degrees (inclusive).
    payloads_kg : tuple of float
        Payloads on top of the end-effector mount.
    measurement_sigma_m : float
        Standard deviation of the end-effector measurement per axis.
    strain_sigma : float
        Standard deviation of the settled strain readings, m/m.
    seed : int
        Measurement noise seed (and the stereo lab's lighting and clutter).
    measure : str
        ``"noise"`` (truth + Gaussian noise) or ``"stereo"`` (rendered pairs, stereo tracker).
    plant : str
        The simulated arm the poses settle on (:data:`PLANTS`, :func:`plant_config`); ``"stiff"`` (the
        plant the shipped stereo collection was made on) leaves the key as it was.
    """

    theta2_deg: tuple = (0.0, 180.0, 10.0)
    theta3_deg: tuple = (-90.0, 90.0, 10.0)
    payloads_kg: tuple = (0.0, 0.1, 0.2, 0.3, 0.4)
    measurement_sigma_m: float = 0.001
    strain_sigma: float = 1e-7
    seed: int = 0
    measure: str = "noise"
    plant: str = "stiff"

    def __post_init__(self):
        if self.measure not in ("noise", "stereo"):
            raise ValueError(f"measure: expected 'noise' or 'stereo', got {self.measure!r}")
        if self.plant not in PLANTS:
            raise ValueError(f"plant: expected one of {', '.join(PLANTS)}, got {self.plant!r}")

    def key(self) -> str:
        """Short hash of the options (the cache file's name); the stiff plant hashes as before the field existed."""
        d = asdict(self)
        if d["plant"] == "stiff":
            del d["plant"]
        return hashlib.sha1(json.dumps(d, sort_keys=True).encode()).hexdigest()[:12]


#: The demo's collection: the seed's grid (1805 poses) measured through the stereo tracker on
#: rendered pairs (about 6 minutes to render and track on one core; shipped in PACKAGED_DIR).
DEMO_COLLECTION = CollectionOptions(measure="stereo")


def _grid(spec):
    a, b, s = (float(v) for v in spec)
    if not s > 0 or b < a:
        raise ValueError(f"grid: expected (start, stop, step > 0) with stop >= start, got {spec}")
    return np.deg2rad(np.arange(a, b + 1e-9, s))


def collect_settled_poses(options: CollectionOptions = CollectionOptions(), params=None, *,
                          show_progress: bool | None = False) -> dict:
    """Settle the simulated arm on the joint grid for every payload and measure it.

    Returns
    -------
    dict of ndarray
        ``theta`` (N, 3) rad (theta1 = 0), ``strains`` (N, 4) m/m,
        ``payload_kg`` (N,) (added payload, without the mount), ``mount_kg`` (scalar),
        ``p_meas_base`` (N, 3) measured end effector (NaN where not tracked), ``valid`` (N,) bool,
        ``p_true_base`` (N, 3) ground truth (evaluation only); with ``measure="stereo"`` also
        ``T_base_left`` (4, 4), the base calibration used.

    Examples
    --------
    >>> d = collect_settled_poses(CollectionOptions(theta2_deg=(30, 40, 10), theta3_deg=(0, 0, 10),
    ...                                              payloads_kg=(0.0, 0.2)))
    >>> d["theta"].shape, d["strains"].shape
    ((4, 3), (4, 4))
    """
    from ..robot import load_robot_params
    from ..sim.arm import ElasticArm, Payload

    p = params or load_robot_params()
    rng = np.random.default_rng(options.seed)
    mount = float(p.end_effector_mount_mass_kg)
    rows, tips = [], []
    for m in options.payloads_kg:
        # one plant per payload (building the modal model is the expensive part); each pose is then
        # the static equilibrium at that configuration (what ElasticArm(theta) starts in)
        arm = ElasticArm([0.0, 0.0, 0.0], payload=Payload(mass_kg=mount + float(m)), params=p,
                         config=plant_config(options.plant))
        for t2 in _grid(options.theta2_deg):
            for t3 in _grid(options.theta3_deg):
                arm.reset_at_rest([0.0, t2, t3])
                rows.append((0.0, t2, t3, *arm.strain, float(m), *arm.ee_position()))
                tips.append((np.array(arm.tip2, float), np.array(arm.tip3, float)))
    a = np.array(rows, float)
    n = len(a)
    p_true = a[:, 8:11]
    out = {"theta": a[:, 0:3], "strains": a[:, 3:7] + rng.normal(0.0, options.strain_sigma, (n, 4)),
           "payload_kg": a[:, 7], "mount_kg": np.float64(mount), "p_true_base": p_true}
    if options.measure == "noise":
        out["p_meas_base"] = p_true + rng.normal(0.0, options.measurement_sigma_m, (n, 3))
        out["valid"] = np.ones(n, bool)
        return out
    # stereo: render each settled pose (the arm's shape: joint angles and tip deflections)
    lab = StereoLab(p, seed=options.seed)
    poses = [(a[i, 0:3], tips[i][0], tips[i][1]) for i in range(n)]
    meas = np.full((n, 3), np.nan)
    for i in progress(range(n), desc="stereo poses", enabled=show_progress):
        meas[i] = lab.measure(*poses[i])
    out["p_meas_base"] = meas
    out["valid"] = np.all(np.isfinite(meas), axis=1)
    out["T_base_left"] = lab.T_base_left
    return out


class StereoLab:
    """The ceiling stereo rig of the virtual lab, the stereo tracker and the lab's base calibration.

    Renders the arm in a given (settled) shape and measures its end effector
    with the project's stereo pipeline, as a lab would with real cameras:
    colour models from one pick per camera and sphere, the base frame from a
    theta1 sweep (:meth:`calibrate_base`), never from the scene's ground truth.

    Parameters
    ----------
    params : RobotParams
    seed : int
        Lighting and clutter of the rendered lab.
    sweep_deg : (float, float, float)
        theta1 sweep ``(start, stop, step)`` in degrees for the base calibration.
    """

    def __init__(self, params, *, seed: int = 0, sweep_deg=(-80.0, 80.0, 10.0)):
        from .record import T_WORLD_BASE, calibration_from_cameras, elastic_arm_geometry
        from ..sim.scenes import stereo_lab
        from ..stereo import PipelineOptions, StereoPipeline, fit_color_model_set

        self.params = params
        self._geometry = elastic_arm_geometry
        self._shape = None
        rng = np.random.default_rng([seed, 7])
        self.rng = rng
        self._set_shape(np.deg2rad([0.0, 90.0, 0.0]))
        self.setup = stereo_lab(rng, arm=lambda t: self._shape, T_world_base=T_WORLD_BASE, t0=0.0)
        self.left, self.right = self.setup.cameras["left"], self.setup.cameras["right"]
        self.calibration = calibration_from_cameras({"left": self.left, "right": self.right},
                                                    stereo=("left", "right"))
        # colour models from one pick per camera and sphere on the first pair (the vertical posture)
        pair = self._render()
        picks = self._user_picks()
        models = fit_color_model_set({"left": pair[0], "right": pair[1]}, picks)
        self._opts = PipelineOptions(sphere_separation_m=float(np.linalg.norm(
            np.subtract(*params.sphere_offsets_ee_m.values()))))
        self._camera_pipe = StereoPipeline(self.calibration, models, options=self._opts)
        self.T_base_left = self.calibrate_base(sweep_deg)
        self.pipe = StereoPipeline(self.calibration, models, T_base_left=self.T_base_left, options=self._opts)

    def _set_shape(self, theta, tip2=None, tip3=None) -> None:
        from .record import static_arm_state
        from ..sim.arm import Payload

        if tip2 is None:
            tip2, tip3 = static_arm_state(theta, Payload.from_parts(self.params), self.params)
        self._shape = self._geometry(np.asarray(theta, float), tip2, tip3, self.params)
        self._theta = np.asarray(theta, float)
        self._tips = (tip2, tip3)

    def _render(self):
        from ..sim.render import render_bgr

        return (render_bgr(self.left, self.setup.scene, 0.0, rng=self.rng),
                render_bgr(self.right, self.setup.scene, 0.0, rng=self.rng))

    def _user_picks(self) -> list:
        # where a user clicks: the sphere centre and a point 0.75 radius to its right, per camera
        from ..sim.arm import fk_elastic, spheres_from_T
        from ..sim.camera import project_points
        from .record import T_WORLD_BASE

        T = fk_elastic(self._theta, *self._tips, self.params)
        sph = spheres_from_T(T, self.params)
        picks = []
        for name, cam in (("left", self.left), ("right", self.right)):
            for s in ("red", "green"):
                pw = (T_WORLD_BASE @ np.r_[sph[s], 1.0])[:3]
                uv = project_points(cam, pw[None])[0]
                z = (np.linalg.inv(cam.T_world_cam) @ np.r_[pw, 1.0])[2]
                r = 0.75 * cam.K[0, 0] * self.params.sphere_radius_m / z
                picks.append(f"{name}:{s}:{uv[0]:.2f},{uv[1]:.2f}:{uv[0] + r:.2f},{uv[1]:.2f}")
        return picks

    def _track(self, pipe) -> np.ndarray:
        from ..io.frames import StereoFrame

        left, right = self._render()
        pipe.reset()
        res = pipe.process(StereoFrame(t=0.0, index=0, left=left, right=right))
        return np.asarray(res.ee, float) if res.valid else np.full(3, np.nan)

    def calibrate_base(self, sweep_deg=(-80.0, 80.0, 10.0)) -> np.ndarray:
        """``T_base_left`` from a rendered theta1 sweep (theta2 = theta3 = 0) and the vertical posture.

        The seed's base calibration (section B.5) with the project's tracker
        and :func:`tudorvision.stereo.base_frame_from_theta1_sweep`.

        Parameters
        ----------
        sweep_deg : (float, float, float)
            ``(start, stop, step)`` of theta1, degrees.

        Returns
        -------
        ndarray, shape (4, 4)
            Left camera to robot base.
        """
        from ..stereo import base_frame_from_theta1_sweep

        a, b, st = sweep_deg
        n = int(round((b - a) / st)) + 1
        th = np.column_stack([np.deg2rad(np.arange(a, b + 1e-9, st)), np.zeros(n), np.zeros(n)])
        pts = []
        for t in th:
            self._set_shape(t)
            pts.append(self._track(self._camera_pipe))
        pts = np.array(pts)
        ok = np.all(np.isfinite(pts), axis=1)
        self._set_shape(np.deg2rad([0.0, 90.0, 0.0]))
        vert = self._track(self._camera_pipe)
        T, _ = base_frame_from_theta1_sweep(pts[ok], th[ok], vert if np.all(np.isfinite(vert)) else None, self.params)
        return T

    def measure(self, theta, tip2, tip3) -> np.ndarray:
        """End effector of the settled pose in the base frame (calibrated), NaN if not tracked."""
        self._set_shape(theta, tip2, tip3)
        return self._track(self.pipe)


def remap_errors(ikm, params=None, *, n: int = 50, seed: int = 0, payload_range_kg=(0.0, 0.4),
                 near_deg=(0.0, 60.0, 60.0), plant: str = "stiff") -> dict:
    """Remap error of compensated vs rigid inverse kinematics on the simulated arm (seed: 2.6 mm).

    Random targets in the working plane (r in [-0.5, 0.5] m, z in [0.6, 1.1] m)
    and payloads; each is solved by ``ikm`` (compensated, told the payload)
    and by the rigid :func:`tudorvision.robot.ik`; the settled elastic arm at
    each solution is compared with the target (ground truth, evaluation only).

    ``plant`` names the simulated arm (:data:`PLANTS`).

    Returns
    -------
    dict
        ``compensated_m`` (n,), ``rigid_m`` (n,): end-effector distances from the targets.
    """
    from ..robot import ik, load_robot_params
    from ..sim.arm import ElasticArm, Payload

    p = params or load_robot_params()
    rng = np.random.default_rng(seed)
    near = np.deg2rad(near_deg)
    e_c, e_r = [], []
    while len(e_c) < n:
        tgt = np.array([rng.uniform(-0.5, 0.5), 0.0, rng.uniform(0.6, 1.1)])
        mass = rng.uniform(*payload_range_kg)
        try:
            th_c = ikm(tgt, 0.0, mass, near=near)
            th_r = ik(tgt, p, near=near)
        except ValueError:
            continue
        pay = Payload(mass_kg=p.end_effector_mount_mass_kg + mass)
        cfg = plant_config(plant)
        e_c.append(np.linalg.norm(ElasticArm(th_c, payload=pay, params=p, config=cfg).ee_position() - tgt))
        e_r.append(np.linalg.norm(ElasticArm(th_r, payload=pay, params=p, config=cfg).ee_position() - tgt))
    return {"compensated_m": np.array(e_c), "rigid_m": np.array(e_r)}


def robot_key(params=None) -> str:
    """``""`` for the packaged robot (or None), else ``"_robot"`` and a short hash of the parameters.

    Parameters
    ----------
    params : RobotParams, optional
        Robot parameters.

    Returns
    -------
    str
        A file-name suffix that tells collections of different robots apart.
    """
    from ..robot import load_robot_params
    if params is None:
        return ""

    def text(p) -> str:
        d = asdict(p)
        return json.dumps(d, sort_keys=True, default=lambda a: np.asarray(a).tolist())

    key = hashlib.sha256(text(params).encode()).hexdigest()[:10]
    default = hashlib.sha256(text(load_robot_params()).encode()).hexdigest()[:10]
    return "" if key == default else f"_robot{key}"


#: Where collections shipped with the package live (generated by :func:`load_or_collect` with
#: ``cache_dir=PACKAGED_DIR``; see docs/catch.md).
PACKAGED_DIR = Path(__file__).resolve().parent.parent / "catch" / "data"


def load_or_collect(cache_dir, options: CollectionOptions = CollectionOptions(), params=None, *,
                    show_progress: bool | None = False) -> dict:
    """Load the collection for ``options`` from ``cache_dir`` (or the packaged data), else collect and save it.

    The file name carries a hash of ``options`` (and of ``params`` where they differ from the
    packaged ``tudor.yaml``, e.g. ``--robot``), so a changed grid, measurement or robot never
    reads a stale file.
    """
    name = f"catch_kinematics_{options.key()}{robot_key(params)}.npz"
    for path in (Path(cache_dir) / name, PACKAGED_DIR / name):
        if path.exists():
            with np.load(path) as z:
                return {k: z[k] for k in z.files}
    d = collect_settled_poses(options, params, show_progress=show_progress)
    path = Path(cache_dir) / name
    from ..io.atomic import atomic_path
    with atomic_path(path) as tmp:   # a cache file is never half-written
        np.savez_compressed(tmp, **d)
    return d
