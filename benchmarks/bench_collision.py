"""Benchmark: collision detection, isolation and reaction on the simulated TUDOR (chapter 11).

Steps (two-way coupled plant, the contact-consistent model: by default the
lab's soft plant ``PlantConfig()`` (hub springs, dampers, backlash) with the
collision runs' proportional damping ``SOFT_COLLISION_K_EPS`` at the joint
layer's scaled position loop; ``--plant stiff`` the former stiff plant with
the gains scheduled on the known payload, see
``tudorvision.lab.collision_experiments.CollisionSetup``; proportional
damping on as in the seed; strain noise on the gauges; joint 1 held at 0):

1. identification (10.4): APRBS setpoints for joints 2 and 3 (70 deg/s,
   200 deg/s^2) with payloads 0, 100, 200, 300, 400 g (plates on the 50 g
   mount); root strains and encoder angles at 2 kHz; velocities and
   accelerations by Savitzky-Golay differentiation, subsampled to 100 Hz;
   payload-affine least squares on half of the data (alternating 5 s
   blocks), goodness of fit (B.4) on the other half;
2. thresholds: 6 sigma of the online momentum residual on fresh
   collision-free APRBS runs, per payload the larger of the payload's own
   6 sigma and the pooled 6 sigma of all payloads (``--pooled-thresholds``:
   the pooled pair for every payload); from the same data the share
   ``c(m)`` of the link-2 residual in the link-3 residual and the 6-sigma
   threshold of ``r3 - c(m) r2`` for isolation (``ResidualCoupling``);
3. false positives: further collision-free random motion with payloads
   0-400 g for ``--fp-minutes`` (default 10) with the detector armed;
4. contacts (300 g and 400 g): an obstacle sphere put in the path of the end effector (link 3)
   and of a point on link 2, with each strategy (none = no detection, stop,
   reflex, interaction): contact onset, detection delay, isolated link,
   direction, contact force peak and force at the end.

Run:  .venv/bin/python benchmarks/bench_collision.py [--plant soft|stiff] [--soft-k-eps 500 1600]
      [--id-seconds 60] [--thr-seconds 60]
      [--fp-minutes 10] [--noise 2e-6] [--k-i 200] [--reuse | --reuse-model] [--out out/collision]
      [--scheduler serial|local|tcp://HOST:8786] [--workers 2]
      [--k-eps 800 3200] [--n-window 1000] [--no-decouple] [--tune-damping K2,K3 ...]

Every run is a task of the experiment runner (tudorvision.lab.runner; the run functions are in
tudorvision.lab.collision_experiments, docs/experiments.md): records in OUT/runs/ as they arrive, the same
command resumes, ``--jobs`` is the old name of ``--workers``. collision.json no longer holds cpu, jobs and
wall_s: they are in OUT/runner.json; OUT/contacts.csv has one row per contact scenario.
"""
from __future__ import annotations

import argparse
import csv
import dataclasses
import io
import json
import os
import sys
import time

import numpy as np

from _machine import cpu_model  # benchmarks/ is on sys.path when run as a script
from bench_damping_ch8 import check_scheduler, scheduler_options
from tudorvision.io.atomic import write_text_atomic
from tudorvision.joint.collision import (DEFAULT_K_I, ResidualCoupling, fit_residual_coupling,
                                         thresholds_from_residuals)
from tudorvision.joint.collision_thresholds import payload_thresholds
from tudorvision.joint.identification import fit_with_validation
from tudorvision.joint.strain_dynamics import StrainDynamicsModel, fit_report, fit_strain_dynamics
from tudorvision.lab.collision_experiments import (CONTACT_PLATES, PLANTS, PLATES, STRATEGIES, CollisionSetup,
                                                   contact_run, identification_run, residual_run, thr_of)
from tudorvision.lab.runner import Task, config_digest, run_tasks

_DEFAULT = CollisionSetup()


class _Incomplete(Exception):
    """A stage did not finish (failed tasks or Ctrl-C): its records stay for a resumed run."""


