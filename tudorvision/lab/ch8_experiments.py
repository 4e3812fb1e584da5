"""Chapter 8 of the seed as runner tasks: oscillation damping compared over experiments, laws and payloads.

One task is one simulated run of an experiment of figure 8.1 (a point-to-point
move of joints 2 and 3 with a payload, strain measurement noise drawn from the
run's seed) under one damping law; it returns the chapter's metrics (B.4) of
the run for both strain signals (``online``: what the damper sees; ``dynamic``:
the noise-free strain minus the static strain of the pose), so that only a few
numbers travel back from a worker. The metrics' spectral amplitude needs the
dominant frequency of the experiment, taken from its undamped run with seed 0;
each task also returns the amplitude at every candidate frequency, and
:func:`resolve_runs` picks the reference's once all runs are in, so the runs
never wait for each other (one pass through the runner).

The benchmark scripts ``benchmarks/bench_damping_ch8.py`` and
``benchmarks/bench_damping_payloads.py`` build on these functions; the runner
(:mod:`tudorvision.lab.runner`) runs the tasks serially, on a local Dask
cluster or on a running scheduler with the same results.
"""
from __future__ import annotations

import csv
import dataclasses
import io
from pathlib import Path
from typing import Callable

import numpy as np

from ..joint.cascade import friction_compensation
from ..joint.controlled import ControlledArm
from ..joint.damping import ASSISTED_GAINS, GAIN_SETS, DampingConfig, StrainDamper, pd_scale_of
from ..joint.identification import fit_with_validation
from ..joint.metrics import METRIC_NAMES, damping_metrics, normalise_metrics, spectral_amplitude
from ..joint.strain_dynamics import StrainDynamicsModel, aprbs, derivatives
from ..io.atomic import write_text_atomic
from ..robot import load_robot_params
from ..sim.arm import ElasticArm, Payload, PlantConfig, link_static_loads
from .runner import Task, config_digest, run_tasks
from .simulation import SimCore

__all__ = ["OPS_DEG", "EXPERIMENTS", "LAWS", "HORIZON_S", "SIGNALS", "ID_LO_RAD", "ID_HI_RAD",
           "static_strain_link2_root", "friction_feedforward", "run_experiment", "dominant_freq", "ch8_task",
           "resolve_runs", "run_damping_study", "evaluate", "runs_csv", "identification_task", "identify",
           "DROP_POSE_DEG", "DROP_MOVE_DEG", "payload_change_task", "drive_aprbs", "PLANTS", "FILTERS",
           "plant_config"]

#: Operating points of figure 8.1, deg (assumed; see ``benchmarks/bench_damping_ch8.py``).
OPS_DEG = {1: (0.0, 0.0, 0.0), 2: (0.0, 45.0, -45.0), 3: (0.0, 90.0, 0.0), 4: (0.0, 135.0, 45.0),
           5: (0.0, 180.0, 0.0)}
_SMALL = (0.0, 5.0, 5.0)
#: The 12 experiments: name -> (start, goal) joint angles, deg.
EXPERIMENTS = {f"{i:02d}": (OPS_DEG[i], tuple(a + b for a, b in zip(OPS_DEG[i], _SMALL))) for i in range(1, 6)}
EXPERIMENTS.update({"06": (OPS_DEG[1], OPS_DEG[2]), "07": (OPS_DEG[2], OPS_DEG[3]),
                    "08": (OPS_DEG[3], OPS_DEG[4]), "09": (OPS_DEG[4], OPS_DEG[5]),
                    "10": (OPS_DEG[1], OPS_DEG[3]), "11": (OPS_DEG[3], OPS_DEG[5]),
                    "12": (OPS_DEG[5], OPS_DEG[2])})
