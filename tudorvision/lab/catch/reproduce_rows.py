"""The catching row of ``tudorvision reproduce``: the demo's success rate on the runner, in one call.

:func:`catch_success` runs the demo with its default options (the seed-measured
plant, the wall camera calibrated from the simulated disc sweep, compensated
kinematics learnt on the same plant) as sessions of 30 throws
(:func:`~tudorvision.lab.catch.sessions.run_sessions`) with the detection-noise
model instead of rendered frames (rendering every frame of hundreds of throws
takes too long) and returns the strict and lenient rates and the misses.
"""
from __future__ import annotations

import tempfile
from dataclasses import replace

from .options import DemoOptions
from .sessions import run_sessions

__all__ = ["catch_success"]


def catch_success(throws: int, seed: int, scheduler: str | None = "serial", *, out=None,
                  options: DemoOptions | None = None, session_throws: int = 30, workers: int | None = None) -> dict:
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

    Returns
    -------
    dict
        ``crossing`` (throws crossing the reachable workspace), ``caught`` (of those, the whole ball
        through the ring), ``success_rate`` (strict, None without crossings), ``caught_centre`` and
        ``success_rate_centre`` (the earlier criterion: the ball centre within the net radius),
        ``misses`` (``{reason: count}``, :data:`~tudorvision.lab.catch.score.MISS_REASONS`, the throws
        outside the workspace included), ``throws``, ``seed``, ``plant``, ``complete``.

    Raises
    ------
    ValueError
        On a non-positive number of throws.
    """
    o = replace(options or DemoOptions(render=False), throws=int(throws), seed=int(seed))

    def run(folder) -> dict:
        return run_sessions(folder, o, session_throws=session_throws, scheduler=scheduler, workers=workers)

    if out is None:
        with tempfile.TemporaryDirectory(prefix="tudorvision-catch-success-") as d:
            s = run(d)
    else:
        s = run(out)
    return {"crossing": s["crossing_workspace"], "caught": s["caught_in_workspace"],
            "success_rate": s["success_rate"], "caught_centre": s["caught_centre_in_workspace"],
            "success_rate_centre": s["success_rate_centre"], "misses": dict(s["misses"]),
            "throws": int(throws), "seed": int(seed), "plant": o.plant, "complete": bool(s["complete"])}
