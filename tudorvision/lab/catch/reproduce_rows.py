"""The catching row of ``tudorvision reproduce``: the demo's success rate on the runner, in one call.

:func:`catch_success` runs the demo with its default options (the seed-measured
plant, the wall camera calibrated from the simulated disc sweep, compensated
kinematics learnt on the same plant) as sessions of 30 throws
(:func:`~tudorvision.lab.catch.sessions.run_sessions`) with the detection-noise
model instead of rendered frames (rendering every frame of hundreds of throws
takes too long) and returns the strict and lenient rates and the misses;
:func:`catch_success_seeds` does the same over several seeds and adds them up
(issue 18 asks for the seeds the demo was never tuned on to be reported apart).
"""
from __future__ import annotations

import tempfile
from dataclasses import replace
from pathlib import Path

from .options import DemoOptions
from .sessions import run_sessions

__all__ = ["catch_success", "catch_success_seeds"]


def catch_success(throws: int, seed: int, scheduler: str | None = "serial", *, out=None,
                  options: DemoOptions | None = None, session_throws: int = 30, workers: int | None = None,
                  calibrations: int = 1) -> dict:
    """Success rate of the catching demo over ``throws`` throws (seed section 9.3, issue 18's criterion).

    Parameters
    ----------
    throws : int
        Throws in all (about 42 % cross the reachable workspace).
    seed : int
        Seed of the run (session ``b`` uses ``seed * 1000 + b``).
    scheduler : str or None
        ``"serial"``, ``"local"`` or a Dask scheduler address (:func:`~tudorvision.lab.runner.run_tasks`).
    out : str or Path, optional
        Folder for the runner's records, ``throws.csv`` and ``summary.json`` (a re-run skips the sessions
        done); default: a temporary folder, removed afterwards.
    options : DemoOptions, optional
        The demo's options (default: ``DemoOptions()`` with ``render=False``); ``throws`` and ``seed``
        are replaced by the arguments.
    session_throws : int
        Throws per session.
    workers : int, optional
        Local worker processes (``scheduler="local"``).
    calibrations : int
        Wall-camera calibrations the sessions take in turn (session ``b`` calibrates with its own disc
        sweep, ``calibration_seed + b % calibrations``; :func:`~tudorvision.lab.catch.sessions.plan_sessions`).

    Returns
    -------
    dict
        ``crossing`` (throws crossing the reachable workspace), ``caught`` (of those, the whole ball
        through the ring), ``success_rate`` (strict, None without crossings), ``caught_centre`` and
        ``success_rate_centre`` (the earlier criterion: the ball centre within the net radius),
        ``misses`` (``{reason: count}``, :data:`~tudorvision.lab.catch.score.MISS_REASONS`, the throws
        outside the workspace included), ``throws``, ``seed``, ``plant``, ``calibrations``, ``complete``.

    Raises
    ------
    ValueError
        On a non-positive number of throws or of calibrations.
    """
    o = replace(options or DemoOptions(render=False), throws=int(throws), seed=int(seed))

    def run(folder) -> dict:
        return run_sessions(folder, o, session_throws=session_throws, scheduler=scheduler, workers=workers,
                            calibrations=calibrations)

    if out is None:
        with tempfile.TemporaryDirectory(prefix="tudorvision-catch-success-") as d:
            s = run(d)
    else:
        s = run(out)
    return {"crossing": s["crossing_workspace"], "caught": s["caught_in_workspace"],
            "success_rate": s["success_rate"], "caught_centre": s["caught_centre_in_workspace"],
            "success_rate_centre": s["success_rate_centre"], "misses": dict(s["misses"]),
            "throws": int(throws), "seed": int(seed), "plant": o.plant, "calibrations": int(calibrations),
            "complete": bool(s["complete"])}


def catch_success_seeds(throws: int, seeds, scheduler: str | None = "serial", *, out=None,
                        options: DemoOptions | None = None, session_throws: int = 30, workers: int | None = None,
                        calibrations: int = 1) -> dict:
    """:func:`catch_success` for each of ``seeds`` (``throws`` each), and the counts added up.

    Parameters
    ----------
    throws : int
        Throws per seed.
    seeds : sequence of int
        Seeds of the runs (distinct, at least one).
    scheduler, options, session_throws, workers, calibrations
        As :func:`catch_success`.
    out : str or Path, optional
        Folder; each seed's run goes to ``out/seed<S>`` (default: temporary folders).

    Returns
    -------
    dict
        ``crossing``, ``caught``, ``success_rate`` (strict, None without crossings), ``caught_centre``,
        ``success_rate_centre``, ``misses`` (summed), ``throws`` (per seed), ``seeds``, ``per_seed`` (each
        seed's :func:`catch_success` dict, in order), ``calibrations``, ``complete`` (every seed complete).

    Raises
    ------
    ValueError
        On no seeds, a repeated seed, or what :func:`catch_success` refuses.

    Examples
    --------
    >>> catch_success_seeds(10, [])
    Traceback (most recent call last):
    ...
    ValueError: seeds: expected at least one seed
    """
    seeds = [int(s) for s in seeds]
    if not seeds:
        raise ValueError("seeds: expected at least one seed")
    if len(set(seeds)) != len(seeds):
        raise ValueError(f"seeds: each seed once, got {seeds}")
    per = [catch_success(throws, s, scheduler, out=None if out is None else Path(out) / f"seed{s}",
                         options=options, session_throws=session_throws, workers=workers,
                         calibrations=calibrations) for s in seeds]
    crossing = sum(r["crossing"] for r in per)
    caught = sum(r["caught"] for r in per)
    caught_c = sum(r["caught_centre"] for r in per)
    misses: dict = {}
    for r in per:
        for k, v in r["misses"].items():
            misses[k] = misses.get(k, 0) + int(v)
    return {"crossing": crossing, "caught": caught, "success_rate": caught / crossing if crossing else None,
            "caught_centre": caught_c, "success_rate_centre": caught_c / crossing if crossing else None,
            "misses": misses, "throws": int(throws), "seeds": seeds, "per_seed": per,
            "calibrations": int(calibrations), "complete": all(r["complete"] for r in per)}
