"""The rest of chapter 8 of the seed: external disturbances (8.4) and damping with one actuator (8.5).

Three experiments on the soft plant identified on the seed's measured modes
(:meth:`~tudorvision.sim.arm.PlantConfig.seed_measured`, passed explicitly),
each compared undamped against the damping laws as the joint layer exposes
them (:func:`~tudorvision.joint.damping.default_damping_config` with the
plant's gain set, :func:`~tudorvision.joint.damping_gains.gain_set_of`) and the
seed's static strain filter (section 2.2: ``N_FIR = 50`` at 100 Hz,
``FILTERS["seed"]`` of :mod:`tudorvision.lab.ch8_experiments`):

* :func:`periodic_disturbance_8_4` -- section 8.4, "Periodic excitation": the
  arm held in the horizontal joint-zero pose, a sinusoidal vertical force at
  the end effector at the first eigenfrequency of the pose (the seed's
  unbalanced DC motor, tuned "close to resonance"); damping off for the
  first part, then the tuned gains switched on. The seed: the strain
  amplitude drops from close to 400 um/m to about 100 um/m.
* :func:`payload_drop_8_4` -- section 8.4, "Disturbance steps": the 120 g
  net at the end effector in operating point 5, a 600 g mass dropped into
  it from 0.5 m (mass added with :meth:`~tudorvision.sim.arm.ElasticArm.set_payload`,
  its momentum as a short force pulse). The seed: proportional feedback and
  half-integrator damp the oscillation "within about two seconds".
* :func:`one_actuator_damping_8_5` -- section 8.5: experiment 06 (300 g)
  with the joint-2 gain set to zero, only joint 3 damping; link-2 strain
  settling against no damping and damping at both joints. The seed: clearly
  better than undamped, "cannot compete" with both actuators; the
  half-integrator is the better of the two laws.

The external force acts through the plant's contact interface: an
:class:`EndEffectorForce` is passed to :class:`~tudorvision.sim.arm.ElasticArm`
in place of an obstacle (``force(p_base, v_base)``, ``probe_link``,
``probe_x_m``), so the sim needs no change. Like the sim's contacts, the force
acts from the step after it is evaluated (0.5 ms late).

Results are plain numbers (dicts of floats and lists); ``quick=True`` runs a
shorter version of each (shorter runs, one switching phase, no scan of the joint-3 gain).
"""
from __future__ import annotations

import copy
import math

import numpy as np

from ..joint.controlled import ControlledArm
from ..joint.damping import StrainDamper, default_damping_config
from ..joint.damping_gains import gain_set_of
from ..joint.metrics import STRAIN_BAND, iats, settling_time
from ..robot import load_robot_params
from ..sim.arm import ElasticArm, Payload, PlantConfig
from .ch8_experiments import EXPERIMENTS, FILTERS, HORIZON_S, OPS_DEG, static_strain_link2_root

__all__ = ["SEED_8_4_PERIODIC_UM_M", "SEED_8_4_DROP_SETTLE_S", "PERIODIC_POSE_DEG", "NET_POSE_DEG", "NET_MASS_KG",
           "DROP_MASS_KG", "DROP_HEIGHT_M", "CATCH_TIME_S", "PERIODIC_FORCE_N", "EndEffectorForce", "damped_arm",
           "hold_run", "envelope_decay", "periodic_disturbance_8_4", "payload_drop_8_4", "one_actuator_damping_8_5"]

