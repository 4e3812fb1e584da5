"""The experiment runner (issue 17): identical results in every mode, resumable, failures kept apart.

* probe tasks: serial and a threaded local cluster give the same records; a
  task that raises is retried once, recorded with its error and seed, and the
  others complete; a task that raises ``KeyboardInterrupt`` stops the run with
  the finished records kept, and the re-run finishes it with the same results;
* the servo repeatability study (4 short runs): serial and a local cluster of
  two worker *processes* write byte-identical ``runs.csv`` and ``summary.json``;
  a run killed after two tasks and resumed on a cluster gives the same bytes;
* the catch demo in sessions (4 throws): serial, threaded cluster and the CLI
  give the same ``throws.csv`` and ``summary.json``; Ctrl-C in the second
  session leaves the first one's throws and a summary flagged incomplete
  (exit 130), and the re-run completes it with the same bytes;
* ``track batch`` over synthetic mono sequences matches ``track mono`` per
  sequence and reports the broken one;
* an external ``dask scheduler`` + ``dask worker`` on loopback runs the same
  tasks with the same results.
"""
from __future__ import annotations

import filecmp
import json
import os
import shutil
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from tudorvision.cli import main
from tudorvision.lab.runner import RUNS_DIR, Task, derive_seed, parse_scheduler, probe_task, run_tasks

import tudorvision

ROOT = Path(tudorvision.__file__).resolve().parents[1]        # the tree under test, for the external worker
DASK = Path(sys.executable).with_name("dask")


def _probe_tasks(n=6, fail=None):
    """``n`` probe tasks; ``fail`` maps an index to probe_task's ``fail`` argument (not part of the key)."""
    fail = fail or {}
    return [Task("probe", {"i": i}, derive_seed("probe", {"i": i}, 7), probe_task,
                 (derive_seed("probe", {"i": i}, 7), 0.0, fail.get(i))) for i in range(n)]


def _results(report):
    return [None if r is None else (r["key"], r["status"], r["result"], r["error"]) for r in report.records]


def _same_files(a: Path, b: Path, names) -> None:
    for name in names:
        assert filecmp.cmp(a / name, b / name, shallow=False), name


# ----------------------------------------------------------------------------- probe tasks
def test_serial_and_local_cluster_agree_and_a_raising_task_is_kept_apart(tmp_path):
    tasks = _probe_tasks(6, fail={2: "raise", 4: f"once:{tmp_path / 'flag'}"})
    serial = run_tasks(tasks, tmp_path / "serial", scheduler="serial", show_progress=False)
    (tmp_path / "flag").unlink()
    local = run_tasks(tasks, tmp_path / "local", scheduler="local", workers=2, processes=False,
                      dashboard_address=None, show_progress=False)
    assert _results(serial) == _results(local)
    for rep in (serial, local):
        assert not rep.complete and not rep.interrupted
        assert [r["status"] for r in rep.records] == ["done", "done", "failed", "done", "done", "done"]
        bad = rep.failed[0]
        assert bad["attempts"] == 2 and bad["error"] == f"ValueError: probe task {tasks[2].seed} raised as asked"
        assert bad["seed"] == tasks[2].seed and bad["params"] == {"i": 2} and "Traceback" in bad["traceback"]
        assert rep.records[4]["attempts"] == 2      # failed once, then done
        assert rep.info()["failures"] == [{"key": bad["key"], "seed": bad["seed"], "params": {"i": 2},
                                           "error": bad["error"]}]
    # every record is on disk under its key; the draws come from the key's seed only
    rec = json.loads((tmp_path / "local" / RUNS_DIR / f"{tasks[0].key}.json").read_text())
    assert rec["result"]["draw"] == np.random.default_rng(tasks[0].seed).standard_normal(3).tolist()
    # a re-run retries the failed task only (it raises again) and skips the rest
    again = run_tasks(tasks[:2] + [tasks[2]], tmp_path / "serial", scheduler="serial", show_progress=False)
    assert again.skipped == 2 and [r["status"] for r in again.records] == ["done", "done", "failed"]


