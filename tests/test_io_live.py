"""Live sources: timestamp pairing (pure), OpenCV captures on a video file and on a loopback MJPEG stream.

No camera exists here: the "streams" are an MJPG ``.avi`` written with
``cv2.VideoWriter`` and an HTTP ``multipart/x-mixed-replace`` MJPEG server
run by the test itself on 127.0.0.1.
"""
from __future__ import annotations

import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import cv2
import numpy as np
import pytest

from tudorvision._checks import TudorVisionError
import tudorvision.cli
from tudorvision.cli import main
from tudorvision.io import open_sequence
from tudorvision.io._index import associate
from tudorvision.io.live import (LiveCapture, StereoPairer, StreamEnded, is_live_source, live_spec,
                                 pair_by_timestamp, split_live_sources)



@pytest.fixture(autouse=True)
def _only_needed_commands(monkeypatch):
    """Build the real CLI with the commands these tests run (others may be mid-development)."""
    monkeypatch.setattr(tudorvision.cli, "COMMAND_MODULES", ("tudorvision.cli.seq", "tudorvision.cli.stereo"))

# ----------------------------------------------------------------------------- pairing (pure)
def test_pairing_exact_on_synthetic_timestamps():
    t_left = np.arange(10) / 30.0
    t_right = t_left + 0.004
    t_right = np.delete(t_right, [3, 7])                  # right camera lost two frames
    pairs = pair_by_timestamp(t_left, t_right, tol_s=0.5 / 30)
    assert pairs[:, 0].tolist() == [0, 1, 2, 4, 5, 6, 8, 9]
    assert pairs[:, 1].tolist() == list(range(8))


@pytest.mark.parametrize("seed", range(5))
def test_pairing_property_random_jitter_and_drops(seed):
    rng = np.random.default_rng(seed)
    period, n = 1 / 30, 300
    base = np.arange(n) * period
    t_left = np.sort(base + rng.normal(0, 0.002, n))[rng.random(n) > 0.1]
    t_right = np.sort(base + 0.006 + rng.normal(0, 0.002, n))[rng.random(n) > 0.1]
    tol = 0.4 * period
    pairs = pair_by_timestamp(t_left, t_right, tol)
    dt = np.abs(t_left[pairs[:, 0]] - t_right[pairs[:, 1]])
    assert np.all(dt <= tol)
    assert np.all(np.diff(pairs[:, 0]) > 0) and np.all(np.diff(pairs[:, 1]) > 0)    # each frame once, in order
    # the streaming pairer finds what the offline greedy association finds when the tolerance is below half a period
    assert np.array_equal(pairs, associate(t_left, t_right, tol))


def test_pairer_drops_frames_without_partner_and_counts():
    p = StereoPairer(0.01)
    assert p.push("left", 0.0, "L0") == []
    assert p.push("left", 0.033, "L1") == []
    out = p.push("right", 0.035, "R0")                    # L0 has no partner: dropped
    assert [(a[1], b[1]) for a, b in out] == [("L1", "R0")] and p.dropped == {"left": 1, "right": 0}
    with pytest.raises(ValueError):
        StereoPairer(0.0)


def test_live_source_names():
    assert split_live_sources("rtsp://10.0.0.2:554/stream") == ["rtsp://10.0.0.2:554/stream"]
    assert split_live_sources("right=/dev/video2,left=/dev/video0") == ["/dev/video0", "/dev/video2"]
    assert is_live_source("http://cam.local/mjpg/video.mjpg") and is_live_source("/dev/video0")
    assert not is_live_source("/dev/sda") and not is_live_source("clip.mp4") and not is_live_source("a.bag")
    assert not is_live_source("/dev/video0,/dev/video1,/dev/video2")


# ----------------------------------------------------------------------------- a video file as a stream
def _frames(n, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        img = np.zeros((48, 64, 3), np.uint8)
        img[:, :] = rng.integers(40, 200, 3)
        cv2.circle(img, (10 + 4 * k, 24), 6, (0, 0, 255), -1)
        out.append(img)
    return out


def test_capture_reads_mjpg_file_then_ends_cleanly(tmp_path):
    path = tmp_path / "clip.avi"
    w = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 30.0, (64, 48))
    frames = _frames(12)
    for f in frames:
        w.write(f)
    w.release()
    cap = LiveCapture(str(path), timeout_s=2.0, buffer=4, drop_old=False)
    got = []
    while (item := cap.get()) is not None:
        got.append(item)
    cap.close()
    assert len(got) == 12 and cap.dropped == 0
    assert all(np.abs(img.astype(int) - f).mean() < 4 for (_, img), f in zip(got, frames))   # JPEG: close, not exact
    assert all(t1 >= t0 for (t0, _), (t1, _) in zip(got, got[1:]))
    assert cap.get(0.1) is None                           # stays ended
    spec = live_spec(str(path), max_frames=5, drop_old=False)
    try:
        assert spec.kind == "mono" and spec.source.count == 5
        spec.source.read(4)
        assert len(spec.source.timestamps) == 5
        with pytest.raises(Exception, match="has passed"):
            spec.source.read(-20)
    finally:
        spec.source.close()