#: Section 8.4, periodic excitation: strain amplitude without and with damping (either law), um/m.
SEED_8_4_PERIODIC_UM_M = (400.0, 100.0)
#: Section 8.4, disturbance steps: damped "within about two seconds", s.
SEED_8_4_DROP_SETTLE_S = 2.0
#: Pose of the periodic excitation: "the horizontally stretched out joint zero configuration", deg.
PERIODIC_POSE_DEG = (0.0, 0.0, 0.0)
#: Amplitude of the periodic force, N: gives about the seed's undamped 400 um/m at resonance (402 um/m after a 40 s
#: warm-up under the identified holding loop; the amplitude is linear in the force up to about 0.04 N, 540 um/m,
#: and saturates above: 0.1 N gave 636 um/m, 334 under the former 3 / 10 ms loop).
PERIODIC_FORCE_N = 0.03
#: Pose of the disturbance steps: operating point 5 (straight horizontal, :data:`OPS_DEG`), deg.
NET_POSE_DEG = OPS_DEG[5]
#: Net with fixture (kg), the dropped test mass (kg) and its drop height (m), section 8.4.
NET_MASS_KG, DROP_MASS_KG, DROP_HEIGHT_M = 0.12, 0.6, 0.5
#: Duration of the net's braking pulse (half sine), s: assumed (the seed gives no number).
CATCH_TIME_S = 0.05
#: Joint-3 gains scanned for damping by joint 3 alone, factors on the larger tuned gain of the law.
_K3_SCAN = (0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0)
#: Laws the seed compares in 8.4 and 8.5 (the integral law is left out there: its drift).
_SEED_LAWS = ("proportional", "half_integrator")


class EndEffectorForce:
    """A prescribed force on the end effector, passed to the plant as an obstacle.

    Implements the obstacle interface of :class:`~tudorvision.sim.arm.ElasticArm`
    (``force(p_base, v_base)``, ``probe_link``, ``probe_x_m``): the plant calls
    :meth:`force` once per step, after the step, and applies it in the next.

    Parameters
    ----------
    profile : callable
        ``profile(t_s) -> (3,)`` force on the end effector at time ``t_s`` (s since the
        first call), N, base frame.
    dt : float
        The plant's step, s (the clock advances by ``dt`` per call).

    Attributes
    ----------
    probe_link : int
        3 (the force acts on link 3).
    probe_x_m : None
        At the tip of link 3 (the end effector).
    t_s : float
        Time of the next call, s.
    """

    probe_link = 3
    probe_x_m = None

    def __init__(self, profile, dt: float):
        if not dt > 0:
            raise ValueError(f"dt: expected > 0, got {dt}")
        self.profile = profile
        self.dt = float(dt)
        self.t_s = 0.0

    def force(self, p_base, v_base) -> np.ndarray:
        """Force at the current time (the probe's position and velocity are ignored).

        Parameters
        ----------
        p_base, v_base : array_like, shape (3,)
            Probe position (m) and velocity (m/s), base frame; unused.

        Returns
        -------
        ndarray, shape (3,)
            Force, N, base frame.
        """
        f = np.asarray(self.profile(self.t_s), dtype=np.float64).reshape(3)
        self.t_s += self.dt
        return f


def damped_arm(pose_deg, payload: Payload, law: str, *, config: PlantConfig, forces=(),
               gains_on: bool = True, k_eps=None, strain_filter: str = "seed"):
    """The plant at rest at a pose, its cascade and a strain damper of ``law`` (gains off or on).

    Parameters
    ----------
    pose_deg : sequence of 3 floats
        Joint angles, deg.
    payload : Payload
        End-effector payload.
    law : str
        Damping law (``"off"``, ``"proportional"``, ``"integral"``, ``"half_integrator"``).
    config : PlantConfig
        The plant (e.g. :meth:`PlantConfig.seed_measured`).
    forces : sequence of EndEffectorForce
        External forces (the plant's obstacles).
    gains_on : bool
        Start with the law's gains; ``False``: gains zero until ``damper.set_gains(gains)``.
    k_eps : sequence of 3 floats, optional
        Gains instead of the joint layer's tuned gains of ``law`` for the plant's gain set.
    strain_filter : {"seed", "2khz"}
        Static strain cancellation (``FILTERS`` of :mod:`tudorvision.lab.ch8_experiments`).

    Returns
    -------
    arm : ElasticArm
    ca : ControlledArm
        Holding ``pose_deg``.
    damper : StrainDamper
    gains : tuple of 3 floats
        The law's gains (rad/s per m/m; rad s^-1/2 per m/m for the half-integrator).
    """
    p = load_robot_params()
    arm = ElasticArm(np.deg2rad(pose_deg), payload=payload, params=p, config=config, obstacles=tuple(forces))
    ca = ControlledArm(arm)
    extra = dict(FILTERS[strain_filter])
    if k_eps is not None:
        extra["k_eps"] = tuple(k_eps)
    cfg = default_damping_config(law, plant=gain_set_of(arm), payload_kg=payload.mass_kg, **extra)
    gains = cfg.k_eps
    damper = StrainDamper(cfg, arm.measured_strain(), config.dt, payload_kg=payload.mass_kg)
    if not gains_on:
        damper.set_gains((0.0, 0.0, 0.0))
    ca.set_damper(damper)
    return arm, ca, damper, gains


