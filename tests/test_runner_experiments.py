"""The chapter-8 and collision benchmarks on the experiment runner (issue 17).

* chapter 8 (experiment 06, undamped and proportional, 2 repetitions, 3 s): the
  serial run and a local cluster of two worker processes write byte-identical
  per-run rows (``runs.csv``) and summaries (``ch8_metrics.csv``/``.md``,
  ``meta.json``); every run uses the dominant frequency of the undamped
  seed-0 run, computed here directly; a run with one record lost (killed before it was written)
  resumes, runs only that task and writes the same bytes;
* collision (a small model fitted here, ``--reuse``; false-positive runs of all
  payloads and the two contact scenarios without detection): serial and
  a two-process cluster write the same ``collision.json``, ``collision.md`` and
  ``contacts.csv``; a resumed run with a lost contact record writes the same
  summary.
"""
from __future__ import annotations

import filecmp
import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from tudorvision.joint.strain_dynamics import fit_strain_dynamics
from tudorvision.lab.ch8_experiments import ch8_task, dominant_freq, resolve_runs, run_experiment
from tudorvision.lab.collision_experiments import CollisionSetup, identification_run
from tudorvision.lab.runner import RUNS_DIR

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import bench_collision  # noqa: E402
import bench_damping_ch8  # noqa: E402

CH8_ARGS = ["--plant", "one-way", "--reps", "2", "--experiments", "06", "--laws", "proportional",
            "--horizon", "3", "--quiet"]
CH8_FILES = ("runs.csv", "ch8_metrics.csv", "ch8_metrics.md", "meta.json")


def _same(a: Path, b: Path, names) -> None:
    for name in names:
        assert filecmp.cmp(a / name, b / name, shallow=False), name


def _records(folder: Path) -> list:
    return sorted((folder / RUNS_DIR).glob("*.json"))


@pytest.fixture(scope="module")
def ch8_serial(tmp_path_factory):
    out = tmp_path_factory.mktemp("ch8") / "serial"
    assert bench_damping_ch8.main(CH8_ARGS + ["--scheduler", "serial", "--out", str(out)]) == 0
    return out / "one-way"


def test_ch8_serial_rows_follow_the_runs(ch8_serial):
    rows = (ch8_serial / "runs.csv").read_text().splitlines()
    assert [r.split(",")[:3] for r in rows[1:]] == [["06", "off", "0"], ["06", "off", "1"],
                                                    ["06", "proportional", "0"], ["06", "proportional", "1"]]
    # the reference frequency is the undamped seed-0 run's own, and every run of the experiment uses it
    r = run_experiment("06", "off", (0.0, 0.0, 0.0), plant="one-way", noise=2e-6, seed=0, horizon_s=3.0)
    freq = dominant_freq(r["t"], r["eps_dynamic"])
    assert {float(row.split(",")[3]) for row in rows[1:]} == {freq}
    # damping works: the undamped strain never settles within the 3 s, the damped one does
    table = (ch8_serial / "ch8_metrics.csv").read_text().splitlines()
    online = {row.split(",")[2]: float(row.split(",")[7]) for row in table[1:] if row.startswith("online")}
    assert online["off"] == 100.0 and online["proportional"] < 95.0      # strain_settling_s_pct
    info = json.loads((ch8_serial / "runner.json").read_text())
    assert info["complete"] and info["scheduler"] == "serial"
    assert len(_records(ch8_serial)) == 4


def test_ch8_task_is_its_run():
    a = ch8_task("06", "proportional", (0.0, 2000.0, 2000.0), "one-way", 2e-6, 1, 1.5, 3, True, None, None)
    r = run_experiment("06", "proportional", (0.0, 2000.0, 2000.0), plant="one-way", noise=2e-6, seed=1,
                       horizon_s=1.5)
    assert a["final_err_deg"] == r["final_err_deg"]
    assert a["metrics"]["online"]["max_strain"] == float(np.max(np.abs(r["eps_online"])))
    assert a["freq_hz"] == dominant_freq(r["t"], r["eps_dynamic"])
    # the amplitude at every candidate frequency; the run's own frequency is one of them
    i = list(a["bins_hz"]).index(a["freq_hz"])
    for sig in ("online", "dynamic"):
        assert a["spectral_by_bin"][sig][i] == a["metrics"][sig]["spectral_amp"]
    # a reference's frequency is handed to the other runs of its group
    res = resolve_runs({("g", "off", 0): a, ("g", "x", 0): {**a, "freq_hz": 9.9}}, ["g"], "off")
    assert res[("g", "x", 0)]["freq_hz"] == a["freq_hz"] and set(res) == {("g", "off", 0), ("g", "x", 0)}