# ----------------------------------------------------------------------------- an MJPEG stream on loopback
class _Mjpeg:
    """Serve JPEG frames as multipart/x-mixed-replace at ``fps`` on 127.0.0.1, optionally stalling."""

    def __init__(self, frames, fps=30.0, stall_after=None):
        jpgs = [cv2.imencode(".jpg", f, [cv2.IMWRITE_JPEG_QUALITY, 95])[1].tobytes() for f in frames]
        stop = self.stop = threading.Event()

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args):
                pass

            def do_GET(self):
                self.send_response(200)
                self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=frame")
                self.end_headers()
                try:
                    for k, j in enumerate(jpgs):
                        if stall_after is not None and k >= stall_after:
                            stop.wait(10)
                            return
                        self.wfile.write(b"--frame\r\nContent-Type: image/jpeg\r\nContent-Length: %d\r\n\r\n"
                                         % len(j) + j + b"\r\n")
                        self.wfile.flush()
                        time.sleep(1 / fps)
                except OSError:
                    pass

        self.server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.server.daemon_threads = True
        threading.Thread(target=self.server.serve_forever, daemon=True).start()
        self.url = f"http://127.0.0.1:{self.server.server_address[1]}/stream.mjpg"

    def close(self):
        self.stop.set()
        self.server.shutdown()
        self.server.server_close()


@pytest.fixture
def mjpeg():
    servers = []

    def make(*args, **kw):
        s = _Mjpeg(*args, **kw)
        servers.append(s)
        return s

    yield make
    for s in servers:
        s.close()


def test_open_sequence_on_http_mjpeg_stream_and_track(mjpeg):
    frames = _frames(15)
    srv = mjpeg(frames)
    with open_sequence(srv.url, max_frames=10, timeout_s=3.0) as seq:
        assert seq.layout == "live" and seq.kind == "mono" and len(seq) == 10
        got = list(seq)
    assert len(got) == 10
    ts = np.array([f.t for f in got])
    assert np.all(np.diff(ts) >= 0) and abs(ts[0] - time.time()) < 10
    # detect the red disc in each frame: it moves 4 px right per frame, as drawn
    for f in got:
        mask = (f.image[:, :, 2] > 200) & (f.image[:, :, 1] < 80)
        u = np.nonzero(mask)[1].mean()
        k = int(np.argmin([np.abs(g.astype(int) - f.image).mean() for g in frames]))
        assert abs(u - (10 + 4 * k)) < 1.5


def test_seq_import_live_stream_until_it_ends(mjpeg, tmp_path, capsys):
    srv = mjpeg(_frames(8))
    out = tmp_path / "live"
    assert main(["seq", "import", srv.url, "--out", str(out), "--timeout", "2"]) == 0
    text = capsys.readouterr().out
    assert "stream ended after 8 frames" in text and "wrote" in text
    with open_sequence(out) as seq:
        assert seq.kind == "mono" and len(seq) == 8 and seq.meta["source_layout"] == "live"


def test_stalled_stream_times_out_and_stops(mjpeg):
    srv = mjpeg(_frames(10), stall_after=3)
    t0 = time.monotonic()
    seq = open_sequence(srv.url, timeout_s=1.0)
    try:
        assert all(seq[i] is not None for i in range(3))
        with pytest.raises(StreamEnded, match="stream ended after 3 frames"):
            seq[3]
    finally:
        seq.close()
    assert time.monotonic() - t0 < 8


def test_stereo_from_two_streams_paired_by_arrival_time(mjpeg):
    left, right = _frames(12, seed=1), _frames(12, seed=2)
    a, b = mjpeg(left), mjpeg(right)
    with open_sequence(f"left={a.url},right={b.url}", max_frames=6, timeout_s=3.0, max_dt_s=0.5 / 30) as seq:
        assert seq.kind == "stereo"
        got = list(seq)
    assert len(got) == 6
    for f in got:     # each side comes from its own stream
        assert min(np.abs(g.astype(int) - f.left).mean() for g in left) < 4
        assert min(np.abs(g.astype(int) - f.right).mean() for g in right) < 4


def test_unopenable_device_one_line_error(capsys):
    with pytest.raises(TudorVisionError, match="/dev/video97: cannot open the live source"):
        open_sequence("/dev/video97", timeout_s=0.5)
    assert main(["seq", "info", "/dev/video97", "--timeout", "0.5"]) == 2
    err = capsys.readouterr().err
    assert err.strip().count("\n") == 0 and "Traceback" not in err and "/dev/video97" in err


def test_seq_info_on_a_stream_reads_a_few_frames(mjpeg, capsys):
    srv = mjpeg(_frames(20))
    assert main(["seq", "info", srv.url, "--max-frames", "5", "--timeout", "2"]) == 0
    out = capsys.readouterr().out
    assert "layout       live" in out and "frames       5 (5 readable)" in out and "kind         mono" in out