def test_ctrl_c_keeps_the_finished_records_and_the_rerun_finishes(tmp_path, capsys):
    fresh = run_tasks(_probe_tasks(6), tmp_path / "fresh", scheduler="serial", show_progress=False)
    rep = run_tasks(_probe_tasks(6, fail={3: "interrupt"}), tmp_path / "out", scheduler="serial")
    assert rep.interrupted and not rep.complete
    assert [r is not None for r in rep.records] == [True, True, True, False, False, False]
    assert "interrupted; the finished runs are kept" in capsys.readouterr().err
    assert len(list((tmp_path / "out" / RUNS_DIR).glob("*.json"))) == 3
    resumed = run_tasks(_probe_tasks(6), tmp_path / "out", scheduler="local", workers=2, processes=False,
                        dashboard_address=None, show_progress=False)
    assert resumed.skipped == 3 and resumed.complete
    assert _results(resumed) == _results(fresh)


def test_resumed_records_made_by_other_code_are_reused_and_named(tmp_path, capsys, monkeypatch):
    import tudorvision.lab.runner as runner_mod
    from tudorvision.lab.provenance import code_version

    first = run_tasks(_probe_tasks(3), tmp_path, scheduler="serial", show_progress=False)
    assert first.reused_other_code == 0
    rec = json.loads((tmp_path / RUNS_DIR / f"{first.records[0]['key']}.json").read_text())
    assert rec["code"] == code_version()
    again = run_tasks(_probe_tasks(3), tmp_path, scheduler="serial", show_progress=False)
    assert again.skipped == 3 and again.reused_other_code == 0 and "other code" not in capsys.readouterr().err
    monkeypatch.setattr(runner_mod, "code_version", lambda: "9.9 (git abc1234)")
    later = run_tasks(_probe_tasks(4), tmp_path, scheduler="serial", show_progress=False, label="probe")
    err = capsys.readouterr().err
    assert later.skipped == 3 and later.reused_other_code == 3 and later.info()["reused_other_code"] == 3
    assert "probe: 3 of the 3 finished task(s)" in err and code_version() in err and "9.9 (git abc1234)" in err
    assert _results(later)[:3] == _results(first)           # reused as they were, not run again


def test_drop_stale_records_makes_other_code_run_again(tmp_path, capsys):
    """--rerun-stale: records of other code (also in nested runs/ folders) are deleted, then run again;
    the running code's records, other JSON files and unreadable ones stay."""
    from tudorvision.cli import main as cli_main
    from tudorvision.lab.runner import drop_stale_records

    run_tasks(_probe_tasks(3), tmp_path, scheduler="serial", show_progress=False, code="old")
    run_tasks(_probe_tasks(2), tmp_path / "section" / "sessions", scheduler="serial", show_progress=False,
              code="new")
    (tmp_path / RUNS_DIR / "notes.json").write_text('{"what": "not a record"}')
    (tmp_path / RUNS_DIR / "broken.json").write_text("{not json")
    gone = drop_stale_records(tmp_path, code="new")
    assert sorted(p.parent for p in gone) == [tmp_path / RUNS_DIR] * 3
    assert sorted(p.name for p in (tmp_path / RUNS_DIR).iterdir()) == ["broken.json", "notes.json"]
    assert len(list((tmp_path / "section" / "sessions" / RUNS_DIR).glob("*.json"))) == 2
    rep = run_tasks(_probe_tasks(3), tmp_path, scheduler="serial", show_progress=False, code="new")
    assert rep.skipped == 0 and rep.complete and rep.reused_other_code == 0
    assert drop_stale_records(tmp_path, code="new") == []
    # the command line: only where the runner runs
    assert cli_main(["catch", "demo", "--rerun-stale", "--out", str(tmp_path / "c")]) != 0
    assert "--rerun-stale: only on the runner" in capsys.readouterr().err


