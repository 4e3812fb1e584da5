"""``tudorvision track batch``: track many recorded sequences into one folder, on the experiment runner.

Each sequence is one runner task (:mod:`tudorvision.lab.runner`): a worker runs
the same code as ``tudorvision track stereo`` / ``track mono`` on it and sends
the CSV back; the client writes ``OUT/<sequence name>.csv`` and ``OUT/batch.csv``
(one line per sequence: output, rows, exit code, status, error). Workers read
the sequences, colour models and calibrations by path: on a cluster they must
see the same files (a shared folder). A sequence that fails (unreadable,
wrong kind) is recorded and retried once; the others go on. Running the same
command again skips the sequences already tracked.

This module also holds the options every runner-backed command shares
(:func:`add_scheduler_arguments`).
"""
from __future__ import annotations

import contextlib
import csv
import io
import shlex
import tempfile
from pathlib import Path

from .._checks import TudorVisionError

__all__ = ["register_track_batch", "add_scheduler_arguments", "add_rerun_stale_argument", "apply_rerun_stale",
           "track_sequence_task", "run_batch"]

SCHEDULER_HELP = ("where the runs go: 'serial' (this process), 'local' (a Dask cluster of --workers processes on "
                  "this machine, the default) or a running Dask scheduler's address, e.g. tcp://host:8786 "
                  "(started with 'dask scheduler' and 'dask worker')")


def add_scheduler_arguments(parser, *, default: str | None = "local", workers: bool = True) -> None:
    """Add ``--scheduler`` (and ``--workers``) for a command that runs on the experiment runner.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The command's parser.
    default : str or None
        Default scheduler (``None``: the command decides).
    workers : bool
        Also add ``--workers N`` (local cluster size; default: the machine's cores).
    """
    parser.add_argument("--scheduler", default=default, metavar="serial|local|ADDRESS", help=SCHEDULER_HELP)
    add_rerun_stale_argument(parser)
    if workers:
        parser.add_argument("--workers", type=int, default=None, metavar="N",
                            help="local cluster: worker processes (default: the machine's cores)")


def add_rerun_stale_argument(parser) -> None:
    """Add ``--rerun-stale`` for a resumable command (see :func:`apply_rerun_stale`).

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The command's parser.
    """
    parser.add_argument("--rerun-stale", action="store_true",
                        help="run again the finished tasks in OUT that other code made (their records are "
                             "deleted first; by default they are reused and counted as such)")


def apply_rerun_stale(args, out) -> None:
    """With ``--rerun-stale``: delete the records under ``out`` made by other code, and say how many.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line (``rerun_stale``).
    out : str or Path
        The command's output folder.
    """
    if getattr(args, "rerun_stale", False):
        from ..lab.runner import drop_stale_records
        gone = drop_stale_records(out)
        print(f"--rerun-stale: {len(gone)} record(s) of other code deleted under {out}", file=sys.stderr)


def register_track_batch(tsub) -> None:
    """Add ``batch`` to the ``track`` group (``tudorvision track batch``).

    Parameters
    ----------
    tsub : argparse subparsers action
        The ``track`` group's subcommands (from :mod:`tudorvision.cli.stereo`).
    """
    b = tsub.add_parser(
        "batch", help="track many sequences into one folder (serially, on a local Dask cluster or a cluster)",
        description="Run 'track stereo' or 'track mono' on every SEQ and write OUT/<name>.csv per sequence and "
                    "OUT/batch.csv. Resumable: a re-run skips the sequences already done (records in OUT/runs/). "
                    "On a cluster the workers must see the sequence and model files at the same paths.")
    b.add_argument("seqs", nargs="*", metavar="SEQ", help="sequence directories or video files")
    b.add_argument("--list", metavar="FILE", help="text file with one sequence path per line (added to SEQ)")
    b.add_argument("--kind", choices=("stereo", "mono"), required=True, help="tracking mode")
    b.add_argument("--colormodel", required=True, help="colour model file")
    b.add_argument("--out", required=True, metavar="DIR", help="output folder")
    b.add_argument("--sphere", help="mono: sphere name in the colour model file")
    b.add_argument("--calib", help="stereo: calibration file for every sequence (default: each sequence's)")
    b.add_argument("--track-args", default="", metavar="ARGS",
                   help="further options of 'track stereo' / 'track mono' as one quoted string, "
                        "e.g. \"--full-frame --centre centroid\"")
    add_scheduler_arguments(b)
    b.set_defaults(func=_main)


def track_sequence_task(kind: str, seq: str, colormodel: str, extra: list) -> dict:
    """Track one sequence as ``tudorvision track KIND`` would (a runner task; files by path only).

    Parameters
    ----------
    kind : {"stereo", "mono"}
        Tracking mode.
    seq : str
        Sequence directory or video file.
    colormodel : str
        Colour model file.
    extra : list of str
        Further command-line options of ``track KIND``.

    Returns
    -------
    dict
        ``exit_code`` (of ``track KIND``: 0, 2 after a stopping error with the rows so far), ``csv``
        (the written CSV's text), ``rows`` (data rows), ``stdout`` (what the command printed).
    """
    from . import build_parser
    with tempfile.TemporaryDirectory(prefix="tudorvision-track-") as d:
        out = Path(d) / "track.csv"
        args = build_parser().parse_args(["track", kind, str(seq), "--colormodel", str(colormodel), "--out",
                                          str(out), *extra])
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            rc = int(args.func(args) or 0)
        text = out.read_text() if out.is_file() else ""
    lines = [ln for ln in text.splitlines() if ln and not ln.startswith("#")]
    return {"exit_code": rc, "csv": text, "rows": max(len(lines) - 1, 0), "stdout": buf.getvalue()}