#: The undamped cascade and the three damping laws.
LAWS = ("off", "proportional", "integral", "half_integrator")
#: Horizon of a run and of the strain settling time's normalisation, s.
HORIZON_S = 10.0
#: The two strain signals the metrics are taken on.
SIGNALS = ("online", "dynamic")
#: Plants of the chapter-8 runs: ``soft`` the default (seed-measured hubs, backlash, two-way),
#: ``one-way`` / ``two-way`` the stiff rigid-hub plant with either coupling (``PlantConfig.stiff``).
PLANTS = ("soft", "one-way", "two-way")
#: Static strain cancellation of the damper (section 2.2): ``seed`` the seed's filter as written
#: (moving average N = 50 at 100 Hz applied twice: the 2 kHz damper takes every 20th sample and
#: holds its estimate), ``2khz`` the project's variant (the same 0.5 s window at the 2 kHz control
#: rate, N = 1000: no 10 ms hold, no aliasing), ``seed-iir`` the seed's IIR variant (2.2.3, double
#: exponential smoothing with alpha = 0.02 at 100 Hz, figures 2.3 / 2.4; the seed did not use it).
FILTERS = {"seed": {"n_window": 50, "decimation": 20}, "2khz": {"n_window": 1000, "decimation": 1},
           "seed-iir": {"iir_alpha": 0.02, "decimation": 20}}


def plant_config(plant: str, **fields) -> PlantConfig:
    """The :class:`PlantConfig` of a chapter-8 plant name (:data:`PLANTS`).

    Parameters
    ----------
    plant : {"soft", "one-way", "two-way"}
        Plant name.
    **fields
        Further :class:`PlantConfig` fields (noise, seed, friction).

    Returns
    -------
    PlantConfig

    Raises
    ------
    ValueError
        On an unknown plant name.
    """
    if plant == "soft":
        return PlantConfig(**fields)
    if plant in ("one-way", "two-way"):
        return PlantConfig.stiff(two_way=plant == "two-way", **fields)
    raise ValueError(f"plant: expected one of {PLANTS}, got {plant!r}")


#: APRBS ranges of the identification for the model-assisted cancellation (joints 2, 3), rad: they
#: cover the operating points of figure 8.1 (joint 2 from horizontal to horizontal).
ID_LO_RAD, ID_HI_RAD = np.deg2rad([-5.0, -60.0]), np.deg2rad([185.0, 60.0])


def static_strain_link2_root(arm: ElasticArm, theta) -> np.ndarray:
    """Static strain at the link-2 root gauge for given poses (the plant's formula).

    Parameters
    ----------
    arm : ElasticArm
        The plant (bodies, gravity, link model).
    theta : array_like, shape (N, 3)
        Joint angles, rad.

    Returns
    -------
    ndarray, shape (N,)
        Strain, m/m.
    """
    l2, _ = link_static_loads(np.asarray(theta, float), arm.bodies, arm.g)
    lm = arm.link2
    x = lm.gauges[0]
    c = (l2[:, 0] * (lm.L - x) ** 2 / 2.0 + l2[:, 1] * (lm.L - x) + l2[:, 2]) / lm.EI
    return -0.5 * lm.h * c


def friction_feedforward(spec: str | None, params):
    """The velocity loop's Coulomb feed-forward from ``"SOURCE:SCALE:BAND"`` (e.g. ``measured:1.0:0.01``).

    Parameters
    ----------
    spec : str or None
        Source (``reference``, ``measured`` or ``command``), scale and ramp band (rad/s); ``None`` or ``""``: none.
    params : RobotParams
        Robot parameters (the A.3 friction model).

    Returns
    -------
    FrictionCompensation or None
        The feed-forward.

    Raises
    ------
    ValueError
        On a malformed ``spec``.
    """
    if not spec:
        return None
    try:
        src, scale, band = spec.split(":")
        comp = friction_compensation(params, scale=float(scale), w_band=float(band))
    except ValueError:
        raise ValueError(f"--friction-ff: expected SOURCE:SCALE:BAND, got {spec!r}") from None
    return dataclasses.replace(comp, source=src)