def hold_run(arm, ca, damper, seconds: float, *, events=None, every: int = 4) -> dict:
    """Step the cascade for ``seconds``; sample the link-2 root strain and joint 2 every ``every`` steps.

    Parameters
    ----------
    arm : ElasticArm
    ca : ControlledArm
    damper : StrainDamper
    seconds : float
        Simulated time, s.
    events : dict, optional
        ``{step_index: callable()}`` run before that step (e.g. gains on, payload dropped).
    every : int
        Decimation of the samples (4: 500 Hz).

    Returns
    -------
    dict
        ``t`` (N,) s from the start of this call, ``eps`` (N,) root strain of link 2 (noise-free),
        ``eps_tilde`` (N,) the damper's mean-liberated link-2 strain, ``eps_dyn`` (N,) root strain
        minus the static strain of the pose and current payload, ``eps3`` (N,) link-3 root strain,
        ``theta2``, ``ref2``, ``dtheta2``, ``dtheta3`` (N,) rad, rad/s, all m/m or SI.
    """
    events = events or {}
    n = int(round(seconds / arm.dt))
    keys = ("t", "eps", "eps_tilde", "eps3", "theta2", "ref2", "dtheta2", "dtheta3")
    rec = {k: [] for k in keys}
    th = []
    t0 = arm.t
    for k in range(n):
        if k in events:
            events[k]()
        ca.step()
        if k % every == 0:
            for key, v in zip(keys, (arm.t - t0, arm.strain[0], damper.eps_tilde[0], arm.strain[2],
                                     arm.theta[1], ca.theta_ref[1], arm.dtheta[1], arm.dtheta[2])):
                rec[key].append(v)
            th.append(list(arm.theta))
    out = {k: np.asarray(v) for k, v in rec.items()}
    # static strain with the payload at the end of the run (a drop changes it once)
    out["eps_dyn"] = out["eps"] - static_strain_link2_root(arm, np.asarray(th))
    return out


def _amplitude(x) -> float:
    """Half the peak-to-peak of ``x``."""
    return 0.5 * float(np.max(x) - np.min(x))


def _vertical_sine(amp_N: float, freq_hz: float):
    w = 2.0 * math.pi * freq_hz
    return lambda t: (0.0, 0.0, amp_N * math.sin(w * t))


def _window(t, t_end: float, freq_hz: float):
    """Samples of about the last two seconds before ``t_end`` in whole periods of ``freq_hz``."""
    period = 1.0 / freq_hz
    n_per = max(2, int(round(2.0 / period)))
    return (t > t_end - n_per * period) & (t <= t_end + 1e-9)