def test_ch8_local_cluster_and_resume_give_the_same_bytes(ch8_serial, tmp_path):
    out = tmp_path / "local"
    assert bench_damping_ch8.main(CH8_ARGS + ["--scheduler", "local", "--workers", "2", "--out", str(out)]) == 0
    local = out / "one-way"
    _same(ch8_serial, local, CH8_FILES)
    info = json.loads((local / "runner.json").read_text())
    assert info["scheduler"] == "local" and info["workers"] == 2 and info["complete"]
    # a run killed before the last record was written: the record is gone and no tables were written
    killed = tmp_path / "killed"
    shutil.copytree(ch8_serial.parent, killed)
    recs = _records(killed / "one-way")
    victim = max(recs, key=lambda p: json.loads(p.read_text())["params"]["label"] == "proportional")
    victim.unlink()
    for name in CH8_FILES:
        (killed / "one-way" / name).unlink()
    assert bench_damping_ch8.main(CH8_ARGS + ["--scheduler", "serial", "--out", str(killed)]) == 0
    _same(ch8_serial, killed / "one-way", CH8_FILES)
    stages = json.loads((killed / "one-way" / "runner.json").read_text())["stages"]
    assert sum(s["skipped"] for s in stages) == 3 and sum(s["tasks"] for s in stages) == 4


def test_ch8_bad_options_are_one_line_errors(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        bench_damping_ch8.main(["--scheduler", "nowhere", "--out", str(tmp_path)])
    assert exc.value.code == 2 and "--scheduler" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        bench_damping_ch8.main(["--experiments", "13", "--out", str(tmp_path)])


# ----------------------------------------------------------------------------- collision

COLL_ARGS = ["--reuse", "--fp-minutes", "0.01", "--contact-plates", "3", "--strategies", "no detection",
             "--quiet"]
COLL_FILES = ("collision.json", "collision.md", "contacts.csv")


@pytest.fixture(scope="module")
def collision_fixture(tmp_path_factory):
    """An earlier run's folder for ``--reuse``: a model fitted on 2 x 3 s here, fixed thresholds."""
    src = tmp_path_factory.mktemp("coll") / "fixture"
    src.mkdir()
    setup = CollisionSetup()
    data = [identification_run(setup, pl, 3.0, 100 + pl) for pl in (0, 4)]
    cat = {q: np.concatenate([d[q] for d in data]) for q in ("theta", "d", "dd", "eps", "m")}
    model = fit_strain_dynamics(cat["theta"], cat["d"], cat["dd"], cat["eps"], cat["m"])
    np.save(src / "chi.npy", model.chi)
    np.save(src / "thr.npy", np.full(2, 40e-6))
    np.save(src / "thr_per_payload.npy", np.full((5, 2), 40e-6))
    np.save(src / "coupling.npy", np.array([0.1, 0.0, 40e-6]))
    (src / "collision.json").write_text(json.dumps({"identification": {"validation": "fixture"},
                                                    "thresholds_um_m": [40.0, 40.0]}))
    return src


def _collision(src: Path, dst: Path, *mode) -> Path:
    if not dst.exists():
        shutil.copytree(src, dst)
    assert bench_collision.main(COLL_ARGS + list(mode) + ["--out", str(dst)]) == 0
    return dst


def test_collision_serial_local_and_resume_agree(collision_fixture, tmp_path):
    serial = _collision(collision_fixture, tmp_path / "serial", "--scheduler", "serial")
    rep = json.loads((serial / "collision.json").read_text())
    assert rep["false_positives"]["minutes"] == 0.01
    assert [(c["kind"], c["strategy"], c["payload_g"]) for c in rep["contacts"]] == [
        ("link3", "no detection", 300), ("link2", "no detection", 300)]
    # the sphere is put in the path: without detection the arm runs into it
    assert all(c["onset_s"] is not None and c["peak_force_N"] > 0 for c in rep["contacts"])
    assert "wall_s" not in rep and json.loads((serial / "runner.json").read_text())["complete"]
    local = _collision(collision_fixture, tmp_path / "local", "--scheduler", "local", "--workers", "2")
    _same(serial, local, COLL_FILES)
    # resume: a contact record lost (and the summary not written yet) -> only that task runs again
    resumed = tmp_path / "resumed"
    shutil.copytree(serial, resumed)
    for name in COLL_FILES:
        (resumed / name).unlink()
    shutil.copy(collision_fixture / "collision.json", resumed / "collision.json")
    contact = [p for p in _records(resumed) if p.name.startswith("collision-contact")]
    assert len(contact) == 2
    contact[0].unlink()
    _collision(collision_fixture, resumed, "--scheduler", "serial")
    _same(serial, resumed, COLL_FILES)
    stages = json.loads((resumed / "runner.json").read_text())["stages"]
    assert [s["skipped"] for s in stages] == [5 + 1]