def run_experiment(exp: str, law: str, k_eps, *, plant: str, noise: float, seed: int,
                   horizon_s: float = HORIZON_S, plates: int = 3, coulomb: bool = True,
                   friction_ff: str | None = None, model_chi=None, strain_filter: str = "seed") -> dict:
    """Simulate one run of an experiment; the series the metrics need, decimated to 500 Hz.

    Parameters
    ----------
    exp : str
        Experiment name (key of :data:`EXPERIMENTS`).
    law : str
        Damping law (:data:`LAWS`).
    k_eps : sequence of float, length 3
        Damping gains, rad/s per m/m.
    plant : {"soft", "one-way", "two-way"}
        Plant (:func:`plant_config`).
    noise : float
        Strain noise standard deviation, m/m.
    seed : int
        Noise seed.
    horizon_s : float
        Simulated time, s.
    plates : int
        Test plates (100 g each) on the end-effector mount.
    coulomb : bool
        Coulomb friction in the joints.
    friction_ff : str or None
        Coulomb feed-forward (:func:`friction_feedforward`).
    model_chi : array_like or None
        Parameters of a :class:`~tudorvision.joint.strain_dynamics.StrainDynamicsModel` for the
        model-assisted static strain cancellation.
    strain_filter : {"seed", "2khz", "seed-iir"}
        Static strain cancellation (:data:`FILTERS`).

    Returns
    -------
    dict
        ``t`` (N,) s, ``theta2`` and ``ref2`` (N,) rad, ``eps_online``, ``eps3_online`` and ``eps_dynamic``
        (N,) m/m, ``goal2`` rad, ``final_err_deg`` (3,).
    """
    p = load_robot_params()
    start, goal = (np.deg2rad(v) for v in EXPERIMENTS[exp])
    cfg = plant_config(plant, strain_noise_m_m=noise, noise_seed=seed, coulomb_friction=coulomb)
    arm = ElasticArm(start, payload=Payload.from_parts(p, plates=plates), params=p, config=cfg)
    ca = ControlledArm(arm, friction=friction_feedforward(friction_ff, p))
    model = None if model_chi is None else StrainDynamicsModel(chi=np.asarray(model_chi))
    damper = StrainDamper(DampingConfig(law=law, k_eps=tuple(k_eps), pd_gain_scale=pd_scale_of(law, plant),
                                        **FILTERS[strain_filter]),
                          arm.measured_strain(), cfg.dt,
                          strain_model=model, payload_kg=arm.payload.mass_kg)
    ca.set_damper(damper)
    ca.set_goal(goal)
    n = int(round(horizon_s / cfg.dt))
    dec = 4
    t, th2, ref2, et0, et2, th, strain0 = [], [], [], [], [], [], []
    t0 = arm.t
    for k in range(n):
        ca.step()
        if k % dec == 0:
            t.append(arm.t - t0)
            th.append(list(arm.theta))
            th2.append(arm.theta[1])
            ref2.append(ca.theta_ref[1])
            et0.append(damper.eps_tilde[0])
            et2.append(damper.eps_tilde[2])
            strain0.append(arm.strain[0])
    dyn = np.asarray(strain0) - static_strain_link2_root(arm, np.asarray(th))
    return {"t": np.asarray(t), "theta2": np.asarray(th2), "ref2": np.asarray(ref2),
            "eps_online": np.asarray(et0), "eps3_online": np.asarray(et2), "eps_dynamic": dyn,
            "goal2": float(goal[1]), "final_err_deg": np.rad2deg(np.asarray(arm.theta) - goal).tolist()}


def dominant_freq(t, x) -> float:
    """Frequency of the largest spectral peak of ``x`` between 1 and 6 Hz.

    Parameters
    ----------
    t : ndarray, shape (N,)
        Uniform sample times, s.
    x : ndarray, shape (N,)
        The signal.

    Returns
    -------
    float
        Hz.
    """
    f = np.fft.rfftfreq(t.size, t[1] - t[0])
    X = np.abs(np.fft.rfft(x - x.mean()))
    m = (f > 1.0) & (f < 6.0)
    return float(f[m][np.argmax(X[m])])


def _candidate_bins(t) -> np.ndarray:
    f = np.fft.rfftfreq(t.size, t[1] - t[0])
    return f[(f > 1.0) & (f < 6.0)]


