"""``tudorvision joint serve/status/move``: a served layer in a subprocess, queried through the CLI."""
from __future__ import annotations

import select
import socket
import subprocess
import sys
import time

import pytest

from _subproc import start_cli, stop
from tudorvision.cli import main

SERVE_S = 20.0


@pytest.fixture(scope="module")
def served_port():
    proc, line = start_cli(["joint", "serve", "--port", "0", "--duration", SERVE_S],
                           expect=["listening on udp 127.0.0.1:"], timeout_s=15.0)
    try:
        yield int(line.rsplit(":", 1)[1])
    finally:
        stop(proc)


def _dead_port() -> int:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    return port


def test_status_answers(served_port, capsys):
    assert main(["joint", "status", "--port", str(served_port), "--timeout", "3"]) == 0
    out = capsys.readouterr().out
    assert "mode IDLE" in out and "theta_deg" in out and "counters accepted=" in out


def test_move_settles_then_status_shows_it(served_port, capsys):
    t0 = time.monotonic()
    code = main(["joint", "move", "--port", str(served_port), "--to", "5,85,-10",
                 "--timeout", "15"])
    out = capsys.readouterr().out
    assert code == 0, out
    assert "settled at theta_deg 5.000 85.000 -10.000" in out
    assert time.monotonic() - t0 < 15.0
    assert main(["joint", "status", "--port", str(served_port)]) == 0
    out = capsys.readouterr().out
    assert "mode SETPOINT" in out and "SETTLED" in out