def _periodic_runs(law: str, freq_hz: float, amp_N: float, config: PlantConfig, payload: Payload,
                   warm_s: float, on_s: float, phases) -> list:
    """Periodic excitation: ``warm_s`` undamped, then per phase ``phase_s`` more and ``on_s`` with the gains on.

    The phases continue copies of one warmed-up arm (same state at ``warm_s``).
    """
    push = EndEffectorForce(_vertical_sine(amp_N, freq_hz), config.dt)
    arm, ca, damper, gains = damped_arm(PERIODIC_POSE_DEG, payload, law, config=config, forces=(push,),
                                        gains_on=False)
    ca.controller.set_pd_scale(1.0)     # the bare cascade until the law is switched on (with its PD scale)
    warm = hold_run(arm, ca, damper, warm_s)
    runs = []
    for phase_s in phases:
        arm_c, ca_c, damper_c = copy.deepcopy((arm, ca, damper))
        k_on = int(round(phase_s / config.dt))
        on = {k_on: lambda d=damper_c, c=ca_c: (d.set_gains(gains), c.controller.set_pd_scale(d.pd_scale))}
        r = hold_run(arm_c, ca_c, damper_c, phase_s + on_s, events=on)
        t = r["t"] + warm_s
        series = {k: np.concatenate([warm[k], t if k == "t" else r[k]]) for k in warm}
        t_on = warm_s + phase_s
        tt, eps = series["t"], series["eps"]
        before, after = _window(tt, t_on, freq_hz), _window(tt, t_on + on_s, freq_hz)
        runs.append({"amp_before": _amplitude(eps[before]), "amp_after": _amplitude(eps[after]),
                     "joint2_speed_amp_after_rad_s": _amplitude(series["dtheta2"][after]),
                     "series": series, "t_on": t_on})
    return runs


def periodic_disturbance_8_4(quick: bool = False, *, config: PlantConfig | None = None, laws=_SEED_LAWS,
                             freq_hz: float | None = None, force_N: float = PERIODIC_FORCE_N,
                             durations=None, keep_series: bool = False) -> dict:
    """Section 8.4, periodic excitation near the first resonance: strain amplitude without and with damping.

    A vertical sinusoidal force of ``force_N`` at the end effector (300 g of plates on the
    mount) at the first eigenfrequency of the held arm at :data:`PERIODIC_POSE_DEG`
    (:meth:`~tudorvision.sim.arm.ElasticArm.coupled_frequencies_hz`; the seed tuned its
    unbalanced motor "close to resonance" by hand). The default force gives an undamped
    amplitude near the seed's "close to 400 um/m". Each run is undamped for a warm-up (the
    oscillation builds up; near resonance it beats slowly about its steady state), then
    the law's tuned gains are switched on, as in the seed; the amplitudes are half the
    peak-to-peak of the link-2 root strain over about 2 s before the switch and at the
    end of the damped part (the damped oscillation reaches its steady state within about
    10 s). ``quick``: a shorter warm-up and damped part and one switching phase; otherwise
    three phases (the seed's repetitions switch at different phases of the oscillation),
    continued from one warmed-up arm per law.

    Parameters
    ----------
    quick : bool
        Short version (16 s warm-up, 12 s damped; about half a minute of wall time).
    config : PlantConfig, optional
        Plant; default :meth:`PlantConfig.seed_measured`.
    laws : sequence of str
        Damping laws compared (default the seed's: proportional, half-integrator).
    freq_hz : float, optional
        Excitation frequency instead of the first eigenfrequency, Hz.
    force_N : float
        Amplitude of the force, N.
    durations : tuple of 2 floats, optional
        Undamped warm-up and damped time, s (default 16, 12 quick; 40, 20).
    keep_series : bool
        Also return the time series of the first phase per law (for figures).

    Returns
    -------
    dict
        ``freq_hz``, ``first_mode_hz``, ``force_N``, ``laws`` ``{law: {"before_um_m", "after_um_m",
        "after_std_um_m", "reduction", "joint2_speed_amp_deg_s"}}`` (before: undamped at the
        switch, after: at the end; std over the phases), ``seed`` (the seed's numbers),
        ``pose_deg``, ``payload_kg``, ``t_on_s``, ``phases_s``; with ``keep_series`` also ``series``
        ``{law: {"t", "eps", ...}}``.
    """
    cfg = config or PlantConfig.seed_measured()
    p = load_robot_params()
    payload = Payload.from_parts(p, plates=3)
    probe = ElasticArm(np.deg2rad(PERIODIC_POSE_DEG), payload=payload, params=p, config=cfg)
    f1 = float(probe.coupled_frequencies_hz()[0])
    f = f1 if freq_hz is None else float(freq_hz)
    warm, on = durations or ((16.0, 12.0) if quick else (40.0, 20.0))
    phases = (0.0,) if quick else tuple(i / (3.0 * f) for i in range(3))
    out = {"freq_hz": f, "first_mode_hz": f1, "force_N": float(force_N), "pose_deg": list(PERIODIC_POSE_DEG),
           "payload_kg": payload.mass_kg, "t_on_s": warm, "phases_s": list(phases), "laws": {},
           "seed": {"undamped_um_m": SEED_8_4_PERIODIC_UM_M[0], "damped_um_m": SEED_8_4_PERIODIC_UM_M[1],
                    "reduction": SEED_8_4_PERIODIC_UM_M[0] / SEED_8_4_PERIODIC_UM_M[1]}}
    series = {}
    for law in laws:
        runs = _periodic_runs(law, f, force_N, cfg, payload, warm, on, phases)
        before = np.array([r["amp_before"] for r in runs])
        after = np.array([r["amp_after"] for r in runs])
        out["laws"][law] = {"before_um_m": 1e6 * float(before.mean()), "after_um_m": 1e6 * float(after.mean()),
                            "after_std_um_m": 1e6 * float(after.std()),
                            "reduction": float(before.mean() / after.mean()),
                            "joint2_speed_amp_deg_s": float(np.rad2deg(np.mean(
                                [r["joint2_speed_amp_after_rad_s"] for r in runs])))}
        series[law] = runs[0]["series"]
    if keep_series:
        out["series"] = series
    return out


