"""Live viewing: ``--rerun FILE``, ``--rerun-live [ADDR]`` and ``--rerun-web [PORT]`` on the long commands."""
from __future__ import annotations

import re
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from _subproc import start_cli, stop
from tudorvision._checks import TudorVisionError
from tudorvision.cli import _viewer, main
from tudorvision.stereo import read_mono_track_csv

pytest.importorskip("rerun")

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_data"
LEFT_PICKS = ["left:red:421.9,165.2:427.9,165.2", "left:green:443.3,179.8:449.5,179.8"]
RRD_MAGIC = b"RRF2"


def _run(capsys, *argv):
    rc = main([str(a) for a in argv])
    out = capsys.readouterr()
    return rc, out.out, out.err


def _entity_rows(rrd: Path) -> Counter:
    """Rows per entity path of a recording, read back by the SDK's own ``rerun rrd print`` (None: no binary)."""
    exe = _viewer._viewer_executable()
    if exe is None:
        pytest.skip("no rerun executable to read the recording back")
    p = subprocess.run([exe, "rrd", "print", str(rrd)], capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    rows = Counter()
    for m in re.finditer(r"with (\d+) rows .*? - (/\S+) - data columns", p.stdout):
        rows[m.group(2)] += int(m.group(1))
    return rows


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    path = tmp_path_factory.mktemp("rerun_live") / "models.yaml"
    argv = ["colormodel", str(SAMPLE / "stereo-step"), "--frame", "0", "--out", str(path)]
    for p in LEFT_PICKS:
        argv += ["--pick", p]
    assert main(argv) == 0
    return path


def _headless(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)


def test_track_mono_rerun_file_and_headless_live_warns(models, tmp_path, capsys, monkeypatch):
    _headless(monkeypatch)
    rrd, csv = tmp_path / "sub" / "mono.rrd", tmp_path / "mono.csv"
    rc, out, err = _run(capsys, "track", "mono", SAMPLE / "stereo-step" / "left", "--camera", "left",
                        "--colormodel", models, "--sphere", "red", "--out", csv, "--rerun", rrd, "--rerun-live")
    assert rc == 0, err
    warnings = [ln for ln in err.splitlines() if ln.startswith("warning:")]
    assert len(warnings) == 1 and "--rerun-live" in warnings[0] and "headless" in warnings[0], err
    assert rrd.read_bytes()[:4] == RRD_MAGIC
    assert f"wrote {rrd}" in out
    track = read_mono_track_csv(csv)
    rows = _entity_rows(rrd)
    n_valid = int(np.sum(track["valid"]))
    assert n_valid > 0
    # one point and one u, v sample per valid frame, a Clear per invalid frame
    assert rows["/plots/red/u_px"] == n_valid and rows["/plots/red/v_px"] == n_valid
    assert rows["/cameras/left/red"] == len(track["frame"])


def test_live_to_an_address_without_viewer_warns_and_continues(models, tmp_path, capsys):
    with socket.socket() as s:      # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    rc, out, err = _run(capsys, "track", "mono", SAMPLE / "stereo-step" / "left", "--camera", "left",
                        "--colormodel", models, "--sphere", "green", "--out", tmp_path / "m.csv",
                        "--rerun-live", f"127.0.0.1:{port}")
    assert rc == 0, err
    assert f"no rerun viewer answers at rerun+http://127.0.0.1:{port}/proxy" in err
    assert "wrote" in out and (tmp_path / "m.csv").is_file()