def _output_names(seqs) -> list[str]:
    names, seen = [], {}
    for s in seqs:
        p = Path(s)
        base = (p.stem if p.is_file() else p.name) or "sequence"
        seen[base] = seen.get(base, 0) + 1
        names.append(base if seen[base] == 1 else f"{base}_{seen[base]}")
    return names


def run_batch(seqs, out, *, kind: str, colormodel, extra=(), scheduler: str | None = "local",
              workers: int | None = None, processes: bool = True, show_progress: bool | None = None,
              dashboard_address: str | None = ":8787") -> dict:
    """Track every sequence on the runner; write ``OUT/<name>.csv`` and ``OUT/batch.csv``.

    Parameters
    ----------
    seqs : sequence of str or Path
        The sequences, in output order.
    out : str or Path
        Output folder.
    kind : {"stereo", "mono"}
        Tracking mode.
    colormodel : str or Path
        Colour model file.
    extra : sequence of str
        Further options of ``track KIND``.
    scheduler : str or None
        ``"serial"``, ``"local"`` or a scheduler address.
    workers : int, optional
        Local cluster size.
    processes : bool
        Local cluster of processes (else threads).
    show_progress : bool or None
        Runner progress on stderr.
    dashboard_address : str or None
        Local cluster's dashboard.

    Returns
    -------
    dict
        ``rows`` (the lines of ``batch.csv`` as dicts), ``complete``, ``interrupted``, ``failed``
        (count), ``runner`` (counts and timing).
    """
    from ..io.atomic import atomic_write, write_text_atomic
    from ..lab.runner import Task, config_digest, run_tasks
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    seqs = [str(s) for s in seqs]
    extra = [str(a) for a in extra]
    digest = config_digest((kind, str(colormodel), tuple(extra)))
    tasks = [Task("track-batch", {"sequence": s, "kind": kind, "options": digest}, 0, track_sequence_task,
                  (kind, s, str(colormodel), extra)) for s in seqs]
    report = run_tasks(tasks, out, scheduler=scheduler, workers=workers, processes=processes,
                       dashboard_address=dashboard_address, show_progress=show_progress, label="track batch")
    rows = []
    for seq, name, rec in zip(seqs, _output_names(seqs), report.records):
        row = {"sequence": seq, "output": "", "rows": "", "exit_code": "", "status": "not run", "error": ""}
        if rec is not None and rec["status"] == "done":
            res = rec["result"]
            write_text_atomic(out / f"{name}.csv", res["csv"])
            row.update(output=f"{name}.csv", rows=res["rows"], exit_code=res["exit_code"],
                       status="done" if res["exit_code"] == 0 else "partial")
        elif rec is not None:
            row.update(status="failed", error=rec["error"])
        rows.append(row)
    with atomic_write(out / "batch.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]) if rows else ["sequence"])
        w.writeheader()
        w.writerows(rows)
    import json
    info = report.info()
    write_text_atomic(out / "runner.json", json.dumps(info, indent=2))
    return {"rows": rows, "complete": report.complete and all(r["status"] == "done" for r in rows),
            "interrupted": report.interrupted, "failed": sum(r["status"] != "done" for r in rows), "runner": info}


def _main(args) -> int:
    from ..lab.runner import parse_scheduler
    seqs = list(args.seqs)
    if args.list:
        lst = Path(args.list)
        if not lst.is_file():
            raise TudorVisionError(f"--list: {lst}: no such file")
        seqs += [ln.strip() for ln in lst.read_text().splitlines() if ln.strip() and not ln.startswith("#")]
    if not seqs:
        raise TudorVisionError("SEQ: give at least one sequence (or --list FILE)")
    for s in seqs:
        if not Path(s).exists():
            raise TudorVisionError(f"{s}: no such file or directory")
    if not Path(args.colormodel).is_file():
        raise TudorVisionError(f"--colormodel: {args.colormodel}: no such file")
    try:
        extra = shlex.split(args.track_args)
    except ValueError as exc:
        raise TudorVisionError(f"--track-args: {exc}") from None
    if args.kind == "mono":
        if not args.sphere:
            raise TudorVisionError("--sphere: required with --kind mono")
        extra = ["--sphere", args.sphere, *extra]
    elif args.sphere:
        raise TudorVisionError("--sphere: only with --kind mono")
    if args.calib:
        if args.kind != "stereo":
            raise TudorVisionError("--calib: only with --kind stereo")
        extra = ["--calib", args.calib, *extra]
    from . import build_parser
    build_parser().parse_args(["track", args.kind, seqs[0], "--colormodel", args.colormodel, "--out", "x.csv",
                               *extra])        # a wrong option stops here, before any task runs
    apply_rerun_stale(args, args.out)
    res = run_batch(seqs, args.out, kind=args.kind, colormodel=args.colormodel, extra=extra,
                    scheduler=parse_scheduler(args.scheduler), workers=args.workers)
    for r in res["rows"]:
        what = (f"{r['output']} ({r['rows']} rows)" if r["status"] in ("done", "partial") else r["status"])
        print(f"{r['sequence']}: {what}" + (f": {r['error']}" if r["error"] else "")
              + (" (stopped early, exit code {})".format(r["exit_code"]) if r["status"] == "partial" else ""))
    print(f"wrote {Path(args.out) / 'batch.csv'}: {len(res['rows']) - res['failed']} of {len(res['rows'])} "
          f"sequences tracked" + (" (interrupted: run the same command again to finish)"
                                  if res["interrupted"] else ""))
    if res["interrupted"]:
        return 130
    return 0 if res["complete"] else 1