def test_bad_scheduler_and_duplicate_keys(tmp_path):
    with pytest.raises(ValueError, match="--scheduler"):
        parse_scheduler("cluster")
    t = _probe_tasks(1)
    with pytest.raises(ValueError, match="share a key"):
        run_tasks(t + t, tmp_path, show_progress=False)
    assert main(["catch", "demo", "--no-render", "--scheduler", "bogus", "--out", str(tmp_path / "c")]) == 2


# ----------------------------------------------------------------------------- servo repeatability
@pytest.fixture(scope="module")
def servo_plan():
    from tudorvision.lab.servo_experiments import plan_repeatability
    from tudorvision.lab.servo_lab import LabConfig
    cfg = replace(LabConfig(), t_max_s=0.4)
    return plan_repeatability(repetitions=1, seed=3, laws=("hybrid",), payloads_g=(200,), cfg=cfg)


def test_servo_study_serial_vs_worker_processes_and_resumed(servo_plan, tmp_path):
    from tudorvision.lab.servo_experiments import write_repeatability
    tasks, ctx = servo_plan
    assert len(tasks) == 8
    tasks = tasks[::2]        # poses 0, 2 (near) and 4, 6 (far)
    a = tmp_path / "serial"
    write_repeatability(a, ctx, run_tasks(tasks, a, scheduler="serial", show_progress=False))
    b = tmp_path / "processes"
    rep = run_tasks(tasks, b, scheduler="local", workers=2, processes=True, dashboard_address=None,
                    show_progress=False)
    assert rep.complete and len({r["worker"] for r in rep.records}) == 2    # both worker processes ran tasks
    s = write_repeatability(b, ctx, rep)
    _same_files(a, b, ["runs.csv", "summary.json"])
    assert s["complete"] and s["runs_done"] == 4 and "wall_s" not in json.loads((b / "summary.json").read_text())
    # a run killed after two runs holds their records only (as the serial run wrote them); resumed on a
    # threaded cluster it gives the same bytes as the uninterrupted run
    c = tmp_path / "resumed"
    (c / RUNS_DIR).mkdir(parents=True)
    for t in tasks[:2]:
        shutil.copy(a / RUNS_DIR / f"{t.key}.json", c / RUNS_DIR)
    rest = run_tasks(tasks, c, scheduler="local", workers=2, processes=False, dashboard_address=None,
                     show_progress=False)
    assert rest.skipped == 2
    write_repeatability(c, ctx, rest)
    _same_files(a, c, ["runs.csv", "summary.json"])
    rows = (a / "runs.csv").read_text().splitlines()
    assert rows[0].startswith("law,payload_g,pose") and len(rows) == 5
    assert [r.split(",")[2] for r in rows[1:]] == ["0", "2", "4", "6"]


# ----------------------------------------------------------------------------- catch sessions
def test_catch_sessions_serial_local_cli_and_ctrl_c_agree(tmp_path, capsys, monkeypatch):
    from tudorvision.lab.catch import DemoOptions, run_sessions, sessions
    opts = DemoOptions(throws=4, seed=2, render=False)
    s1 = run_sessions(tmp_path / "serial", opts, session_throws=2, scheduler="serial")
    s2 = run_sessions(tmp_path / "local", opts, session_throws=2, scheduler="local", workers=2, processes=False,
                      dashboard_address=None)
    assert s1["complete"] and s1["throws_done"] == 4 and s1["sessions"] == 2
    assert [r["session_seed"] for r in s1["per_throw"]] == [2000] * 2 + [2001] * 2
    _same_files(tmp_path / "serial", tmp_path / "local", ["throws.csv", "summary.json"])
    assert s2["per_throw"] == s1["per_throw"]
    argv = ["catch", "demo", "--no-render", "--throws", "4", "--seed", "2", "--session-throws", "2",
            "--scheduler", "serial", "--out", str(tmp_path / "cli")]
    real = sessions.catch_session_task

    def ctrl_c_in_session_1(options):
        if options.seed == 2001:
            raise KeyboardInterrupt
        return real(options)

    monkeypatch.setattr(sessions, "catch_session_task", ctrl_c_in_session_1)
    assert main(argv) == 130
    killed = json.loads((tmp_path / "cli" / "summary.json").read_text())
    assert killed["interrupted"] and not killed["complete"] and killed["throws_done"] == 2
    assert len((tmp_path / "cli" / "throws.csv").read_text().splitlines()) == 3
    monkeypatch.setattr(sessions, "catch_session_task", real)
    assert main(argv) == 0
    _same_files(tmp_path / "serial", tmp_path / "cli", ["throws.csv", "summary.json"])
    capsys.readouterr()
    assert main(argv) == 0                      # everything done: skipped, same files
    assert "2 of 2 already done" in capsys.readouterr().err
    _same_files(tmp_path / "serial", tmp_path / "cli", ["throws.csv", "summary.json"])