def ch8_task(exp: str, law: str, k_eps, plant: str, noise: float, seed: int, horizon_s: float, plates: int,
             coulomb: bool, friction_ff: str | None, model_chi, strain_filter: str = "seed") -> dict:
    """One run as a runner task: the run's metrics on both strain signals (a few numbers, not the series).

    The spectral amplitude needs the experiment's dominant frequency, which only its undamped
    run with seed 0 knows; so the task returns the amplitude at every candidate frequency (the
    DFT bins between 1 and 6 Hz that :func:`dominant_freq` chooses from) and :func:`resolve_runs`
    picks the reference's once all runs are in. The runs therefore do not wait for each other.

    Parameters
    ----------
    exp, law, k_eps, plant, noise, seed, horizon_s, plates, coulomb, friction_ff, model_chi, strain_filter
        As for :func:`run_experiment`.

    Returns
    -------
    dict
        ``freq_hz`` (this run's own dominant frequency of the dynamic strain, Hz), ``metrics``
        (``{signal: damping metrics}`` for :data:`SIGNALS`, spectral amplitude at ``freq_hz``),
        ``bins_hz`` (K,) candidate frequencies, ``spectral_by_bin`` (``{signal: (K,) amplitudes, m/m}``),
        ``eps3_tail_max`` (largest link-3 root online strain in the last 2 s, m/m), ``final_err_deg`` (3,).
    """
    r = run_experiment(exp, law, k_eps, plant=plant, noise=noise, seed=seed, horizon_s=horizon_s,
                       plates=plates, coulomb=coulomb, friction_ff=friction_ff, model_chi=model_chi,
                       strain_filter=strain_filter)
    freq = dominant_freq(r["t"], r["eps_dynamic"])
    metrics = {s: damping_metrics(r["t"], r[f"eps_{s}"], r["theta2"], r["ref2"], theta_goal=r["goal2"],
                                  freq_hz=freq, horizon_s=horizon_s) for s in SIGNALS}
    bins = _candidate_bins(r["t"])
    spectra = {s: [spectral_amplitude(r["t"], r[f"eps_{s}"], f) for f in bins] for s in SIGNALS}
    tail = r["t"] > horizon_s - 2.0
    return {"freq_hz": freq, "metrics": metrics, "bins_hz": bins, "spectral_by_bin": spectra,
            "eps3_tail_max": float(np.max(np.abs(r["eps3_online"][tail]))), "final_err_deg": r["final_err_deg"]}


def resolve_runs(raw: dict, groups, reference: str) -> dict:
    """Give every run its group's reference frequency (undamped, seed 0) and the spectral amplitude there.

    Parameters
    ----------
    raw : dict
        ``{(group, label, seed): ch8_task result}``.
    groups : sequence of str
        Groups to resolve (each needs its ``(group, reference, 0)`` run).
    reference : str
        Label of the undamped runs.

    Returns
    -------
    dict
        ``{(group, label, seed): {"freq_hz", "metrics", "eps3_tail_max", "final_err_deg"}}`` with
        ``freq_hz`` the reference's and ``spectral_amp`` taken at it.

    Raises
    ------
    ValueError
        If a run's candidate frequencies differ from its reference's (another horizon or step).
    """
    out = {}
    for g in groups:
        ref = raw[(g, reference, 0)]
        freq, bins = ref["freq_hz"], [float(f) for f in ref["bins_hz"]]
        i = bins.index(freq)
        for (gg, lab, s), r in raw.items():
            if gg != g:
                continue
            if [float(f) for f in r["bins_hz"]] != bins:
                raise ValueError(f"run {(gg, lab, s)}: its frequency bins differ from the reference run's")
            metrics = {sig: {**r["metrics"][sig], "spectral_amp": float(r["spectral_by_bin"][sig][i])}
                       for sig in SIGNALS}
            out[(gg, lab, s)] = {"freq_hz": freq, "metrics": metrics, "eps3_tail_max": r["eps3_tail_max"],
                                 "final_err_deg": r["final_err_deg"]}
    return out


