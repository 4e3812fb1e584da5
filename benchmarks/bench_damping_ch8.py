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

Plants (``--plant``): ``soft`` the default seed-measured plant (hub springs, dampers, backlash,
two-way; issue 18), ``one-way`` / ``two-way`` the stiff rigid-hub plant; gains ``GAIN_SETS[plant]``.
Static strain cancellation (``--filter``): ``seed`` the seed's filter as written (N = 50 at 100 Hz,
applied twice), ``2khz`` the project's variant (the same window at the 2 kHz control rate).

Run:  .venv/bin/python benchmarks/bench_damping_ch8.py [--reps 20] [--plant soft|one-way|two-way|both|all]
      [--filter seed|2khz]
      [--noise 2e-6] [--scheduler serial|local|tcp://HOST:8786] [--workers 2] [--tune] [--no-coulomb]
      [--friction-ff SRC:SCALE:BAND] [--model-assist [--model chi.npy] [--id-seconds 30]]
      [--experiments 06,07] [--laws off,proportional] [--horizon 10] [--out out/damping_ch8]

The runs are tasks of the experiment runner (tudorvision.lab.runner; the run functions are in
tudorvision.lab.ch8_experiments, docs/experiments.md): each finished run is recorded in
OUT/<plant>/runs/ as it arrives and the same command resumes; the tables do not depend on the
scheduler. Changes from the --jobs version: ``--jobs`` is the old name of ``--workers``; meta.json no
longer holds wall_s, cpu and jobs (they are in runner.json beside it); runs.csv (one row per run) and
``--horizon`` are new.
"""
from __future__ import annotations

import argparse
import csv
import io
import json
import os
import sys
import time

import numpy as np

from _machine import cpu_model  # benchmarks/ is on sys.path when run as a script
from tudorvision.io.atomic import write_text_atomic
from tudorvision.joint.damping import ASSISTED_GAINS, GAIN_SETS
from tudorvision.joint.metrics import METRIC_NAMES, iats
from tudorvision.lab.ch8_experiments import (EXPERIMENTS, FILTERS, HORIZON_S, LAWS, OPS_DEG, PLANTS, evaluate,
                                             identify, run_damping_study, run_experiment, runs_csv)
from tudorvision.lab.runner import parse_scheduler


def tune(law: str, *, plant: str, x0=None, maxiter: int = 40, strain_filter: str = "seed") -> tuple:
    """Nelder-Mead on log gains (joints 2, 3) minimising IATS of both root gauges on experiment 06."""
    from scipy.optimize import minimize

    def cost(lk):
        k = (0.0, float(np.exp(lk[0])), float(np.exp(lk[1])))
        r = run_experiment("06", law, k, plant=plant, noise=0.0, seed=0, horizon_s=6.0, strain_filter=strain_filter)
        if not np.all(np.isfinite(r["eps_online"])) or abs(r["final_err_deg"][1]) > 1.0:
            return 1e3
        c = iats(r["t"], r["eps_online"]) + iats(r["t"], r["eps3_online"])
        return float(c * 1e6)

    k0 = GAIN_SETS[plant][law] if x0 is None else x0
    res = minimize(cost, np.log(np.asarray(k0[1:], float)), method="Nelder-Mead",
                   options={"maxiter": maxiter, "xatol": 0.05, "fatol": 1e-3})
    return (0.0, float(np.exp(res.x[0])), float(np.exp(res.x[1]))), float(res.fun)


def write_outputs(table, exps, laws, out_dir, meta):
    os.makedirs(out_dir, exist_ok=True)
    keys = ["freq_hz"] + [k + s for k in METRIC_NAMES for s in ("_pct", "_pct_std", "_abs")] \
        + ["final_joint_error_deg_max"]
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(["signal", "experiment", "law"] + keys)
    for (sig, exp, law), row in table.items():
        w.writerow([sig, exp, law] + [f"{row[k]:.6g}" for k in keys])
    write_text_atomic(os.path.join(out_dir, "ch8_metrics.csv"), buf.getvalue())
    short = {"max_strain": "max|eps|", "strain_settling_s": "T_CS(eps)", "spectral_amp": "|F(w1)|",
             "iats": "IATS", "joint_settling_s": "T_CS(theta2)", "iate": "IATE"}
    lines = [f"# Chapter 8 on the simulated TUDOR ({meta['plant']})", "",
             f"{meta['reps']} repetitions, strain noise {meta['noise']:.1e} m/m, payload 300 g + mount; "
             f"percent of the undamped case (T_CS(eps): of the {meta['horizon_s']:g} s horizon); mean ± std.", ""]
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
    write_text_atomic(os.path.join(out_dir, "ch8_metrics.md"), "\n".join(lines) + "\n")
    write_text_atomic(os.path.join(out_dir, "meta.json"), json.dumps(meta, indent=1))
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


def scheduler_options(ap) -> None:
    """The runner's options (shared with bench_damping_payloads.py)."""
    ap.add_argument("--scheduler", default="local",
                    help="serial, local (a Dask LocalCluster; default) or a scheduler address tcp://HOST:8786")
    ap.add_argument("--workers", type=int, default=None,
                    help="worker processes of the local cluster (default: the machine's cores)")
    ap.add_argument("--jobs", type=int, default=None, help="old name of --workers")
    ap.add_argument("--quiet", action="store_true", help="no progress lines")


def check_scheduler(ap, a) -> None:
    """Check --scheduler / --workers / --jobs (argparse error on bad values)."""
    try:
        a.scheduler = parse_scheduler(a.scheduler)
    except ValueError as exc:
        ap.error(str(exc))
    if a.workers is None:
        a.workers = a.jobs
    if a.workers is not None and a.workers < 1:
        ap.error(f"--workers: expected >= 1, got {a.workers}")


def runner_info(reports, t0: float, a) -> dict:
    """What differs between modes (kept out of the summary): scheduler, workers, timing, counts."""
    infos = [r.info() for r in reports]
    return {"scheduler": a.scheduler, "workers": max([r.workers for r in reports], default=1),
            "cpu": cpu_model(), "total_wall_s": time.time() - t0,
            "complete": bool(reports) and all(r.complete for r in reports),
            "interrupted": any(r.interrupted for r in reports), "stages": infos}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=20)
    ap.add_argument("--plant", choices=PLANTS + ("both", "all"), default="soft",
                    help="soft (the default seed-measured plant), one-way / two-way (the stiff plant), "
                         "both (the two stiff ones), all")
    ap.add_argument("--filter", choices=tuple(FILTERS), default="seed",
                    help="static strain cancellation: seed (N=50 at 100 Hz twice, section 2.2) or 2khz "
                         "(the same 0.5 s window at the control rate)")
    ap.add_argument("--noise", type=float, default=2e-6, help="strain noise std, m/m")
    scheduler_options(ap)
    ap.add_argument("--experiments", default=",".join(EXPERIMENTS))
    ap.add_argument("--horizon", type=float, default=HORIZON_S,
                    help="simulated seconds per run and strain settling horizon (the seed: 10)")
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
    check_scheduler(ap, a)
    exps = [e for e in a.experiments.split(",") if e]
    bad = [e for e in exps if e not in EXPERIMENTS]
    if bad or not exps:
        ap.error(f"--experiments: unknown {bad}; expected some of {list(EXPERIMENTS)}")
    laws = tuple(["off"] + [x for x in a.laws.split(",") if x and x != "off"])
    bad = [x for x in laws if x not in LAWS]
    if bad:
        ap.error(f"--laws: unknown {bad}; expected some of {list(LAWS)}")
    if a.reps < 1 or a.horizon <= 0.5:
        ap.error("--reps: expected >= 1; --horizon: expected > 0.5 s")
    if a.model and not os.path.isfile(a.model):
        ap.error(f"--model: no such file {a.model}")
    progress = False if a.quiet else None
    plants = {"both": ("one-way", "two-way"), "all": PLANTS}.get(a.plant, (a.plant,))
    status = 0
    for plant in plants:
        table = GAIN_SETS[plant]
        gains = {law: table.get(law, (0.0, 0.0, 0.0)) for law in LAWS}
        gains["off"] = (0.0, 0.0, 0.0)
        out = os.path.join(a.out, plant + ("" if a.filter == "seed" else f"-filter-{a.filter}")
                           + ("-no-coulomb" if a.no_coulomb else "")
                           + (f"-ff-{a.friction_ff.replace(':', '_')}" if a.friction_ff else "")
                           + ("-model-assist" if a.model_assist else ""))
        t0 = time.time()
        chi, fits = None, None
        if a.model_assist:
            gains["proportional"] = ASSISTED_GAINS[plant]
            if a.model:
                chi = np.load(a.model)
            else:
                try:
                    model, fits = identify(out, plant=plant, seconds=a.id_seconds, noise=a.noise,
                                           coulomb=not a.no_coulomb, scheduler=a.scheduler, workers=a.workers,
                                           show_progress=progress)
                except RuntimeError as exc:
                    print(f"[{plant}] {exc}; records kept in {out}, run again to resume", file=sys.stderr)
                    return 1
                chi = model.chi
                print(f"[{plant}] identified strain dynamics in {time.time() - t0:.0f} s; validation fit "
                      f"(link-2 / link-3 root): {fits}", flush=True)
        if a.gains:
            gains.update({k: tuple(v) for k, v in json.loads(a.gains).get(plant, {}).items()})
        if a.tune:
            for law in LAWS[1:]:
                gains[law], c = tune(law, plant=plant, x0=gains[law], strain_filter=a.filter)
                print(f"[{plant}] tuned {law}: k = {np.round(gains[law], 1).tolist()} (IATS cost {c:.3g})",
                      flush=True)

        def run_args(exp, law):
            return {"exp": exp, "law": law, "k_eps": [float(k) for k in gains[law]], "plant": plant,
                    "noise": a.noise, "horizon_s": a.horizon, "plates": 3, "coulomb": not a.no_coulomb,
                    "friction_ff": a.friction_ff, "model_chi": chi, "strain_filter": a.filter}

        results, report = run_damping_study(out, exps, laws, a.reps, run_args, experiment="ch8",
                                             scheduler=a.scheduler, workers=a.workers, show_progress=progress)
        reports = [report]
        info = runner_info(reports, t0, a)
        write_text_atomic(os.path.join(out, "runner.json"), json.dumps(info, indent=1))
        if not info["complete"]:
            n_fail = sum(len(r.failed) for r in reports)
            print(f"[{plant}] incomplete ({n_fail} failed run(s){', interrupted' if info['interrupted'] else ''}); "
                  f"records kept in {out}/runs, runner.json lists the failures; run again to resume", file=sys.stderr)
            return 130 if info["interrupted"] else 1
        runs_csv(results, os.path.join(out, "runs.csv"))
        table = evaluate(results, exps, laws, a.reps, horizon_s=a.horizon)
        meta = {"plant": plant + f", {a.filter} filter" + (" without Coulomb friction" if a.no_coulomb else "")
                + (f", Coulomb feed-forward {a.friction_ff}" if a.friction_ff else "")
                + (", model-assisted static strain cancellation" if a.model_assist else ""), "reps": a.reps,
                "noise": a.noise, "gains": gains, "experiments": exps, "laws": list(laws), "horizon_s": a.horizon,
                "operating_points_deg": OPS_DEG}
        if fits is not None:
            meta["identification_fit"] = fits
            meta["identification_seconds_per_payload"] = a.id_seconds
        write_outputs(table, exps, laws, out, meta)
        if chi is not None:
            np.save(os.path.join(out, "chi.npy"), chi)
        r06 = table.get(("online", "06", "proportional"))
        if r06:
            print(f"[{plant}] exp 06 proportional: strain settling {r06['strain_settling_s_abs']:.2f} s "
                  f"({r06['strain_settling_s_pct']:.0f} % of {a.horizon:g} s; undamped "
                  f"{table[('online', '06', 'off')]['strain_settling_s_abs']:.2f} s), "
                  f"max final joint error {r06['final_joint_error_deg_max']:.4f} deg", flush=True)
        print(f"[{plant}] wrote {out} in {info['total_wall_s']:.1f} s ({a.scheduler}, {info['workers']} "
              f"worker(s))", flush=True)
    return status


if __name__ == "__main__":
    sys.exit(main())