def test_catch_sessions_take_the_calibrations_in_turn(tmp_path, capsys, monkeypatch):
    """``calibrations=K``: session b calibrates with calibration_seed + b % K; K = 1 keeps the old tasks."""
    from tudorvision.lab.catch import DemoOptions, run_sessions, sessions
    opts = DemoOptions(throws=7, seed=3, render=False, calibration_seed=5)
    one, three = sessions.plan_sessions(opts, 2), sessions.plan_sessions(opts, 2, calibrations=3)
    assert [t.args[0].calibration_seed for t in one] == [5, 5, 5, 5]
    assert [t.args[0].calibration_seed for t in three] == [5, 6, 7, 5]
    assert [t.args[0].seed for t in three] == [t.args[0].seed for t in one] == [3000, 3001, 3002, 3003]
    assert all("calibrations" not in t.params for t in one) and all(t.params["calibrations"] == 3 for t in three)
    assert not {t.key for t in one} & {t.key for t in three}        # a K-calibration run never reuses K = 1 records
    for bad in (0, 1.5):
        with pytest.raises(ValueError, match="--calibrations"):
            sessions.plan_sessions(opts, 2, calibrations=bad)

    def fake_session(options):          # the calibration each session was given, its error a function of it
        return {"per_throw": [], "balls_in_net": 0, "net_emptied": 0, "setpoints_not_acknowledged": 0,
                "layer_faults_cleared": 0,
                "calibration": {"calibration_seed": options.calibration_seed,
                                "error_at_arm_m": 0.001 * options.calibration_seed}}

    monkeypatch.setattr(sessions, "catch_session_task", fake_session)
    s = run_sessions(tmp_path / "k3", opts, session_throws=2, calibrations=3, scheduler="serial")
    assert s["complete"] and s["calibration_error_at_arm_m"] == {"5": 0.005, "6": 0.006, "7": 0.007}
    assert "calibration_error_at_arm_m" not in run_sessions(tmp_path / "k1", opts, session_throws=2,
                                                            scheduler="serial")
    assert main(["catch", "demo", "--no-render", "--throws", "2", "--calibrations", "0",
                 "--out", str(tmp_path / "cli")]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--calibrations: expected >= 1, got 0" in err[0]
    assert main(["catch", str(tmp_path), "--calibrations", "2"]) != 0
    assert "only with 'catch demo'" in capsys.readouterr().err


# ----------------------------------------------------------------------------- track batch
def _ball_image(u):
    img = np.full((60, 80, 3), 90, np.uint8)
    cv2.circle(img, (u, 30), 10, (0, 0, 255), -1)
    return img


def test_track_batch_matches_track_mono_and_reports_a_broken_sequence(tmp_path, capsys):
    from tudorvision.cli.batch import run_batch
    from tudorvision.io import SequenceWriter
    from tudorvision.stereo.colormodel import fit_color_model_set, save_color_models
    seqs = []
    for j in range(2):
        d = tmp_path / f"seq{j}"
        with SequenceWriter(d, kind="mono", rate_hz=10.0, image_ext=".png") as wr:
            for k in range(5):
                wr.add_mono(k / 10.0, _ball_image(25 + 4 * k + 3 * j))
        seqs.append(d)
    broken = tmp_path / "broken"
    broken.mkdir()
    models = tmp_path / "models.yaml"
    save_color_models(fit_color_model_set({"mono": _ball_image(40)}, ["mono:red:40,30:50,30"]), models)
    single = tmp_path / "single.csv"
    assert main(["track", "mono", str(seqs[1]), "--colormodel", str(models), "--sphere", "red",
                 "--out", str(single)]) == 0
    rc = main(["track", "batch", *map(str, seqs + [broken]), "--kind", "mono", "--colormodel", str(models),
               "--sphere", "red", "--out", str(tmp_path / "serial"), "--scheduler", "serial"])
    assert rc == 1                              # one sequence failed, the others are written
    assert (tmp_path / "serial" / "seq1.csv").read_text() == single.read_text()
    assert "broken: failed" in capsys.readouterr().out
    res = run_batch(seqs + [broken], tmp_path / "local", kind="mono", colormodel=models, extra=["--sphere", "red"],
                    scheduler="local", workers=2, processes=False, dashboard_address=None, show_progress=False)
    assert not res["complete"] and res["failed"] == 1
    _same_files(tmp_path / "serial", tmp_path / "local", ["seq0.csv", "seq1.csv", "batch.csv"])
    lines = (tmp_path / "serial" / "batch.csv").read_text().splitlines()
    assert lines[0] == "sequence,output,rows,exit_code,status,error"
    assert lines[1].endswith("seq0.csv,5,0,done,") and ",failed," in lines[3]


# ----------------------------------------------------------------------------- external scheduler
def test_external_dask_scheduler_and_worker_on_loopback(tmp_path):
    # about 10 s on an idle 2-core machine (the scheduler's and the worker's start-up), 30 s under load
    if not DASK.exists():
        pytest.skip("no dask command next to the Python interpreter")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
           "OMP_NUM_THREADS": "1"}
    sched_file = tmp_path / "scheduler.json"
    procs = []
    try:
        procs.append(subprocess.Popen([str(DASK), "scheduler", "--host", "127.0.0.1", "--port", "0",
                                       "--no-dashboard", "--scheduler-file", str(sched_file)],
                                      env=env, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        t0 = time.monotonic()
        while not sched_file.exists() and time.monotonic() - t0 < 30:
            time.sleep(0.1)
        address = json.loads(sched_file.read_text())["address"]
        procs.append(subprocess.Popen([str(DASK), "worker", address, "--nthreads", "1", "--nworkers", "1",
                                       "--no-dashboard", "--host", "127.0.0.1"],
                                      env=env, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        assert address.startswith("tcp://127.0.0.1:")
        tasks = _probe_tasks(5, fail={1: "raise"})
        remote = run_tasks(tasks, tmp_path / "remote", scheduler=address, show_progress=False)
        serial = run_tasks(tasks, tmp_path / "serial", scheduler="serial", show_progress=False)
        assert _results(remote) == _results(serial) and len(remote.failed) == 1
        assert remote.records[0]["worker"].split(":")[1] != str(os.getpid())
        again = run_tasks(tasks, tmp_path / "remote", scheduler=address, show_progress=False)
        assert again.skipped == 4 and _results(again) == _results(serial)
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in reversed(procs):
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


def test_twenty_throw_catch_run_identical_serial_and_on_two_worker_processes(tmp_path):
    """Issue 17's catch case at its size: 20 throws in 4 sessions, serial vs a 2-process local cluster."""
    from tudorvision.lab.catch import DemoOptions, run_sessions
    opts = DemoOptions(throws=20, seed=5, render=False)
    s1 = run_sessions(tmp_path / "serial", opts, session_throws=5, scheduler="serial")
    s2 = run_sessions(tmp_path / "local", opts, session_throws=5, scheduler="local", workers=2,
                      dashboard_address=None)
    assert s1["complete"] and s2["complete"] and s1["throws_done"] == 20 and s1["sessions"] == 4
    _same_files(tmp_path / "serial", tmp_path / "local", ["throws.csv", "summary.json"])
    assert s2["per_throw"] == s1["per_throw"]
