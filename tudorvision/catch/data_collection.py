"""Training data for the data-based kinematics (section 9.2): settled poses of the simulated arm.

The seed sampled theta2 in 10 deg steps over [0, 180] deg and theta3 over
[-90, 90] deg with payloads 0-400 g in 100 g steps (1805 settled poses) and
recorded joint angles, settled strains and the end effector measured by its
stereo system. Here each pose is the simulated elastic arm
(:class:`tudorvision.sim.arm.ElasticArm`) at static equilibrium; the payload
adds to the end-effector mount. The measured end effector is the true
deflected one plus isotropic Gaussian noise of ``measurement_sigma_m``
(``measure="noise"``; default 1 mm, about the project's stereo accuracy on
rendered pairs). Ground truth is kept beside it (``p_true_base``) for
evaluation only.

Results are cached in an ``.npz`` file keyed by the grid, so the demo does
not recollect.
"""
from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

__all__ = ["CollectionOptions", "collect_settled_poses", "load_or_collect"]


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
        Measurement noise seed.
    """

    theta2_deg: tuple = (0.0, 180.0, 10.0)
    theta3_deg: tuple = (-90.0, 90.0, 10.0)
    payloads_kg: tuple = (0.0, 0.1, 0.2, 0.3, 0.4)
    measurement_sigma_m: float = 0.001
    strain_sigma: float = 1e-7
    seed: int = 0

    def key(self) -> str:
        return hashlib.sha1(json.dumps(asdict(self), sort_keys=True).encode()).hexdigest()[:12]


def _grid(spec):
    a, b, s = (float(v) for v in spec)
    if not s > 0 or b < a:
        raise ValueError(f"grid: expected (start, stop, step > 0) with stop >= start, got {spec}")
    return np.deg2rad(np.arange(a, b + 1e-9, s))


def _settle_at(arm, theta) -> None:
    """Put the simulated arm at rest in static equilibrium at ``theta`` (as its constructor does)."""
    arm.theta = [float(x) for x in theta]
    arm.dtheta = [0.0, 0.0, 0.0]
    for lst in (arm.deta2, arm.deta3):
        lst[:] = [0.0] * len(lst)
    arm._settle()
    arm._outputs()


def collect_settled_poses(options: CollectionOptions = CollectionOptions(), params=None) -> dict:
    """Settle the simulated arm on the joint grid for every payload and measure it.

    Returns
    -------
    dict of ndarray
        ``theta`` (N, 3) rad (theta1 = 0), ``strains`` (N, 4) m/m,
        ``payload_kg`` (N,) (added payload, without the mount), ``mount_kg`` (scalar),
        ``p_meas_base`` (N, 3) measured end effector, ``p_true_base`` (N, 3) ground truth (evaluation only).

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
    rows = []
    for m in options.payloads_kg:
        # one plant per payload (building the modal model is the expensive part); each pose is then
        # the static equilibrium at that configuration (what ElasticArm(theta) starts in)
        arm = ElasticArm([0.0, 0.0, 0.0], payload=Payload(mass_kg=mount + float(m)), params=p)
        for t2 in _grid(options.theta2_deg):
            for t3 in _grid(options.theta3_deg):
                _settle_at(arm, [0.0, t2, t3])
                rows.append((0.0, t2, t3, *arm.strain, float(m), *arm.ee_position()))
    a = np.array(rows, float)
    n = len(a)
    p_true = a[:, 8:11]
    return {"theta": a[:, 0:3], "strains": a[:, 3:7] + rng.normal(0.0, options.strain_sigma, (n, 4)),
            "payload_kg": a[:, 7], "mount_kg": np.float64(mount),
            "p_meas_base": p_true + rng.normal(0.0, options.measurement_sigma_m, (n, 3)),
            "p_true_base": p_true}


def load_or_collect(cache_dir, options: CollectionOptions = CollectionOptions(), params=None) -> dict:
    """Load the collection for ``options`` from ``cache_dir`` or collect and save it there."""
    path = Path(cache_dir) / f"catch_kinematics_{options.key()}.npz"
    if path.exists():
        with np.load(path) as z:
            return {k: z[k] for k in z.files}
    d = collect_settled_poses(options, params)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **d)
    return d
