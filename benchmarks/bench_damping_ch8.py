"""Benchmark: chapter 8 of the seed on the simulated TUDOR (oscillation damping comparison).

The 12 experiments of figure 8.1 with a 300 g payload (3 plates, plus the
50 g end-effector mount of the parameter file), 60 deg/s and 200 deg/s^2,
repeated with strain measurement noise (a different noise seed per
repetition), for the undamped cascade and the three damping laws of
:mod:`tudorvision.joint.damping`. Metrics (B.4) on the link-2 root gauge and
joint 2, normalised to the undamped case (strain settling time to the 10 s
horizon), as mean and standard deviation over the repetitions.

Operating points (figure 8.1 is a drawing; its poses are not in the text).
Assumed from the text: experiment 06 = (1) -> (2) is the chapter 5-7 motion
[0,0,0] -> [0,45,-45] deg; (3) is the straight vertical pose; (5) the straight
horizontal pose that (5) -> (2) reaches only through the vertical; (4) mirrors
(2) about the vertical::

    (1) [0, 0, 0]  (2) [0, 45, -45]  (3) [0, 90, 0]  (4) [0, 135, 45]  (5) [0, 180, 0]

Gains are tuned once on experiment 06 without noise (Nelder-Mead on
log-gains minimising IATS of both root gauges, ``--tune``) and kept for all
experiments, as in the seed.

Two strain signals are evaluated: ``online`` is the mean-liberated strain the
controller sees (double moving average of the noisy measurement, 0.5 s
windows), as in the seed; ``dynamic`` is the noise-free true strain minus the
static strain of the current pose (what oscillates).

Model-assisted static strain cancellation (``--model-assist``, off by default):
a strain-referred dynamics model (chapter 10) is identified on the same plant
by least squares from APRBS motions with payloads 0-400 g (damping on, other
noise seeds than the experiments), or loaded with ``--model chi.npy``; the
damper subtracts the model's expected root strains along the planned reference
before the double moving average (:class:`tudorvision.joint.damping.StrainDamper`,
``strain_model``). Proportional gains then default to ``ASSISTED_GAINS``.

Run:  .venv/bin/python benchmarks/bench_damping_ch8.py [--reps 20] [--plant one-way|two-way|both]
      [--noise 2e-6] [--jobs 2] [--tune] [--no-coulomb] [--friction-ff SRC:SCALE:BAND]
      [--model-assist [--model chi.npy] [--id-seconds 30]] [--laws off,proportional] [--out out/damping_ch8]
"""
from __future__ import annotations

import argparse
import csv
import json
import os

from _machine import cpu_model  # benchmarks/ is on sys.path when run as a script
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from tudorvision.joint.cascade import friction_compensation
from tudorvision.joint.strain_dynamics import StrainDynamicsModel, aprbs, derivatives
from tudorvision.joint.identification import fit_with_validation
from tudorvision.joint.damping import (ASSISTED_GAINS, ONE_WAY_GAINS, TWO_WAY_GAINS, DampingConfig,
                                       StrainDamper)
from tudorvision.joint.metrics import METRIC_NAMES, damping_metrics, iats, normalise_metrics
from tudorvision.robot import load_robot_params
from tudorvision.sim.arm import ElasticArm, Payload, PlantConfig, link_static_loads
from tudorvision.joint.controlled import ControlledArm

OPS_DEG = {1: (0.0, 0.0, 0.0), 2: (0.0, 45.0, -45.0), 3: (0.0, 90.0, 0.0), 4: (0.0, 135.0, 45.0),
           5: (0.0, 180.0, 0.0)}
SMALL = (0.0, 5.0, 5.0)
EXPERIMENTS = {f"{i:02d}": (OPS_DEG[i], tuple(a + b for a, b in zip(OPS_DEG[i], SMALL))) for i in range(1, 6)}
EXPERIMENTS.update({"06": (OPS_DEG[1], OPS_DEG[2]), "07": (OPS_DEG[2], OPS_DEG[3]),
                    "08": (OPS_DEG[3], OPS_DEG[4]), "09": (OPS_DEG[4], OPS_DEG[5]),
                    "10": (OPS_DEG[1], OPS_DEG[3]), "11": (OPS_DEG[3], OPS_DEG[5]),
                    "12": (OPS_DEG[5], OPS_DEG[2])})
LAWS = ("off", "proportional", "integral", "half_integrator")
HORIZON_S = 10.0