class _Stages:
    """Runs each stage's tasks through the runner into the output folder; keeps the reports."""

    def __init__(self, a, setup: CollisionSetup):
        self.a, self.setup, self.reports = a, setup, []

    def run(self, name, specs, fn):
        """``specs``: (params, seed, args after the setup); returns the results in order."""
        return self.run_many([(name, specs, fn)])[0]

    def run_many(self, groups):
        """Independent groups ``(name, specs, fn)`` in one pass (one cluster); their results, group by group."""
        tasks = [Task(f"collision-{name}", {**self.setup.params(), **params}, seed, fn, (self.setup, *args))
                 for name, specs, fn in groups for params, seed, args in specs]
        name = " + ".join(g[0] for g in groups)
        rep = run_tasks(tasks, self.a.out, scheduler=self.a.scheduler, workers=self.a.workers,
                        show_progress=False if self.a.quiet else None, label=f"collision {name}")
        self.reports.append(rep)
        if not rep.complete:
            raise _Incomplete(f"stage {name}: {len(rep.failed)} failed task(s)"
                              + (", interrupted" if rep.interrupted else ""))
        out, i = [], 0
        for _, specs, _ in groups:
            out.append([r["result"] for r in rep.records[i:i + len(specs)]])
            i += len(specs)
        return out