def run_damping_study(out, groups, labels, reps: int, run_args: Callable, *, experiment: str = "ch8",
                      scheduler: str | None = "serial", workers: int | None = None, show_progress=None,
                      processes: bool = True, dashboard_address: str | None = ":8787"):
    """Run ``groups x labels x reps`` runs through the runner (one task each) and resolve their frequencies.

    Parameters
    ----------
    out : str or Path
        Output folder of the runner's records.
    groups : sequence of str
        Groups normalised together (experiments, or payloads).
    labels : sequence of str
        Cases per group; ``labels[0]`` is the undamped reference.
    reps : int
        Repetitions (noise seeds ``0 .. reps-1``).
    run_args : callable
        ``run_args(group, label)`` -> dict of :func:`ch8_task`'s arguments but ``seed`` (JSON values but
        ``model_chi``, an array or ``None``).
    experiment : str
        Experiment name of the tasks.
    scheduler, workers, show_progress, processes, dashboard_address
        As for :func:`~tudorvision.lab.runner.run_tasks`.

    Returns
    -------
    results : dict
        ``{(group, label, seed): resolved result}`` (:func:`resolve_runs`) of the groups whose runs all
        finished.
    report : RunReport
        The runner's report.
    """
    keys, tasks = [], []
    for g in groups:
        for lab in labels:
            kw = dict(run_args(g, lab))
            chi = kw.pop("model_chi", None)
            params = {"group": g, "label": lab, **kw,
                      "model": None if chi is None else config_digest(np.asarray(chi).tolist())}
            args = (kw["exp"], kw["law"], tuple(kw["k_eps"]), kw["plant"], kw["noise"])
            rest = (kw["horizon_s"], kw["plates"], kw["coulomb"], kw["friction_ff"], chi,
                    kw.get("strain_filter", "seed"))
            for s in range(reps):
                keys.append((g, lab, s))
                tasks.append(Task(experiment, params, s, ch8_task, args + (s,) + rest))
    report = run_tasks(tasks, out, scheduler=scheduler, workers=workers, show_progress=show_progress,
                       processes=processes, dashboard_address=dashboard_address, label=f"{experiment} runs")
    raw = {k: rec["result"] for k, rec in zip(keys, report.records) if rec is not None and rec["status"] == "done"}
    whole = [g for g in groups if all((g, lab, s) in raw for lab in labels for s in range(reps))]
    return resolve_runs(raw, whole, labels[0]), report


def evaluate(results: dict, groups, labels, reps: int, *, horizon_s: float = HORIZON_S) -> dict:
    """Normalised statistics per (signal, group, label) from the runs' metrics.

    Parameters
    ----------
    results : dict
        ``{(group, label, seed): ch8_task result}``, all runs present.
    groups : sequence of str
        Groups (experiments or payloads).
    labels : sequence of str
        Cases; ``"off"`` (or ``labels[0]``) is the undamped reference.
    reps : int
        Repetitions.
    horizon_s : float
        Horizon of the strain settling time's normalisation, s.

    Returns
    -------
    dict
        ``{(signal, group, label): row}``; a row holds ``freq_hz``, ``<metric>_pct``, ``<metric>_pct_std``
        (percent of the undamped mean), ``<metric>_abs`` (mean) and ``final_joint_error_deg_max``.
    """
    ref = "off" if "off" in labels else labels[0]
    table = {}
    for signal in SIGNALS:
        for g in groups:
            freq = results[(g, ref, 0)]["freq_hz"]
            mu = [results[(g, ref, s)]["metrics"][signal] for s in range(reps)]
            u_mean = {k: float(np.mean([m[k] for m in mu])) for k in METRIC_NAMES}
            for lab in labels:
                ms = [results[(g, lab, s)]["metrics"][signal] for s in range(reps)]
                norm = [normalise_metrics(m, u_mean, horizon_s=horizon_s) for m in ms]
                row = {"freq_hz": freq}
                for k in METRIC_NAMES:
                    v = np.array([n[k] for n in norm])
                    row[k + "_pct"] = float(v.mean())
                    row[k + "_pct_std"] = float(v.std())
                    row[k + "_abs"] = float(np.mean([m[k] for m in ms]))
                row["final_joint_error_deg_max"] = float(max(abs(np.rad2deg(m["final_joint_error_rad"]))
                                                             for m in ms))
                table[(signal, g, lab)] = row
    return table


def runs_csv(results: dict, path) -> int:
    """Write one row per run (group, label, seed, frequency, metrics of both signals) in key order.

    Parameters
    ----------
    results : dict
        ``{(group, label, seed): ch8_task result}``.
    path : str or Path
        The CSV file (written atomically).

    Returns
    -------
    int
        Rows written.
    """
    head = (["group", "label", "seed", "freq_hz"] + [f"{s}_{k}" for s in SIGNALS for k in METRIC_NAMES]
            + [f"{s}_final_joint_error_rad" for s in SIGNALS] + ["eps3_tail_max", "final_err2_deg", "final_err3_deg"])
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(head)
    for (g, lab, s) in sorted(results):
        r = results[(g, lab, s)]
        m = r["metrics"]
        w.writerow([g, lab, s, repr(r["freq_hz"])] + [repr(m[si][k]) for si in SIGNALS for k in METRIC_NAMES]
                   + [repr(m[si]["final_joint_error_rad"]) for si in SIGNALS]
                   + [repr(r["eps3_tail_max"]), repr(r["final_err_deg"][1]), repr(r["final_err_deg"][2])])
    write_text_atomic(Path(path), buf.getvalue())
    return len(results)


