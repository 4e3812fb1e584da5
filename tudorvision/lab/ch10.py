"""Chapter 10 in the lab: APRBS identification runs and the reference comparison of table 10.1.

The seed identifies two models of the damped arm from the same APRBS
responses (section 10.4): the motor-current model (10.1.2) and the
strain-referred model (10.2.8). Here each run drives joints 2 and 3 of the
simulated arm (:class:`tudorvision.sim.arm.ElasticArm`, joint 1 at zero)
through the joint layer's cascade with proportional strain damping, as the
seed's "inner loop oscillation damping" does, with the seed's planned limits
(70 deg/s, 200 deg/s^2) and APRBS setpoints over the joint ranges.

Motor current. The simulated plant takes amplifier voltages and has no
current sensor. The seed merges the amplifier's PI current loop (833 Hz) into
the gain ``k_M = n_M k_tau k_amp`` (3.1.2), so the winding current is the
current loop's reference, ``i_M = k_amp v_M``, limited where the torque
saturates; the lab reads it from the electrical torque the plant applied in
the step, ``i_M = tau_E / (n_M k_tau)``. Optional white noise
(``current_noise_A``) stands for the measurement noise the seed sees at rest
(figure 10.4); the seed gives no value for it.

The models are fitted by :mod:`tudorvision.joint.identification` on alternate
5 s blocks and validated on the blocks in between (the seed splits its 20 Hz
samples at random, 50 / 50). :data:`SEED_TABLE_10_1` holds the seed's table
10.1 column by column: for each payload the data-driven reference (ELM)
comes first, then the analytical model (AN).
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .code_hash import source_hash

__all__ = ["SEED_TABLE_10_1", "Ch10Options", "collect_aprbs_run", "reproduce_table_10_1", "summarize_table_10_1",
           "with_current_noise", "format_table_10_1", "reference_friction", "identified_strain_model",
           "strain_model_key", "CATCH_IDENTIFICATION", "IDENTIFICATION_CODE_FILES", "IDENTIFICATION_CODE_EXEMPT",
           "identification_code_hash", "check_shipped_strain_model"]

_PAYLOADS_G = (0, 100, 200, 300, 400)

#: Table 10.1 of the seed: ``model -> set -> metric -> {"ELM": [...], "AN": [...]}``, one value per
#: payload 0, 100, 200, 300, 400 g. Models ``"current"`` (RMSE, sigma in A) and ``"strain"``
#: (um/m); sets ``"identification"`` and ``"validation"``; metrics ``"rmse"``, ``"sigma"``,
#: ``"fit_pct"``. The seed aggregates both outputs (joints 2 and 3, links 2 and 3) in one number.
SEED_TABLE_10_1 = {
    "current": {
        "identification": {
            "rmse": {"ELM": [0.11, 0.16, 0.13, 0.20, 0.22], "AN": [0.12, 0.19, 0.17, 0.22, 0.24]},
            "sigma": {"ELM": [0.07, 0.11, 0.09, 0.13, 0.15], "AN": [0.07, 0.10, 0.08, 0.12, 0.14]},
            "fit_pct": {"ELM": [71.02, 57.99, 69.19, 62.97, 63.53], "AN": [69.32, 53.36, 38.60, 59.36, 61.28]},
        },
        "validation": {
            "rmse": {"ELM": [0.15, 0.20, 0.23, 0.23, 0.28], "AN": [0.13, 0.19, 0.22, 0.22, 0.26]},
            "sigma": {"ELM": [0.10, 0.16, 0.23, 0.14, 0.46], "AN": [0.08, 0.11, 0.12, 0.13, 0.16]},
            "fit_pct": {"ELM": [58.92, 50.13, 47.62, 54.50, 40.21], "AN": [63.96, 55.65, 52.75, 54.78, 56.96]},
        },
    },
    "strain": {
        "identification": {
            "rmse": {"ELM": [12.19, 18.15, 24.86, 28.48, 47.65], "AN": [13.11, 19.93, 28.30, 31.83, 53.77]},
            "sigma": {"ELM": [14.22, 18.60, 30.76, 30.22, 62.20], "AN": [16.04, 20.63, 33.44, 34.61, 67.19]},
            "fit_pct": {"ELM": [92.26, 90.40, 87.16, 87.71, 80.07], "AN": [91.44, 89.41, 85.83, 86.03, 78.05]},
        },
        "validation": {
            "rmse": {"ELM": [17.76, 26.72, 28.86, 33.36, 57.27], "AN": [14.92, 25.77, 27.73, 32.36, 54.71]},
            "sigma": {"ELM": [21.84, 40.54, 32.11, 34.92, 78.35], "AN": [17.44, 32.45, 27.85, 32.97, 69.44]},
            "fit_pct": {"ELM": [88.30, 82.02, 86.58, 85.28, 76.02], "AN": [90.59, 84.59, 87.75, 85.88, 77.78]},
        },
    },
}


@dataclass(frozen=True, kw_only=True)
class Ch10Options:
    """Identification runs of chapter 10 (section 10.4).

    Attributes
    ----------
    seconds : float
        Length of the APRBS run per payload, seconds (the seed: 10 runs of 80 s).
    plates : tuple of int
        Payload plates (100 g each) on the 50 g mount, one run each.
    v_max_deg_s, a_max_deg_s2 : float
        Planned joint speed and acceleration limits (the seed: 70 deg/s, 200 deg/s^2).
    lo_deg, hi_deg : tuple of 2 floats
        APRBS amplitude range of joints 2 and 3, degrees.
    hold_s : tuple of 2 floats
        Range of the APRBS hold times, seconds.
    strain_noise_m_m : float
        Strain-gauge noise of the plant, m/m.
    current_noise_A : float
        White noise added to the winding currents, A.
    sample_hz : float
        Rate of the samples kept for the fit (the seed records at 100 Hz).
    seed0 : int
        Seed of the first run (stimulus and noise); run ``k`` uses ``seed0 + k``.
    k_eps : tuple of 3 floats or None
        Proportional damping gains; ``None``: the joint layer's ``ASSISTED_GAINS`` for the
        plant (one-way or two-way).
    """

    seconds: float = 60.0
    plates: tuple = (0, 1, 2, 3, 4)
    v_max_deg_s: float = 70.0
    a_max_deg_s2: float = 200.0
    lo_deg: tuple = (-5.0, -60.0)
    hi_deg: tuple = (185.0, 60.0)
    hold_s: tuple = (0.6, 2.5)
    strain_noise_m_m: float = 2e-6
    current_noise_A: float = 0.0
    sample_hz: float = 100.0
    seed0: int = 900
    k_eps: tuple | None = None


def reference_friction(params) -> np.ndarray:
    """The plant's friction of joints 2 and 3 in winding-current units (the oracle for the fit).

    Parameters
    ----------
    params : RobotParams

    Returns
    -------
    ndarray, shape (2, 3)
        ``k_v+, k_v-`` (A s/rad) and the mean Coulomb magnitude ``k_c`` (A) per joint,
        from appendix A.3: ``n_M k_v / k_tau`` and ``k_c / k_tau``.
    """
    n = np.asarray(params.gear_ratio, float)[1:]
    kt = np.asarray(params.torque_constant_Nm_A, float)[1:]
    kvp = n * np.asarray(params.viscous_pos_Nms_rad, float)[1:] / kt
    kvn = n * np.asarray(params.viscous_neg_Nms_rad, float)[1:] / kt
    kc = 0.5 * (np.asarray(params.coulomb_pos_Nm, float)[1:] + np.asarray(params.coulomb_neg_Nm, float)[1:]) / kt
    return np.stack([kvp, kvn, kc], axis=1)


def collect_aprbs_run(plates: int, options: Ch10Options = Ch10Options(), config=None, *, seed: int = 900,
                      params=None) -> dict:
    """One APRBS response of the damped arm with strains and winding currents.

    Parameters
    ----------
    plates : int
        Payload plates (100 g each) on the end-effector mount.
    options : Ch10Options
    config : PlantConfig, optional
        The plant (default :class:`tudorvision.sim.arm.PlantConfig`); its strain noise and
        noise seed are replaced by ``options.strain_noise_m_m`` and ``seed``.
    seed : int
        Stimulus and noise seed.
    params : RobotParams, optional

    Returns
    -------
    dict
        ``t`` (N,) s, ``theta``, ``d``, ``dd`` (N, 3) rad, rad/s, rad/s^2 (measured angles,
        Savitzky-Golay derivatives), ``eps`` (N, 2) link-2 / link-3 root strains m/m,
        ``i_M`` (N, 2) joint-2 / joint-3 currents A, ``m`` (N,) payload kg (mount included),
        ``plates``; sampled at ``options.sample_hz`` after a 0.1 s margin at both ends.

    Raises
    ------
    ValueError
        If ``plates`` is negative or the run is shorter than 1 s.
    """
    from dataclasses import replace

    from ..joint.controlled import ControlledArm
    from ..joint.damping import StrainDamper, default_damping_config
    from ..joint.strain_dynamics import aprbs, derivatives
    from ..robot import load_robot_params
    from ..sim.arm import ElasticArm, Payload, PlantConfig
    from .ch8_experiments import drive_aprbs

    if int(plates) < 0:
        raise ValueError(f"plates: expected >= 0, got {plates}")
    if not options.seconds >= 1.0:
        raise ValueError(f"seconds: expected >= 1, got {options.seconds}")
    p = params or load_robot_params()
    cfg = replace(config or PlantConfig(), strain_noise_m_m=options.strain_noise_m_m, noise_seed=int(seed))
    rng = np.random.default_rng(seed)
    times, levels = aprbs(rng, options.seconds, np.deg2rad(options.lo_deg), np.deg2rad(options.hi_deg),
                          hold_s=options.hold_s)
    arm = ElasticArm([0.0, levels[0, 0], levels[0, 1]], payload=Payload.from_parts(p, plates=int(plates)),
                     params=p, config=cfg)
    ca = ControlledArm(arm, v_max=np.deg2rad(options.v_max_deg_s), a_max=np.deg2rad(options.a_max_deg_s2))
    over = {} if options.k_eps is None else {"k_eps": tuple(float(k) for k in options.k_eps)}
    dcfg = default_damping_config("proportional", plant=arm.gain_set, assisted=True, **over)
    ca.set_damper(StrainDamper(dcfg, arm.measured_strain(), cfg.dt))
    per_amp = 1.0 / (np.asarray(p.gear_ratio, float) * np.asarray(p.torque_constant_Nm_A, float))
    n = int(round(options.seconds / cfg.dt))
    th, eps, tau = drive_aprbs(ca, arm, times, levels, n, torque=True)
    cur = tau * per_amp[1:]
    if options.current_noise_A > 0:
        cur += np.random.default_rng([seed, 10]).normal(0.0, options.current_noise_A, cur.shape)
    t = np.arange(n) * cfg.dt
    d, dd = derivatives(t, th, window_s=0.04)
    step = max(1, int(round(1.0 / (options.sample_hz * cfg.dt))))
    edge = int(round(0.1 / cfg.dt))
    sl = slice(edge, n - edge, step)
    return {"t": t[sl], "theta": th[sl], "d": d[sl], "dd": dd[sl], "eps": eps[sl], "i_M": cur[sl],
            "m": np.full(t[sl].size, arm.payload.mass_kg), "plates": int(plates)}


def _run(args):
    plates, options, config, seed = args
    return collect_aprbs_run(plates, options, config, seed=seed)


def reproduce_table_10_1(config=None, options: Ch10Options = Ch10Options(), *, jobs: int = 1,
                         runs=None) -> dict:
    """Identify both models of chapter 10 on the lab's plant and set them beside table 10.1.

    Parameters
    ----------
    config : PlantConfig, optional
        The plant (default :class:`tudorvision.sim.arm.PlantConfig`).
    options : Ch10Options
    jobs : int
        Worker processes for the runs (one run per payload).
    runs : list of dict, optional
        Recorded runs (:func:`collect_aprbs_run`) to use instead of recording.

    Returns
    -------
    dict
        ``"strain"`` and ``"current"``: ``{"fits": per payload label (B.4 fit % per output and
        their mean, RMSE, sigma, on validation and identification blocks), "seed": the AN and
        ELM columns of :data:`SEED_TABLE_10_1`}``; ``"current_model"``, ``"strain_model"``
        (the identified models); ``"friction"``: identified vs plant friction (A, A s/rad);
        ``"runs"``: the recorded runs.
    """
    from ..joint.identification import fit_current_with_validation, fit_with_validation

    if runs is None:
        args = [(pl, options, config, options.seed0 + k) for k, pl in enumerate(options.plates)]
        if jobs > 1:
            from concurrent.futures import ProcessPoolExecutor
            with ProcessPoolExecutor(max_workers=jobs) as ex:
                runs = list(ex.map(_run, args))
        else:
            runs = [_run(a) for a in args]
    s_model, s_fits = fit_with_validation(runs)
    c_model, c_fits = fit_current_with_validation(runs)
    for fits in (s_fits, c_fits):
        for f in fits.values():
            f["fit_pct_mean"] = round(float(np.mean(f["fit_pct"])), 1)
            f["fit_pct_id_mean"] = round(float(np.mean(f["fit_pct_id"])), 1)
    from ..robot import load_robot_params
    p = load_robot_params()
    return {"strain": {"fits": s_fits, "seed": SEED_TABLE_10_1["strain"]},
            "current": {"fits": c_fits, "seed": SEED_TABLE_10_1["current"]},
            "strain_model": s_model, "current_model": c_model,
            "friction": {"identified": c_model.friction().tolist(), "plant": reference_friction(p).tolist()},
            "runs": runs}


#: The catching demo's identification of its strain model (:func:`identified_strain_model`): 40 s of APRBS per
#: payload of 0-300 g of plates, which spans the mount with up to eight 30 g balls.
CATCH_IDENTIFICATION = Ch10Options(seconds=40.0, plates=(0, 1, 2, 3))


def identified_strain_model(config=None, options: Ch10Options = CATCH_IDENTIFICATION, *, params=None,
                            cache_dir=None):
    """The strain-referred dynamics (10.2.8) of a lab plant, identified on APRBS runs as in section 10.4 (cached).

    What a user does once on a real arm before switching on the model-assisted static strain cancellation
    (``SimCore(damping_model=...)``): one APRBS run per payload, :func:`collect_aprbs_run`, fitted on alternate
    5 s blocks (:func:`tudorvision.joint.identification.fit_with_validation`).

    Parameters
    ----------
    config : PlantConfig, optional
        The plant (default :class:`tudorvision.sim.arm.PlantConfig`).
    options : Ch10Options
        The runs (default :data:`CATCH_IDENTIFICATION`).
    params : RobotParams, optional
        Robot parameters (default the packaged ones).
    cache_dir : str or Path, optional
        Where the fitted parameters are kept (``strain_model_<hash>.npz``, the hash over the plant, the runs and
        the robot); identified again when absent from it and from the package's data (the catching demo's
        default plant ships its model).

    Returns
    -------
    StrainDynamicsModel
        The fitted model.
    """
    from ..joint.identification import fit_with_validation
    from ..joint.strain_dynamics import StrainDynamicsModel
    from ..sim.arm import PlantConfig
    from .data_collection import PACKAGED_DIR, robot_key

    config = config or PlantConfig()
    name = f"strain_model_{strain_model_key(config, options)}{robot_key(params)}.npz"
    path = None if cache_dir is None else Path(cache_dir) / name
    for found in ([] if path is None else [path]) + [PACKAGED_DIR / name]:
        if found.exists():
            with np.load(found) as z:
                return StrainDynamicsModel(chi=z["chi"])
    runs = [collect_aprbs_run(pl, options, config, seed=options.seed0 + k, params=params)
            for k, pl in enumerate(options.plates)]
    model, _ = fit_with_validation(runs)
    if path is not None:
        from ..io.atomic import atomic_path
        with atomic_path(path) as tmp:
            np.savez_compressed(tmp, chi=model.chi)
    return model


#: The sources (relative to the package) whose code decides an identification (:func:`identified_strain_model`):
#: every file whose code runs in one (``tests/test_catch_damping_model.py`` profiles a short identification
#: against this list) and the robot's parameter file. The shipped model of the catch demo's plant names this
#: code (:func:`identification_code_hash`); :func:`check_shipped_strain_model` identifies it afresh.
IDENTIFICATION_CODE_FILES = (
    "joint/cascade.py", "joint/controlled.py", "joint/current_model.py", "joint/damping.py", "joint/damping_gains.py",
    "joint/identification.py", "joint/metrics.py", "joint/planner.py", "joint/strain_dynamics.py", "lab/ch10.py",
    "lab/ch8_experiments.py", "lab/data_collection.py", "robot/actuators.py", "robot/params.py",
    "robot/data/tudor.yaml", "sim/arm.py", "sim/beam.py", "sim/joint_compliance.py", "sim/link_modes.py",
    "sim/model.py")
#: Files whose code runs in an identification but decides no number of it: checks, imports, file writes, the
#: experiment runner's bookkeeping, the hash itself.
IDENTIFICATION_CODE_EXEMPT = ("_checks.py", "_lazy.py", "io/__init__.py", "io/atomic.py", "lab/code_hash.py",
                              "lab/provenance.py", "lab/runner.py", "lab/runner_progress.py")


def identification_code_hash() -> str:
    """A short hash of :data:`IDENTIFICATION_CODE_FILES` (:func:`tudorvision.lab.code_hash.source_hash`).

    Returns
    -------
    str
        16 hex digits.
    """
    return source_hash(IDENTIFICATION_CODE_FILES)


def check_shipped_strain_model(config, options: Ch10Options | None = None, *, ship: bool = False,
                               rtol: float = 1e-3) -> dict:
    """Identify a plant's strain model afresh and compare it with the one the package ships (for maintainers).

    The catch demo's plant ships its model (``tudorvision/catch/data/strain_model_<key>.npz``, named by the
    plant and the runs, and holding the code hash it was identified with). Compared by what they predict:
    the small coefficients of the least-squares fit move by up to 25 % between numpy / LAPACK builds (the
    fit is ill-conditioned there) while the strains move by 1e-4 of their RMS; a change to the plant or the
    identification moves them by far more. About 1-2 min on one core for :data:`CATCH_IDENTIFICATION`.

    Parameters
    ----------
    config : PlantConfig
        The plant (the demo's: ``plant_config(DemoOptions().plant)``).
    options : Ch10Options, optional
        The runs (default :data:`CATCH_IDENTIFICATION`).
    ship : bool
        Write the shipped file with today's code hash: the shipped coefficients where the fresh model
        predicts the same strains within ``rtol`` (every recorded run's numbers stay, bit for bit), else
        the fresh ones.
    rtol : float
        Largest RMS difference of the predicted root strains over the runs, relative to the strains' RMS,
        that counts as the same model.

    Returns
    -------
    dict
        ``shipped`` (a file was shipped), ``code`` (this code's hash), ``shipped_code`` (the file's, or None),
        ``max_relative_rms`` (None without a shipped file), ``same`` (within ``rtol``), ``shipped_to``
        (the path written, or None), ``kept_coefficients`` (with ``ship``).
    """
    from ..io.atomic import atomic_path
    from ..joint.identification import fit_with_validation
    from ..joint.strain_dynamics import StrainDynamicsModel
    from .data_collection import PACKAGED_DIR

    options = CATCH_IDENTIFICATION if options is None else options
    path = PACKAGED_DIR / f"strain_model_{strain_model_key(config, options)}.npz"
    shipped_chi = shipped_code = None
    if path.exists():
        with np.load(path) as z:
            shipped_chi = np.array(z["chi"])
            shipped_code = str(z["code"]) if "code" in z.files else None
    runs = [collect_aprbs_run(pl, options, config, seed=options.seed0 + k) for k, pl in enumerate(options.plates)]
    fresh, _ = fit_with_validation(runs)
    worst = None
    if shipped_chi is not None:
        old = StrainDynamicsModel(chi=shipped_chi)
        worst = 0.0
        for r in runs:
            a = fresh.predict(r["theta"], r["d"], r["dd"], r["m"])
            b = old.predict(r["theta"], r["d"], r["dd"], r["m"])
            rel = np.sqrt(np.mean((a - b) ** 2, axis=0)) / np.sqrt(np.mean(r["eps"] ** 2, axis=0))
            worst = max(worst, float(np.max(rel)))
    code = identification_code_hash()
    out = {"shipped": shipped_chi is not None, "code": code, "shipped_code": shipped_code,
           "max_relative_rms": worst, "same": worst is not None and worst <= rtol, "shipped_to": None}
    if ship:
        keep = out["same"]
        with atomic_path(path) as tmp:
            np.savez_compressed(tmp, chi=shipped_chi if keep else fresh.chi, code=np.array(code))
        out["shipped_to"], out["kept_coefficients"] = str(path), keep
    return out


def strain_model_key(config, options: Ch10Options) -> str:
    """Short hash of a plant and its identification runs (the file name of :func:`identified_strain_model`).

    Examples
    --------
    >>> from tudorvision.sim.arm import PlantConfig
    >>> len(strain_model_key(PlantConfig(), CATCH_IDENTIFICATION))
    16
    """
    return hashlib.sha256(repr((config, options)).encode()).hexdigest()[:16]


def summarize_table_10_1(result: dict) -> dict:
    """Mean fits of both models beside the seed's AN column (validation and identification).

    Parameters
    ----------
    result : dict
        From :func:`reproduce_table_10_1`.

    Returns
    -------
    dict
        Per model (``"current"``, ``"strain"``): ``lab_validation_mean``, ``lab_identification_mean``,
        ``seed_AN_validation_mean``, ``seed_AN_identification_mean`` (%), ``ratio_validation``,
        ``lab_validation_range_out2`` / ``_out3`` and ``seed_AN_validation_range`` ([min, max], %).
    """
    out = {}
    for model in ("current", "strain"):
        fits, seed = result[model]["fits"], result[model]["seed"]
        lab_v = float(np.mean([f["fit_pct_mean"] for f in fits.values()]))
        lab_i = float(np.mean([f["fit_pct_id_mean"] for f in fits.values()]))
        an_v = float(np.mean(seed["validation"]["fit_pct"]["AN"]))
        an_i = float(np.mean(seed["identification"]["fit_pct"]["AN"]))
        per = np.array([f["fit_pct"] for f in fits.values()])
        out[model] = {"lab_validation_mean": round(lab_v, 1), "lab_identification_mean": round(lab_i, 1),
                      "seed_AN_validation_mean": round(an_v, 1), "seed_AN_identification_mean": round(an_i, 1),
                      "ratio_validation": round(lab_v / an_v, 3),
                      "lab_validation_range_out2": [float(per[:, 0].min()), float(per[:, 0].max())],
                      "lab_validation_range_out3": [float(per[:, 1].min()), float(per[:, 1].max())],
                      "seed_AN_validation_range": [min(seed["validation"]["fit_pct"]["AN"]),
                                                   max(seed["validation"]["fit_pct"]["AN"])]}
    return out


def with_current_noise(runs, sigma_A: float, seed: int = 123) -> list:
    """The recorded runs with white noise added to the motor currents (a real amplifier's measurement noise).

    Parameters
    ----------
    runs : list of dict
        From :func:`collect_aprbs_run` (``i_M``: currents, shape (T, 2), A).
    sigma_A : float
        Standard deviation of the noise, A.
    seed : int
        Seed of the noise.

    Returns
    -------
    list of dict
        Copies with noisy ``i_M``.
    """
    rng = np.random.default_rng(seed)
    return [dict(r, i_M=r["i_M"] + rng.normal(0.0, sigma_A, np.shape(r["i_M"]))) for r in runs]


def format_table_10_1(result: dict, *, title: str = "lab") -> list:
    """Markdown rows: the seed's AN and ELM fits beside the lab's, per payload and output.

    Parameters
    ----------
    result : dict
        From :func:`reproduce_table_10_1`.
    title : str
        Name of the lab column (e.g. the plant).

    Returns
    -------
    list of str
        Table lines (header, separator, one row per model, set and payload).
    """
    lines = [f"| model | set | payload | seed AN fit % | seed ELM fit % | {title}: fit % output 2 / 3 (mean) "
             f"| {title}: RMSE 2 / 3 | seed AN RMSE |",
             "|---|---|---|---|---|---|---|---|"]
    for model, unit in (("current", "A"), ("strain", "um_m")):
        fits, seed = result[model]["fits"], result[model]["seed"]
        for set_name, suffix in (("identification", "_id"), ("validation", "")):
            sd = seed[set_name]
            for label, f in fits.items():
                try:
                    i = _PAYLOADS_G.index(int(str(label).split()[0]))
                    an, elm = f"{sd['fit_pct']['AN'][i]:.1f}", f"{sd['fit_pct']['ELM'][i]:.1f}"
                    rm = f"{sd['rmse']['AN'][i]:g}"
                except (ValueError, IndexError):
                    an = elm = rm = "-"
                fp = f[f"fit_pct{suffix}"]
                rmse = f[f"rmse_{unit}{suffix}"]
                ustr = "A" if unit == "A" else "um/m"
                lines.append(f"| {model} | {set_name} | {label} | {an} | {elm} | {fp[0]:.1f} / {fp[1]:.1f} "
                             f"({f[f'fit_pct{suffix}_mean']:.1f}) | {rmse[0]:.3g} / {rmse[1]:.3g} {ustr} | "
                             f"{rm} {ustr} |")
    return lines