def envelope_decay(t, x, *, window_s: float = 1.0, floor: float = 2.0 * STRAIN_BAND) -> float:
    """Decay rate of an oscillation from a log-linear fit of its peak per window (negative: growing).

    Parameters
    ----------
    t : ndarray, shape (N,)
        Sample times, s.
    x : ndarray, shape (N,)
        Oscillating signal about zero (e.g. dynamic strain, m/m).
    window_s : float
        Window of each peak, s (longer than a period).
    floor : float
        Windows whose peak is below this are left out (noise, quantisation), same unit as ``x``.

    Returns
    -------
    float
        ``-d ln(peak) / dt``, 1/s; ``nan`` with fewer than three windows above ``floor``.
    """
    edges = np.arange(t[0], t[-1] - window_s + 1e-9, window_s)
    tc, pk = [], []
    for a in edges:
        m = (t >= a) & (t < a + window_s)
        v = float(np.max(np.abs(x[m])))
        if v > floor:
            tc.append(a + 0.5 * window_s)
            pk.append(math.log(v))
    if len(tc) < 3:
        return float("nan")
    return float(-np.polyfit(tc, pk, 1)[0])


def _catch_pulse(t_drop_s: float, impulse_Ns: float, duration_s: float):
    """Downward half-sine force pulse of ``impulse_Ns`` starting at ``t_drop_s`` (the net braking the mass)."""
    peak = impulse_Ns * math.pi / (2.0 * duration_s)

    def profile(t):
        u = t - t_drop_s
        if 0.0 <= u < duration_s:
            return (0.0, 0.0, -peak * math.sin(math.pi * u / duration_s))
        return (0.0, 0.0, 0.0)
    return profile