def static_strain_link2_root(arm: ElasticArm, theta) -> np.ndarray:
    """Static strain at the link-2 root gauge for poses ``theta`` (N, 3), m/m (plant formula)."""
    l2, _ = link_static_loads(theta, arm.bodies, arm.g)
    lm = arm.link2
    x = lm.gauges[0]
    L = lm.L
    c = (l2[:, 0] * (L - x) ** 2 / 2.0 + l2[:, 1] * (L - x) + l2[:, 2]) / lm.EI
    return -0.5 * lm.h * c


def run_experiment(exp: str, law: str, k_eps, *, two_way: bool, noise: float, seed: int,
                   horizon_s: float = HORIZON_S, plates: int = 3, coulomb: bool = True,
                   friction_ff: str | None = None, model_chi=None) -> dict:
    """Simulate one run; return time series needed by the metrics (decimated to 500 Hz)."""
    p = load_robot_params()
    start, goal = (np.deg2rad(v) for v in EXPERIMENTS[exp])
    cfg = PlantConfig(two_way=two_way, strain_noise_m_m=noise, noise_seed=seed, coulomb_friction=coulomb)
    arm = ElasticArm(start, payload=Payload.from_parts(p, plates=plates), params=p, config=cfg)
    ca = ControlledArm(arm, friction=_friction(friction_ff, p))
    model = None if model_chi is None else StrainDynamicsModel(chi=np.asarray(model_chi))
    damper = StrainDamper(DampingConfig(law=law, k_eps=k_eps), arm.measured_strain(), cfg.dt,
                          strain_model=model, payload_kg=arm.payload.mass_kg)
    ca.set_damper(damper)
    ca.set_goal(goal)
    n = int(round(horizon_s / cfg.dt))
    dec = 4
    t, th2, ref2, et0, et2, th = [], [], [], [], [], []
    strain0 = []
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
    th = np.asarray(th)
    dyn = np.asarray(strain0) - static_strain_link2_root(arm, th)
    return {"t": np.asarray(t), "theta2": np.asarray(th2), "ref2": np.asarray(ref2),
            "eps_online": np.asarray(et0), "eps3_online": np.asarray(et2), "eps_dynamic": dyn,
            "goal2": float(goal[1]), "final_err_deg": np.rad2deg(np.asarray(arm.theta) - goal).tolist()}


def _friction(spec: str | None, params):
    """``"SOURCE:SCALE:BAND"`` (e.g. ``measured:1.0:0.01``) -> FrictionCompensation, or None."""
    if not spec:
        return None
    import dataclasses
    src, scale, band = spec.split(":")
    return dataclasses.replace(friction_compensation(params, scale=float(scale), w_band=float(band)), source=src)


def _dominant_freq(t, x) -> float:
    dt = t[1] - t[0]
    f = np.fft.rfftfreq(t.size, dt)
    X = np.abs(np.fft.rfft(x - x.mean()))
    m = (f > 1.0) & (f < 6.0)
    return float(f[m][np.argmax(X[m])])


def _job(args):
    exp, law, k, two_way, noise, seed, coulomb, ff, chi = args
    r = run_experiment(exp, law, k, two_way=two_way, noise=noise, seed=seed, coulomb=coulomb, friction_ff=ff,
                       model_chi=chi)
    return (exp, law, seed), r


#: APRBS ranges of the identification for the model-assisted cancellation (joints 2, 3): they
#: cover the operating points of figure 8.1 (joint 2 from horizontal to horizontal).
ID_LO, ID_HI = np.deg2rad([-5.0, -60.0]), np.deg2rad([185.0, 60.0])


def _id_run(args):
    """APRBS motion of joints 2, 3 with proportional damping; 100 Hz samples for the fit."""
    plates, seconds, two_way, noise, seed, coulomb = args
    p = load_robot_params()
    rng = np.random.default_rng(seed)
    times, levels = aprbs(rng, seconds, ID_LO, ID_HI)
    cfg = PlantConfig(two_way=two_way, strain_noise_m_m=noise, noise_seed=seed, coulomb_friction=coulomb)
    arm = ElasticArm([0.0, levels[0, 0], levels[0, 1]], payload=Payload.from_parts(p, plates=plates), params=p,
                     config=cfg)
    ca = ControlledArm(arm)
    # damped as in the seed's identification (10.4); ONE_WAY_GAINS' link-3 gain lets the long APRBS
    # runs grow joint-3 oscillations (see ASSISTED_GAINS), so the assisted gains damp here
    k = ASSISTED_GAINS["two-way" if two_way else "one-way"]
    ca.set_damper(StrainDamper(DampingConfig(law="proportional", k_eps=k), arm.measured_strain(), cfg.dt))
    n = int(round(seconds / cfg.dt))
    th, eps = np.empty((n, 3)), np.empty((n, 2))
    nxt = 1
    for k in range(n):
        if nxt < times.size and k * cfg.dt >= times[nxt]:
            ca.set_goal([0.0, levels[nxt, 0], levels[nxt, 1]])
            nxt += 1
        ca.step()
        th[k] = arm.measured_theta()
        ms = arm.measured_strain()
        eps[k] = ms[0], ms[2]
    t = np.arange(n) * cfg.dt
    d, dd = derivatives(t, th, window_s=0.04)
    sl = slice(200, -200, 20)
    return {"t": t[sl], "theta": th[sl], "d": d[sl], "dd": dd[sl], "eps": eps[sl],
            "m": np.full(t[sl].size, arm.payload.mass_kg), "plates": plates}