def test_live_without_viewer_binary_warns(models, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("DISPLAY", ":99")
    monkeypatch.setattr(_viewer, "_viewer_executable", lambda: None)
    monkeypatch.setattr(_viewer, "_port_open", lambda host, port, timeout_s=0.5: False)
    rc, _, err = _run(capsys, "track", "mono", SAMPLE / "stereo-step" / "left", "--camera", "left",
                      "--colormodel", models, "--sphere", "green", "--out", tmp_path / "m.csv",
                      "--rerun", tmp_path / "m.rrd", "--rerun-live")
    assert rc == 0, err
    assert "no rerun viewer installed" in err and len(err.strip().splitlines()) == 1, err
    assert (tmp_path / "m.rrd").read_bytes()[:4] == RRD_MAGIC


def test_grpc_url_forms():
    assert _viewer.grpc_url("9877") == "rerun+http://127.0.0.1:9877/proxy"
    assert _viewer.grpc_url("lab-pc:9000") == "rerun+http://lab-pc:9000/proxy"
    assert _viewer.grpc_url("rerun+http://10.0.0.2:9876/proxy") == "rerun+http://10.0.0.2:9876/proxy"
    for bad in ("lab-pc", "http://x:1/proxy", ":12", "host:port"):
        with pytest.raises(TudorVisionError, match="--rerun-live"):
            _viewer.grpc_url(bad)


def test_bad_live_address_is_a_one_line_error(models, tmp_path, capsys):
    rc, _, err = _run(capsys, "track", "mono", SAMPLE / "stereo-step" / "left", "--camera", "left",
                      "--colormodel", models, "--sphere", "green", "--out", tmp_path / "m.csv",
                      "--rerun-live", "nohost")
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "--rerun-live" in err, err


def test_servo_open_loop_rerun_file(tmp_path, capsys):
    rrd = tmp_path / "servo.rrd"
    rc, out, err = _run(capsys, "servo", SAMPLE / "servo-views", "--goal", SAMPLE / "servo-views" / "rgb" / "000000.jpg",
                        "--rerun", rrd)
    assert rc == 0, err
    assert rrd.read_bytes()[:4] == RRD_MAGIC
    lines = [ln for ln in out.splitlines() if ln and ln[0].isdigit()]
    rows = _entity_rows(rrd)
    # one joint command per frame, errors only where the command was ok (3rd column)
    assert rows["/command/theta_dot_1"] == len(lines)
    assert rows["/errors/e_u_px"] == sum(ln.split()[2] == "1" for ln in lines) > 0
    assert rows["/goal/image"] == 1


def test_catch_open_loop_rerun_file(tmp_path, capsys):
    rrd = tmp_path / "catch.rrd"
    seq = SAMPLE / "rgbd-throws"
    rc, out, err = _run(capsys, "catch", seq, "--calib", seq / "wall_calibration.yaml", "--out", tmp_path / "o",
                        "--rerun", rrd)
    assert rc == 0, err
    assert rrd.read_bytes()[:4] == RRD_MAGIC
    n_det = int(re.search(r"(\d+) detections in (\d+) frames", out).group(1))
    n_frames = int(re.search(r"(\d+) detections in (\d+) frames", out).group(2))
    rows = _entity_rows(rrd)
    assert rows["/world/detections"] == n_det > 0
    assert rows["/camera/depth"] == len(range(0, n_frames, 5))


def test_catch_demo_rerun_file_replaces_default(tmp_path, capsys):
    rrd = tmp_path / "mine.rrd"
    rc, out, err = _run(capsys, "catch", "demo", "--throws", "1", "--seed", "0", "--no-render",
                        "--out", tmp_path / "d", "--rerun", rrd)
    assert rc == 0, err
    assert rrd.read_bytes()[:4] == RRD_MAGIC and not (tmp_path / "d" / "catch.rrd").exists()
    assert f"wrote {rrd}" in out
    rows = _entity_rows(rrd)
    assert rows["/world/detections"] > 0 and rows["/world/net"] == rows["/world/detections"]


def _listening(port: int) -> set:
    """Local addresses listening on ``port`` (Linux /proc/net/tcp[6])."""
    addrs = set()
    for name in ("/proc/net/tcp", "/proc/net/tcp6"):
        try:
            lines = Path(name).read_text().splitlines()[1:]
        except OSError:
            continue
        for ln in lines:
            f = ln.split()
            ip, p = f[1].split(":")
            if f[3] == "0A" and int(p, 16) == port:
                addrs.add(ip)
    return addrs


def _sigint_default() -> None:
    # a suite run in the background (`make test &`) inherits SIGINT ignored, as POSIX shells start
    # background jobs, and a Python started that way keeps ignoring it; Ctrl-C from a terminal reaches a
    # foreground command, which is what these tests play
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _track_with_web_viewer(models, tmp_path):
    """``track mono`` of the sample step sequence with ``--rerun-web`` on a free port: ``(Popen, port)``."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    cmd = [sys.executable, "-m", "tudorvision", "track", "mono", str(SAMPLE / "stereo-step" / "left"), "--camera",
           "left", "--colormodel", str(models), "--sphere", "red", "--out", str(tmp_path / "m.csv"),
           "--rerun-web", str(port)]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            preexec_fn=_sigint_default), port


def test_rerun_web_serves_on_loopback_only(models, tmp_path):
    if _viewer._viewer_executable() is None:
        pytest.skip("no rerun executable")
    p, port = _track_with_web_viewer(models, tmp_path)
    try:
        url, served, lines = None, False, []
        t0 = time.monotonic()
        for line in p.stdout:
            lines.append(line)
            m = re.search(r"rerun web viewer: (\S+)", line)
            if m:
                url = m.group(1)
                assert url.startswith(f"http://127.0.0.1:{port}/")
                with urllib.request.urlopen(url, timeout=5) as r:
                    assert r.status == 200 and b"<html" in r.read(4096).lower()
                assert time.monotonic() - t0 < 90          # generous: the suite may share a loaded machine
                addrs = _listening(port)
                if Path("/proc/net/tcp").exists():
                    assert addrs == {"0100007F"}, addrs      # 127.0.0.1, not 0.0.0.0 (00000000)
                    gport = int(re.search(r"127\.0\.0\.1%3A(\d+)%2Fproxy", url).group(1))
                    assert _listening(gport) == {"0100007F"}  # the gRPC server behind it too
            if "keeps serving" in line:
                served = True
                p.send_signal(signal.SIGINT)
                break
        rest = p.communicate(timeout=90)[0]
        assert url is not None and served, "".join(lines) + rest
        assert p.returncode == 0, "".join(lines) + rest
        assert "frames tracked" in rest
        time.sleep(0.5)
        assert not _listening(port)          # the web viewer stopped with the command
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()


def test_ctrl_c_reaching_another_thread_still_stops_the_web_viewer(models, tmp_path):
    """Ctrl-C is a process signal: the kernel may hand it to one of rerun's threads, which does not
    interrupt the main thread's blocking wait (the command then served on for ever). Played here by
    sending SIGINT to a thread other than the main one."""
    import ctypes
    import os

    tgkill = getattr(ctypes.CDLL(None, use_errno=True), "tgkill", None)
    if _viewer._viewer_executable() is None or tgkill is None or not Path("/proc/self/task").exists():
        pytest.skip("needs the rerun executable and Linux tgkill")
    p, port = _track_with_web_viewer(models, tmp_path)
    try:
        sent = False
        for line in p.stdout:
            if "keeps serving" in line:
                others = [int(t) for t in os.listdir(f"/proc/{p.pid}/task") if int(t) != p.pid]
                assert others, "rerun runs no thread of its own here"
                assert tgkill(p.pid, others[0], int(signal.SIGINT)) == 0
                sent = True
                break
        assert sent
        rest = p.communicate(timeout=30)[0]
        assert p.returncode == 0 and "frames tracked" in rest, rest
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()


def test_joint_move_records_joint_angles(tmp_path, capsys):
    pytest.importorskip("tudorvision.sim.arm", reason="simulated arm not available")
    proc, line = start_cli(["joint", "serve", "--port", "0", "--core", "sim", "--duration", "40"],
                           expect=["listening on udp 127.0.0.1:"])
    try:
        port = int(line.rsplit(":", 1)[1])
        rrd = tmp_path / "move.rrd"
        rc, out, err = _run(capsys, "joint", "move", "--port", port, "--to", "0,80,0", "--timeout", "25",
                            "--damping", "proportional", "--progress", "0", "--rerun", rrd)
        assert rc == 0, err
        assert out.splitlines()[-1].startswith("settled at theta_deg") and f"wrote {rrd}" in out
    finally:
        stop(proc)
    rows = _entity_rows(rrd)
    n = rows["/joints/theta_deg/2"]
    assert n >= 2 and all(rows[f"/joints/{k}/{j}"] == n for k in ("theta_deg", "setpoint_deg") for j in (1, 2, 3))
    assert rows["/strains/4_um_m"] == n


def test_calib_rgbd_base_records_disc_and_base_frame(tmp_path, capsys):
    rrd = tmp_path / "wall.rrd"
    rc, out, err = _run(capsys, "calib", "rgbd-base", SAMPLE / "rgbd-disc", "--seed", "402,284",
                        "--out", tmp_path / "wall.yaml", "--rerun", rrd)
    assert rc == 0, err
    rows = _entity_rows(rrd)
    # the sample: 11 sweep poses and 4 vertical frames, one disc sample (or clear) each; depth every 5th frame
    assert rows["/camera/disc"] == 15
    assert rows["/camera/depth"] == 3
    assert rows["/camera/base"] == 1 and rows["/camera/sweep"] == 1 and rows["/camera/base/axes"] == 1
