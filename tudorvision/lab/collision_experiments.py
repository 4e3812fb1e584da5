"""The collision benchmark of chapter 11 as runner tasks: identification, residual and contact runs.

Every run builds its own two-way coupled plant (the soft default plant,
``PlantConfig()``, or the former stiff one, ``CollisionSetup(plant="stiff")``)
with proportional damping (:class:`CollisionSetup`) and strain noise drawn
from its seed, so the runs are independent tasks for
:mod:`tudorvision.lab.runner`:

* :func:`identification_run`: APRBS motion of joints 2 and 3, 100 Hz samples
  for the strain-referred dynamics fit (10.4);
* :func:`residual_run`: APRBS motion with the momentum observer armed,
  its residuals (for thresholds) or their peaks and the detections (false
  positives);
* :func:`contact_run`: an obstacle sphere in the path of link 3 or link 2,
  with a reaction strategy: onset, detection delay, isolation, forces.

Everything a run needs (the setup, the identified model's parameters,
thresholds, the residual coupling) travels as its arguments, never as a
global; ``benchmarks/bench_collision.py`` runs the stages.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from ..joint.collision import (DEFAULT_K_I, CollisionMonitor, ResidualCoupling, reaction_config,
                               root_torque_per_strain)
from ..joint.controlled import ControlledArm
from ..joint.damping import DampingConfig, StrainDamper, default_damping_config
from ..joint.strain_dynamics import StrainDynamicsModel, aprbs, derivatives
from ..robot import load_robot_params
from ..sim.arm import ElasticArm, Payload, PlantConfig, SpringDamperObstacle

__all__ = ["PLANTS", "SOFT_COLLISION_K_EPS",
           "PLATES", "LO_RAD", "HI_RAD", "V_ID_RAD_S", "A_ID_RAD_S2", "ARMED_AFTER_S", "CONTACT_PLATES",
           "STRATEGIES", "CollisionSetup", "make_arm", "random_motion", "identification_run", "residual_run",
           "contact_scenario", "contact_run", "thr_of"]

_DEG = np.pi / 180
#: Payloads of identification, thresholds and false positives (plates of 100 g on the 50 g mount).
PLATES = (0, 1, 2, 3, 4)
#: APRBS ranges of joints 2 and 3, rad.
LO_RAD, HI_RAD = np.array([20.0, -80.0]) * _DEG, np.array([160.0, 80.0]) * _DEG
#: Speed and acceleration limits of the random motions, rad/s and rad/s^2.
V_ID_RAD_S, A_ID_RAD_S2 = np.array([1.0, 70.0, 70.0]) * _DEG, np.array([1.0, 200.0, 200.0]) * _DEG
#: Residual runs start 1 s before the counted/evaluated period (start-up sag, see :func:`random_motion`).
ARMED_AFTER_S = 1.0
#: Default payload of the contact scenarios (plates).
CONTACT_PLATES = 3
#: Reaction strategies of the contact scenarios.
STRATEGIES = ("no detection", "stop", "reflex", "interaction")
#: Plants of the benchmark: the soft default plant (``PlantConfig()``) and the former stiff one.
PLANTS = ("soft", "stiff")
#: Proportional damping gains of the collision runs on the soft plant, rad/s per m/m, with the joint
#: layer's position-loop scale for that law (``PD_SCALES``, 0.04). The layer's own soft gains
#: (``SOFT_GAINS``, (0, 250, 800), tuned for settling in chapter 8) leave the link-2 impact's residual
#: at 0.55-0.63 of its 6-sigma threshold in the first 20 ms (the contact moment reaches the root gauge
#: only through the link's inertia and hub spring; detection came at 28-32 ms, from the link-3 residual,
#: as link 3); with larger gains the damper's answer to the impact strain decelerates the joints at once,
#: which the model sees. Chosen on tuning seeds 5000+ (20 s identification and residual per payload,
#: thresholds per payload, contacts at 300 / 400 g): (400, 800) still misses link 2 (0.76 / 0.82 of the
#: threshold); (500, 800) 10.5 / 8.0 ms; (500, 1600) 7.5 / 6.5 ms with the collision-free peaks at most
#: 0.74 of the thresholds; (600, 1200), (700, 800) 0.79-0.81; (1000, 800) 0.97; (1000, 1600) over
#: (docs/benchmarks.md, "Collision detection on the soft plant").
SOFT_COLLISION_K_EPS = (0.0, 500.0, 1600.0)


@dataclass(frozen=True)
class CollisionSetup:
    """Settings shared by every run of the benchmark (travels to the workers with each task).

    Parameters
    ----------
    plant : {"soft", "stiff"}
        ``"soft"``: the lab's default plant (``PlantConfig()``: hub springs, dampers, backlash,
        two-way coupling) with the damping of ``soft_k_eps``; ``"stiff"``: the former plant
        (``PlantConfig.stiff(two_way=True)``) with ``k_eps`` and the heavy-payload schedule.
    soft_k_eps : tuple of float, length 3
        Proportional damping gains on the soft plant, rad/s per m/m, run with the joint layer's
        position-loop scale for the law (:data:`SOFT_COLLISION_K_EPS`); ``()``: the layer's own
        soft gains (``SOFT_GAINS``).
    noise : float
        Strain noise standard deviation, m/m.
    k_i : float
        Observer gain K_I of the momentum residual, 1/s.
    k_eps : tuple of float, length 3
        Proportional damping gains on the stiff plant, rad/s per m/m. ``TWO_WAY_GAINS`` (tuned on
        experiment 06 at 300 g) drive the 400 g arm into bursts of large oscillation during long
        APRBS runs; these were tuned for the smallest collision-free residual over 0-400 g on
        tuning seeds. Not used on the soft plant (``soft_k_eps``; these gains at the full position
        gain start limit cycles there).
    n_window : int
        Window of the damping's static strain filter, samples at 2 kHz (the seed's 0.5 s).
    heavy_from : int
        Plates from which ``heavy_k_eps`` and ``heavy_n_window`` apply (5: never).
    heavy_k_eps : tuple of float, length 3
        Damping gains of the heavy payloads, rad/s per m/m.
    heavy_n_window : int
        Static strain filter window of the heavy payloads, samples.
    isolation_window_s : float
        How long the (decoupled) link-3 residual must stay over its threshold for link 3, s.
    detect_decoupled : bool
        Also detect on the decoupled link-3 residual.
    input_lag_s : float
        Lag of the observer's angle and strain inputs, s (0: raw inputs).
    detect_highpass_hz : float
        Corner of the high-pass on the detection residual, Hz (0: off).
    transient_gain : float or None
        Thresholds widened by this multiple of the inertial transient due after a change of planned
        acceleration (:class:`~tudorvision.joint.collision_transient.TransientAllowance`; 0: off);
        None: :data:`~tudorvision.joint.collision_transient.SOFT_TRANSIENT_GAIN` on the soft plant, 0 on
        the stiff one.
    """

    plant: str = "soft"
    soft_k_eps: tuple = SOFT_COLLISION_K_EPS
    noise: float = 2e-6
    k_i: float = DEFAULT_K_I
    k_eps: tuple = (0.0, 800.0, 3200.0)
    n_window: int = 1000
    heavy_from: int = 4
    heavy_k_eps: tuple = (0.0, 400.0, 1600.0)
    heavy_n_window: int = 1000
    isolation_window_s: float = 0.02
    detect_decoupled: bool = False
    input_lag_s: float = 0.0
    detect_highpass_hz: float = 0.0
    transient_gain: float | None = None

    def __post_init__(self):
        if self.plant not in PLANTS:
            raise ValueError(f"plant: expected one of {PLANTS}, got {self.plant!r}")
        if len(self.soft_k_eps) not in (0, 3):
            raise ValueError(f"soft_k_eps: expected 3 gains or (), got {self.soft_k_eps!r}")
        if self.transient_gain is None:
            from ..joint.collision_transient import SOFT_TRANSIENT_GAIN

            object.__setattr__(self, "transient_gain", SOFT_TRANSIENT_GAIN if self.plant == "soft" else 0.0)
        if not self.transient_gain >= 0:
            raise ValueError(f"transient_gain: expected >= 0, got {self.transient_gain!r}")

    def params(self) -> dict:
        """The setup as JSON values (part of every task's key).

        Returns
        -------
        dict
            Field name -> value.
        """
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in dataclasses.asdict(self).items()}


def make_arm(setup: CollisionSetup, plates: int, theta0, *, seed: int, obstacles=(), two_way: bool = True):
    """The plant with the benchmark's damping (scheduled on the payload) and speed limits.

    Parameters
    ----------
    setup : CollisionSetup
        Noise and damping.
    plates : int
        Test plates (100 g each).
    theta0 : array_like, shape (3,)
        Start joint angles, rad.
    seed : int
        Noise seed.
    obstacles : sequence
        Obstacles of the plant.
    two_way : bool
        Two-way coupled plant.

    Returns
    -------
    arm : ElasticArm
        The plant.
    ca : ControlledArm
        Its controller.
    """
    p = load_robot_params()
    make_cfg = PlantConfig if setup.plant == "soft" else PlantConfig.stiff
    cfg = make_cfg(two_way=two_way, strain_noise_m_m=setup.noise, noise_seed=seed)
    arm = ElasticArm(theta0, payload=Payload.from_parts(p, plates=plates), params=p, config=cfg,
                     obstacles=obstacles)
    ca = ControlledArm(arm, v_max=V_ID_RAD_S, a_max=A_ID_RAD_S2)
    heavy = plates >= setup.heavy_from
    k, nw = (setup.heavy_k_eps, setup.heavy_n_window) if heavy else (setup.k_eps, setup.n_window)
    if arm.gain_set == "soft":     # the joint layer's proportional law for the soft plant (its PD scale)
        gains = {"k_eps": tuple(float(x) for x in setup.soft_k_eps)} if setup.soft_k_eps else {}
        dcfg = default_damping_config("proportional", plant="soft", n_window=nw, **gains)
    else:
        dcfg = DampingConfig(law="proportional", k_eps=tuple(float(x) for x in k), n_window=nw)
    ca.set_damper(StrainDamper(dcfg, arm.measured_strain(), cfg.dt))
    return arm, ca


def _monitor(setup: CollisionSetup, model, thr, mass_kg: float, dt: float, reaction, coupling, **kw):
    return CollisionMonitor(model, thr, mass_kg, dt, reaction, k_i=setup.k_i, input_lag_s=setup.input_lag_s,
                            detect_highpass_hz=setup.detect_highpass_hz, isolation_coupling=coupling,
                            transient_gain=setup.transient_gain,
                            isolation_window_s=setup.isolation_window_s,
                            detect_decoupled=setup.detect_decoupled and coupling is not None, **kw)


def random_motion(setup: CollisionSetup, plates: int, seconds: float, *, seed: int, monitor_args=None,
                  record: bool = True, armed_after_s: float = 0.0) -> dict:
    """APRBS motion of joints 2, 3; 2 kHz records and (optionally) the online residuals.

    Detections before ``armed_after_s`` are not counted: at start the cascade's PI
    integrators are empty and the joints sag under gravity for ~20 ms (up to 0.1 rad/s),
    which the residual sees as an unexplained strain; the thresholds are computed on
    the residuals after the first second for the same reason.

    Parameters
    ----------
    setup : CollisionSetup
        Noise, damping, observer.
    plates : int
        Test plates.
    seconds : float
        Length, s.
    seed : int
        Seed of the APRBS and the noise.
    monitor_args : tuple or None
        ``(model, thresholds (2,), strategy, coupling or None)``: arm a :class:`CollisionMonitor`.
    record : bool
        Record angles and strains.
    armed_after_s : float
        Detections counted from this time on, s.

    Returns
    -------
    dict
        ``theta`` (N, 3) rad, ``eps`` (N, 2) m/m (noisy), ``res`` (N, 2) m/m, ``payload`` kg,
        ``detections`` (list of (s after arming, plates, seed, link, direction)), ``dt`` s.
    """
    rng = np.random.default_rng(seed)
    times, levels = aprbs(rng, seconds, LO_RAD, HI_RAD)
    arm, ca = make_arm(setup, plates, np.array([0.0, levels[0, 0], levels[0, 1]]), seed=seed)
    mon = None
    if monitor_args is not None:
        model, thr, strategy, coupling = monitor_args
        mon = _monitor(setup, model, thr, arm.payload.mass_kg, arm.config.dt, reaction_config(strategy), coupling)
        ca.reaction = mon
    n = int(round(seconds / arm.config.dt))
    th, eps, res = np.empty((n, 3)), np.empty((n, 2)), np.empty((n, 2))
    nxt = 1
    detections = []
    last_over = -np.inf
    for k in range(n):
        t = k * arm.config.dt
        if nxt < times.size and t >= times[nxt]:
            ca.set_goal([0.0, levels[nxt, 0], levels[nxt, 1]])
            nxt += 1
        ca.step()
        if record:
            th[k] = arm.measured_theta()
            s = arm.strain
            eps[k] = s[0], s[2]
        if mon is not None:
            res[k] = mon.residual[1], mon.residual[2]
            if mon.collision:       # count events: one event until both residuals stay under threshold 0.5 s
                if t - last_over > 0.5 and t >= armed_after_s:
                    detections.append((round(t - armed_after_s, 4), plates, seed, mon.link, mon.direction))
                last_over = t
                mon.reset()
    # measurement noise on the recorded strains (the online loop drew its own)
    if record and setup.noise:
        eps += np.random.default_rng(seed + 10_000).normal(0.0, setup.noise, size=eps.shape)
    return {"theta": th, "eps": eps, "res": res, "payload": arm.payload.mass_kg, "detections": detections,
            "dt": arm.config.dt}


def identification_run(setup: CollisionSetup, plates: int, seconds: float, seed: int) -> dict:
    """One identification run (task): APRBS motion, 100 Hz samples with Savitzky-Golay derivatives.

    Parameters
    ----------
    setup : CollisionSetup
        Noise and damping.
    plates : int
        Test plates.
    seconds : float
        Length, s.
    seed : int
        Seed.

    Returns
    -------
    dict
        ``t`` (M,) s, ``theta``, ``d``, ``dd`` (M, 3) rad, rad/s, rad/s^2, ``eps`` (M, 2) m/m, ``m`` (M,) kg,
        ``plates``.
    """
    r = random_motion(setup, plates, seconds, seed=seed)
    t = np.arange(r["theta"].shape[0]) * r["dt"]
    d, dd = derivatives(t, r["theta"], window_s=0.04)
    sl = slice(200, -200, 20)                                   # 100 Hz, edges dropped
    return {"t": t[sl], "theta": r["theta"][sl], "d": d[sl], "dd": dd[sl], "eps": r["eps"][sl],
            "m": np.full(t[sl].size, r["payload"]), "plates": plates}


def _coupling(coupling):
    return None if coupling is None else ResidualCoupling(*(float(c) for c in coupling))


def residual_run(setup: CollisionSetup, plates: int, seconds: float, seed: int, model_chi, thr, strategy: str,
                 coupling=None, keep_residuals: bool = True) -> dict:
    """One collision-free run with the observer armed (task), after :data:`ARMED_AFTER_S` of start-up.

    Parameters
    ----------
    setup : CollisionSetup
        Noise, damping, observer.
    plates : int
        Test plates.
    seconds : float
        Evaluated length (after the start-up second), s.
    seed : int
        Seed.
    model_chi : array_like
        Parameters of the identified :class:`StrainDynamicsModel`.
    thr : array_like, shape (2,)
        Detection thresholds (link-2, link-3 root residual), m/m; ``inf``: never detect.
    strategy : str
        Reaction strategy.
    coupling : sequence of 3 floats or None
        ``(c0, c1, threshold)`` of the :class:`ResidualCoupling` for isolation; ``None``: none.
    keep_residuals : bool
        Return the residuals themselves (thresholds) or only their peaks (false positives).

    Returns
    -------
    dict
        ``plates``, ``seconds``, ``payload`` kg, ``detections``, ``res_absmax`` (2,) m/m and, with
        ``keep_residuals``, ``res`` (N, 2) m/m.
    """
    model = StrainDynamicsModel(chi=np.asarray(model_chi, float))
    thr = np.asarray(thr, float)
    r = random_motion(setup, plates, seconds + ARMED_AFTER_S, seed=seed,
                      monitor_args=(model, thr, strategy, _coupling(coupling)), record=False,
                      armed_after_s=ARMED_AFTER_S)
    res = r["res"][int(round(ARMED_AFTER_S / r["dt"])):]
    out = {"plates": plates, "seconds": seconds, "payload": r["payload"], "detections": r["detections"],
           "res_absmax": np.abs(res).max(axis=0)}
    if keep_residuals:
        out["res"] = res
    return out


class _ProbeRecorder:
    """An obstacle that never touches: it records where the plant puts its probe point after each step."""

    def __init__(self, link: int, x_m):
        self.probe_link, self.probe_x_m = link, x_m
        self.positions = []

    def force(self, p, v):
        self.positions.append(np.array(p, float))
        return np.zeros(3)


def contact_scenario(setup: CollisionSetup, kind: str, strategy: str, model, thr, *, seed: int = 7,
                     seconds: float = 2.5, plates: int = CONTACT_PLATES, coupling=None) -> dict:
    """An obstacle sphere in the path of the end effector or of a point on link 2, with one strategy.

    A free run first finds where the probe point passes 0.6 s into the motion; the sphere is
    put just ahead of it in its direction of motion.

    Parameters
    ----------
    setup : CollisionSetup
        Noise, damping, observer.
    kind : str
        ``"link3"`` (end effector) or ``"link2"`` (a point 0.30 m along link 2).
    strategy : str
        One of :data:`STRATEGIES`.
    model : StrainDynamicsModel
        The identified model.
    thr : array_like, shape (2,)
        Thresholds, m/m.
    seed : int
        Noise seed.
    seconds : float
        Length of the contact run, s.
    plates : int
        Test plates.
    coupling : ResidualCoupling or None
        Isolation coupling.

    Returns
    -------
    dict
        ``kind``, ``strategy``, ``onset_s``, ``peak_force_N``, ``final_force_N``, ``theta_end_deg`` (3,), and
        with detection ``detected_s``, ``link``, ``direction``, ``delay_ms``.
    """
    start, goal = np.array([0.0, 45.0, -45.0]) * _DEG, np.array([0.0, 150.0, 60.0]) * _DEG
    link, x = (3, None) if kind == "link3" else (2, 0.30)
    probe = _ProbeRecorder(link, x)
    arm, ca = make_arm(setup, plates, start, seed=seed, obstacles=(probe,), two_way=True)
    ca.set_goal(goal)
    for _ in range(int(round(0.6 / arm.config.dt)) + 1):
        ca.step()
    p0, p1 = probe.positions[-2], probe.positions[-1]
    v = (p1 - p0) / arm.config.dt
    centre = p1 + v / np.linalg.norm(v) * (0.05 + 0.02 + 0.002)
    ob = SpringDamperObstacle(kind="sphere", point_base=centre, radius_m=0.05, probe_link=link, probe_x_m=x,
                              probe_radius_m=0.02, stiffness_N_m=5.0e3, damping_Ns_m=20.0)
    arm, ca = make_arm(setup, plates, start, seed=seed, obstacles=(ob,))
    mon = None
    if strategy != "no detection":
        mon = _monitor(setup, model, thr, arm.payload.mass_kg, arm.config.dt,
                       reaction_config(strategy, torque_per_strain=root_torque_per_strain(arm.params)), coupling,
                       armed_after_s=0.1)   # start-up sag, as SimCore
        ca.reaction = mon
    ca.set_goal(goal)
    n = int(round(seconds / arm.config.dt))
    f = np.empty(n)
    onset = None
    for k in range(n):
        ca.step()
        f[k] = np.linalg.norm(arm.contact_force)
        if onset is None and f[k] > 0:
            onset = (k + 1) * arm.config.dt
    out = {"kind": kind, "strategy": strategy, "onset_s": onset, "peak_force_N": float(f.max()),
           "final_force_N": float(f[-1]), "theta_end_deg": np.round(np.rad2deg(arm.theta), 2).tolist()}
    if mon is not None:
        out.update(detected_s=mon.detected_at, link=mon.link, direction=mon.direction,
                   delay_ms=None if (mon.detected_at is None or onset is None) else 1e3 * (mon.detected_at - onset))
    return out


def contact_run(setup: CollisionSetup, kind: str, strategy: str, model_chi, thr, coupling, plates: int) -> dict:
    """One contact scenario as a task (:func:`contact_scenario` with the model's parameters as the argument).

    Parameters
    ----------
    setup : CollisionSetup
        Noise, damping, observer.
    kind : str
        ``"link3"`` or ``"link2"``.
    strategy : str
        One of :data:`STRATEGIES`.
    model_chi : array_like
        Parameters of the identified model.
    thr : array_like, shape (2,)
        Thresholds, m/m.
    coupling : sequence of 3 floats or None
        ``(c0, c1, threshold)`` of the isolation coupling.
    plates : int
        Test plates.

    Returns
    -------
    dict
        :func:`contact_scenario`'s result plus ``payload_g``.
    """
    out = contact_scenario(setup, kind, strategy, StrainDynamicsModel(chi=np.asarray(model_chi, float)),
                           np.asarray(thr, float), plates=plates, coupling=_coupling(coupling))
    out["payload_g"] = 100 * plates
    return out


def thr_of(thr, plates: int) -> np.ndarray:
    """Thresholds for a payload: ``thr`` itself (pooled) or its row ``plates`` (per payload).

    Parameters
    ----------
    thr : array_like, shape (2,) or (5, 2)
        Pooled or per-payload thresholds, m/m.
    plates : int
        Test plates.

    Returns
    -------
    ndarray, shape (2,)
        m/m.
    """
    thr = np.asarray(thr)
    return thr[plates] if thr.ndim == 2 else thr