def identify(*, two_way: bool, seconds: float, noise: float, coulomb: bool, jobs: int):
    """Strain-referred dynamics (10.2.8) by least squares on APRBS runs, payloads 0-400 g.

    Fit on alternate 5 s blocks, validation (B.4 goodness of fit) on the others. Noise
    seeds 900+ (the experiments use 0..reps-1).

    Returns
    -------
    model : StrainDynamicsModel
    fits : dict
        Validation fit (%) and RMSE (um/m) of the link-2 / link-3 root strain per payload.
    """
    args = [(pl, seconds, two_way, noise, 900 + pl, coulomb) for pl in range(5)]
    with ProcessPoolExecutor(max_workers=jobs) as ex:
        data = list(ex.map(_id_run, args))
    return fit_with_validation(data)


def tune(law: str, *, two_way: bool, x0=None, maxiter: int = 40) -> tuple:
    """Nelder-Mead on log gains (joints 2, 3) minimising IATS of both root gauges on experiment 06."""
    from scipy.optimize import minimize

    def cost(lk):
        k = (0.0, float(np.exp(lk[0])), float(np.exp(lk[1])))
        r = run_experiment("06", law, k, two_way=two_way, noise=0.0, seed=0, horizon_s=6.0)
        if not np.all(np.isfinite(r["eps_online"])) or abs(r["final_err_deg"][1]) > 1.0:
            return 1e3
        c = iats(r["t"], r["eps_online"]) + iats(r["t"], r["eps3_online"])
        return float(c * 1e6)

    k0 = (TWO_WAY_GAINS if two_way else ONE_WAY_GAINS)[law] if x0 is None else x0
    res = minimize(cost, np.log(np.asarray(k0[1:], float)), method="Nelder-Mead",
                   options={"maxiter": maxiter, "xatol": 0.05, "fatol": 1e-3})
    return (0.0, float(np.exp(res.x[0])), float(np.exp(res.x[1]))), float(res.fun)


def evaluate(results: dict, exps, laws, reps) -> dict:
    """Metrics per run and normalised statistics per (signal, experiment, law)."""
    table = {}
    for signal in ("online", "dynamic"):
        for exp in exps:
            und = [results[(exp, "off", s)] for s in range(reps)]
            freq = _dominant_freq(und[0]["t"], und[0]["eps_dynamic"])
            def met(r):
                return damping_metrics(r["t"], r[f"eps_{signal}"], r["theta2"], r["ref2"],
                                       theta_goal=r["goal2"], freq_hz=freq, horizon_s=HORIZON_S)
            mu = [met(r) for r in und]
            u_mean = {k: float(np.mean([m[k] for m in mu])) for k in METRIC_NAMES}
            for law in laws:
                ms = [met(results[(exp, law, s)]) for s in range(reps)]
                norm = [normalise_metrics(m, u_mean, horizon_s=HORIZON_S) for m in ms]
                row = {"freq_hz": freq}
                for k in METRIC_NAMES:
                    v = np.array([n[k] for n in norm])
                    row[k + "_pct"] = float(v.mean())
                    row[k + "_pct_std"] = float(v.std())
                    row[k + "_abs"] = float(np.mean([m[k] for m in ms]))
                row["final_joint_error_deg_max"] = float(max(abs(np.rad2deg(m["final_joint_error_rad"]))
                                                             for m in ms))
                table[(signal, exp, law)] = row
    return table