def test_move_out_of_range_is_refused(served_port, capsys):
    assert main(["joint", "move", "--port", str(served_port), "--to", "0,300,0"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("tudorvision joint move: setpoint refused: OUT_OF_RANGE")
    assert len(err.splitlines()) == 1


def test_payload_is_accepted_by_the_sim_core_and_range_checked(capsys):
    proc = subprocess.Popen(
        [sys.executable, "-m", "tudorvision.cli", "joint", "serve", "--port", "0", "--core", "sim",
         "--duration", "15"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        ready, _, _ = select.select([proc.stdout], [], [], 15.0)
        line = proc.stdout.readline() if ready else ""
        assert "listening on udp 127.0.0.1:" in line, line
        port = line.rsplit(":", 1)[1].strip()
        assert main(["joint", "payload", "--port", port, "--kg", "0.2", "--timeout", "3"]) == 0
        assert "payload 0.2 kg accepted" in capsys.readouterr().out
        assert main(["joint", "payload", "--port", port, "--kg", "9", "--timeout", "3"]) == 1
        err = capsys.readouterr().err.strip()
        assert err.startswith("tudorvision joint payload: refused: OUT_OF_RANGE") and len(err.splitlines()) == 1
    finally:
        proc.terminate()
        proc.wait(timeout=5)


def test_payload_on_dead_port_fails_with_one_line(capsys):
    assert main(["joint", "payload", "--port", str(_dead_port()), "--kg", "0.1", "--timeout", "0.3"]) == 1
    err = capsys.readouterr().err.strip()
    assert "no answer" in err and len(err.splitlines()) == 1


def test_status_on_dead_port_fails_with_one_line(capsys):
    port = _dead_port()
    assert main(["joint", "status", "--port", str(port), "--timeout", "0.3"]) == 1
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"tudorvision joint status: no answer from 127.0.0.1:{port} within 0.3 s")
    assert captured.out == ""


def test_status_on_dead_port_subprocess_exit_code():
    port = _dead_port()
    proc = subprocess.run([sys.executable, "-m", "tudorvision.cli", "joint", "status",
                           "--port", str(port), "--timeout", "0.2"],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1
    assert len(proc.stderr.strip().splitlines()) == 1 and "no answer" in proc.stderr


@pytest.mark.parametrize("argv, named", [
    (["joint", "move", "--port", "9", "--to", "1,2"], "argument --to"),
    (["joint", "move", "--port", "9", "--to", "a,b,c"], "argument --to"),
    (["joint", "status", "--port", "70000"], "argument --port"),
    (["joint", "status", "--port", "5", "--timeout", "-1"], "argument --timeout"),
    (["joint", "serve", "--port", "x"], "argument --port"),
    (["joint", "payload", "--port", "5", "--kg", "-1"], "argument --kg"),
    (["joint", "payload", "--port", "5", "--kg", "nan"], "argument --kg"),
])
def test_parse_errors_name_the_argument(argv, named, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    assert named in capsys.readouterr().err


def test_unknown_core_is_one_line_error(capsys):
    assert main(["joint", "serve", "--port", "0", "--duration", "0.1", "--core", "nope"]) == 2
    err = capsys.readouterr().err
    assert "unknown core 'nope'" in err and "kinematic" in err


def _model_folder(tmp_path, chi_shape=(2, 32)):
    import numpy as np
    d = tmp_path / "model"
    d.mkdir()
    np.save(d / "chi.npy", np.zeros(chi_shape))
    np.save(d / "thr.npy", np.array([6e-4, 2e-4]))
    np.save(d / "coupling.npy", np.array([0.2, 0.3, 1e-5]))
    return d


def test_serve_loads_collision_and_damping_models(tmp_path, capsys, monkeypatch):
    from tudorvision.joint import server as server_mod
    d = _model_folder(tmp_path)
    built = {}
    real = server_mod.make_core

    def spy(name, **options):
        built.update(options)
        return real(name, **options)

    monkeypatch.setattr(server_mod, "make_core", spy)
    assert main(["joint", "serve", "--port", "0", "--core", "sim", "--duration", "0.2",
                 "--collision-model", str(d), "--damping-model", str(d / "chi.npy")]) == 0
    assert "listening on udp 127.0.0.1:" in capsys.readouterr().out
    assert built["collision_model"].chi.shape == (2, 32) and list(built["collision_thresholds"]) == [6e-4, 2e-4]
    assert built["collision_coupling"].c1 == 0.3 and built["damping_model"].chi.shape == (2, 32)


@pytest.mark.parametrize("case", ["wrong_shape", "not_npy", "missing", "kinematic", "strings", "negative"])
def test_serve_model_errors_are_one_line_and_name_the_file(tmp_path, capsys, case):
    d = _model_folder(tmp_path, chi_shape=(2, 31) if case == "wrong_shape" else (2, 32))
    argv = ["joint", "serve", "--port", "0", "--duration", "0.1", "--core", "sim"]
    if case == "wrong_shape":
        argv += ["--collision-model", str(d)]
    elif case in ("strings", "negative"):       # a .npy of text (was a TypeError), a threshold below zero
        import numpy as np
        np.save(d / "thr.npy", np.array(["6e-4", "2e-4"]) if case == "strings" else np.array([6e-4, -2e-4]))
        argv += ["--collision-model", str(d)]
    elif case == "not_npy":
        (d / "x.npy").write_text("hello")
        argv += ["--damping-model", str(d / "x.npy")]
    elif case == "missing":
        argv += ["--damping-model", str(d / "absent.npy")]
    else:
        argv = ["joint", "serve", "--port", "0", "--duration", "0.1", "--collision-model", str(d)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    named = {"wrong_shape": "chi.npy", "not_npy": "x.npy", "missing": "absent.npy", "kinematic": "--core sim",
             "strings": "thr.npy", "negative": "thr.npy"}[case]
    assert named in err


def test_collision_model_folder_whose_gains_differ_from_the_served_layer_is_named(tmp_path):
    import json

    from tudorvision.cli.joint import collision_model_mismatch
    from tudorvision.joint.damping_gains import SOFT_GAINS

    meta = tmp_path / "collision.json"
    meta.write_text(json.dumps({"plant": "soft", "soft_k_eps": [0.0, 500.0, 1600.0]}))
    note = collision_model_mismatch(str(meta))
    assert note is not None and "(0.0, 500.0, 1600.0)" in note and "collision.json" in note
    meta.write_text(json.dumps({"plant": "soft", "soft_k_eps": list(SOFT_GAINS["proportional"])}))
    assert collision_model_mismatch(str(meta)) is None
    meta.write_text(json.dumps({"plant": "stiff", "k_eps": [0.0, 800.0, 3200.0]}))
    assert "'stiff' plant" in collision_model_mismatch(str(meta))
    meta.write_text("{not json")                                      # hostile file: no crash, no claim
    assert collision_model_mismatch(str(meta)) is None
    meta.write_text(json.dumps([1, 2, 3]))
    assert collision_model_mismatch(str(meta)) is None
    assert collision_model_mismatch(str(tmp_path / "absent.json")) is None