def _arrays(d: dict) -> dict:
    return {k: (np.asarray(v, float) if isinstance(v, list) and k not in ("detections",) else v)
            for k, v in d.items()}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--id-seconds", type=float, default=60.0, help="APRBS seconds per payload for the fit")
    ap.add_argument("--thr-seconds", type=float, default=60.0, help="seconds per payload for the thresholds")
    ap.add_argument("--fp-minutes", type=float, default=10.0, help="collision-free minutes for false positives")
    ap.add_argument("--noise", type=float, default=_DEFAULT.noise)
    ap.add_argument("--plant", choices=PLANTS, default=_DEFAULT.plant,
                    help="soft: the lab's default plant PlantConfig() (default); stiff: PlantConfig.stiff(two_way=True)")
    ap.add_argument("--soft-k-eps", type=float, nargs=2, default=list(_DEFAULT.soft_k_eps[1:]), metavar=("K2", "K3"),
                    help="soft plant: proportional damping gains of joints 2, 3 (rad/s per m/m) at the joint layer's "
                         "scaled position loop; 0 0: the layer's own soft gains (SOFT_GAINS)")
    scheduler_options(ap)
    ap.add_argument("--out", default="out/collision")
    ap.add_argument("--k-i", type=float, default=DEFAULT_K_I, help="observer gain K_I of the residual, 1/s")
    ap.add_argument("--reuse-model", action="store_true",
                    help="load the identified model from --out and recompute the thresholds (e.g. for another K_I)")
    ap.add_argument("--reuse", action="store_true",
                    help="load the model and thresholds of an earlier run from --out (skip steps 1-2)")
    ap.add_argument("--transient-gain", type=float, default=None,
                    help="widen the thresholds by this multiple of the inertial transient after a change of planned "
                         "acceleration (joint.collision_transient; 0: off; default 1 on the soft plant, 0 stiff)")
    ap.add_argument("--detect-highpass", type=float, default=0.0,
                    help="corner (Hz) of the high-pass on the detection residual; 0: off (the seed's rule)")
    ap.add_argument("--input-lag", type=float, default=0.0,
                    help="lag (s) of the observer's angle/strain inputs, matched to the velocity filter")
    ap.add_argument("--k-eps", type=float, nargs=2, default=list(_DEFAULT.k_eps[1:]), metavar=("K2", "K3"),
                    help="stiff plant: proportional damping gains of joints 2, 3 (rad/s per m/m)")
    ap.add_argument("--n-window", type=int, default=_DEFAULT.n_window,
                    help="moving-average window of the damping's static strain filter (samples at 2 kHz)")
    ap.add_argument("--heavy-from", type=int, default=_DEFAULT.heavy_from,
                    help="plates (100 g each) from which the heavy damping applies (5: never)")
    ap.add_argument("--heavy-k-eps", type=float, nargs=2, default=list(_DEFAULT.heavy_k_eps[1:]), metavar=("K2", "K3"))
    ap.add_argument("--heavy-n-window", type=int, default=_DEFAULT.heavy_n_window)
    ap.add_argument("--isolation-window", type=float, default=_DEFAULT.isolation_window_s,
                    help="how long the (decoupled) link-3 residual must stay over its threshold for link 3, s")
    ap.add_argument("--pooled-thresholds", action="store_true",
                    help="one pair of thresholds (6 sigma of all payloads pooled) instead of per payload: "
                         "max(6 sigma of the payload's own collision-free residual, pooled 6 sigma)")
    ap.add_argument("--fp-seed0", type=int, default=1000,
                    help="first seed of the false-positive runs (seed0 + 10 plates + chunk)")
    ap.add_argument("--contact-plates", type=int, nargs="+", default=[CONTACT_PLATES, 4],
                    help="payloads (plates of 100 g) of the contact scenarios")
    ap.add_argument("--strategies", default=",".join(STRATEGIES),
                    help="comma-separated reaction strategies of the contact scenarios (default: all four)")
    ap.add_argument("--detect-decoupled", action="store_true",
                    help="also flag a collision when the decoupled link-3 residual exceeds its threshold")
    ap.add_argument("--no-decouple", action="store_true",
                    help="isolate on the link-3 residual itself (no ResidualCoupling)")
    ap.add_argument("--tune-damping", nargs="+", metavar="K2,K3",
                    help="only compare damping gains: per pair, identify on 20 s APRBS per payload and report the "
                         "collision-free residual on 20 s more (tuning seeds 5000+, not the benchmark's)")
    a = ap.parse_args(argv)
    check_scheduler(ap, a)
    bad = [pl for pl in a.contact_plates if pl not in PLATES]
    if bad:
        ap.error(f"--contact-plates: expected plates in {list(PLATES)}, got {bad}")
    a.strategies = [x.strip() for x in a.strategies.split(",") if x.strip()]
    bad = [x for x in a.strategies if x not in STRATEGIES]
    if bad or not a.strategies:
        ap.error(f"--strategies: unknown {bad}; expected some of {list(STRATEGIES)}")
    a.per_payload_thresholds = not a.pooled_thresholds
    soft_k = (0.0, *map(float, a.soft_k_eps)) if any(a.soft_k_eps) else ()
    setup = CollisionSetup(plant=a.plant, soft_k_eps=soft_k, noise=a.noise, k_i=a.k_i,
                           k_eps=(0.0, *map(float, a.k_eps)), n_window=a.n_window,
                           heavy_from=a.heavy_from, heavy_k_eps=(0.0, *map(float, a.heavy_k_eps)),
                           heavy_n_window=a.heavy_n_window, isolation_window_s=a.isolation_window,
                           detect_decoupled=a.detect_decoupled, input_lag_s=a.input_lag,
                           detect_highpass_hz=a.detect_highpass, transient_gain=a.transient_gain)
    if a.tune_damping:
        for pair in a.tune_damping:
            gains = (0.0, *(float(x) for x in pair.split(",")))
            tuned = dataclasses.replace(setup, **{"soft_k_eps" if a.plant == "soft" else "k_eps": gains})
            print(json.dumps(tune_damping(tuned)), flush=True)
        return 0
    if (a.reuse or a.reuse_model) and not os.path.isfile(os.path.join(a.out, "collision.json")):
        ap.error(f"--reuse/--reuse-model: no collision.json of an earlier run in {a.out}")
    os.makedirs(a.out, exist_ok=True)
    t0 = time.time()
    st = _Stages(a, setup)
    try:
        report = _benchmark(a, setup, st)
    except _Incomplete as exc:
        write_text_atomic(os.path.join(a.out, "runner.json"), json.dumps(_runner_info(st, t0, a), indent=1))
        print(f"incomplete: {exc}; records kept in {a.out}/runs, runner.json lists the failures; run the same "
              "command again to resume", file=sys.stderr)
        return 130 if any(r.interrupted for r in st.reports) else 1
    info = _runner_info(st, t0, a)
    write_text_atomic(os.path.join(a.out, "runner.json"), json.dumps(info, indent=1))
    write_text_atomic(os.path.join(a.out, "collision.json"), json.dumps(report, indent=1, default=float))
    _contacts_csv(report["contacts"], os.path.join(a.out, "contacts.csv"))
    _markdown(report, os.path.join(a.out, "collision.md"))
    print(f"wrote {a.out} in {info['total_wall_s']:.0f} s ({a.scheduler}, {info['workers']} worker(s))")
    return 0


