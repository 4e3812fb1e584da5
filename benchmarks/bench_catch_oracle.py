"""Benchmark (issue 18): an oracle upper bound of the catching demo, the agent told the true crossing.

What limits the catch rate: perception, or the arm? The same arm, joint layer, ready pose, compensated
IK, net target (reach margin), setpoint margins and profile rules (speed choice, late speed, arrival
before the crossing) as the demo's defaults, but the agent's intercept estimate replaced by the
throw's TRUE crossing point and time. Variants (``--variants``):

* ``baseline``: the demo unchanged (the estimate passes through; only the targets are recorded).
* ``release`` (oracle at release): the true crossing is given on the first frame with a detection
  of the throw (the first frame on which the agent runs its filter, one or two frames after the
  release), released at once when it is reachable (rigid IK within the joint ranges, or at most
  the planner's reach tolerance beyond full stretch); a single setpoint, no refinements.
* ``second``, ``third``: the same on the second or third detection (a filter started on two or on
  three detections could know the crossing no earlier).
* ``own`` (oracle at the agent's own timing): the first setpoint goes out on the frame where the
  agent's own release rule fires on its own estimate, but to the true crossing; no refinements
  (they would target the same point).

The oracle lives only in this script, never in the agent's path (the agent never reads ground
truth): it subclasses the demo's scenario (to note each throw's truth as it is drawn) and the
agent's perception (``CatchPerception.step``: the record's intercept becomes the truth, its
``send`` flag the oracle's), and wraps the scorer to record each throw's net target. It runs
through the same path as the demo's sessions (``run_sessions``, serial, sessions of 30 throws,
session seeds ``seed * 1000 + b``, detection-noise model), so ``baseline`` gives the same throws
as ``catch demo --no-render --throws N --seed S --session-throws 30``.

Per variant it prints crossing throws, caught (strict: the whole ball through the ring), the miss
reasons (ball hit the rim, arm late, other), the net's error against the target it was sent to at
the crossing (x / z mean and sd, RMS, p90 of the distance; arrived throws: caught or on the rim,
crossings inside 0.8 m of the shoulder) and where the misses lie (distance and direction from the
shoulder, balls in the net), with the ratio of caught against the baseline. Per throw rows go to
``OUT/<variant>_<replan>_s<seed>_n<throws>.csv``, with how far the first and second intercept setpoints' estimates
were from the true crossing and when they went out (``first_error_m``, ``t_first_s``, ``second_error_m``,
``t_second_s``), how many of its setpoints were pass-through goals (``passed``) and how many joints of its first
setpoint were hedged (``hedged``); ``--keep-predictions`` also writes the agent's estimate and setpoint rows of every
throw (``predictions_<...>.csv``, ``setpoints_<...>.csv``, the demo's columns after ``session_seed``).

Run (2-core container: about 2 min per variant for 240 throws, 15 min for 1980; ``--workers N`` spreads the
sessions of every seed given over N processes, the same records as the serial run)::

    .venv/bin/python benchmarks/bench_catch_oracle.py --throws 240 --seed 0 --variants baseline release own
    .venv/bin/python benchmarks/bench_catch_oracle.py --throws 1980 --seed 0 --variants release
    .venv/bin/python benchmarks/bench_catch_oracle.py --throws 240 --seed 0 --variants baseline --replan blend
    .venv/bin/python benchmarks/bench_catch_oracle.py --throws 480 --seed 500 600 700 --variants baseline --workers 16

``--set NAME=VALUE`` (repeatable): a :class:`DemoOptions` field for every variant: a number, a switch (0 or 1)
or a choice by name, e.g. ``release_sigma_m=0.1`` (the demo before the twentieth session's release rule) or
``damping=integral``; the output files carry it in their names.

``--replan blend``: the joint layer re-plans a move in flight with continuous acceleration
(``DemoOptions.replan``); output files carry the mode in their names.
"""
from __future__ import annotations

import argparse
import csv
import dataclasses
import json
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from tudorvision.catch.intercept import Intercept, net_target, reachable_solutions
from tudorvision.catch.perception import CatchPerception
from tudorvision.lab.catch import run as demo_run
from tudorvision.lab.catch.agent import CatchAgent
from tudorvision.lab.catch.options import DemoOptions
from tudorvision.lab.catch.scenario import CatchScenario
from tudorvision.lab.catch.score import ThrowResult, summarize_throws
from tudorvision.lab.catch.sessions import MAX_SESSIONS, catch_session_task, plan_sessions, run_sessions
from tudorvision.robot import load_robot_params

