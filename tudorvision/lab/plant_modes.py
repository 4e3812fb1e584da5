"""The lab's version of the seed's frequency measurements (sections 4.7, 4.8): modes of the plant at a pose.

Two views of the same plant:

* linearised (:func:`tudorvision.sim.mode_analysis.held_joint_modes`): the
  link modes with the joints held, hub springs engaged. Link 2's two lowest
  frequencies are the two lowest coupled modes (both dominate the link-2
  strain, figure 4.6); link 3's first frequency is that of link 3 on its hub
  spring with the payload (the seed's reading of its 6.3 Hz peak, compared
  with the link-3 BVP).
* ring-down (the oracle, and the only view of the backlash): a hammer
  impulse at the end effector while the joint cascade holds the pose; the
  first dominant frequency is the spectral peak of the link-2 hub strain
  and the decay rate ``zeta_1`` (1/s, as the seed's B.3.26) is fitted to the
  envelope of that strain band-passed around the peak.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.signal import butter, hilbert, sosfiltfilt

from ..joint.cascade import JointCascade, design_cascade
from ..joint.damping_gains import HOLD_LOOPS, hold_loop_of
from ..joint.planner import plan_motion
from ..robot.params import RobotParams, load_robot_params
from ..sim.arm import ElasticArm, Payload, PlantConfig
from ..sim.mode_analysis import held_joint_matrices, held_joint_modes
from .simulation import simulate

__all__ = ["plate_payload", "linear_modes", "ring_down", "dominant_frequency_hz", "decay_rate_per_s",
           "plant_modes", "identify_hub_stiffness", "HAMMER_IMPULSE_NS", "SEED_MODES_300G", "modes_map"]

#: The seed's numbers at 300 g: figure 4.6 (link 2 first, second; link 3 first) and the top of figure 4.8, Hz.
SEED_MODES_300G = {"link2_hz": (2.0, 9.9), "link3_hz": 6.3, "f1_max_hz": 2.74}

#: Hammer impulse at the end effector along link 3's bending direction, N s (about 150 um/m on link 2).
HAMMER_IMPULSE_NS = 0.25


def plate_payload(payload_kg: float, params: RobotParams | None = None, plate_size_m: float = 0.08) -> Payload:
    """The seed's test payload: ``payload_kg`` of plates on the end-effector mount.

    Parameters
    ----------
    payload_kg : float
        Plate mass, kg (0.3 kg gives the seed's ``I_L = 1.6e-4 kg m^2``).
    params : RobotParams, optional
        Robot parameters (mount mass); default the packaged file.
    plate_size_m : float, optional
        Plate edge, metres.

    Returns
    -------
    Payload
        Mass ``mount + payload_kg`` (kg) and inertia ``payload_kg a^2 / 12`` (kg m^2).

    Raises
    ------
    ValueError
        If ``payload_kg`` is negative or not finite.
    """
    if not (math.isfinite(payload_kg) and payload_kg >= 0):
        raise ValueError(f"payload_kg: expected a finite mass >= 0, got {payload_kg}")
    p = params or load_robot_params()
    return Payload(mass_kg=p.end_effector_mount_mass_kg + payload_kg,
                   inertia_kg_m2=payload_kg * plate_size_m**2 / 12.0)


def linear_modes(theta_rad, payload_kg: float, config: PlantConfig, params: RobotParams | None = None) -> dict:
    """Linearised modes at a pose (joints held, springs engaged).

    Parameters
    ----------
    theta_rad : array_like, shape (3,)
        Joint angles, rad.
    payload_kg : float
        Plate payload, kg (:func:`plate_payload`).
    config : PlantConfig
        Plant options (hub compliance).
    params : RobotParams, optional
        Robot parameters; default the packaged file.

    Returns
    -------
    dict
        ``link2_hz`` [first, second], ``link3_hz`` [first], ``decay_linear_per_s`` (first mode,
        hub dampers engaged), ``modes_hz`` (all modes, Hz). With ``config.two_way`` the
        link-2 values are the two lowest coupled modes; for the one-way plant they are
        link 2's own BVP frequencies (what that plant rings at).
    """
    arm = ElasticArm(theta_rad, payload=plate_payload(payload_kg, params), params=params, config=config)
    f, decay, _ = held_joint_modes(arm, coupled=bool(config.two_way))
    if not config.two_way:          # one-way plant: link 2 rings at its own BVP frequencies
        order = np.argsort(f)
        f, decay = f[order], decay[order]
        return {"link2_hz": [float(x) for x in arm.link2.basis.frequency_hz[:2]],
                "link3_hz": [float(arm.link3.basis.frequency_hz[0])],
                "decay_linear_per_s": float(decay[np.argmin(np.abs(f - arm.link2.basis.frequency_hz[0]))]),
                "modes_hz": [float(x) for x in f]}
    return {"link2_hz": [float(f[0]), float(f[1])], "link3_hz": [float(arm.link3.basis.frequency_hz[0])],
            "decay_linear_per_s": float(decay[0]), "modes_hz": [float(x) for x in f]}


#: ``(t_d, t_l)`` of the holding cascade identified on figure 4.8's decay range (s): the seed gives the
#: cascade's structure (3.2.1, 3.2.2) but not these; with them the lab's map spans 1.61-2.63 Hz and
#: 0.031-1.18 1/s (seed 1.56-2.74 Hz, 0.03-1.24 1/s). The joint layer holds the seed-measured plant with it
#: (``joint.damping_gains.HOLD_LOOPS``; docs/simulation.md, "Decay floor").
SEED_HOLD_TIME_CONSTANTS_S = HOLD_LOOPS["soft"]


def _servo_kw(servo_time_constants_s, arm) -> dict:
    """``design_cascade``'s ``t_d`` / ``t_l``: ``(t_d, t_l)`` checked (two positive seconds), or the arm's loop."""
    if servo_time_constants_s is None:
        return hold_loop_of(arm)
    tc = np.asarray(servo_time_constants_s, dtype=float)
    if tc.shape != (2,) or not np.all(np.isfinite(tc)) or np.any(tc <= 0):
        raise ValueError(f"servo_time_constants_s: expected two positive seconds (t_d, t_l), "
                         f"got {servo_time_constants_s!r}")
    return {"t_d": float(tc[0]), "t_l": float(tc[1])}


def ring_down(theta_rad, payload_kg: float, config: PlantConfig, duration_s: float = 8.0,
              impulse_Ns: float = HAMMER_IMPULSE_NS, params: RobotParams | None = None,
              servo_time_constants_s: tuple | None = None):
    """Free vibration after a hammer impulse at the end effector, the joint cascade holding the pose.

    Parameters
    ----------
    theta_rad : array_like, shape (3,)
        Joint angles, rad.
    payload_kg : float
        Plate payload, kg.
    config : PlantConfig
        Plant options.
    duration_s : float, optional
        Simulated seconds after the impulse.
    impulse_Ns : float, optional
        Impulse along link 3's bending direction at its tip, N s.
    params : RobotParams, optional
        Robot parameters; default the packaged file.
    servo_time_constants_s : tuple of 2 floats, optional
        ``(t_d, t_l)`` of the holding cascade (:func:`~tudorvision.joint.cascade.design_cascade`:
        velocity filter and position-loop lag, s); ``None``: the joint layer's loop for this plant
        (``hold_loop_of``: 1 / 3 ms on the seed-measured plant). The seed does not give its values; a
        stiffer hold dissipates less of the link's energy.

    Returns
    -------
    SimLog
        The run (``strain[:, 0]`` is the link-2 hub gauge).
    """
    return _ring_down(theta_rad, payload_kg, config, duration_s, impulse_Ns, params, servo_time_constants_s)[0]


def _ring_down(theta_rad, payload_kg, config, duration_s, impulse_Ns, params, servo_time_constants_s):
    """:func:`ring_down`'s run and the ``design_cascade`` time constants it held the pose with (dict)."""
    p = params or load_robot_params()
    arm = ElasticArm(theta_rad, payload=plate_payload(payload_kg, p), params=p, config=config)
    kw = _servo_kw(servo_time_constants_s, arm)
    ctrl = JointCascade(design_cascade(p, arm.design_inertia_kg_m2(), **kw), config.dt, arm.measured_theta())
    k2, k3 = arm.link2, arm.link3
    c3 = math.cos(arm.theta[2])
    Q = np.array([k2.phiL[r] * c3 + k2.dphiL[r] * k3.L for r in range(k2.n)] + list(k3.phiL)) * impulse_Ns
    M, _, _ = held_joint_matrices(arm)
    dv = np.linalg.solve(M, Q)
    for r in range(k2.n):
        arm.deta2[r] += float(dv[r])
    for q in range(k3.n):
        arm.deta3[q] += float(dv[k2.n + q])
    th = np.asarray(arm.theta)
    return simulate(arm, ctrl, plan_motion(th, th, v_max=1.0, a_max=1.0), duration_s), kw


def dominant_frequency_hz(signal, dt: float, f_lo: float = 0.5, f_hi: float = 5.0) -> float:
    """Frequency of the largest spectral peak of ``signal`` between ``f_lo`` and ``f_hi``, Hz.

    Parameters
    ----------
    signal : array_like, shape (N,)
        Uniformly sampled signal.
    dt : float
        Sample period, s.
    f_lo, f_hi : float, optional
        Search band, Hz.

    Returns
    -------
    float
        Peak frequency (Hann window, 16x zero padding, parabolic interpolation), Hz.
    """
    x = np.asarray(signal, dtype=np.float64)
    x = (x - x.mean()) * np.hanning(len(x))
    nfft = 16 * len(x)
    S = np.abs(np.fft.rfft(x, n=nfft))
    f = np.fft.rfftfreq(nfft, dt)
    idx = np.nonzero((f >= f_lo) & (f <= f_hi))[0]
    j = idx[np.argmax(S[idx])]
    if 0 < j < len(S) - 1:
        a, b, c = np.log(S[j - 1] + 1e-300), np.log(S[j] + 1e-300), np.log(S[j + 1] + 1e-300)
        den = a - 2 * b + c
        if den < 0:
            return float(f[j] + 0.5 * (a - c) / den * (f[1] - f[0]))
    return float(f[j])


def decay_rate_per_s(signal, dt: float, f_hz: float, skip_s: float = 0.5) -> float:
    """Exponential decay rate of the oscillation at ``f_hz`` in ``signal``, 1/s (the seed's ``zeta_1``).

    The mean-free signal is band-passed to ``[0.6, 1.5] f_hz`` (zero phase),
    its Hilbert envelope taken and ``log(envelope)`` fitted by a line after
    ``skip_s`` and before the last ``skip_s`` (filter edges); the rate is minus its slope.

    Parameters
    ----------
    signal : array_like, shape (N,)
        Uniformly sampled signal.
    dt : float
        Sample period, s.
    f_hz : float
        Frequency of the oscillation, Hz.
    skip_s : float, optional
        Seconds left out at both ends.

    Returns
    -------
    float
        Decay rate, 1/s (``nan`` when the record is too short).
    """
    x = np.asarray(signal, dtype=np.float64)
    x = x - x.mean()
    fs = 1.0 / dt
    sos = butter(2, [0.6 * f_hz, min(1.5 * f_hz, 0.45 * fs)], btype="band", fs=fs, output="sos")
    y = sosfiltfilt(sos, x)
    env = np.abs(hilbert(y))
    t = np.arange(len(x)) * dt
    keep = (t > skip_s) & (t < t[-1] - skip_s) & (env > 0)
    if keep.sum() < 10:
        return float("nan")
    slope = np.polyfit(t[keep], np.log(env[keep]), 1)[0]
    return float(-slope)


def plant_modes(theta_rad, payload_kg: float, config: PlantConfig | None = None,
                duration_s: float = 8.0, params: RobotParams | None = None,
                servo_time_constants_s: tuple | None = None) -> dict:
    """Everything ``tudorvision sim modes`` reports for one pose.

    Parameters
    ----------
    theta_rad : array_like, shape (3,)
        Joint angles, rad.
    payload_kg : float
        Plate payload, kg.
    config : PlantConfig, optional
        Default ``PlantConfig()`` (the seed-measured plant).
    duration_s : float, optional
        Ring-down length, s.
    params : RobotParams, optional
        Robot parameters (``--robot``); default the packaged file.
    servo_time_constants_s : tuple of 2 floats, optional
        ``(t_d, t_l)`` of the holding cascade, s (:func:`ring_down`).

    Returns
    -------
    dict
        :func:`linear_modes`'s keys plus ``decay_per_s`` and ``ringdown_hz`` (ring-down, link-2 hub strain)
        and ``servo_time_constants_s`` (``[t_d, t_l]`` of the holding cascade, s).
    """
    cfg = config or PlantConfig()
    out = linear_modes(theta_rad, payload_kg, cfg, params)
    log, kw = _ring_down(theta_rad, payload_kg, cfg, duration_s, HAMMER_IMPULSE_NS, params, servo_time_constants_s)
    s = log.strain[:, 0]
    f1 = dominant_frequency_hz(s, cfg.dt, 0.5, 0.5 * (out["link2_hz"][0] + out["link2_hz"][1]))
    out["ringdown_hz"] = f1
    out["decay_per_s"] = decay_rate_per_s(s, cfg.dt, f1)
    out["servo_time_constants_s"] = [kw["t_d"], kw["t_l"]]
    return out


def modes_map(step_deg: float, payload_kg: float = 0.3, config=None, duration_s: float = 6.0,
              servo_time_constants_s: tuple | None = None) -> dict:
    """Ring-down first frequency and decay of link 2 over a grid of the workspace (the lab's figure 4.8).

    Parameters
    ----------
    step_deg : float
        Grid step over theta2 in [-10, 190] deg and theta3 in [-100, 100] deg.
    payload_kg : float
        Plate payload, kg.
    config : PlantConfig, optional
        Default ``PlantConfig()`` (the seed-measured plant).
    duration_s : float
        Ring-down length per pose, s.
    servo_time_constants_s : tuple of 2 floats, optional
        ``(t_d, t_l)`` of the holding cascade, s (:func:`ring_down`).

    Returns
    -------
    dict
        ``theta2_deg`` (n2,), ``theta3_deg`` (n3,), ``ringdown_hz`` and ``decay_per_s`` (n3, n2),
        ``linear_hz`` (n3, n2): the linearised first frequency.
    """
    cfg = config or PlantConfig()
    t2s = np.arange(-10.0, 190.0 + 1e-9, step_deg)
    t3s = np.arange(-100.0, 100.0 + 1e-9, step_deg)
    F, Z, FL = (np.zeros((len(t3s), len(t2s))) for _ in range(3))
    for i, t3 in enumerate(t3s):
        for j, t2 in enumerate(t2s):
            th = np.deg2rad([0.0, t2, t3])
            lin = linear_modes(th, payload_kg, cfg)
            s = ring_down(th, payload_kg, cfg, duration_s,
                          servo_time_constants_s=servo_time_constants_s).strain[:, 0]
            f1 = dominant_frequency_hz(s, cfg.dt, 0.5, 0.5 * sum(lin["link2_hz"]))
            F[i, j], Z[i, j], FL[i, j] = f1, decay_rate_per_s(s, cfg.dt, f1), lin["link2_hz"][0]
    return {"theta2_deg": t2s.tolist(), "theta3_deg": t3s.tolist(), "ringdown_hz": F.tolist(),
            "decay_per_s": Z.tolist(), "linear_hz": FL.tolist()}


def identify_hub_stiffness(candidates_Nm_rad=(float("inf"), 3000.0, 1500.0, 1000.0, 800.0, 600.0),
                           theta3_extreme_deg: float = 102.0) -> tuple:
    """Grid search of the hub stiffnesses of links 2 and 3 against the seed's frequencies at 300 g.

    For every pair ``(K_r2, K_r3)`` of ``candidates_Nm_rad`` the two-way plant is
    linearised at theta = (0, 0, 0) (figure 4.6: link 2 first and second,
    link 3 first) and at theta3 = +-``theta3_extreme_deg`` (the largest first
    frequency, the top of figure 4.8's 1.56-2.74 Hz); the pair with the
    smallest worst relative error against :data:`SEED_MODES_300G` wins.

    Parameters
    ----------
    candidates_Nm_rad : sequence of float, optional
        Candidate ``K_r`` values, N m/rad (``inf`` = rigid).
    theta3_extreme_deg : float, optional
        Elbow angle where the first frequency peaks, degrees.

    Returns
    -------
    best : tuple of 2 floats
        ``(K_r2, K_r3)``, N m/rad.
    table : list of tuple
        ``(K_r2, K_r3, f21, f22, f31, f1max, worst_rel_error)`` per candidate pair.
    """
    seed = SEED_MODES_300G
    table = []
    for K2 in candidates_Nm_rad:
        for K3 in candidates_Nm_rad:
            cfg = PlantConfig.stiff(two_way=True, hub_stiffness_Nm_rad=(K2, K3))
            m0 = linear_modes(np.zeros(3), 0.3, cfg)
            fmax = max(linear_modes(np.deg2rad([0.0, 0.0, s3 * theta3_extreme_deg]), 0.3, cfg)["link2_hz"][0]
                       for s3 in (-1.0, 1.0))
            vals = (m0["link2_hz"][0], m0["link2_hz"][1], m0["link3_hz"][0], fmax)
            ref = (seed["link2_hz"][0], seed["link2_hz"][1], seed["link3_hz"], seed["f1_max_hz"])
            worst = max(abs(v / r - 1.0) for v, r in zip(vals, ref))
            table.append((float(K2), float(K3), *(float(v) for v in vals), float(worst)))
    best = min(table, key=lambda row: row[-1])
    return (best[0], best[1]), table