def _runner_info(st, t0, a) -> dict:
    return {"scheduler": a.scheduler, "workers": max([r.workers for r in st.reports], default=1), "cpu": cpu_model(),
            "total_wall_s": time.time() - t0, "complete": bool(st.reports) and all(r.complete for r in st.reports),
            "interrupted": any(r.interrupted for r in st.reports), "stages": [r.info() for r in st.reports]}


def _benchmark(a, setup: CollisionSetup, st: _Stages) -> dict:
    """Steps 1-4; the report (collision.json) without timing."""
    report = {"plant": setup.plant, "soft_k_eps": list(setup.soft_k_eps),
              "noise": a.noise, "k_eps": list(setup.k_eps), "n_window": setup.n_window,
              "heavy": {"from_plates": setup.heavy_from, "k_eps": list(setup.heavy_k_eps),
                        "n_window": setup.heavy_n_window},
              "isolation_window_s": setup.isolation_window_s, "detect_decoupled": a.detect_decoupled,
              "per_payload_thresholds": a.per_payload_thresholds,
              "decouple": not a.no_decouple, "k_i": a.k_i,
              "detect_highpass_hz": a.detect_highpass, "input_lag_s": a.input_lag,
              "transient_gain": setup.transient_gain}
    prev = {}
    if a.reuse:
        prev = json.load(open(os.path.join(a.out, "collision.json")))
        model = StrainDynamicsModel(chi=np.load(os.path.join(a.out, "chi.npy")))
        thr = np.load(os.path.join(a.out, "thr_per_payload.npy" if a.per_payload_thresholds else "thr.npy"))
        coupling = ResidualCoupling(*np.load(os.path.join(a.out, "coupling.npy")))
        for key in ("identification", "thresholds_um_m", "thresholds_per_payload_um_m", "residual_sigma_um_m",
                    "residual_sigma_per_payload_um_m", "residual_mean_per_payload_um_m", "coupling"):
            if key in prev:
                report[key] = prev[key]
    else:
        model, thr, coupling = _identify(st, a, report)
    chi = np.asarray(model.chi)
    mparams = {"model": config_digest(chi.tolist())}
    cpl = None if a.no_decouple else [float(coupling.c0), float(coupling.c1), float(coupling.threshold)]
    # 3. false positives and 4. contacts: independent given the model and thresholds, one pass
    per = a.fp_minutes * 60.0 / len(PLATES)
    chunks = max(1, int(np.ceil(per / 60.0)))
    fp_specs = [({**mparams, "stage": "false positives", "plates": pl, "seconds": per / chunks,
                  "thr": thr_of(thr, pl).tolist(), "coupling": cpl}, a.fp_seed0 + 10 * pl + c,
                 (pl, per / chunks, a.fp_seed0 + 10 * pl + c, chi, thr_of(thr, pl), "none", cpl, False))
                for pl in PLATES for c in range(chunks)] if a.fp_minutes > 0 else []
    scen = [(pl, k, s) for pl in a.contact_plates for k in ("link3", "link2") for s in a.strategies]
    specs = [({**mparams, "stage": "contact", "plates": pl, "kind": k, "strategy": s, "thr": thr_of(thr, pl).tolist(),
               "coupling": cpl}, 7, (k, s, chi, thr_of(thr, pl), cpl, pl)) for pl, k, s in scen]
    fp, contacts = st.run_many([("fp", fp_specs, residual_run), ("contact", specs, contact_run)])
    if a.fp_minutes > 0:
        n_fp = sum(len(r["detections"]) for r in fp)
        per_pl = {f"{100 * pl} g": sum(len(r["detections"]) for r in fp if r["plates"] == pl) for pl in PLATES}
        peak = {f"{100 * pl} g": np.round(np.max([np.asarray(r["res_absmax"]) / thr_of(thr, pl) for r in fp
                                                  if r["plates"] == pl], axis=0), 2).tolist() for pl in PLATES}
        report["false_positives"] = {"minutes": a.fp_minutes, "seed0": a.fp_seed0, "count": n_fp, "per_payload": per_pl,
                                     "peak_over_threshold": peak,
                                     "events_note": "(seconds after arming, plates, seed, link, direction)",
                                     "events": [d for r in fp for d in r["detections"]][:20]}
        print(f"false positives in {a.fp_minutes:g} min: {n_fp}", flush=True)
    elif a.reuse and "false_positives" in prev:
        report["false_positives"] = prev["false_positives"]
    report["contacts"] = contacts
    for o in report["contacts"]:
        print(o, flush=True)
    return report


