"""Benchmark: the experiment runner (issue 17) against the old single-process path, and its overhead.

Three parts, in one run:

1. Wall time of the same servo repeatability runs (the 8 start poses x
   ``--repetitions``, payload 200 g, hybrid law; the lab as ``tudorvision servo
   --sim --experiment repeatability``) five ways: the old single-process path (a
   plain loop calling the run function, what ``repeatability(workers=1)`` did
   before the runner), the old process pool (``ProcessPoolExecutor`` with 2
   processes, what ``repeatability(workers=2)`` did), the runner serially, and
   the runner on a local Dask cluster of 1 and of 2 worker processes (start-up
   included). Ratios against the old single-process path; all five must give
   the same rows.
2. Scheduler overhead per task: no-op tasks (:func:`~tudorvision.lab.runner.probe_task`)
   serially and on the 2-process local cluster, ``(wall(N) - wall(n)) / (N - n)``,
   which counts the client's work too (the atomic, fsync'ed record per task).
3. The numbers the scaling estimate in ``docs/benchmarks.md`` uses: mean task
   duration, cluster start-up and overhead per task; the estimate for
   ``W`` workers is ``startup + max(N * t_task / W, N * overhead)``.

Run::

    nice .venv/bin/python benchmarks/bench_runner.py [--repetitions 1] [--t-max 10] [--noop 400]
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from dataclasses import replace

os.environ.setdefault("OMP_NUM_THREADS", "1")

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from _machine import cpu_model  # noqa: E402
from tudorvision.lab.runner import Task, probe_task, run_tasks, to_jsonable  # noqa: E402
from tudorvision.lab.servo_experiments import plan_repeatability  # noqa: E402
from tudorvision.lab.servo_lab import LabConfig  # noqa: E402


def timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def old_path(tasks):
    """The single-process path before the runner: call each run in turn, keep the rows."""
    return [t.fn(*t.args) for t in tasks]


def _call(t):
    return t.fn(*t.args)


def old_pool(tasks, workers):
    """The old ``repeatability(workers=N)`` path: a ProcessPoolExecutor mapping the runs."""
    from concurrent.futures import ProcessPoolExecutor
    with ProcessPoolExecutor(max_workers=workers) as ex:
        return list(ex.map(_call, tasks, chunksize=1))


def runner_rows(tasks, scheduler, workers=None):
    with tempfile.TemporaryDirectory() as d:
        rep = run_tasks(tasks, d, scheduler=scheduler, workers=workers, dashboard_address=None,
                        show_progress=False)
    assert rep.complete, rep.info()
    return [r["result"] for r in rep.records], rep


def noop_wall(n, scheduler, workers=None):
    tasks = [Task("noop", {"i": i}, i, probe_task, (i,)) for i in range(n)]
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        rep = run_tasks(tasks, d, scheduler=scheduler, workers=workers, dashboard_address=None, show_progress=False)
        wall = time.perf_counter() - t0
    assert rep.complete
    return wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repetitions", type=int, default=1, help="servo repetitions (8 runs each)")
    ap.add_argument("--t-max", type=float, default=10.0, help="longest servo run, simulated s (default 10)")
    ap.add_argument("--noop", type=int, default=400, help="no-op tasks for the overhead")
    args = ap.parse_args()
    print(f"machine: {cpu_model()}, {os.cpu_count()} cores, Python {platform.python_version()}, "
          f"load average {os.getloadavg()[0]:.1f}")

    cfg = replace(LabConfig(), t_max_s=args.t_max)
    (tasks, _), t_plan = timed(lambda: plan_repeatability(repetitions=args.repetitions, seed=0, laws=("hybrid",),
                                                          payloads_g=(200,), cfg=cfg))
    print(f"servo repeatability: {len(tasks)} runs (payload 200 g, hybrid), planning {t_plan:.1f} s (not timed "
          "below)")
    ref, t_old = timed(lambda: old_path(tasks))
    for r in ref:
        r.pop("wall_s", None)
    pool, t_pool = timed(lambda: old_pool(tasks, 2))
    for r in pool:
        r.pop("wall_s", None)
    rows = {"old pool": to_jsonable(pool)}
    (rows["serial"], rep_serial), t_serial = timed(lambda: runner_rows(tasks, "serial"))
    (rows["local 1"], rep1), t_l1 = timed(lambda: runner_rows(tasks, "local", 1))
    (rows["local 2"], rep2), t_l2 = timed(lambda: runner_rows(tasks, "local", 2))
    ref_text = json.dumps(to_jsonable(ref))
    for k, v in rows.items():
        assert json.dumps(v) == ref_text, f"{k}: rows differ from the old path"
    task_s = rep_serial.info()["task_s_mean"]
    print("  rows identical in all five modes: yes")
    print(f"  {'mode':34s} {'wall s':>8s} {'vs old':>8s}")
    for label, t in (("old single-process loop", t_old), ("old process pool, 2 processes", t_pool),
                     ("runner, serial", t_serial),
                     ("runner, local cluster, 1 worker", t_l1), ("runner, local cluster, 2 workers", t_l2)):
        print(f"  {label:34s} {t:8.1f} {t / t_old:8.2f}")
    print(f"  mean task duration (serial) {task_s:.2f} s; on 2 workers "
          f"{rep2.info()['task_s_mean']:.2f} s (the 2 workers share 2 cores with the client and other jobs)")

    n_small = 20
    print(f"no-op tasks ({args.noop} vs {n_small}):")
    res = {}
    for label, sch, w in (("serial", "serial", None), ("local cluster, 2 workers", "local", 2)):
        w_big = noop_wall(args.noop, sch, w)
        w_small = noop_wall(n_small, sch, w)
        per = (w_big - w_small) / (args.noop - n_small)
        res[label] = (w_small, per)
        print(f"  {label:26s} {args.noop} tasks {w_big:6.2f} s, {n_small} tasks {w_small:6.2f} s, "
              f"overhead {per * 1e3:6.2f} ms/task")
    startup, per = res["local cluster, 2 workers"]
    n480 = 480
    print("scaling estimate, startup + max(N t / W, N overhead), N = 480 servo runs of "
          f"{task_s:.2f} s, overhead {per * 1e3:.1f} ms/task, startup {startup:.1f} s:")
    for w in (1, 2, 8, 32, 100):
        est = startup + max(n480 * task_s / w, n480 * per)
        print(f"  {w:4d} workers: {est:8.0f} s  (speed-up {n480 * task_s / est:5.1f})")


if __name__ == "__main__":
    main()