def drive_aprbs(ca, arm, times, levels, n: int, *, torque: bool = False):
    """Drive a controlled arm through APRBS joint-2/3 levels and sample it every control period.

    Parameters
    ----------
    ca : tudorvision.joint.controlled.ControlledArm
        The arm's cascade (its goal is set to each level at the level's time).
    arm : Plant
        The arm under ``ca`` (``measured_theta()``, ``measured_strain()``, ``tau``, ``dt``).
    times : ndarray, shape (L,)
        Start time of each level, s (level 0 is the start pose).
    levels : ndarray, shape (L, 2)
        theta2, theta3 of each level, rad.
    n : int
        Control periods to run.
    torque : bool
        Also sample the applied joint-2/3 torques.

    Returns
    -------
    theta : ndarray, shape (n, 3)
        Measured joint angles, rad.
    eps : ndarray, shape (n, 2)
        Root strains of links 2 and 3, m/m.
    tau : ndarray, shape (n, 2) or None
        Applied joint-2/3 torques, N m (``torque`` only).
    """
    dt = arm.dt
    th, eps = np.empty((n, 3)), np.empty((n, 2))
    tau = np.empty((n, 2)) if torque else None
    nxt = 1
    for i in range(n):
        if nxt < times.size and i * dt >= times[nxt]:
            ca.set_goal([0.0, levels[nxt, 0], levels[nxt, 1]])
            nxt += 1
        ca.step()
        th[i] = arm.measured_theta()
        ms = arm.measured_strain()
        eps[i] = ms[0], ms[2]
        if torque:
            tau[i] = arm.tau[1], arm.tau[2]
    return th, eps, tau


def identification_task(plates: int, seconds: float, plant: str, noise: float, seed: int, coulomb: bool) -> dict:
    """APRBS motion of joints 2, 3 with proportional damping; 100 Hz samples for the strain-dynamics fit.

    Parameters
    ----------
    plates : int
        Test plates (100 g each).
    seconds : float
        Length of the motion, s.
    plant : {"soft", "one-way", "two-way"}
        Plant (:func:`plant_config`).
    noise : float
        Strain noise, m/m.
    seed : int
        Seed of the APRBS and the noise.
    coulomb : bool
        Coulomb friction in the joints.

    Returns
    -------
    dict
        ``t`` (M,) s, ``theta``, ``d``, ``dd`` (M, 3) rad, rad/s, rad/s^2, ``eps`` (M, 2) m/m, ``m`` (M,) kg,
        ``plates``.
    """
    p = load_robot_params()
    rng = np.random.default_rng(seed)
    times, levels = aprbs(rng, seconds, ID_LO_RAD, ID_HI_RAD)
    cfg = plant_config(plant, strain_noise_m_m=noise, noise_seed=seed, coulomb_friction=coulomb)
    arm = ElasticArm([0.0, levels[0, 0], levels[0, 1]], payload=Payload.from_parts(p, plates=plates), params=p,
                     config=cfg)
    ca = ControlledArm(arm)
    # damped as in the seed's identification (10.4); ONE_WAY_GAINS' link-3 gain lets the long APRBS
    # runs grow joint-3 oscillations (see ASSISTED_GAINS), so the assisted gains damp here
    k = ASSISTED_GAINS[plant]
    ca.set_damper(StrainDamper(DampingConfig(law="proportional", k_eps=k), arm.measured_strain(), cfg.dt))
    n = int(round(seconds / cfg.dt))
    th, eps, _ = drive_aprbs(ca, arm, times, levels, n)
    t = np.arange(n) * cfg.dt
    d, dd = derivatives(t, th, window_s=0.04)
    sl = slice(200, -200, 20)
    return {"t": t[sl], "theta": th[sl], "d": d[sl], "dd": dd[sl], "eps": eps[sl],
            "m": np.full(t[sl].size, arm.payload.mass_kg), "plates": plates}


