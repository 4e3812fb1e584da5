"""The catching demo as independent sessions on the experiment runner (``catch demo --scheduler ...``).

Throws within one :func:`~tudorvision.lab.catch.run.run_demo` run share the
arm, the net and the payload estimate, so they run in order. Many throws are
split into *sessions* of ``session_throws`` throws: session ``b`` is a fresh
demo (fresh arm, empty net) with seed ``seed * 1000 + b`` (as the catch
benchmark's batches), and each session is one runner task, keyed by
``("catch-demo", {session, throws, options digest}, session seed)``. Sessions
run serially, on a local Dask cluster or on a remote scheduler, and the
combined ``throws.csv`` and ``summary.json`` are the same bytes in every mode.
Per-session records (every throw's score) stay in ``out/runs/``; a re-run
skips the sessions already done.
"""
from __future__ import annotations

import csv
import json
import math
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from .options import DemoOptions
from .score import PER_THROW_COLUMNS, ThrowResult, summarize_throws
from .writers import format_row

__all__ = ["catch_session_task", "plan_sessions", "run_sessions", "write_sessions", "SESSION_COLUMNS",
           "MAX_SESSIONS"]

#: Sessions per seed (session seeds ``seed * 1000 + b`` stay distinct between seeds).
MAX_SESSIONS = 1000

#: Columns of the combined ``throws.csv``: the session, its seed, then the per-throw score.
SESSION_COLUMNS = ["session", "session_seed", *PER_THROW_COLUMNS]

_COUNTS = ("balls_in_net", "net_emptied", "setpoints_not_acknowledged", "layer_faults_cleared")


def catch_session_task(options: DemoOptions) -> dict:
    """Run one session of the demo (no files kept: no recording, no plots) and return its scores.

    Parameters
    ----------
    options : DemoOptions
        The session's options (its own seed and number of throws).

    Returns
    -------
    dict
        ``per_throw`` (one :meth:`ThrowResult.as_dict <tudorvision.lab.catch.score.ThrowResult.as_dict>`
        per throw) and the counts ``balls_in_net``, ``net_emptied``, ``setpoints_not_acknowledged``,
        ``layer_faults_cleared``, ``calibration`` (the wall camera's, as in the demo's ``summary.json``,
        without ``cached``); nothing that depends on the machine (no wall times).
    """
    from .run import run_demo
    o = replace(options, rerun=False, plots=False, show_progress=False)
    with tempfile.TemporaryDirectory(prefix="tudorvision-catch-") as d:
        s = run_demo(d, o)
    calib = {k: v for k, v in s["calibration"].items() if k != "cached"}
    return {"per_throw": s["per_throw"], **{k: s[k] for k in _COUNTS}, "calibration": calib}


def _options_digest(options: DemoOptions) -> str:
    from ..runner import config_digest
    return config_digest(replace(options, seed=0, throws=1, rerun=False, plots=False, show_progress=False,
                                 cache_dir=""))


def plan_sessions(options: DemoOptions, session_throws: int = 30, calibrations: int = 1) -> list:
    """Split ``options.throws`` into sessions of ``session_throws`` as runner tasks.

    Parameters
    ----------
    options : DemoOptions
        The demo (``throws`` in all, ``seed``, ``calibration_seed``).
    session_throws : int
        Throws per session (the last one may have fewer).
    calibrations : int
        Wall-camera calibrations the sessions take in turn: session ``b`` calibrates with
        ``calibration_seed + b % calibrations`` (its own rendered disc sweep and depth noise), so the
        catch is measured over a family of calibrations, not one draw; 1: every session shares
        ``calibration_seed``'s (the behaviour before).

    Returns
    -------
    list of Task
        One per session, session order.

    Raises
    ------
    ValueError
        On ``session_throws < 1``, ``calibrations < 1`` or more than :data:`MAX_SESSIONS` sessions.
    """
    from ..runner import Task
    if session_throws < 1:
        raise ValueError(f"--session-throws: expected >= 1, got {session_throws}")
    if int(calibrations) != calibrations or calibrations < 1:
        raise ValueError(f"--calibrations: expected a positive integer, got {calibrations}")
    n = math.ceil(options.throws / session_throws)
    if n > MAX_SESSIONS:
        raise ValueError(f"--session-throws: {options.throws} throws make {n} sessions, more than {MAX_SESSIONS}")
    digest = _options_digest(options)
    tasks = []
    for b in range(n):
        k = min(session_throws, options.throws - b * session_throws)
        seed = int(options.seed) * MAX_SESSIONS + b
        params = {"session": b, "throws": k, "options": digest}
        if calibrations > 1:          # (keys of single-calibration runs unchanged: their records are reused)
            params["calibrations"] = int(calibrations)
        session = replace(options, seed=seed, throws=k,
                          calibration_seed=int(options.calibration_seed) + b % int(calibrations))
        tasks.append(Task("catch-demo", params, seed, catch_session_task, (session,)))
    return tasks