def _fit(st, a, report):
    """Step 1: identification on APRBS data; saves ``chi.npy``."""
    specs = [({"stage": "identification", "plates": pl, "seconds": a.id_seconds}, 100 + pl,
              (pl, a.id_seconds, 100 + pl)) for pl in PLATES]
    data = [_arrays(d) for d in st.run("id", specs, identification_run)]
    try:
        model, fits = fit_with_validation(data)
    except ValueError as exc:   # too little data for the alternate 5 s blocks
        raise _Incomplete(f"identification with --id-seconds {a.id_seconds:g}: {exc} (use 20 s or more)") from None
    report["identification"] = {"seconds_per_payload": a.id_seconds, "validation": fits}
    print("fit (validation, link-2 / link-3 root):", fits, flush=True)
    np.save(os.path.join(a.out, "chi.npy"), model.chi)
    return model


def _identify(st, a, report):
    """Steps 1 (identification) and 2 (thresholds); saves ``chi.npy`` and ``thr.npy`` to ``a.out``."""
    if a.reuse_model:
        model = StrainDynamicsModel(chi=np.load(os.path.join(a.out, "chi.npy")))
        report["identification"] = json.load(open(os.path.join(a.out, "collision.json")))["identification"]
    else:
        model = _fit(st, a, report)
    # 2. thresholds from collision-free residuals
    chi = np.asarray(model.chi)
    inf = [np.inf, np.inf]
    specs = [({"stage": "thresholds", "model": config_digest(chi.tolist()), "plates": pl, "seconds": a.thr_seconds},
              200 + pl, (pl, a.thr_seconds, 200 + pl, chi, inf, "none", None, True)) for pl in PLATES]
    rs = [_arrays(r) for r in st.run("thr", specs, residual_run)]
    res = np.concatenate([r["res"] for r in rs])
    # pooled 6 sigma and per payload max(own 6 sigma, pooled) (runs in PLATES order)
    thr, thr_pl = payload_thresholds([r["res"] for r in sorted(rs, key=lambda r: r["plates"])])
    # isolation: the link-3 residual less its share of the common arm mode, from the same data
    coupling = fit_residual_coupling(res, np.concatenate([np.full(r["res"].shape[0], r["payload"]) for r in rs]))
    report["thresholds_um_m"] = np.round(thr * 1e6, 2).tolist()
    report["residual_sigma_um_m"] = np.round(res.std(axis=0) * 1e6, 3).tolist()
    report["residual_sigma_per_payload_um_m"] = {f"{100 * r['plates']} g": np.round(r["res"].std(axis=0) * 1e6, 1)
                                                 .tolist() for r in rs}
    report["residual_mean_per_payload_um_m"] = {f"{100 * r['plates']} g": np.round(r["res"].mean(axis=0) * 1e6, 1)
                                                .tolist() for r in rs}
    report["coupling"] = {"c0": round(coupling.c0, 4), "c1_per_kg": round(coupling.c1, 4),
                          "threshold_um_m": round(coupling.threshold * 1e6, 2)}
    print("thresholds (um/m):", report["thresholds_um_m"], "coupling:", report["coupling"], flush=True)
    np.save(os.path.join(a.out, "thr.npy"), thr)
    np.save(os.path.join(a.out, "coupling.npy"), np.array([coupling.c0, coupling.c1, coupling.threshold]))
    np.save(os.path.join(a.out, "thr_per_payload.npy"), thr_pl)
    report["thresholds_per_payload_um_m"] = {f"{100 * pl} g": np.round(thr_pl[pl] * 1e6, 1).tolist()
                                             for pl in PLATES}
    if a.per_payload_thresholds:
        print("per-payload thresholds (um/m):", report["thresholds_per_payload_um_m"], flush=True)
        return model, thr_pl, coupling
    return model, thr, coupling


