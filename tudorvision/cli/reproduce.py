"""``tudorvision reproduce``: re-run the seed's experiments in the lab and write the side-by-side report."""
from __future__ import annotations

import sys

from .._checks import TudorVisionError
from .batch import add_scheduler_arguments, apply_rerun_stale

__all__ = ["register"]


def _cmd_reproduce(args) -> int:
    from ..lab.reproduce import run_reproduce
    if args.list:
        from ..lab.reproduce_sections import SECTIONS
        for s in SECTIONS:
            print(f"{s.name:14s} chapter {s.chapter:4s} ~{s.minutes_quick:g} min quick, ~{s.minutes_full:g} min full: "
                  f"{s.title}")
        return 0
    if not args.out:
        raise TudorVisionError("--out: required (the folder the report and the runs go to)")
    only = [x for x in (args.only or "").split(",") if x.strip()]
    if args.seed < 0:
        raise TudorVisionError(f"--seed: expected >= 0, got {args.seed}")
    small = [x for x in (args.quick_sections or "").split(",") if x.strip()]   # names checked by run_reproduce
    apply_rerun_stale(args, args.out)
    res = run_reproduce(args.out, quick=True if args.quick else small, only=only or None, seed=args.seed, scheduler=args.scheduler,
                        workers=args.workers)
    counts: dict = {}
    for r in res["rows"]:
        key = r["verdict"].split(" (")[0].split(" by ")[0]
        counts[key] = counts.get(key, 0) + 1
    print(f"{len(res['rows'])} rows: " + ", ".join(f"{n} {k}" for k, n in sorted(counts.items()))
          + f"; wrote {', '.join(res['paths'])}")
    if not res["complete"]:
        bad = [f"{s['name']} ({s['status']})" for s in res["sections"] if s["status"] != "done"]
        print(f"tudorvision reproduce: warning: incomplete, section(s) {', '.join(bad)} did not finish; "
              f"the report lists the others (run the same command again to resume)", file=sys.stderr)
        return 130 if res["interrupted"] else 3
    return 0


def register(sub) -> None:
    p = sub.add_parser("reproduce", help="re-run the seed's experiments in the lab, seed vs lab table",
                       description="Re-run the dissertation's experiments in the virtual lab (chapters 4, 8, 9, 10, "
                                   "11 and appendix B.5) and write OUT/reproduction.md with the seed's value, the "
                                   "lab's value and a verdict per row. Each section is a task of the experiment "
                                   "runner: finished sections are kept in OUT/runs/ and skipped when the same "
                                   "command runs again. Exit code 3 when a section failed (the others are "
                                   "written).")
    p.add_argument("--out", help="output folder (required unless --list)")
    p.add_argument("--quick", action="store_true", help="small versions (minutes, numbers indicative)")
    p.add_argument("--quick-sections", metavar="A,B", help="small versions of these sections only")
    p.add_argument("--only", metavar="A,B", help="run only these sections (see --list)")
    p.add_argument("--list", action="store_true", help="list the sections and exit")
    p.add_argument("--seed", type=int, default=0, help="seed of the experiments (default 0)")
    add_scheduler_arguments(p, default="serial")
    p.set_defaults(func=_cmd_reproduce)