VARIANTS = ("baseline", "release", "second", "third", "own")
#: variants that send the truth on the n-th detection of the throw
NTH_DETECTION = {"release": 1, "second": 2, "third": 3}
BALL_KG = 0.03

#: What the lab side knows now (serial sessions in this process): the throw in the air, the agent.
CURRENT: dict = {"throw": None, "agent": None, "variant": "baseline"}
#: One dict per scored throw (filled by the scorer's wrapper).
RECORDS: list = []


class OracleScenario(CatchScenario):
    """The demo's scenario; notes each throw's ground truth where the oracle perception reads it."""

    def throw(self, index, t_now):
        th = super().throw(index, t_now)
        CURRENT["throw"] = th
        return th


class RecordingAgent(CatchAgent):
    """The demo's agent, unchanged; registers itself so the scorer's wrapper can read its setpoint rows."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        CURRENT["agent"] = self


def reachable_with_tol(p_base, params, reach_tol_m: float) -> bool:
    """Whether a crossing (m, base frame) is reachable: rigid IK within the ranges, or pulled in from at
    most ``reach_tol_m`` beyond full stretch (the planner's rule, without its 2 deg joint margin)."""
    reach = params.link2_length_m + params.link3_length_m
    dz = p_base[2] - params.link1_height_m
    d = math.hypot(p_base[0], dz)
    if d > reach + reach_tol_m:
        return False
    q = np.array(p_base, float)
    if d > reach:
        s = (reach - 1e-6) / d
        q[0], q[2] = q[0] * s, params.link1_height_m + dz * s
    return len(reachable_solutions(q, 0.0, params)) > 0


class OraclePerception(CatchPerception):
    """The agent's perception, its intercept replaced by the throw's true crossing (lab side only).

    The filter still runs (its first release is noted); the record's ``intercept`` is the truth with
    ``send`` set once per throw: on the first, second or third detection of the throw (variants
    ``release``, ``second``, ``third``) or when the filter's own release rule first fires (``own``).
    """

    def __init__(self, ekf, intercept, params=None, **kwargs):
        super().__init__(ekf, intercept, params, **kwargs)
        self.sent_for = -1            # throw index the oracle released for
        self.reach_tol_m = float(intercept.reach_tol_m)
        self.params = params or load_robot_params()
        self.ekf_release = {}         # throw index -> time of the filter's first release, s
        self.n_det = {}               # throw index -> detections so far

    def step(self, t, p_base, cov_base):
        rec = super().step(t, p_base, cov_base)
        th = CURRENT["throw"]
        own = rec["intercept"]
        if own is not None and own.send and th.index not in self.ekf_release:
            self.ekf_release[th.index] = float(t)
        variant = CURRENT["variant"]
        if variant == "baseline":
            return rec
        if not th.crosses:
            rec["intercept"] = None
            return rec
        p = np.array(th.p_cross_base, float)
        if p_base is not None:
            self.n_det[th.index] = self.n_det.get(th.index, 0) + 1
        if variant in NTH_DETECTION:
            send = (self.sent_for != th.index and self.n_det.get(th.index, 0) >= NTH_DETECTION[variant]
                    and reachable_with_tol(p, self.params, self.reach_tol_m))
        else:
            send = self.sent_for != th.index and own is not None and own.send
        if send:
            self.sent_for = th.index
        rec["intercept"] = Intercept(t=float(t), t_cross=float(th.t_cross_s), p_base=p, cov_base=np.zeros((3, 3)),
                                     sigma_m=0.0, reachable=True, send=bool(send))
        if "x" not in rec:
            rec["x"] = np.full(6, np.nan)
        return rec


def scoring_wrapper(score):
    """The demo's ``score_throw``, recording each throw's target and truth into :data:`RECORDS`."""

    def wrapped(throw, log, **kw):
        res = score(throw, log, **kw)
        o, params, agent = kw["options"], kw["params"], CURRENT["agent"]
        rows = [r for r in agent.setpoints if r[0] == throw.index]
        d = res.as_dict()
        d.update(variant=CURRENT["variant"], session_seed=int(o.seed),
                 balls=int(round(kw["payload_true_kg"] / BALL_KG)), setpoints=len(rows),
                 x_target_m=math.nan, z_target_m=math.nan, clipped=False, t_ekf_release_s=math.nan,
                 first_error_m=math.nan, t_first_s=math.nan, second_error_m=math.nan, t_second_s=math.nan,
                 x_ready_m=float(o.ready_point_base[0]), z_ready_m=float(o.ready_point_base[2]),
                 passed=int(log.passed), hedged=int(log.hedged))
        if throw.p_cross_base is not None:
            # how far the first and second setpoints' estimates were from the true crossing, and when (after release)
            for k, name in enumerate(("first", "second")[:len(rows)]):
                d[f"{name}_error_m"] = float(np.linalg.norm(np.asarray(rows[k][5:8], float) - throw.p_cross_base))
                d[f"t_{name}_s"] = float(rows[k][1] - throw.t_release_s)
        per = agent.perception
        if isinstance(per, OraclePerception) and throw.index in per.ekf_release:
            d["t_ekf_release_s"] = per.ekf_release[throw.index] - throw.t_release_s
        if rows:
            last = rows[-1]
            tgt = net_target(np.array(last[5:8], float), float(log.yaw_rad), params, reach_margin_m=o.reach_margin_m,
                             inner_reach_m=agent.inner_reach_m)
            d["x_target_m"], d["z_target_m"] = float(tgt[0]), float(tgt[2])
            lims, m = np.asarray(params.joint_limits_rad, float), np.asarray(o.setpoint_margin_rad, float)
            th = np.asarray(last[2:5], float)
            d["clipped"] = bool(np.any(np.abs(th - (lims[:, 0] + m)) < 1e-9)
                                or np.any(np.abs(th - (lims[:, 1] - m)) < 1e-9))
        # the agent's own rows for this throw (written with --keep-predictions; not CSV columns of the throw rows)
        d["_predictions"] = [[int(o.seed), *r] for r in agent.predictions if r[0] == throw.index]
        d["_setpoints"] = [[int(o.seed), *r] for r in rows]
        RECORDS.append(d)
        return res

    return wrapped


def _patch(variant: str) -> tuple:
    """Put the oracle's classes in the demo's path for ``variant``; returns what they replaced."""
    saved = (demo_run.CatchScenario, demo_run.CatchAgent, demo_run.CatchPerception, demo_run.score_throw)
    demo_run.CatchScenario, demo_run.CatchAgent = OracleScenario, RecordingAgent
    demo_run.CatchPerception, demo_run.score_throw = OraclePerception, scoring_wrapper(saved[3])
    CURRENT["variant"] = variant
    return saved


def run_variant(variant: str, throws: int, seed: int, calibrations: int = 1, **kw) -> tuple[list, dict, float]:
    """Run one variant through the demo's session path; returns (records, summary, wall s)."""
    saved = _patch(variant)
    del RECORDS[:]
    t0 = time.perf_counter()
    try:
        with tempfile.TemporaryDirectory(prefix="oracle-") as d:
            s = run_sessions(d, DemoOptions(render=False, throws=throws, seed=seed, rerun=False, plots=False, **kw),
                             scheduler="serial", calibrations=calibrations)
    finally:
        demo_run.CatchScenario, demo_run.CatchAgent, demo_run.CatchPerception, demo_run.score_throw = saved
    s = {k: v for k, v in s.items() if k != "per_throw"}
    return list(RECORDS), s, time.perf_counter() - t0


def _session_job(options: DemoOptions) -> tuple:
    """One session in a pool worker: (its seed, its records, its result as ``catch_session_task`` returns it)."""
    del RECORDS[:]
    res = catch_session_task(options)
    return int(options.seed), list(RECORDS), res


def run_variant_pool(variant: str, throws: int, seeds, workers: int, calibrations: int = 1, **kw) -> dict:
    """:func:`run_variant` for several seeds at once, the sessions spread over ``workers`` processes.

    Every session runs as in the serial path (its own seed ``seed * 1000 + b``, a fresh arm), so the records
    equal the serial run's on the same machine; returns ``{seed: (records, summary, wall s)}`` with the
    summary's counts from :func:`summarize_throws` over the sessions' throws.
    """
    import multiprocessing

    t0 = time.perf_counter()
    jobs = []
    for seed in seeds:
        o = DemoOptions(render=False, throws=throws, seed=seed, rerun=False, plots=False, **kw)
        jobs += [task.args[0] for task in plan_sessions(o, calibrations=calibrations)]
    with multiprocessing.get_context("fork").Pool(workers, initializer=_patch, initargs=(variant,)) as pool:
        done = pool.map(_session_job, jobs, chunksize=1)
    wall = time.perf_counter() - t0
    out = {}
    for seed in seeds:
        mine = [d for d in done if d[0] // MAX_SESSIONS == seed]
        s = summarize_throws([ThrowResult(**t) for _, _, res in mine for t in res["per_throw"]])
        s["layer_faults_cleared"] = sum(int(res["layer_faults_cleared"]) for _, _, res in mine)
        out[seed] = ([r for _, recs, _ in mine for r in recs], s, wall)
    return out


def _counts(rows) -> dict:
    ws = [r for r in rows if r["crossing_workspace"]]
    n, k = len(ws), sum(r["caught"] for r in ws)
    rim = sum(r["reason"] == "ball hit the rim" for r in ws)
    late = sum(r["reason"] == "arm late" for r in ws)
    return {"n": n, "caught": k, "rate": k / n if n else math.nan, "rim": rim, "late": late,
            "other": n - k - rim - late}


def net_error(rows, max_dist_m: float = 0.8) -> dict:
    """The net against its target at the crossing (cm): arrived throws (caught or rim) inside ``max_dist_m``."""
    prm = load_robot_params()
    sel = [r for r in rows if r["crossing_workspace"] and (r["caught"] or r["reason"] == "ball hit the rim")
           and math.hypot(r["x_cross_true_m"], r["z_cross_true_m"] - prm.link1_height_m) < max_dist_m
           and not math.isnan(r["x_target_m"])]
    e = np.array([[r["x_net_m"] - r["x_target_m"], r["z_net_m"] - r["z_target_m"]] for r in sel]) * 100
    if not len(e):
        return {"n": 0}
    dist = np.hypot(e[:, 0], e[:, 1])
    # along the move from the ready point to the target (> 0: past the target; moves over 5 cm)
    move = np.array([[r["x_target_m"] - r["x_ready_m"], r["z_target_m"] - r["z_ready_m"]] for r in sel])
    length = np.hypot(move[:, 0], move[:, 1])
    far = length > 0.05
    along = np.sum(e[far] * move[far], axis=1) / length[far]
    return {"n": len(e), "mean_x_cm": float(e[:, 0].mean()), "mean_z_cm": float(e[:, 1].mean()),
            "sd_x_cm": float(e[:, 0].std()), "sd_z_cm": float(e[:, 1].std()),
            "rms_cm": float(np.sqrt(np.mean(dist ** 2))), "median_cm": float(np.median(dist)),
            "p90_cm": float(np.percentile(dist, 90)),
            "along_move_mean_cm": float(along.mean()) if len(along) else math.nan}


def breakdown(rows) -> list[str]:
    """Misses by distance / direction from the shoulder and balls in the net (lines of text)."""
    prm = load_robot_params()
    ws = [r for r in rows if r["crossing_workspace"]]
    for r in ws:
        dz = r["z_cross_true_m"] - prm.link1_height_m
        r["dist"], r["dir"] = math.hypot(r["x_cross_true_m"], dz), math.degrees(math.atan2(dz, r["x_cross_true_m"]))
    groups = [("dist m", "dist", [0.6, 0.7, 0.78, 0.81]), ("dir deg", "dir", [45, 75, 105, 135]),
              ("balls", "balls", [0.5, 1.5, 2.5, 3.5, 4.5, 5.5, 6.5])]
    lines = []
    for label, key, edges in groups:
        b = np.digitize([r[key] for r in ws], edges)
        cells = []
        for i in range(len(edges) + 1):
            g = [r for r, j in zip(ws, b) if j == i]
            c = _counts(g)
            lo = "<" if i == 0 else f"{edges[i - 1]}"
            cells.append(f"[{lo}{'' if i == 0 else '-'}{edges[i] if i < len(edges) else '+'}] n={c['n']} "
                         f"{100 * c['rate']:.0f}% rim={c['rim']} late={c['late']} oth={c['other']}")
        lines.append(f"  {label}: " + " | ".join(cells))
    return lines


def write_rows(path: Path, rows) -> None:
    """Per-throw rows (the demo's columns plus the oracle's) as CSV."""
    if not rows:
        return
    cols = [c for c in rows[0] if not c.startswith("_")]
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, cols, extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)


def write_agent_rows(out: Path, stem: str, rows) -> None:
    """The agent's estimate and setpoint rows of every throw (``predictions_STEM.csv``, ``setpoints_STEM.csv``)."""
    from tudorvision.lab.catch.agent import PREDICTION_COLUMNS, SETPOINT_COLUMNS

    for key, cols in (("_predictions", PREDICTION_COLUMNS), ("_setpoints", SETPOINT_COLUMNS)):
        with open(out / f"{key[1:]}_{stem}.csv", "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(["session_seed", *cols])
            w.writerows(r for d in rows for r in d.get(key, []))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--throws", type=int, default=240)
    ap.add_argument("--seed", type=int, nargs="+", default=[0], help="one or more seeds, each run and reported alone")
    ap.add_argument("--workers", type=int, default=1,
                    help="processes the sessions are spread over (all seeds' sessions in one pool); 1: serial")
    ap.add_argument("--variants", nargs="+", choices=VARIANTS, default=list(VARIANTS))
    ap.add_argument("--replan", choices=("restart", "blend"), default="restart",
                    help="how the joint layer re-plans a move in flight (DemoOptions.replan)")
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="a DemoOptions field for every variant: a number, a switch (0 or 1) or a choice by name, "
                         "e.g. release_sigma_m=0.1 or damping=integral (repeatable)")
    ap.add_argument("--calibrations", type=int, default=1, metavar="K",
                    help="wall-camera calibrations the sessions take in turn (session b: calibration_seed + b %% K); "
                         "1: one calibration for every session")
    ap.add_argument("--keep-predictions", action="store_true",
                    help="also write the agent's intercept estimates and setpoints per throw "
                         "(predictions_*.csv, setpoints_*.csv; session_seed first, then the demo's columns)")
    ap.add_argument("--compare", default=None, metavar="DIR",
                    help="a folder of an earlier run of this benchmark: per seed, the throws won and lost against "
                         "its baseline CSV of the same seed and throws, with McNemar's exact p")
    ap.add_argument("--out", default="out/bench_catch_oracle")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    fields = {f.name: f for f in dataclasses.fields(DemoOptions)}
    extra = {}
    for item in args.set:
        name, _, value = item.partition("=")
        if name not in fields or not value:
            ap.error(f"--set {item!r}: expected NAME=VALUE with NAME a DemoOptions field")
        if fields[name].type in (str, "str"):        # a named choice, checked by DemoOptions
            extra[name] = value
            continue
        if "," in value or fields[name].type in (tuple, "tuple"):    # numbers separated by commas
            try:
                extra[name] = tuple(float(x) for x in value.split(","))
            except ValueError:
                ap.error(f"--set {item!r}: VALUE must be numbers separated by commas")
            continue
        try:
            extra[name] = float(value)
        except ValueError:
            ap.error(f"--set {item!r}: VALUE must be a number")
        if fields[name].type in (bool, "bool"):     # a switch: 0 or 1
            if extra[name] not in (0.0, 1.0):
                ap.error(f"--set {item!r}: {name} is a switch, VALUE must be 0 or 1")
            extra[name] = bool(extra[name])
    try:
        DemoOptions(**extra)                          # checked here, not after the first variant's run
    except (TypeError, ValueError) as e:
        ap.error(f"--set: {e}")
    def _fmt(v):
        return v if isinstance(v, str) else "-".join(format(x, "g") for x in v) if isinstance(v, tuple) \
            else format(v, "g")

    tag = "".join(f"_{k}{_fmt(v)}" for k, v in sorted(extra.items()))
    if args.calibrations < 1:
        ap.error(f"--calibrations {args.calibrations}: expected at least 1")
    if args.calibrations > 1:
        tag += f"_cal{args.calibrations}"
    if args.workers < 1:
        ap.error(f"--workers {args.workers}: expected at least 1")
    if args.workers == 1:
        for seed in args.seed:
            report(args, out, tag, seed, {v: run_variant(v, args.throws, seed, args.calibrations,
                                                      replan=args.replan, **extra)
                                          for v in args.variants})
    else:
        runs = {v: run_variant_pool(v, args.throws, args.seed, args.workers, args.calibrations,
                                    replan=args.replan, **extra)
                for v in args.variants}
        for seed in args.seed:
            report(args, out, tag, seed, {v: runs[v][seed] for v in args.variants})


def paired_turnover(rows, reference_csv: Path) -> dict:
    """Throws crossing the workspace in both runs, caught in one only: won and lost against ``reference_csv``.

    The same throws (``session_seed``, ``throw``) of another run of this benchmark; ``p`` is the exact two-sided
    McNemar test (binomial on the discordant throws): a run of sessions is chaotic (one different setpoint changes
    the arm's state, and the balls in the net, for every later throw), so a change of a few throws in 400 is what
    any rule gives.
    """
    from scipy.stats import binomtest

    with open(reference_csv, newline="") as fh:
        ref = {(r["session_seed"], r["throw"]): r["caught"] == "True" for r in csv.DictReader(fh)
               if r["crossing_workspace"] == "True"}
    now = {(str(r["session_seed"]), str(r["throw"])): bool(r["caught"]) for r in rows if r["crossing_workspace"]}
    both = sorted(set(ref) & set(now))
    won = sum(now[k] and not ref[k] for k in both)
    lost = sum(ref[k] and not now[k] for k in both)
    p = binomtest(won, won + lost, 0.5).pvalue if won + lost else 1.0
    return {"reference": str(reference_csv), "throws": len(both), "won": won, "lost": lost, "p": float(p)}


def report(args, out: Path, tag: str, seed: int, runs) -> None:
    """Print and write one seed's results: ``runs`` maps each variant to ``(records, summary, wall s)``."""
    results = {}
    for v, (rows, s, wall) in runs.items():
        stem = f"{v}_{args.replan}{tag}_s{seed}_n{args.throws}"
        write_rows(out / f"{stem}.csv", rows)
        if args.keep_predictions:
            write_agent_rows(out, stem, rows)
        c, err = _counts(rows), net_error(rows)
        assert c["n"] == s["crossing_workspace"] and c["caught"] == s["caught_in_workspace"], (c, s)
        results[v] = {"counts": c, "net_vs_target": err, "wall_s": wall, "misses": s.get("misses"),
                      "layer_faults_cleared": s.get("layer_faults_cleared")}
        print(f"{v:8s} seed {seed} throws {args.throws}: crossing {c['n']} caught {c['caught']} "
              f"({100 * c['rate']:.1f} %) rim {c['rim']} late {c['late']} other {c['other']}  "
              f"faults {s.get('layer_faults_cleared')}  [{wall:.0f} s]", flush=True)
        print("  net - target (cm): " + ", ".join(f"{k} {val:.2f}" if isinstance(val, float) else f"{k} {val}"
                                                for k, val in err.items()), flush=True)
        for line in breakdown(rows):
            print(line, flush=True)
        if args.compare is not None:
            refs = sorted(Path(args.compare).glob(f"baseline_*_s{seed}_n{args.throws}.csv"))
            if len(refs) != 1:
                print(f"  compare: expected one baseline_*_s{seed}_n{args.throws}.csv in {args.compare}, "
                      f"found {len(refs)}", flush=True)
            else:
                t = results[v]["turnover"] = paired_turnover(rows, refs[0])
                print(f"  against {refs[0].name}: won {t['won']}, lost {t['lost']} of {t['throws']} crossing "
                      f"throws (McNemar p = {t['p']:.2f})", flush=True)
    if "baseline" in results:
        b = results["baseline"]["counts"]["caught"]
        for v, r in results.items():
            print(f"{v}: caught {r['counts']['caught']} vs baseline {b}: ratio {r['counts']['caught'] / b:.3f}")
    (out / f"summary_{args.replan}{tag}_s{seed}_n{args.throws}.json").write_text(json.dumps(results, indent=2))


if __name__ == "__main__":
    main()