def _drop_run(law: str, config: PlantConfig, *, rest_s: float, horizon_s: float, drop_height_m: float,
              catch_time_s: float) -> dict:
    p = load_robot_params()
    net = Payload(mass_kg=p.end_effector_mount_mass_kg + NET_MASS_KG)
    loaded = Payload(mass_kg=net.mass_kg + DROP_MASS_KG, inertia_kg_m2=net.inertia_kg_m2)
    impulse = DROP_MASS_KG * math.sqrt(2.0 * p.gravity_m_s2 * drop_height_m)
    pulse = EndEffectorForce(_catch_pulse(rest_s, impulse, catch_time_s), config.dt)
    arm, ca, damper, gains = damped_arm(NET_POSE_DEG, net, law, config=config, forces=(pulse,))
    k_drop = int(round(rest_s / config.dt))
    static = []

    def land():
        static.append(static_strain_link2_root(arm, [arm.theta])[0])
        arm.set_payload(loaded)
        static.append(static_strain_link2_root(arm, [arm.theta])[0])
    r = hold_run(arm, ca, damper, rest_s + horizon_s, events={k_drop: land})
    after = r["t"] >= rest_s - 1e-9
    t = r["t"][after] - r["t"][after][0]
    dyn, online = r["eps_dyn"][after], r["eps_tilde"][after]
    return {"t": t, "eps_dyn": dyn, "eps_tilde": online, "dtheta2": r["dtheta2"][after], "gains": gains,
            "settle_s": settling_time(t, dyn, band=STRAIN_BAND, horizon_s=horizon_s),
            "settle_online_s": settling_time(t, online, band=STRAIN_BAND, horizon_s=horizon_s),
            "max_um_m": 1e6 * float(np.max(np.abs(dyn))),
            "static_um_m": [1e6 * float(x) for x in static],
            "residual_2s_um_m": 1e6 * float(np.max(np.abs(dyn[(t >= 2.0) & (t < 3.0)]))),
            "decay_per_s": envelope_decay(t[t >= 1.0], dyn[t >= 1.0]),
            "impulse_Ns": impulse}


def payload_drop_8_4(quick: bool = False, *, config: PlantConfig | None = None, laws=_SEED_LAWS,
                     horizon_s: float | None = None, drop_height_m: float = DROP_HEIGHT_M,
                     catch_time_s: float = CATCH_TIME_S, keep_series: bool = False) -> dict:
    """Section 8.4, disturbance steps: 600 g dropped into the net at operating point 5; settling time.

    The arm holds :data:`NET_POSE_DEG` carrying the mount and the 120 g net. After 1 s at
    rest the 600 g mass lands: the payload becomes mount + net + 600 g
    (:meth:`~tudorvision.sim.arm.ElasticArm.set_payload`, link shapes kept) and the
    mass's momentum after falling ``drop_height_m`` enters as a downward half-sine force
    pulse of ``catch_time_s`` (the net braking it; assumed). The settling time is the
    time after the landing until the link-2 root strain stays within the 15 um/m band
    (B.4) about the static strain of the pose with the new payload (``settle_s``; capped
    at ``horizon_s``), also on the damper's own mean-liberated strain
    (``settle_online_s``), with the tuned gains on from the start.

    Parameters
    ----------
    quick : bool
        Observe 10 s after the landing instead of 20 s.
    config : PlantConfig, optional
        Plant; default :meth:`PlantConfig.seed_measured`.
    laws : sequence of str
        Damping laws compared (default the seed's: proportional, half-integrator).
    horizon_s : float, optional
        Time observed after the landing (and the settling cap), s; default 10 (quick) or 20.
    drop_height_m : float
        Fall height, m (0: the mass is put in at rest).
    catch_time_s : float
        Duration of the braking pulse, s.
    keep_series : bool
        Also return the time series per law (for figures).

    Returns
    -------
    dict
        ``laws``: ``{"off" and each law: {"settle_s", "settle_online_s", "max_um_m", "residual_2s_um_m",
        "decay_per_s"}}`` (``residual_2s_um_m``: largest strain 2-3 s after landing; ``decay_per_s``:
        :func:`envelope_decay` from 1 s after landing, negative when the oscillation grows),
        ``speedup`` ``{law: undamped settle_s / damped settle_s}``, ``impulse_Ns``, ``static_um_m``
        (static strain of the pose before and after the landing), ``seed`` (``{"damped_settle_s":
        2.0}``), ``pose_deg``, ``horizon_s``; with ``keep_series`` also
        ``series`` ``{law: {"t", "eps_dyn", "dtheta2"}}``.
    """
    cfg = config or PlantConfig.seed_measured()
    laws = tuple(laws)
    horizon_s = horizon_s or (HORIZON_S if quick else 2.0 * HORIZON_S)
    out = {"laws": {}, "speedup": {}, "pose_deg": list(NET_POSE_DEG), "horizon_s": horizon_s,
           "drop_height_m": drop_height_m, "catch_time_s": catch_time_s,
           "seed": {"damped_settle_s": SEED_8_4_DROP_SETTLE_S}}
    series = {}
    for law in ("off",) + laws:
        r = _drop_run(law, cfg, rest_s=1.0, horizon_s=horizon_s, drop_height_m=drop_height_m,
                      catch_time_s=catch_time_s)
        keys = ("settle_s", "settle_online_s", "max_um_m", "residual_2s_um_m", "decay_per_s")
        out["laws"][law] = {k: float(r[k]) for k in keys}
        out["impulse_Ns"], out["static_um_m"] = r["impulse_Ns"], r["static_um_m"]
        series[law] = {k: r[k] for k in ("t", "eps_dyn", "dtheta2")}
    base = out["laws"]["off"]["settle_s"]
    for law in laws:
        out["speedup"][law] = base / max(out["laws"][law]["settle_s"], 1e-3)
    if keep_series:
        out["series"] = series
    return out


