"""The experiment runner: independent runs as tasks, serially or on Dask distributed, resumable.

Every run of an experiment is a :class:`Task` keyed by ``(experiment, params,
seed)``. :func:`run_tasks` runs a list of them

* ``scheduler="serial"``: one after the other in this process;
* ``scheduler="local"``: on a Dask ``LocalCluster`` of ``workers`` processes
  (one thread each; the dashboard address is printed);
* ``scheduler="tcp://host:8786"`` (any address with ``://``): on a running Dask
  scheduler, e.g. one started with ``dask scheduler`` and ``dask worker``,
  Kubernetes or SLURM (dask-jobqueue). The workers need the package installed
  and nothing else: a task's function is a module-level function of the
  package and everything it needs travels as its arguments.

Where and in which order the tasks run does not change their results: a task's
randomness comes from its key only (never a global generator, never Python's
``hash()``), results are turned into plain JSON values on arrival, and
:class:`RunReport` hands them back in the order of the task list. The same
tasks therefore give byte-identical tables in every mode.

Resuming: each finished task's record is written atomically to
``out/runs/<key>.json`` as it arrives. Running the same tasks into the same
folder skips the tasks whose record says ``done``; failed ones are tried
again. A task that raises is tried once more (``retries``), then recorded
with its error, seed and parameters while the others go on. Ctrl-C stops
the run: finished records stay, the report says ``interrupted``, and the
caller writes its summary flagged incomplete.

Progress (done / running / failed, ETA) goes to stderr: a live ``rich`` bar on
a terminal, plain lines otherwise.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import socket
import sys
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..io.atomic import write_text_atomic
from .runner_progress import RunProgress
from .provenance import code_version

__all__ = ["Task", "RunReport", "derive_seed", "config_digest", "to_jsonable", "parse_scheduler", "run_tasks",
           "drop_stale_records",
           "execute_task", "probe_task", "RUNS_DIR"]

#: Folder (inside the output folder) holding one ``<key>.json`` record per finished task.
RUNS_DIR = "runs"

#: The Dask setting that keeps the nanny from setting ``MALLOC_TRIM_THRESHOLD_`` in its workers (``None``);
#: for ``dask worker``: ``--no-nanny``, or a Dask configuration file setting it to ``null`` (docs/experiments.md).
NO_MALLOC_TRIM = "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_"


def to_jsonable(value):
    """Plain JSON values (dict, list, str, int, float, bool, None) for a result.

    NumPy scalars become Python numbers, arrays and tuples become lists,
    dict keys become strings. Floats keep their exact value (``repr``
    round-trips), so a record read back from disk equals the fresh one.

    Parameters
    ----------
    value : object
        A task's result.

    Returns
    -------
    object
        The same data as plain JSON values.

    Raises
    ------
    TypeError
        For a value with no JSON form.

    Examples
    --------
    >>> to_jsonable({"a": np.float64(0.5), "b": np.arange(2), 3: (True, None)})
    {'a': 0.5, 'b': [0, 1], '3': [True, None]}
    """
    if isinstance(value, dict):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return to_jsonable(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value)
    if value is None or isinstance(value, str):
        return value
    raise TypeError(f"task result: {type(value).__name__} has no JSON form")


def _canonical(obj) -> str:
    return json.dumps(to_jsonable(obj), sort_keys=True, separators=(",", ":"))


def config_digest(obj) -> str:
    """A short stable digest of an experiment's configuration (for task parameters).

    Parameters
    ----------
    obj : object
        Anything with a stable ``repr`` (dataclasses, numbers, strings) or JSON form.

    Returns
    -------
    str
        16 hex digits of the SHA-256 of its ``repr``.

    Examples
    --------
    >>> config_digest((1, "a")) == config_digest((1, "a")), len(config_digest(0))
    (True, 16)
    """
    return hashlib.sha256(repr(obj).encode()).hexdigest()[:16]


def derive_seed(experiment: str, params: dict, seed: int) -> int:
    """A 63-bit seed derived from a task's key with SHA-256 (the same on every machine and Python).

    Parameters
    ----------
    experiment : str
        Experiment name.
    params : dict
        The task's parameters (JSON values).
    seed : int
        The experiment's seed.

    Returns
    -------
    int
        In ``[0, 2**63)``.

    Examples
    --------
    >>> derive_seed("demo", {"i": 1}, 0) == derive_seed("demo", {"i": 1}, 0)
    True
    >>> derive_seed("demo", {"i": 1}, 0) != derive_seed("demo", {"i": 2}, 0)
    True
    """
    h = hashlib.sha256(_canonical({"experiment": experiment, "params": params, "seed": int(seed)}).encode())
    return int.from_bytes(h.digest()[:8], "big") >> 1


@dataclass(frozen=True)
class Task:
    """One run of an experiment: the key ``(experiment, params, seed)`` and the call that computes it.

    Parameters
    ----------
    experiment : str
        Experiment name (letters, digits, ``-``, ``_``; it starts the record's file name).
    params : dict
        JSON-able parameters that, with ``seed``, identify the run (and select its random streams).
    seed : int
        The run's seed.
    fn : callable
        A module-level function of the package (picklable by reference); ``fn(*args)`` returns
        JSON-able data (dicts, lists, numbers, strings, NumPy values).
    args : tuple
        Its arguments (models, configurations, file names): all a worker needs.
    """

    experiment: str
    params: dict
    seed: int
    fn: Callable
    args: tuple = field(default=())

    @property
    def key(self) -> str:
        """The record's name, ``<experiment>-<16 hex digits of the key's SHA-256>``.

        Returns
        -------
        str
            The key.
        """
        digest = hashlib.sha256(_canonical({"experiment": self.experiment, "params": self.params,
                                            "seed": int(self.seed)}).encode()).hexdigest()[:16]
        return f"{self.experiment}-{digest}"


@dataclass
class RunReport:
    """What :func:`run_tasks` did.

    Parameters
    ----------
    records : list of dict or None
        One per task, in the task list's order: the record written to
        ``runs/<key>.json`` (``key``, ``experiment``, ``params``, ``seed``,
        ``status`` ``"done"`` or ``"failed"``, ``result``, ``error``,
        ``attempts``, ``duration_s``, ``worker``), ``None`` for a task that
        did not finish (interrupted).
    skipped : int
        Tasks found done in the folder and not run again.
    interrupted : bool
        Ctrl-C (or a lost scheduler) stopped the run.
    scheduler : str
        ``"serial"``, ``"local"`` or the scheduler's address.
    workers : int
        Worker threads the tasks ran on.
    dashboard : str or None
        The Dask dashboard address.
    wall_s : float
        Wall time of :func:`run_tasks`, s.
    reused_other_code : int
        Of the tasks found done, those whose record was made by other code than the running one
        (:func:`~tudorvision.lab.provenance.code_version`; records written before it was stamped count too).
    """

    records: list
    skipped: int = 0
    interrupted: bool = False
    scheduler: str = "serial"
    workers: int = 1
    dashboard: str | None = None
    reused_other_code: int = 0
    wall_s: float = 0.0

    @property
    def done(self) -> list:
        """Records of the tasks that finished without error, in task order.

        Returns
        -------
        list of dict
            The records.
        """
        return [r for r in self.records if r is not None and r["status"] == "done"]

    @property
    def failed(self) -> list:
        """Records of the tasks that raised on every attempt, in task order.

        Returns
        -------
        list of dict
            The records.
        """
        return [r for r in self.records if r is not None and r["status"] == "failed"]

    @property
    def complete(self) -> bool:
        """Every task finished without error and the run was not interrupted.

        Returns
        -------
        bool
            Complete.
        """
        return not self.interrupted and all(r is not None and r["status"] == "done" for r in self.records)

    def info(self) -> dict:
        """Counts and timing of the run (what differs between modes; kept out of the summaries).

        Returns
        -------
        dict
            ``tasks``, ``done``, ``failed``, ``not_run``, ``skipped``, ``interrupted``, ``complete``,
            ``scheduler``, ``workers``, ``dashboard``, ``wall_s``, ``task_s_mean`` (mean duration of the
            tasks run now), ``failures`` (key, seed, params, error of each failed task),
            ``reused_other_code``.
        """
        ran = [r["duration_s"] for r in self.records if r is not None and r.get("ran_now")]
        return {"tasks": len(self.records), "done": len(self.done), "failed": len(self.failed),
                "not_run": sum(r is None for r in self.records), "skipped": self.skipped,
                "interrupted": self.interrupted, "complete": self.complete, "scheduler": self.scheduler,
                "workers": self.workers, "dashboard": self.dashboard, "wall_s": self.wall_s,
                "task_s_mean": float(np.mean(ran)) if ran else None,
                "failures": [{k: r[k] for k in ("key", "seed", "params", "error")} for r in self.failed],
                "reused_other_code": self.reused_other_code}


def parse_scheduler(scheduler: str | None) -> str:
    """Check a ``--scheduler`` value.

    Parameters
    ----------
    scheduler : str or None
        ``"serial"``, ``"local"`` or an address such as ``tcp://host:8786``; ``None``: ``"local"``.

    Returns
    -------
    str
        The value.

    Raises
    ------
    ValueError
        On anything else.

    Examples
    --------
    >>> parse_scheduler("tcp://127.0.0.1:8786")
    'tcp://127.0.0.1:8786'
    """
    s = "local" if scheduler is None else str(scheduler).strip()
    if s in ("serial", "local") or ("://" in s and s.split("://", 1)[1]):
        return s
    raise ValueError(f"--scheduler: expected serial, local or a scheduler address such as tcp://host:8786, "
                     f"got {scheduler!r}")


def execute_task(fn: Callable, args: tuple) -> dict:
    """Run ``fn(*args)`` on a worker and catch its error (Ctrl-C and exits pass through).

    Parameters
    ----------
    fn : callable
        The task's function.
    args : tuple
        Its arguments.

    Returns
    -------
    dict
        ``ok`` (bool), ``result`` (JSON values) or ``error`` (the exception's last line and traceback),
        ``duration_s``, ``worker`` (host name and process id).
    """
    t0 = time.perf_counter()
    where = f"{socket.gethostname()}:{os.getpid()}"
    try:
        result = to_jsonable(fn(*args))
    except Exception as exc:
        text = traceback.format_exc(limit=20)
        msg = f"{type(exc).__name__}: {exc}".splitlines()[0]
        return {"ok": False, "error": msg, "traceback": text, "duration_s": time.perf_counter() - t0,
                "worker": where}
    return {"ok": True, "result": result, "duration_s": time.perf_counter() - t0, "worker": where}


def probe_task(seed: int, sleep_s: float = 0.0, fail: str | None = None) -> dict:
    """A cheap task for tests and the overhead benchmark: a few numbers drawn from ``seed``.

    Parameters
    ----------
    seed : int
        Seed of the draw.
    sleep_s : float
        Sleep first, s.
    fail : str or None
        ``"raise"``: raise ``ValueError``; ``"interrupt"``: raise ``KeyboardInterrupt``;
        ``"once:PATH"``: raise unless ``PATH`` exists, creating it (fails the first attempt only).

    Returns
    -------
    dict
        ``seed`` and ``draw`` (three normal samples).

    Raises
    ------
    ValueError
        As asked by ``fail``.
    KeyboardInterrupt
        As asked by ``fail``.

    Examples
    --------
    >>> bool((probe_task(1)["draw"] == probe_task(1)["draw"]).all())
    True
    """
    if sleep_s > 0:
        time.sleep(sleep_s)
    if fail == "raise":
        raise ValueError(f"probe task {seed} raised as asked")
    if fail == "interrupt":
        raise KeyboardInterrupt
    if fail is not None and fail.startswith("once:"):
        flag = Path(fail[5:])
        if not flag.exists():
            flag.write_text("failed once\n")
            raise ValueError(f"probe task {seed} fails its first attempt")
    return {"seed": int(seed), "draw": np.random.default_rng(seed).standard_normal(3)}


def _record_path(out: Path, key: str) -> Path:
    return out / RUNS_DIR / f"{key}.json"


def _load_done(out: Path, task: Task) -> dict | None:
    path = _record_path(out, task.key)
    try:
        rec = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if (rec.get("status") != "done" or rec.get("experiment") != task.experiment or rec.get("seed") != task.seed
            or _canonical(rec.get("params")) != _canonical(task.params)):
        return None
    return rec


class _Book:
    """Bookkeeping shared by the serial and Dask loops: attempts, records, progress."""

    def __init__(self, tasks, out: Path, retries: int, progress: RunProgress, on_record, code: str = ""):
        self.tasks, self.out, self.retries, self.progress = tasks, out, retries, progress
        self.code = code
        self.on_record = on_record
        self.records: list = [None] * len(tasks)
        self.attempts = [0] * len(tasks)
        self.errors: list = [None] * len(tasks)

    def finish(self, i: int, outcome: dict) -> bool:
        """Store one attempt's outcome; ``True`` when the task should be tried again."""
        t = self.tasks[i]
        self.attempts[i] += 1
        if not outcome["ok"] and self.attempts[i] <= self.retries:
            self.errors[i] = outcome
            self.progress.retry(t.key, outcome["error"])
            return True
        rec = {"key": t.key, "experiment": t.experiment, "params": to_jsonable(t.params), "seed": int(t.seed),
               "status": "done" if outcome["ok"] else "failed",
               "result": json.loads(json.dumps(outcome["result"])) if outcome["ok"] else None,
               "error": None if outcome["ok"] else outcome["error"],
               "traceback": None if outcome["ok"] else outcome.get("traceback"),
               "attempts": self.attempts[i], "duration_s": float(outcome["duration_s"]),
               "worker": outcome.get("worker"), "code": self.code}
        write_text_atomic(_record_path(self.out, t.key), json.dumps(rec, indent=1))
        rec["ran_now"] = True
        self.records[i] = rec
        self.progress.finished(ok=outcome["ok"], duration_s=rec["duration_s"], key=t.key, error=rec["error"])
        if self.on_record is not None:
            self.on_record(rec)
        return False


def drop_stale_records(out, code: str | None = None) -> list:
    """Delete the task records under ``out`` (every ``runs/`` folder below it) made by other code.

    A resumed run keys its tasks by their configuration, not the code, so it would reuse them; after
    this they run again. Records without a ``code`` count as other code; unreadable files are left.

    Parameters
    ----------
    out : str or Path
        An output folder of :func:`run_tasks` (nested runs, e.g. ``reproduce``'s sections, included).
    code : str, optional
        The running code (default :func:`~tudorvision.lab.provenance.code_version`).

    Returns
    -------
    list of Path
        The records deleted.
    """
    code = code_version() if code is None else str(code)
    gone = []
    for path in sorted(Path(out).rglob(f"{RUNS_DIR}/*.json")):
        try:
            rec = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if isinstance(rec, dict) and "experiment" in rec and rec.get("code") != code:
            path.unlink()
            gone.append(path)
    return gone


def run_tasks(tasks, out, *, scheduler: str | None = "serial", workers: int | None = None, retries: int = 1,
              processes: bool = True, dashboard_address: str | None = ":8787", show_progress: bool | None = None,
              label: str = "tasks", on_record: Callable | None = None, stream=None,
              code: str | None = None) -> RunReport:
    """Run tasks serially or on Dask, skipping those already done in ``out``; write each record as it arrives.

    Parameters
    ----------
    tasks : sequence of Task
        The runs (distinct keys).
    out : str or Path
        Output folder; records go to ``out/runs/<key>.json``.
    scheduler : str or None
        ``"serial"``, ``"local"`` (a ``LocalCluster``) or a running scheduler's address
        (``tcp://host:8786``); ``None``: ``"local"``.
    workers : int, optional
        ``"local"``: worker processes (default: the machine's cores). Ignored otherwise.
    retries : int
        Further attempts for a task that raised.
    processes : bool
        ``"local"``: worker processes (``True``) or threads in this process.
    dashboard_address : str or None
        ``"local"``: where the dashboard listens (``":0"``: any free port; ``None``: no dashboard).
    show_progress : bool or None
        Progress on stderr: ``None``: a live bar on a terminal, a plain line every few seconds otherwise;
        ``False``: nothing.
    label : str
        Name shown in the progress lines.
    on_record : callable, optional
        ``f(record)`` after each record is written (in arrival order).
    stream : file, optional
        Where progress goes (default ``sys.stderr``).
    code : str, optional
        The code version stamped on each record (``code``) and compared with the reused ones; default
        :func:`~tudorvision.lab.provenance.code_version`.

    Returns
    -------
    RunReport
        Records in task order, counts, ``interrupted``.

    Raises
    ------
    ValueError
        On a bad ``scheduler`` or ``workers``, or duplicate task keys.
    OSError
        When the scheduler cannot be reached.
    """
    t_start = time.perf_counter()
    tasks = list(tasks)
    scheduler = parse_scheduler(scheduler)
    if workers is not None and workers < 1:
        raise ValueError(f"--workers: expected >= 1, got {workers}")
    keys = [t.key for t in tasks]
    if len(set(keys)) != len(keys):
        raise ValueError("tasks: two tasks share a key (experiment, params, seed)")
    out = Path(out)
    (out / RUNS_DIR).mkdir(parents=True, exist_ok=True)
    progress = RunProgress(len(tasks), label=label, enabled=show_progress, stream=stream or sys.stderr)
    code = code_version() if code is None else str(code)
    book = _Book(tasks, out, max(int(retries), 0), progress, on_record, code)
    todo, other = [], []
    for i, t in enumerate(tasks):
        rec = _load_done(out, t)
        if rec is None:
            todo.append(i)
        else:
            book.records[i] = rec
            if rec.get("code") != code:
                other.append(rec.get("code") or "unrecorded")
    skipped = len(tasks) - len(todo)
    progress.skipped(skipped)
    if other:
        # resumable by design (the key is the task, not the code): say so when the code has changed since
        print(f"{label}: {len(other)} of the {skipped} finished task(s) reused from {out / RUNS_DIR} were made "
              f"by other code ({', '.join(sorted(set(other)))}; now {code}); --rerun-stale (or deleting those records) "
              f"runs them again", file=stream or sys.stderr)
    report = RunReport(records=book.records, skipped=skipped, scheduler=scheduler, reused_other_code=len(other))
    ended = False
    try:
        if scheduler == "serial" or not todo:
            report.workers = 1
            progress.start(running=min(1, len(todo)))
            _run_serial(book, todo)
        else:
            _run_dask(book, todo, report, scheduler=scheduler, workers=workers, processes=processes,
                      dashboard_address=dashboard_address)
        ended = True
    except KeyboardInterrupt:
        report.interrupted = ended = True
    finally:
        progress.close(interrupted=report.interrupted, silent=not ended)
    report.wall_s = time.perf_counter() - t_start
    return report


def _run_serial(book: _Book, todo) -> None:
    for n, i in enumerate(todo):
        t = book.tasks[i]
        while True:
            outcome = execute_task(t.fn, t.args)
            book.progress.n_running = min(1, len(todo) - n - 1)
            if not book.finish(i, outcome):
                break


def _run_dask(book: _Book, todo, report: RunReport, *, scheduler, workers, processes, dashboard_address) -> None:
    import logging
    import warnings

    import dask
    from dask.distributed import Client, LocalCluster, as_completed

    cluster = None
    if scheduler == "local":
        n = int(workers or os.cpu_count() or 1)
        # Dask's nanny sets MALLOC_TRIM_THRESHOLD_ in its workers, which turns off glibc's adaptive mmap
        # threshold: every large NumPy temporary is then mapped and unmapped again, and the lab's image-sized
        # arrays ran 2-3 times slower in a worker than in this process. Workers keep glibc's default.
        with warnings.catch_warnings(), dask.config.set({NO_MALLOC_TRIM: None}):
            # 'port 8787 is already in use': another port is taken and printed
            warnings.filterwarnings("ignore", message=".*already in use", category=UserWarning)
            cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=processes,
                                   dashboard_address=dashboard_address or ":0", silence_logs=logging.ERROR)
        client = Client(cluster, set_as_default=False)
        if dashboard_address is not None:
            report.dashboard = cluster.dashboard_link
    else:
        try:
            client = Client(scheduler, timeout="15s", set_as_default=False)
        except (OSError, TimeoutError) as exc:
            raise OSError(f"--scheduler: cannot reach {scheduler} ({exc})") from None
        report.dashboard = client.dashboard_link
    try:
        if scheduler != "local":
            try:
                client.wait_for_workers(1, timeout=60)
            except TimeoutError:
                raise OSError(f"--scheduler: no worker joined {scheduler} within 60 s") from None
        report.workers = max(sum(client.nthreads().values()), 1)
        book.progress.dashboard(report.dashboard)
        which = {}

        def submit(i):
            t = book.tasks[i]
            fut = client.submit(execute_task, t.fn, t.args, key=f"{t.key}-a{book.attempts[i]}", pure=False)
            which[fut.key] = i
            return fut

        ac = as_completed([submit(i) for i in todo], loop=client.loop)
        pending = len(todo)
        book.progress.start(running=min(pending, report.workers))
        try:
            for fut in ac:
                i = which.pop(fut.key)
                if fut.status == "finished":
                    outcome = fut.result()
                else:   # the worker died, or the task could not be unpickled there
                    exc = fut.exception()
                    outcome = {"ok": False, "error": f"{type(exc).__name__}: {exc}".splitlines()[0],
                               "traceback": None, "duration_s": math.nan, "worker": None}
                fut.release()
                book.progress.n_running = min(max(pending - 1, 0), report.workers)
                if book.finish(i, outcome):
                    ac.add(submit(i))
                else:
                    pending -= 1
                book.progress.running(min(pending, report.workers))
        except BaseException:
            client.cancel(list(ac.futures))
            raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