def identify(out, *, plant: str, seconds: float, noise: float, coulomb: bool, scheduler: str | None = "serial",
             workers: int | None = None, show_progress=None):
    """Strain-referred dynamics (10.2.8) by least squares on APRBS runs with payloads 0-400 g, via the runner.

    Fit on alternate 5 s blocks, validation (B.4 goodness of fit) on the others. Noise
    seeds 900+ (the experiments use 0..reps-1).

    Parameters
    ----------
    out : str or Path
        Output folder of the runner's records.
    plant, seconds, noise, coulomb
        As for :func:`identification_task` (``seconds`` per payload).
    scheduler, workers, show_progress
        As for :func:`~tudorvision.lab.runner.run_tasks`.

    Returns
    -------
    model : StrainDynamicsModel
        The fit.
    fits : dict
        Validation fit (%) and RMSE (um/m) of the link-2 / link-3 root strain per payload.

    Raises
    ------
    RuntimeError
        When an identification run failed or was interrupted.
    """
    tasks = [Task("ch8-id", {"plates": pl, "seconds": seconds, "plant": plant, "noise": noise,
                             "coulomb": coulomb}, 900 + pl, identification_task,
                  (pl, seconds, plant, noise, 900 + pl, coulomb)) for pl in range(5)]
    rep = run_tasks(tasks, out, scheduler=scheduler, workers=workers, show_progress=show_progress,
                    label="ch8 identification")
    if not rep.complete:
        raise RuntimeError(f"identification: {len(rep.failed)} run(s) failed"
                           + (", interrupted" if rep.interrupted else ""))
    data = [{k: (v if k == "plates" else np.asarray(v, float)) for k, v in r["result"].items()} for r in rep.records]
    return fit_with_validation(data)


#: Payload-change scenario of section 8.3: the arm rests at DROP_POSE_DEG with the 0.5 kg camera rig,
#: the rig is taken off (0.05 kg mount left) and the arm moves by DROP_MOVE_DEG.
DROP_POSE_DEG, DROP_MOVE_DEG = (0.0, 60.4, 61.5), (0.0, 14.0, -45.0)


def payload_change_task(label: str, law: str, noise: float, seed: int, horizon_s: float = HORIZON_S,
                        plant: str = "one-way") -> dict:
    """The payload-change scenario: rig taken off at rest, then a move; link-3 settling afterwards.

    ``scheduled`` gains are told the new payload at once (``SimCore.set_payload``), ``fixed``
    keeps the gains tuned at 300 g (``GAIN_SETS[plant]``).

    Parameters
    ----------
    label : str
        ``"fixed"`` or ``"scheduled"``.
    law : str
        ``"proportional"`` or ``"integral"``.
    noise : float
        Strain noise, m/m.
    seed : int
        Noise seed.
    horizon_s : float
        Time observed after the move command, s.
    plant : {"soft", "one-way", "two-way"}
        Plant (:func:`plant_config`); the layer uses that plant's gain set.

    Returns
    -------
    dict
        ``tail_max`` (largest link-3 oscillation about the damper's static estimate in the last 2 s, m/m),
        ``settling_s`` (last time it exceeded 15 um/m, s after the move command), ``speed_frac`` (largest
        joint speed at the end as a fraction of the limit).
    """
    p = load_robot_params()
    pose = np.deg2rad(DROP_POSE_DEG)
    core = SimCore(pose, payload=Payload.from_parts(p, camera=True), params=p,
                   config=plant_config(plant, strain_noise_m_m=noise, noise_seed=seed))
    core.set_modes(damping={"proportional": 1, "integral": 2}[law], collision=0)
    if label == "fixed":
        core.controlled.damper.set_gains(GAIN_SETS[plant][law])
    core.step(1.0)
    core.arm.set_payload(Payload.from_parts(p, balls=0))
    if label == "scheduled":
        core.set_payload(core.arm.payload.mass_kg)
    core.step(0.5)
    core.apply_setpoint(pose + np.deg2rad(DROP_MOVE_DEG), max_speed_rad_s=p.max_speed_rad_s,
                        max_accel_rad_s2=p.max_accel_rad_s2)
    env, last_big = [], 0.0
    for k in range(int(round(horizon_s / 0.01))):
        core.step(0.01)
        e = abs(core.arm.strain[2] - core.controlled.damper.mu[2])
        env.append(e)
        if e > 15e-6:
            last_big = (k + 1) * 0.01
    env = np.asarray(env)
    return {"tail_max": float(env[-200:].max()), "settling_s": last_big,
            "speed_frac": float(np.max(np.abs(core.state().theta_dot) / p.max_speed_rad_s))}
