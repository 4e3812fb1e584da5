"""The simulated TUDOR's model: assumptions, configuration, payload, rigid bodies, contacts, elastic kinematics.

The plant that integrates it is :class:`tudorvision.sim.arm.ElasticArm`.

Model (assumptions are listed in full in :data:`ASSUMPTIONS`)
--------------------------------------------------------------
* Joint motion: rigid-equivalent multibody dynamics of the three joints
  ``M(theta) ddtheta + c(theta, dtheta) + g(theta) = tau_E - tau_F + J^T F_c``
  with lumped bodies (link-2 blade, actuator 3 at its tip, link-3 blade,
  payload at the end effector, base inertia), rotor inertia ``n^2 I_M`` on
  the diagonal, friction (3.1.3) with stick/slip and the merged amplifier
  gain (3.1.2). In the stiff plant (``PlantConfig.stiff()``) link oscillations
  do not feed back into the joints (the seed's independent joint-link-module
  assumption, section 5.1); by default (and always with contacts) joints and
  modes share one energy-consistent assumed-modes mass matrix.
* Links 2 and 3: Euler–Bernoulli blades clamped at their hubs (by default
  on a rotary spring with damper and backlash, :mod:`.joint_compliance`) with the
  distal bodies as tip mass and tip inertia (4.4.6). Deflection
  ``w = w_static + sum_r Phi_r (eta_r - eta_static_r)``: the exact static
  cantilever shape under own weight, tip force and tip moment plus the
  dynamic deviation of ``n_modes`` modes (mode-acceleration method). The
  modal coordinates obey
  ``eta'' + 2 D w eta' + w^2 eta = Q_gravity - Gamma alpha_hub - Pi a_hub + Q_contact``,
  so joint accelerations excite them as in (5.1.17); in the one-way model
  the modes are integrated exactly (zero-order hold) at the 2 kHz step, in
  the coupled model with Newmark's average-acceleration rule in the joint solve.
* Link-3 hub motion includes link-2's tip slope and deflection
  accelerations, so link-2 frequencies appear in link-3 strain.
* Contacts: spring–damper obstacles pushing on probe spheres on link 2 or 3
  (default: the end effector); the force acts on the joints through the
  rigid point Jacobian and on the modes as generalised forces.

Frames and signs: joint angles and the base frame follow
:mod:`tudorvision.robot.kinematics`; link deflections and strains follow
:mod:`tudorvision.sim.beam` (deflection toward increasing joint angle,
top-surface strain positive in tension).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .._checks import check_array, check_vector
from ..robot.actuators import reflected_inertia
from ..robot.params import RobotParams, load_robot_params
from .beam import link_rho
from .joint_compliance import SEED_MEASURED, STIFF
from .link_modes import coupled_mass_matrix

__all__ = [
    "coupled_mass_matrix", "zero_config_inertia",
    "ASSUMPTIONS", "PlantConfig", "Payload", "ArmBodies", "arm_bodies", "mass_matrix",
    "bias_torques", "rigid_energy", "link_static_loads", "SpringDamperObstacle",
    "SimLog", "fk_elastic", "spheres_from_T",
]

ASSUMPTIONS = """\
Simulated TUDOR: assumptions
- Joints: rigid-equivalent multibody dynamics with lumped bodies (blades as uniform rods,
  actuator 3 as a point mass with inertia at the link-2 tip, payload as a point mass with
  plate inertia at the end effector); Coriolis/centrifugal terms included; motor electrical
  dynamics neglected (amplifier merged into k_M).
- Friction: Zeng's model (3.1.3) with Coulomb terms opposing motion; sticking when the
  Coulomb impulse of one step exceeds the velocity.
- Links 2 and 3: Euler-Bernoulli blades clamped at the hub on a rotary spring with damper and
  gear backlash (the default PlantConfig(), identified on the seed, joint_compliance) or rigidly
  (K_r -> inf, PlantConfig.stiff()),
  bending only in the arm's vertical plane (out-of-plane bending, torsion, axial strain neglected).
  Tip load of link 2 = actuator 3 + link 3 + payload with inertia about the tip axis
  (parallel-axis theorem, configuration independent); tip load of link 3 = payload.
- Static deflection: exact small-deflection cantilever with own weight, tip force and tip
  moment from the distal bodies, computed on the rigid geometry.