def write_outputs(table, exps, laws, out_dir, meta):
    os.makedirs(out_dir, exist_ok=True)
    keys = ["freq_hz"] + [k + s for k in METRIC_NAMES for s in ("_pct", "_pct_std", "_abs")] \
        + ["final_joint_error_deg_max"]
    with open(os.path.join(out_dir, "ch8_metrics.csv"), "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["signal", "experiment", "law"] + keys)
        for (sig, exp, law), row in table.items():
            w.writerow([sig, exp, law] + [f"{row[k]:.6g}" for k in keys])
    short = {"max_strain": "max|eps|", "strain_settling_s": "T_CS(eps)", "spectral_amp": "|F(w1)|",
             "iats": "IATS", "joint_settling_s": "T_CS(theta2)", "iate": "IATE"}
    lines = [f"# Chapter 8 on the simulated TUDOR ({meta['plant']})", "",
             f"{meta['reps']} repetitions, strain noise {meta['noise']:.1e} m/m, payload 300 g + mount; "
             "percent of the undamped case (T_CS(eps): of the 10 s horizon); mean ± std.", ""]
    for sig in ("online", "dynamic"):
        lines += [f"## strain signal: {sig}", "",
                  "| exp | law | " + " | ".join(short[k] for k in METRIC_NAMES) + " | max final joint err (deg) |",
                  "|---|---|" + "---|" * (len(METRIC_NAMES) + 1)]
        for exp in exps:
            for law in laws:
                r = table[(sig, exp, law)]
                cells = [f"{r[k + '_pct']:.0f} ± {r[k + '_pct_std']:.0f}" for k in METRIC_NAMES]
                lines.append(f"| {exp} | {law} | " + " | ".join(cells) + f" | {r['final_joint_error_deg_max']:.4f} |")
        lines.append("")
        lines.append("Undamped absolute values: " + "; ".join(
            f"{exp}: max {1e6 * table[(sig, exp, 'off')]['max_strain_abs']:.0f} um/m, "
            f"T_CS {table[(sig, exp, 'off')]['strain_settling_s_abs']:.2f} s, "
            f"f1 {table[(sig, exp, 'off')]['freq_hz']:.2f} Hz" for exp in exps))
        lines.append("")
    with open(os.path.join(out_dir, "ch8_metrics.md"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    with open(os.path.join(out_dir, "meta.json"), "w") as fh:
        json.dump(meta, fh, indent=1)
    _figure(table, exps, [law for law in laws if law != "off"], out_dir, meta)


def _figure(table, exps, laws, out_dir, meta):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    titles = {"max_strain": "max |eps2| (%)", "strain_settling_s": "T_CS(eps2) (% of 10 s)",
              "spectral_amp": "|F(w1)| (%)", "iats": "IATS(eps2) (%)",
              "joint_settling_s": "T_CS(theta2) (%)", "iate": "IATE(theta2) (%)"}
    fig, axes = plt.subplots(3, 2, figsize=(11, 9), sharex=True)
    x = np.arange(len(exps))
    w = 0.8 / len(laws)
    for ax, k in zip(axes.ravel(), METRIC_NAMES):
        for i, law in enumerate(laws):
            m = [table[("online", e, law)][k + "_pct"] for e in exps]
            s = [table[("online", e, law)][k + "_pct_std"] for e in exps]
            ax.bar(x + (i - (len(laws) - 1) / 2) * w, m, w, yerr=s, label=law, capsize=2)
        ax.axhline(100.0, color="k", lw=0.6, ls="--")
        ax.set_title(titles[k], fontsize=9)
        ax.set_xticks(x, exps)
    axes[0, 0].legend(fontsize=8)
    fig.suptitle(f"Chapter 8 damping metrics, simulated TUDOR ({meta['plant']}, 300 g, "
                 f"{meta['reps']} reps), normalised to undamped", fontsize=10)
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, "ch8_metrics.png"), dpi=110)
    plt.close(fig)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=20)
    ap.add_argument("--plant", choices=("one-way", "two-way", "both"), default="both")
    ap.add_argument("--noise", type=float, default=2e-6, help="strain noise std, m/m")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--experiments", default=",".join(EXPERIMENTS))
    ap.add_argument("--tune", action="store_true", help="tune gains on experiment 06 first")
    ap.add_argument("--gains", default=None, help="JSON {law: [k1,k2,k3]} overriding the defaults")
    ap.add_argument("--out", default="out/damping_ch8")
    ap.add_argument("--no-coulomb", action="store_true",
                    help="diagnostic: plant without the joints' Coulomb friction (viscous friction kept)")
    ap.add_argument("--friction-ff", default=None, metavar="SOURCE:SCALE:BAND",
                    help="Coulomb feed-forward of the velocity loop from the A.3 friction model, "
                         "e.g. measured:1.0:0.01 (source reference|measured|command, scale, ramp rad/s)")
    ap.add_argument("--model-assist", action="store_true",
                    help="model-assisted static strain cancellation (identified strain dynamics, chapter 10)")
    ap.add_argument("--model", default=None, help="chi.npy of a StrainDynamicsModel (default: identify first)")
    ap.add_argument("--id-seconds", type=float, default=30.0, help="APRBS seconds per payload (identification)")
    ap.add_argument("--laws", default=",".join(LAWS), help="comma-separated laws (off is always run)")
    a = ap.parse_args(argv)
    exps = a.experiments.split(",")
    laws = tuple(["off"] + [x for x in a.laws.split(",") if x and x != "off"])
    bad = [x for x in laws if x not in LAWS]
    if bad:
        ap.error(f"--laws: unknown {bad}; expected some of {list(LAWS)}")
    plants = ("one-way", "two-way") if a.plant == "both" else (a.plant,)
    for plant in plants:
        two_way = plant == "two-way"
        table = TWO_WAY_GAINS if two_way else ONE_WAY_GAINS
        gains = {law: table.get(law, (0.0, 0.0, 0.0)) for law in LAWS}
        gains["off"] = (0.0, 0.0, 0.0)
        chi, fits = None, None
        if a.model_assist:
            gains["proportional"] = ASSISTED_GAINS["two-way" if two_way else "one-way"]
            if a.model:
                chi = np.load(a.model)
            else:
                t_id = time.time()
                model, fits = identify(two_way=two_way, seconds=a.id_seconds, noise=a.noise,
                                       coulomb=not a.no_coulomb, jobs=a.jobs)
                chi = model.chi
                print(f"[{plant}] identified strain dynamics in {time.time() - t_id:.0f} s; validation fit "
                      f"(link-2 / link-3 root): {fits}", flush=True)
        if a.gains:
            gains.update({k: tuple(v) for k, v in json.loads(a.gains).get(plant, {}).items()})
        t0 = time.time()
        if a.tune:
            for law in LAWS[1:]:
                gains[law], c = tune(law, two_way=two_way, x0=gains[law])
                print(f"[{plant}] tuned {law}: k = {np.round(gains[law], 1).tolist()} (IATS cost {c:.3g})",
                      flush=True)
        jobs = [(e, law, gains[law], two_way, a.noise, s, not a.no_coulomb, a.friction_ff, chi) for e in exps
                for law in laws for s in range(a.reps)]
        results = {}
        with ProcessPoolExecutor(max_workers=a.jobs) as ex:
            for key, r in ex.map(_job, jobs, chunksize=4):
                results[key] = r
        table = evaluate(results, exps, laws, a.reps)
        meta = {"plant": plant + (" without Coulomb friction" if a.no_coulomb else "")
                + (f", Coulomb feed-forward {a.friction_ff}" if a.friction_ff else "")
                + (", model-assisted static strain cancellation" if a.model_assist else ""), "reps": a.reps,
                "noise": a.noise, "gains": gains, "experiments": exps,
                "wall_s": time.time() - t0, "cpu": cpu_model(), "jobs": a.jobs,
                "operating_points_deg": OPS_DEG}
        if fits is not None:
            meta["identification_fit"] = fits
            meta["identification_seconds_per_payload"] = a.id_seconds
        out = os.path.join(a.out, plant + ("-no-coulomb" if a.no_coulomb else "")
                           + (f"-ff-{a.friction_ff.replace(':', '_')}" if a.friction_ff else "")
                           + ("-model-assist" if a.model_assist else ""))
        write_outputs(table, exps, laws, out, meta)
        if chi is not None:
            np.save(os.path.join(out, "chi.npy"), chi)
        r06 = table.get(("online", "06", "proportional"))
        if r06:
            print(f"[{plant}] exp 06 proportional: strain settling {r06['strain_settling_s_abs']:.2f} s "
                  f"({r06['strain_settling_s_pct']:.0f} % of 10 s; undamped "
                  f"{table[('online', '06', 'off')]['strain_settling_s_abs']:.2f} s), "
                  f"max final joint error {r06['final_joint_error_deg_max']:.4f} deg", flush=True)
        print(f"[{plant}] wrote {out} in {time.time() - t0:.0f} s", flush=True)


if __name__ == "__main__":
    main()