def tune_damping(setup: CollisionSetup, seconds=20.0, seed0=5000):
    """Residual figures of the setup's damping gains on tuning seeds (one process)."""
    t0 = time.time()
    data = [identification_run(setup, pl, seconds, seed0 + pl) for pl in PLATES]
    cat = {q: np.concatenate([d[q] for d in data]) for q in ("theta", "d", "dd", "eps", "m")}
    model = fit_strain_dynamics(cat["theta"], cat["d"], cat["dd"], cat["eps"], cat["m"])
    fits = [fit_report(model, d["theta"], d["d"], d["dd"], d["eps"], d["m"]).fit_pct for d in data]
    rs = [residual_run(setup, pl, seconds, seed0 + 100 + pl, model.chi, [np.inf, np.inf], "none")
          for pl in PLATES]
    res = np.concatenate([r["res"] for r in rs])
    thr = thresholds_from_residuals(res)
    return {"plant": setup.plant, "k_eps": list(setup.soft_k_eps if setup.plant == "soft" else setup.k_eps),
            "n_window": setup.n_window, "fit_pct_in_sample": np.round(fits, 1).tolist(),
            "max_speed_rad_s": [round(float(np.abs(d["d"][:, 1:]).max()), 2) for d in data],
            "sigma_um_m": np.round(res.std(0) * 1e6, 1).tolist(), "thr_um_m": np.round(thr * 1e6).tolist(),
            "sigma_per_payload": [np.round(r["res"].std(0) * 1e6, 1).tolist() for r in rs],
            "peak_over_thr": [np.round(np.abs(r["res"]).max(0) / thr, 2).tolist() for r in rs],
            "wall_s": round(time.time() - t0, 1)}


def _contacts_csv(outs, path) -> None:
    """One row per contact scenario (the same bytes in every mode)."""
    cols = ["payload_g", "kind", "strategy", "onset_s", "detected_s", "delay_ms", "link", "direction",
            "peak_force_N", "final_force_N"]
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(cols)
    for o in outs:
        w.writerow(["" if o.get(c) is None else (repr(o[c]) if isinstance(o[c], float) else o[c]) for c in cols])
    write_text_atomic(path, buf.getvalue())


def _markdown(rep, path):
    fp = rep.get("false_positives", {"minutes": 0.0, "count": "not run"})
    lines = ["# Collision detection on the simulated TUDOR", "",
             f"Thresholds (6 sigma, link-2 / link-3 root residual): {rep['thresholds_um_m']} um/m; "
             f"false positives in {fp['minutes']:g} min of random motion (0-400 g): {fp['count']} "
             f"(per payload {fp.get('per_payload', '-')}; peak residual / threshold {fp.get('peak_over_threshold', '-')})."
             , "", "Per-payload thresholds (max of own and pooled 6 sigma) used: "
             f"{json.dumps(rep.get('thresholds_per_payload_um_m')) if rep.get('per_payload_thresholds') else 'no'}.",
             "", f"Plant {rep.get('plant', 'stiff')}; damping k_eps "
             + (f"{rep['soft_k_eps']} (layer's position-loop scale)" if rep.get('plant') == 'soft' else
                f"{rep['k_eps']}, heavy payloads {json.dumps(rep.get('heavy'))}")
             + f", static-filter window {rep.get('n_window', 1000)}; isolation window {rep.get('isolation_window_s')} s on "
             f"{'r3 - c(m) r2, coupling ' + json.dumps(rep.get('coupling')) if rep.get('decouple') else 'r3'}.", "",
             "Validation fit (B.4): " + json.dumps(
                 rep["identification"]["validation"]), "",
             "| payload | contact | strategy | onset (s) | detected (s) | delay (ms) | link | dir | peak force (N) | "
             "final force (N) |", "|---|---|---|---|---|---|---|---|---|---|"]
    for o in rep["contacts"]:
        det = "" if o.get("detected_s") is None else f"{o['detected_s']:.4f}"
        onset = "none" if o["onset_s"] is None else f"{o['onset_s']:.4f}"
        lines.append(f"| {o.get('payload_g', 300)} g | {o['kind']} | {o['strategy']} | {onset} | {det} | "
                     f"{'' if o.get('delay_ms') is None else round(o['delay_ms'], 1)} | {o.get('link', '')} | "
                     f"{o.get('direction', '')} | {o['peak_force_N']:.2f} | {o['final_force_N']:.2f} |")
    write_text_atomic(path, "\n".join(lines) + "\n")


if __name__ == "__main__":
    sys.exit(main())