def _exp06_run(law: str, joint3_only: bool, config: PlantConfig, horizon_s: float,
               k3: float | None = None) -> dict:
    start, goal = EXPERIMENTS["06"]
    p = load_robot_params()
    arm, ca, damper, gains = damped_arm(start, Payload.from_parts(p, plates=3), law, config=config)
    if joint3_only:
        damper.set_gains((0.0, 0.0, gains[2] if k3 is None else k3))
    ca.set_goal(np.deg2rad(goal))
    r = hold_run(arm, ca, damper, horizon_s)
    t = r["t"]
    return {"t": t, "eps_dyn": r["eps_dyn"], "dtheta3": r["dtheta3"], "gains": list(gains),
            "settle_s": settling_time(t, r["eps_dyn"], band=STRAIN_BAND, horizon_s=horizon_s),
            "settle_online_s": settling_time(t, r["eps_tilde"], band=STRAIN_BAND, horizon_s=horizon_s),
            "max_um_m": 1e6 * float(np.max(np.abs(r["eps_dyn"]))),
            "eps3_tail_um_m": 1e6 * _amplitude(r["eps3"][t > horizon_s - 2.0]),
            "iats": iats(t, r["eps_dyn"])}


def one_actuator_damping_8_5(quick: bool = False, *, config: PlantConfig | None = None, laws=_SEED_LAWS,
                             horizon_s: float = HORIZON_S, keep_series: bool = False) -> dict:
    """Section 8.5: experiment 06 damped by joint 3 only (joint-2 gain zero) against none and both joints.

    Experiment 06 (operating point 1 to 2, 300 g of plates) on the plant, undamped, with
    the law's tuned gains at both joints, and with the joint-2 gain set to zero (the
    seed's set-up: "only the third joint employed for damping"). The measure is the
    settling of the link-2 root strain (dynamic part: strain minus the static strain of
    the current pose) into the 15 um/m band, capped at ``horizon_s`` (the seed's 10 s
    normalisation), and its settling cut ``100 (1 - T / horizon)`` percent.

    Parameters
    ----------
    quick : bool
        Without the scan of the joint-3 gain (``joint3_scan``, ``joint3_tuned``).
    config : PlantConfig, optional
        Plant; default :meth:`PlantConfig.seed_measured`.
    laws : sequence of str
        Damping laws compared (default the seed's: proportional, half-integrator).
    horizon_s : float
        Simulated time and settling cap, s.
    keep_series : bool
        Also return the time series per case (for figures).

    Returns
    -------
    dict
        ``off`` and per law ``laws[law]["both"]`` / ``laws[law]["joint3_only"]``: ``{"settle_s",
        "settle_online_s", "cut_pct", "max_um_m", "iats", "iats_pct", "eps3_tail_um_m"}`` (``iats`` the
        B.4 integral absolute time-weighted strain, (m/m) s^2, ``iats_pct`` in percent of the undamped;
        ``eps3_tail_um_m`` the link-3 root oscillation in the last 2 s, half peak-to-peak);
        ``gains`` per law; ``fraction`` ``{law: (settling cut, joint 3 only) / (cut, both)}``,
        ``iats_fraction`` the same for the IATS cut; ``seed`` (the seed's ordering). Unless ``quick``,
        per law also ``joint3_scan`` (``k3``, ``iats_pct``, ``cut_pct``, ``eps3_tail_um_m`` over joint-3
        gains of 0.5-32 times the law's larger tuned gain, joint 2 off) and ``joint3_tuned`` (the
        scan's best IATS among the gains that leave link 3 within 15 um/m at the end).
    """
    cfg = config or PlantConfig.seed_measured()
    laws = tuple(laws)

    off = _exp06_run("off", False, cfg, horizon_s)

    def summary(r):
        d = {k: float(r[k]) for k in ("settle_s", "settle_online_s", "max_um_m", "iats", "eps3_tail_um_m")}
        d["cut_pct"] = 100.0 * (1.0 - d["settle_s"] / horizon_s)
        d["iats_pct"] = 100.0 * d["iats"] / float(off["iats"])
        return d
    out = {"off": summary(off), "laws": {}, "gains": {}, "fraction": {}, "iats_fraction": {},
           "horizon_s": horizon_s,
           "seed": {"ordering": "none < joint 3 only < both; half-integrator better than proportional"}}
    series = {"off": off}
    for law in laws:
        both = _exp06_run(law, False, cfg, horizon_s)
        one = _exp06_run(law, True, cfg, horizon_s)
        out["gains"][law] = both["gains"]
        out["laws"][law] = {"both": summary(both), "joint3_only": summary(one)}
        v = out["laws"][law]
        cut_both = v["both"]["cut_pct"]
        out["fraction"][law] = v["joint3_only"]["cut_pct"] / cut_both if cut_both > 0 else float("nan")
        out["iats_fraction"][law] = (100.0 - v["joint3_only"]["iats_pct"]) / (100.0 - v["both"]["iats_pct"])
        series[law + "_both"], series[law + "_joint3"] = both, one
        if not quick:           # can joint 3 damp link 2 at all? its gain scanned for this case
            ref = max(both["gains"][1], both["gains"][2])
            scan = {k3: summary(_exp06_run(law, True, cfg, horizon_s, k3=k3))
                    for k3 in (ref * f for f in _K3_SCAN)}
            calm = [k3 for k3 in scan if scan[k3]["eps3_tail_um_m"] <= 1e6 * STRAIN_BAND] or list(scan)
            best = min(calm, key=lambda k3: scan[k3]["iats"])
            v["joint3_scan"] = {"k3": [float(k) for k in scan],
                                **{m: [scan[k][m] for k in scan] for m in ("iats_pct", "cut_pct", "eps3_tail_um_m")}}
            v["joint3_tuned"] = {"k3": float(best), **scan[best]}
    if keep_series:
        out["series"] = {k: {kk: v[kk] for kk in ("t", "eps_dyn", "dtheta3")} for k, v in series.items()}
    return out
