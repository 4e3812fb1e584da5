"""``tudorvision reproduce``: the seed's experiments re-run in the lab, side by side with the seed's numbers.

Every section of the reproduction (chapter 4's modes, chapter 8's damping,
chapter 9's servoing and catching, chapter 10's models, chapter 11's
collisions, appendix B.5's rail) is one task of the experiment runner
(:mod:`tudorvision.lab.runner`): it runs serially or on Dask, its record is
kept in ``OUT/runs/`` as it arrives, and running the same command again
skips the sections already done. A section returns rows; each row holds the
seed's value, the lab's value and a rule that gives the verdict:

* ``"within:0.10"``: the lab within 10 % of the seed's value;
* ``"max:T"`` / ``"min:T"``: a target (the issue's or the seed's) the lab must not
  exceed / must reach;
* ``"info"``: reported beside the seed, no verdict (a different quantity or no
  number in the seed).

The report (``OUT/reproduction.md``, ``OUT/reproduction.json``) lists the rows
by chapter; a section that failed is listed with its error and the run is
flagged incomplete (the other sections' rows are still written).
"""
from __future__ import annotations

import json
import platform
import time
from pathlib import Path

from ..io.atomic import write_text_atomic
from .provenance import code_version, package_versions
from .reproduce_table import Row, Section, format_report, row_chapter, verdict

__all__ = ["Row", "Section", "verdict", "run_reproduce", "format_report", "section_names", "row_chapter"]


def _sections() -> list:
    from .reproduce_sections import SECTIONS
    return list(SECTIONS)


def section_names() -> list:
    """Names of the reproduction's sections, in report order.

    Returns
    -------
    list of str
        The names ``--only`` accepts.
    """
    return [s.name for s in _sections()]


def _select(only) -> list:
    secs = _sections()
    if not only:
        return secs
    names = [s.name for s in secs]
    wanted = [w.strip() for w in only if w.strip()]
    bad = [w for w in wanted if w not in names]
    if bad:
        raise ValueError(f"--only: unknown section(s) {', '.join(bad)} (choose from {', '.join(names)})")
    return [s for s in secs if s.name in wanted]


def run_reproduce(out, *, quick=False, only=None, seed: int = 0, scheduler: str | None = "serial",
                  workers: int | None = None, show_progress: bool | None = None, stream=None) -> dict:
    """Run the reproduction's sections and write ``reproduction.md`` and ``reproduction.json`` to ``out``.

    Parameters
    ----------
    out : str or Path
        Output folder (``runs/`` holds one record per section; figures go to ``figures/``).
    quick : bool or sequence of str
        ``True``: small versions of every experiment (minutes instead of hours); a list of section
        names: small versions of those only. The report says which sections ran small.
    only : sequence of str, optional
        Section names to run (default all, :func:`section_names`).
    seed : int
        Seed of the experiments.
    scheduler : str or None
        ``"serial"``, ``"local"`` or a Dask scheduler address (:func:`~tudorvision.lab.runner.run_tasks`).
    workers : int, optional
        Worker processes for ``"local"``.
    show_progress : bool or None
        Progress on stderr (``None``: on a terminal).
    stream : file, optional
        Where progress goes.

    Returns
    -------
    dict
        ``rows`` (each row's dict plus ``verdict`` and ``chapter``), ``sections`` (name, chapter,
        title, quick, status, error, figures, notes, duration_s), ``complete``, ``quick`` (the sections
        run small), ``seed``,
        ``wall_s``, ``paths`` (the written report files).

    Raises
    ------
    ValueError
        On an unknown section name or a bad scheduler.
    """
    from .runner import Task, run_tasks

    secs = _select(only)
    small = {s.name for s in secs} if quick is True else set(quick or ())
    unknown = small - set(section_names())
    if unknown:
        raise ValueError(f"--quick-sections: unknown section(s) {', '.join(sorted(unknown))}")
    out = Path(out)
    (out / "figures").mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    tasks = [Task(f"reproduce-{s.name}", {"section": s.name, "quick": s.name in small}, int(seed), s.fn,
                  (str(out), s.name in small, int(seed))) for s in secs]
    code = code_version()

    rep = run_tasks(tasks, out, scheduler=scheduler, workers=workers, show_progress=show_progress,
                    label="reproduce", stream=stream, code=code)
    rows, sections = [], []
    for s, rec in zip(secs, rep.records):
        entry = {"name": s.name, "chapter": s.chapter, "title": s.title, "quick": s.name in small,
                 "status": "not run", "error": None, "code": None,
                 "figures": [], "notes": [], "duration_s": None}
        if rec is not None:
            entry.update(status=rec["status"], error=rec.get("error"), duration_s=rec.get("duration_s"),
                         code=code if rec.get("ran_now") else rec.get("code", "an earlier run"))
            if rec["status"] == "done":
                res = rec["result"] or {}
                entry["figures"] = list(res.get("figures", []))
                entry["notes"] = list(res.get("notes", []))
                for r in res.get("rows", []):
                    rows.append({**r, "chapter": row_chapter(r["section"], s.chapter), "experiment": s.name,
                                 "verdict": verdict(r)})
        sections.append(entry)
    result = {"quick": sorted(small), "seed": int(seed), "complete": rep.complete, "interrupted": rep.interrupted,
              "scheduler": rep.scheduler, "workers": rep.workers, "wall_s": round(time.perf_counter() - t0, 1),
              "machine": f"{platform.machine()} {platform.processor() or ''}".strip(),
              "python": platform.python_version(), "packages": package_versions(), "sections": sections,
              "rows": rows}
    md = out / "reproduction.md"
    js = out / "reproduction.json"
    write_text_atomic(js, json.dumps(result, indent=1) + "\n")
    write_text_atomic(md, format_report(result))
    result["paths"] = [str(md), str(js)]
    return result