def write_sessions(out, options: DemoOptions, report, *, session_throws: int, wall_s: float | None = None) -> dict:
    """Write the combined ``throws.csv``, ``summary.json`` and ``runner.json`` of a session run.

    Parameters
    ----------
    out : str or Path
        Output folder.
    options : DemoOptions
        The demo's options.
    report : RunReport
        From :func:`~tudorvision.lab.runner.run_tasks` on :func:`plan_sessions`' tasks.
    session_throws : int
        Throws per session.
    wall_s : float, optional
        Wall time of the whole run, s (default: the runner's).

    Returns
    -------
    dict
        The summary as written, plus ``per_throw`` (dicts with ``session`` and ``session_seed``) and
        ``runner`` (counts and timing).
    """
    from ...io.atomic import atomic_write, write_text_atomic
    out = Path(out)
    rows, results = [], []
    counts = dict.fromkeys(_COUNTS, 0)
    for rec in report.done:
        for d in rec["result"]["per_throw"]:
            r = ThrowResult(**d)
            results.append(r)
            rows.append({"session": rec["params"]["session"], "session_seed": rec["seed"], **r.as_dict()})
        for k in _COUNTS:
            counts[k] += int(rec["result"][k])
    with atomic_write(out / "throws.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(SESSION_COLUMNS)
        for row in rows:
            w.writerow(format_row(SESSION_COLUMNS, [row[c] for c in SESSION_COLUMNS]))
    score = summarize_throws(results)
    calibs = {}
    for rec in report.done:
        c = rec["result"].get("calibration") or {}
        if "calibration_seed" in c:
            calibs.setdefault(int(c["calibration_seed"]), c)
    summary = {"throws": int(options.throws), "throws_done": len(results), "sessions": len(report.records),
               "session_throws": int(session_throws), "seed": int(options.seed),
               "session_seeds": f"seed * {MAX_SESSIONS} + session",
               **score, "render": options.render, "damping": options.damping, "compensate": options.compensate,
               "net_radius_m": options.net_radius_m, **counts,
               "calibration": next((rec["result"].get("calibration") for rec in report.done), None),
               # several calibrations (plan_sessions' ``calibrations``): each one's error at the arm, m
               **({"calibration_error_at_arm_m": {str(k): c.get("error_at_arm_m") for k, c in sorted(calibs.items())}}
                  if len(calibs) > 1 else {}),
               "complete": report.complete, "interrupted": report.interrupted,
               "sessions_failed": len(report.failed),
               "failures": [{k: r[k] for k in ("key", "seed", "params", "error")} for r in report.failed]}
    write_text_atomic(out / "summary.json", json.dumps(summary, indent=2))
    info = {**report.info(), "total_wall_s": report.wall_s if wall_s is None else wall_s}
    write_text_atomic(out / "runner.json", json.dumps(info, indent=2))
    return {**summary, "per_throw": rows, "runner": info}


def run_sessions(out, options: DemoOptions = DemoOptions(), *, session_throws: int = 30, calibrations: int = 1,
                 scheduler: str | None = "serial", workers: int | None = None, processes: bool = True,
                 show_progress: bool | None = False, dashboard_address: str | None = ":8787") -> dict:
    """Run the demo's throws as independent sessions on the runner and write the combined results.

    Parameters
    ----------
    out : str or Path
        Output folder (``runs/``, ``throws.csv``, ``summary.json``, ``runner.json``).
    options : DemoOptions
        The demo: ``throws`` in all and ``seed``; the recording and plots are not written.
    session_throws : int
        Throws per session.
    calibrations : int
        Wall-camera calibrations the sessions take in turn (:func:`plan_sessions`).
    scheduler : str or None
        ``"serial"``, ``"local"`` or a Dask scheduler address.
    workers : int, optional
        Local worker processes (default: the machine's cores).
    processes : bool
        Local cluster of processes (else threads).
    show_progress : bool or None
        Runner progress on stderr.
    dashboard_address : str or None
        Local cluster's dashboard.

    Returns
    -------
    dict
        As :func:`write_sessions`; ``complete`` is false when sessions failed or the run was interrupted.
    """
    from ..runner import run_tasks
    t0 = time.perf_counter()
    tasks = plan_sessions(options, session_throws, calibrations)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    report = run_tasks(tasks, out, scheduler=scheduler, workers=workers, processes=processes,
                       dashboard_address=dashboard_address, show_progress=show_progress, label="catch sessions")
    return write_sessions(out, options, report, session_throws=session_throws, wall_s=time.perf_counter() - t0)