- Dynamics of the deflection: n_modes modes per link from (4.4.6), mass-normalised,
  proportional modal damping (ratios from tudor.yaml), forced by gravity, hub rotational
  and translational accelerations, joint-3 reaction on the link-2 tip and contact forces.
  Gravity stiffening/softening (axial load) is not modelled; the backlash 'canyons' of fig. 4.8
  appear only with backlash (the default plant), the theta3 dependence only in the two-way model.
- Coupling: by default two-way; PlantConfig.stiff() is one-way (joints drive the links, link
  oscillations do not act back on the joints, section 5.1). With obstacles (or two_way=True) the joints and modes share an
  assumed-modes mass matrix built from the exact kinetic energy of the lumped bodies; the
  servoed joints then load the links: with 300 g the first held-joint frequency is 2.0-2.6 Hz
  depending on theta3 (ElasticArm.coupled_frequencies_hz; the seed measured 1.56-2.74 Hz over
  the workspace), below the BVP value, and the servo adds damping.
- Contact: spring-damper obstacles act on probe spheres on link 2 or 3 (default: the end
  effector); explicit in time (force of the previous step), no friction.
- Encoders: 500 lines x 4 quadrature counts per motor revolution.
"""


@dataclass(frozen=True, kw_only=True)
class PlantConfig:
    """Options of the simulated arm (SI units).

    Attributes
    ----------
    dt : float
        Integration and control step, seconds (2 kHz).
    n_modes : int
        Bending modes per elastic link (>= 1).
    gravity : bool
        Apply gravity.
    elastic : bool
        Simulate link deflection (static and dynamic).
    encoder_counts_per_rev : float or None
        Counts per motor revolution; ``None`` gives exact angle readings.
    base_inertia_kg_m2 : float
        Inertia of the parts turning with joint 1 that are not modelled as
        bodies (link 1, actuator 2 housing), assumed.
    actuator3_inertia_kg_m2 : float
        Inertia of actuator 3's housing about the joint-3 axis, assumed
        (cylinder of 32 mm diameter).
    plate_size_m : float
        Edge of a square payload plate (inertia ``m a^2 / 12``).
    modal_damping_ratio : tuple or None
        Damping ratio per mode; ``None`` takes the values of the parameter file.
    two_way : bool or None
        ``False``: the seed's independent joint-link modules (section 5.1): the
        joints move the links, link oscillations do not act back on the joints;
        frequencies are those of the BVP and oscillations last tens of seconds.
        ``True``: energy-consistent assumed-modes model, joints and modes share
        one mass matrix (exact kinetic energy of the lumped bodies with the BVP
        shapes as Ritz functions); the joint servo then loads the links, which
        shifts frequencies (the BVP ignores the offset centre of mass of the
        distal bodies) and adds damping. ``None`` (default): two-way only when
        obstacles are present, because contact forces need the consistent
        model (the one-way coupling is not passive under contact). Default
        ``True`` (the seed-measured plant); :meth:`stiff` gives ``None``.
    strain_noise_m_m : float
        Standard deviation of the white noise on :meth:`ElasticArm.measured_strain`, m/m.
    noise_seed : int
        Seed of the measurement-noise generator (deterministic runs).
    coulomb_friction : bool
        Apply the joints' Coulomb friction with sticking (3.1.3); ``False``
        keeps only the viscous part (a diagnostic of the damping benchmark).
    hub_stiffness_Nm_rad, hub_damping_Nms_rad, backlash_rad : tuple of 2 floats
        Joint-side compliance of links 2 and 3 (:mod:`tudorvision.sim.joint_compliance`):
        rotary clamping stiffness ``K_r`` of (4.4.5) (``inf``: rigid clamping), a damper
        beside it and the full width of the gear backlash, a dead zone of the spring and
        damper. The defaults are the values identified on the seed's measured modes
        (:data:`tudorvision.sim.joint_compliance.SEED_MEASURED`: 1500 / 800 N m/rad,
        6 / 2 N m s/rad, 0.6 deg); :meth:`stiff` gives rigid hubs.

    Notes
    -----
    ``PlantConfig()`` is the seed-measured plant (issue 18: soft hubs, backlash,
    two-way coupling; :meth:`seed_measured` is an alias). :meth:`stiff` is the
    former default (rigid hubs, one-way coupling), kept for the BVP checks and
    for comparisons.
    """

    dt: float = 0.0005
    n_modes: int = 2
    gravity: bool = True
    elastic: bool = True
    encoder_counts_per_rev: float | None = 2000.0
    base_inertia_kg_m2: float = 0.02
    actuator3_inertia_kg_m2: float = 7.5e-5
    plate_size_m: float = 0.08
    modal_damping_ratio: tuple | None = None
    two_way: bool | None = SEED_MEASURED["two_way"]
    strain_noise_m_m: float = 0.0
    noise_seed: int = 0
    coulomb_friction: bool = True
    hub_stiffness_Nm_rad: tuple = SEED_MEASURED["hub_stiffness_Nm_rad"]
    hub_damping_Nms_rad: tuple = SEED_MEASURED["hub_damping_Nms_rad"]
    backlash_rad: tuple = SEED_MEASURED["backlash_rad"]

    @classmethod
    def seed_measured(cls, **overrides) -> "PlantConfig":
        """The plant identified on the seed's measured modes: the default (alias of ``PlantConfig()``).

        Parameters
        ----------
        **overrides
            Other fields, as for the constructor.

        Returns
        -------
        PlantConfig
            Hub springs, dampers and backlash of :data:`tudorvision.sim.joint_compliance.SEED_MEASURED`,
            two-way coupling.
        """
        return cls(**{**SEED_MEASURED, **overrides})

    @classmethod
    def stiff(cls, **overrides) -> "PlantConfig":
        """The former default plant: rigidly clamped blades, one-way joint-to-link coupling.

        Links ring at the BVP frequencies of (4.4.6) at every pose (2.67 / 9.80 Hz with 300 g),
        the seed's independent joint-link modules (section 5.1); two-way only with obstacles.

        Parameters
        ----------
        **overrides
            Other fields, as for the constructor.

        Returns
        -------
        PlantConfig
            ``two_way=None``, ``hub_stiffness_Nm_rad=(inf, inf)``, no hub damper, no backlash.
        """
        return cls(**{**STIFF, **overrides})

    @property
    def is_stiff(self) -> bool:
        """Whether both blades are rigidly clamped (no hub spring)."""
        return all(not math.isfinite(float(k)) for k in self.hub_stiffness_Nm_rad)


@dataclass(frozen=True, kw_only=True)
class Payload:
    """End-effector payload.

    Attributes
    ----------
    mass_kg : float
        Total mass at the end effector (mount, plates, camera, balls).
    inertia_kg_m2 : float
        Inertia about the bending axis through the end effector.
    """

    mass_kg: float
    inertia_kg_m2: float = 0.0

    @classmethod
    def from_parts(cls, params: RobotParams, *, plates: int = 0, camera: bool = False,
                   balls: int = 0, plate_size_m: float = 0.08) -> "Payload":
        """Payload of the end-effector mount plus plates, camera rig and caught balls.

        Parameters
        ----------
        params : RobotParams
            Robot parameters (masses of the mount, plates, camera rig and balls).
        plates : int, optional
            Number of 100 g payload plates.
        camera : bool, optional
            Include the eye-in-hand camera with the tracking spheres.
        balls : int, optional
            Number of caught balls in the net.
        plate_size_m : float, optional
            Edge length of the square plates, metres (for their inertia).

        Returns
        -------
        Payload
            Total mass, kg, and inertia about the bending axis, kg m^2.

        Raises
        ------
        ValueError
            If ``plates`` or ``balls`` is negative.

        Examples
        --------
        >>> p = Payload.from_parts(load_robot_params(), plates=3)
        >>> round(p.mass_kg, 3), round(p.inertia_kg_m2, 6)
        (0.35, 0.00016)
        """
        if plates < 0 or balls < 0:
            raise ValueError(f"plates, balls: expected >= 0, got {plates}, {balls}")
        m_pl = plates * params.plate_mass_kg
        mass = (params.end_effector_mount_mass_kg + m_pl + balls * params.ball_mass_kg
                + (params.camera_and_spheres_mass_kg if camera else 0.0))
        return cls(mass_kg=mass, inertia_kg_m2=m_pl * plate_size_m**2 / 12.0)


@dataclass(frozen=True, kw_only=True)
class ArmBodies:
    """Lumped bodies of the arm (kg, m, kg m^2) and derived constants."""

    l2: float
    l3: float
    h1: float
    m2: float            # link-2 blade
    mA: float            # actuator 3 (at the link-2 tip)
    IA: float
    m3: float            # link-3 blade
    mP: float            # payload at the end effector
    IP: float
    I_base: float
    rotor: tuple         # n^2 I_M per joint

    @property
    def J2(self) -> float:
        """Inertia about joint 2 of link 2, actuator 3 and the distal masses as points at joint 3."""
        return self.m2 * self.l2**2 / 3 + self.IA + (self.mA + self.m3 + self.mP) * self.l2**2

    @property
    def J3(self) -> float:
        """Inertia of link 3 and payload about joint 3."""
        return self.m3 * self.l3**2 / 3 + self.IP + self.mP * self.l3**2

    @property
    def s3(self) -> float:
        """First moment of link 3 and payload about joint 3, kg m."""
        return self.m3 * self.l3 / 2 + self.mP * self.l3

    @property
    def s2(self) -> float:
        """First moment about joint 2 of link 2 and all masses lumped at joint 3, kg m."""
        return self.m2 * self.l2 / 2 + (self.mA + self.m3 + self.mP) * self.l2


def arm_bodies(params: RobotParams, payload: Payload, config: PlantConfig = PlantConfig()) -> ArmBodies:
    """Lumped bodies for the given parameters and payload."""
    if payload.mass_kg < 0 or payload.inertia_kg_m2 < 0:
        raise ValueError(f"payload: expected mass and inertia >= 0, got {payload}")
    rot = reflected_inertia(params)
    return ArmBodies(
        l2=float(params.link2_length_m), l3=float(params.link3_length_m), h1=float(params.link1_height_m),
        m2=link_rho(params.link2) * float(params.link2.length_m), mA=float(params.actuator_mass_kg[2]),
        IA=config.actuator3_inertia_kg_m2, m3=link_rho(params.link3) * float(params.link3.length_m),
        mP=payload.mass_kg, IP=payload.inertia_kg_m2, I_base=config.base_inertia_kg_m2,
        rotor=tuple(float(r) for r in rot))


def _theta_rows(theta):
    th = np.asarray(theta, dtype=np.float64)
    single = th.ndim == 1
    return check_array(th[None] if single else th, "theta", (None, 3)), single


def _m11_and_partials(b: ArmBodies, t2, t3):
    ca, sa = np.cos(t2), np.sin(t2)
    cb, sb = np.cos(t2 + t3), np.sin(t2 + t3)
    rA = b.l2 * ca
    rP = rA + b.l3 * cb
    f = (b.I_base + b.m2 * b.l2**2 * ca**2 / 3 + b.mA * rA**2
         + b.m3 * (rA**2 + rA * b.l3 * cb + b.l3**2 * cb**2 / 3) + b.mP * rP**2)
    drA2 = -b.l2 * sa
    f2 = (-2 * b.m2 * b.l2**2 * ca * sa / 3 + 2 * b.mA * rA * drA2
          + b.m3 * (2 * rA * drA2 + drA2 * b.l3 * cb - rA * b.l3 * sb - 2 * b.l3**2 * cb * sb / 3)
          + 2 * b.mP * rP * (drA2 - b.l3 * sb))
    f3 = b.m3 * (-rA * b.l3 * sb - 2 * b.l3**2 * cb * sb / 3) - 2 * b.mP * rP * b.l3 * sb
    return f, f2, f3


def mass_matrix(theta, bodies: ArmBodies) -> np.ndarray:
    """Joint-space mass matrix including reflected rotor inertia.

    Parameters
    ----------
    theta : array_like, shape (3,) or (N, 3)
        Joint angles, radians.
    bodies : ArmBodies

    Returns
    -------
    M : ndarray, shape (3, 3) or (N, 3, 3)
        kg m^2. Joint 1 decouples from joints 2 and 3 (bodies lie in the arm plane).
    """
    th, single = _theta_rows(theta)
    b = bodies
    c3 = np.cos(th[:, 2])
    f, _, _ = _m11_and_partials(b, th[:, 1], th[:, 2])
    M = np.zeros((th.shape[0], 3, 3))
    M[:, 0, 0] = f + b.rotor[0]
    M[:, 1, 1] = b.J2 + b.J3 + 2 * b.l2 * b.s3 * c3 + b.rotor[1]
    M[:, 1, 2] = M[:, 2, 1] = b.J3 + b.l2 * b.s3 * c3
    M[:, 2, 2] = b.J3 + b.rotor[2]
    return M[0] if single else M


def bias_torques(theta, dtheta, bodies: ArmBodies, gravity_m_s2: float = 9.81) -> np.ndarray:
    """Coriolis, centrifugal and gravity torques ``c(theta, dtheta) + g(theta)``, N m.

    Parameters
    ----------
    theta, dtheta : array_like, shape (3,) or (N, 3)
        Angles (rad) and velocities (rad/s).
    """
    th, single = _theta_rows(theta)
    dth, _ = _theta_rows(dtheta)
    b, g = bodies, gravity_m_s2
    t2, t3 = th[:, 1], th[:, 2]
    d1, d2, d3 = dth[:, 0], dth[:, 1], dth[:, 2]
    _, f2, f3 = _m11_and_partials(b, t2, t3)
    h = b.l2 * b.s3 * np.sin(t3)
    ca, cb = np.cos(t2), np.cos(t2 + t3)
    out = np.zeros_like(th)
    out[:, 0] = (f2 * d2 + f3 * d3) * d1
    out[:, 1] = -h * (2 * d2 * d3 + d3**2) - 0.5 * f2 * d1**2 + g * (b.s2 * ca + b.s3 * cb)
    out[:, 2] = h * d2**2 - 0.5 * f3 * d1**2 + g * b.s3 * cb
    return out[0] if single else out


def rigid_energy(theta, dtheta, bodies: ArmBodies, gravity_m_s2: float = 9.81) -> np.ndarray:
    """Kinetic plus potential energy of the rigid-equivalent arm, joules (for checks)."""
    th, single = _theta_rows(theta)
    dth, _ = _theta_rows(dtheta)
    M = mass_matrix(th, bodies)
    kin = 0.5 * np.einsum("ni,nij,nj->n", dth, M, dth)
    b = bodies
    pot = gravity_m_s2 * (b.s2 * np.sin(th[:, 1]) + b.s3 * np.sin(th[:, 1] + th[:, 2]))
    e = kin + pot
    return e[0] if single else e


def link_static_loads(theta, bodies: ArmBodies, gravity_m_s2: float = 9.81):
    """Gravity loads on the elastic links along their ``y`` axes (rigid geometry).

    Returns
    -------
    loads2, loads3 : ndarray, shape (3,) or (N, 3)
        ``(q N/m, tip force N, tip moment N m)`` for link 2 and link 3.
    """
    th, single = _theta_rows(theta)
    b, g = bodies, gravity_m_s2
    ca, cb = np.cos(th[:, 1]), np.cos(th[:, 1] + th[:, 2])
    rho2, rho3 = b.m2 / b.l2, b.m3 / b.l3
    l2 = np.stack([-rho2 * g * ca, -(b.mA + b.m3 + b.mP) * g * ca, -g * b.s3 * cb], axis=1)
    l3 = np.stack([-rho3 * g * cb, -b.mP * g * cb, np.zeros_like(cb)], axis=1)
    return (l2[0], l3[0]) if single else (l2, l3)


@dataclass(frozen=True, kw_only=True)
class SpringDamperObstacle:
    """A rigid obstacle touched by a probe sphere on the arm.

    The contact force is ``F = max(0, k d + c d') n`` with penetration depth
    ``d``, its rate ``d'`` and the outward surface normal ``n``. The probe
    sphere sits on link ``probe_link`` (2 or 3) at ``probe_x_m`` from that
    link's hub (default: the tip of link 3, i.e. the end effector). Use one
    obstacle per probe point to let an object touch several places.

    Attributes
    ----------
    kind : {"plane", "sphere"}
    point_base : ndarray, shape (3,)
        A point on the plane, or the sphere centre (metres, base frame).
    normal_base : ndarray, shape (3,)
        Plane normal pointing out of the obstacle (ignored for spheres).
    radius_m : float
        Obstacle sphere radius (ignored for planes).
    stiffness_N_m, damping_Ns_m : float
        Contact spring and damper.
    probe_radius_m : float
        Radius of the probe sphere.
    probe_link : {2, 3}
        Link carrying the probe.
    probe_x_m : float or None
        Probe position along the link from its hub, metres; ``None`` = tip.
    """

    kind: str
    point_base: np.ndarray
    normal_base: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    radius_m: float = 0.0
    stiffness_N_m: float = 2.0e4
    damping_Ns_m: float = 50.0
    probe_radius_m: float = 0.03
    probe_link: int = 3
    probe_x_m: float | None = None

    def __post_init__(self):
        if self.kind not in ("plane", "sphere"):
            raise ValueError(f"kind: expected 'plane' or 'sphere', got {self.kind!r}")
        if self.probe_link not in (2, 3):
            raise ValueError(f"probe_link: expected 2 or 3, got {self.probe_link!r}")
        if self.probe_x_m is not None and self.probe_x_m < 0:
            raise ValueError(f"probe_x_m: expected >= 0 or None, got {self.probe_x_m}")
        object.__setattr__(self, "point_base", check_vector(self.point_base, "point_base", 3))
        n = check_vector(self.normal_base, "normal_base", 3)
        if np.linalg.norm(n) < 1e-12:
            raise ValueError("normal_base: must not be zero")
        object.__setattr__(self, "normal_base", n / np.linalg.norm(n))

    def force(self, p_base, v_base) -> np.ndarray:
        """Contact force on the probe at ``p_base`` moving with ``v_base`` (N, base frame).

        Parameters
        ----------
        p_base : array_like, shape (3,)
            Probe sphere centre, metres, base frame.
        v_base : array_like, shape (3,)
            Probe velocity, m/s, base frame.

        Returns
        -------
        F_base : ndarray, shape (3,)
            Force on the probe, N, base frame (zero without contact).

        Examples
        --------
        >>> floor = SpringDamperObstacle(kind="plane", point_base=[0, 0, 0], damping_Ns_m=0.0,
        ...                              stiffness_N_m=1000.0, probe_radius_m=0.01)
        >>> floor.force([0, 0, 0.005], [0, 0, 0]).tolist()
        [0.0, 0.0, 5.0]
        """
        p = np.asarray(p_base, dtype=np.float64)
        v = np.asarray(v_base, dtype=np.float64)
        if self.kind == "plane":
            n = self.normal_base
            depth = self.probe_radius_m - float(n @ (p - self.point_base))
        else:
            d = p - self.point_base
            dist = float(np.linalg.norm(d))
            n = d / dist if dist > 1e-12 else np.array([0.0, 0.0, 1.0])
            depth = self.radius_m + self.probe_radius_m - dist
        if depth <= 0:
            return np.zeros(3)
        mag = self.stiffness_N_m * depth - self.damping_Ns_m * float(n @ v)
        return max(mag, 0.0) * n


def zero_config_inertia(arm) -> np.ndarray:
    """Diagonal of the mass matrix at the zero configuration (the seed's design point).

    Parameters
    ----------
    arm : ElasticArm
        The arm (uses its ``bodies``).

    Returns
    -------
    ndarray, shape (3,)
        kg m^2.
    """
    return np.diag(mass_matrix(np.zeros(3), arm.bodies)).copy()


def fk_elastic(theta, tip2, tip3, params: RobotParams | None = None):
    """End-effector frame of the deflected arm.

    Parameters
    ----------
    theta : array_like, shape (3,) or (N, 3)
        Joint angles, radians.
    tip2, tip3 : array_like, shape (2,) or (N, 2)
        ``(w(L), w'(L))`` of links 2 and 3: tip deflection (m) and slope (rad).
    params : RobotParams, optional
        Robot parameters; default the packaged ``tudor.yaml``.

    Returns
    -------
    T_base_ee : ndarray, shape (4, 4) or (N, 4, 4)
        Same axis convention as :func:`tudorvision.robot.T_base_ee`, with
        link 3's direction rotated by the link-2 tip slope and the x axis
        along the deflected link-3 tip tangent.

    Examples
    --------
    >>> from tudorvision.robot import T_base_ee
    >>> bool(np.allclose(fk_elastic([0.1, 0.5, 0.2], [0, 0], [0, 0]), T_base_ee([0.1, 0.5, 0.2])))
    True
    """
    p = params or load_robot_params()
    th, single = _theta_rows(theta)
    w2 = np.asarray(tip2, dtype=np.float64).reshape(-1, 2)
    w3 = np.asarray(tip3, dtype=np.float64).reshape(-1, 2)
    a = th[:, 1]
    b = th[:, 1] + th[:, 2] + w2[:, 1]
    e = b + w3[:, 1]
    l2, l3 = p.link2_length_m, p.link3_length_m
    r = l2 * np.cos(a) - w2[:, 0] * np.sin(a) + l3 * np.cos(b) - w3[:, 0] * np.sin(b)
    z = p.link1_height_m + l2 * np.sin(a) + w2[:, 0] * np.cos(a) + l3 * np.sin(b) + w3[:, 0] * np.cos(b)
    c1, s1 = np.cos(th[:, 0]), np.sin(th[:, 0])
    n = th.shape[0]
    T = np.zeros((n, 4, 4))
    T[:, :3, 0] = np.stack([np.cos(e) * c1, np.cos(e) * s1, np.sin(e)], axis=1)
    T[:, :3, 1] = np.stack([-np.sin(e) * c1, -np.sin(e) * s1, np.cos(e)], axis=1)
    T[:, :3, 2] = np.stack([s1, -c1, np.zeros(n)], axis=1)
    T[:, :3, 3] = np.stack([r * c1, r * s1, z], axis=1)
    T[:, 3, 3] = 1.0
    return T[0] if single else T


def spheres_from_T(T_base_ee, params: RobotParams | None = None) -> dict:
    """Tracking-sphere centres ``{"red": (N, 3), "green": (N, 3)}`` from end-effector poses."""
    p = params or load_robot_params()
    T = np.asarray(T_base_ee, dtype=np.float64)
    return {k: T[..., :3, :3] @ off + T[..., :3, 3] for k, off in p.sphere_offsets_ee_m.items()}


@dataclass(frozen=True, kw_only=True)
class SimLog:
    """Time series of one simulation (row k is the state after step k).

    Attributes
    ----------
    t : ndarray, shape (N,)
        Seconds.
    theta, dtheta, ddtheta, theta_ref, dtheta_ref, tau : ndarray, shape (N, 3)
        Joint angles (rad), velocities (rad/s), accelerations (rad/s^2), reference
        angles and velocities, electrical torques (N m).
    strain : ndarray, shape (N, 4)
        Gauge strains (link 2 near, far; link 3 near, far), m/m, top surface, tension positive.
    tip2, tip3 : ndarray, shape (N, 2)
        Tip deflection (m) and slope (rad) of links 2 and 3.
    contact_force : ndarray, shape (N, 3)
        N, base frame.
    params : RobotParams
        Robot parameters of the simulated arm (for the kinematics).
    """

    t: np.ndarray
    theta: np.ndarray
    dtheta: np.ndarray
    ddtheta: np.ndarray
    theta_ref: np.ndarray
    dtheta_ref: np.ndarray
    tau: np.ndarray
    strain: np.ndarray
    tip2: np.ndarray
    tip3: np.ndarray
    contact_force: np.ndarray
    params: RobotParams

    def T_base_ee(self) -> np.ndarray:
        """Deflected end-effector poses, shape (N, 4, 4).

        Returns
        -------
        T_base_ee : ndarray, shape (N, 4, 4)
            Homogeneous poses, ``p_base = T_base_ee @ p_ee``, metres.
        """
        return fk_elastic(self.theta, self.tip2, self.tip3, self.params)

    def ee_position(self) -> np.ndarray:
        """Deflected end-effector positions, shape (N, 3), metres, base frame.

        Returns
        -------
        p_base : ndarray, shape (N, 3)
            End-effector positions, metres, base frame.
        """
        return self.T_base_ee()[:, :3, 3]

    def sphere_positions(self) -> dict:
        """Tracking-sphere centres ``{"red": (N, 3), "green": (N, 3)}``, base frame.

        Returns
        -------
        dict of str to ndarray, shape (N, 3)
            Sphere centres per colour, metres, base frame.
        """
        return spheres_from_T(self.T_base_ee(), self.params)
