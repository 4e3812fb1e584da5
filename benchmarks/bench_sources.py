"""Sources (issue 16): bag reading and live MJPEG throughput against hand-written rosbags / OpenCV loops.

Bags: a 640x480 stereo bag (raw ``bgr8``, and JPEG ``CompressedImage``) in
each storage (ROS 1, ROS 2 sqlite3, ROS 2 mcap) is read as a sequence
(``open_sequence`` + iterate: index scan, pairing, decoding) and by the
peer: ``rosbags`` ``AnyReader.messages`` + ``deserialize`` +
``np.frombuffer`` / ``cv2.imdecode`` written by hand (no pairing). Frames/s
are stereo pairs per second.

Live: an MJPEG stream served on loopback as fast as the socket takes it,
read through ``open_sequence(url)`` (capture thread + queue) and by a bare
``cv2.VideoCapture.read`` loop; plus the latency our thread and queue add
(consumer time minus capture time), p50 / p99.

Run: ``taskset -c 0 .venv/bin/python benchmarks/bench_sources.py [--frames N]``. Not a test.
"""
from __future__ import annotations

import argparse
import sys
import tempfile
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import cv2
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _machine import cpu_model  # noqa: E402

from tudorvision.io import open_sequence  # noqa: E402

W, H = 640, 480


def _image(k: int, side: int) -> np.ndarray:
    v, u = np.mgrid[0:H, 0:W]
    img = np.stack([(u + 3 * k + side) % 256, (v + k) % 256, ((u + v) // 2) % 256], axis=-1).astype(np.uint8)
    cv2.circle(img, (100 + 2 * k, 240), 30, (0, 0, 255), -1)
    return img


def write_bag(path: Path, flavour: str, n: int, compressed: bool) -> None:
    from rosbags.rosbag1 import Writer as Writer1
    from rosbags.rosbag2 import StoragePlugin
    from rosbags.rosbag2 import Writer as Writer2
    from rosbags.typesys import Stores, get_typestore

    ros1 = flavour == "ros1"
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    T = ts.types
    w = Writer1(path) if ros1 else Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP if flavour == "mcap"
                                           else StoragePlugin.SQLITE3)
    w.open()
    typ = "sensor_msgs/msg/CompressedImage" if compressed else "sensor_msgs/msg/Image"
    conns = {s: w.add_connection(f"/{s}/image_raw" + ("/compressed" if compressed else ""), typ, typestore=ts)
             for s in ("left", "right")}
    ser = ts.serialize_ros1 if ros1 else ts.serialize_cdr
    for k in range(n):
        t = 1_700_000_000 * 10**9 + k * 33_333_333
        stamp = T["builtin_interfaces/msg/Time"](sec=t // 10**9, nanosec=t % 10**9)
        hdr = T["std_msgs/msg/Header"](**({"seq": k} if ros1 else {}), stamp=stamp, frame_id="cam")
        for side, s in enumerate(("left", "right")):
            img = _image(k, side)
            if compressed:
                msg = T[typ](header=hdr, format="jpeg", data=cv2.imencode(".jpg", img)[1].ravel())
            else:
                msg = T[typ](header=hdr, height=H, width=W, encoding="bgr8", is_bigendian=0, step=W * 3,
                             data=img.ravel())
            w.write(conns[s], t, ser(msg, typ))
    w.close()


def peer_read(path: Path) -> int:
    """rosbags + numpy / cv2.imdecode by hand: number of images decoded."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    n = 0
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as r:
        conns = [c for c in r.connections if c.msgtype.startswith("sensor_msgs/msg/")]
        for conn, _, raw in r.messages(connections=conns):
            msg = r.deserialize(raw, conn.msgtype)
            if hasattr(msg, "format"):
                img = cv2.imdecode(np.asarray(msg.data), cv2.IMREAD_UNCHANGED)
            else:
                img = np.frombuffer(msg.data, np.uint8).reshape(msg.height, msg.step)[:, :msg.width * 3]
                img = img.reshape(msg.height, msg.width, 3)
            n += img is not None
    return n


def ours_read(path: Path) -> int:
    with open_sequence(path) as seq:
        return sum(1 for _ in seq)


def bench_bags(n: int) -> None:
    with tempfile.TemporaryDirectory() as d:
        for compressed in (False, True):
            for flavour in ("ros1", "sqlite3", "mcap"):
                path = Path(d) / (f"{flavour}{int(compressed)}" + (".bag" if flavour == "ros1" else ""))
                write_bag(path, flavour, n, compressed)
                t_ours, t_peer = np.inf, np.inf
                for _ in range(2):           # best of two: the first run also builds rosbags' deserialisers
                    t0 = time.perf_counter()
                    pairs = ours_read(path)
                    t_ours = min(t_ours, time.perf_counter() - t0)
                    t0 = time.perf_counter()
                    imgs = peer_read(path)
                    t_peer = min(t_peer, time.perf_counter() - t0)
                assert pairs == n and imgs == 2 * n
                print(f"bag {flavour:7s} {'jpeg' if compressed else 'raw '}: ours {n / t_ours:7.1f} pairs/s, "
                      f"rosbags by hand {n / t_peer:7.1f} pairs/s, ratio {t_peer / t_ours:.2f}")


def _server(frames_jpg):
    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args):
            pass

        def do_GET(self):
            self.send_response(200)
            self.send_header("Content-Type", "multipart/x-mixed-replace; boundary=frame")
            self.end_headers()
            try:
                for j in frames_jpg:
                    self.wfile.write(b"--frame\r\nContent-Type: image/jpeg\r\nContent-Length: %d\r\n\r\n"
                                     % len(j) + j + b"\r\n")
            except OSError:
                pass

    srv = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    srv.daemon_threads = True
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    return srv, f"http://127.0.0.1:{srv.server_address[1]}/stream.mjpg"


def bench_live(n: int) -> None:
    jpgs = [cv2.imencode(".jpg", _image(k, 0))[1].tobytes() for k in range(n)]
    srv, url = _server(jpgs)
    try:
        t0 = time.perf_counter()
        cap = cv2.VideoCapture(url)
        got = 0
        while cap.read()[0]:
            got += 1
        cap.release()
        t_peer = time.perf_counter() - t0
        lat = []
        t0 = time.perf_counter()
        with open_sequence(url, timeout_s=2.0) as seq:
            try:
                for f in seq:
                    lat.append(time.time() - f.t)
            except Exception:         # StreamEnded: the server sent everything
                pass
        t_ours = time.perf_counter() - t0
    finally:
        srv.shutdown()
    lat_ms = np.array(lat) * 1e3
    print(f"live MJPEG 640x480: ours {len(lat) / t_ours:7.1f} frames/s ({len(lat)} of {n} frames delivered), "
          f"cv2.VideoCapture loop {got / t_peer:7.1f} frames/s ({got} frames), ratio {t_peer / t_ours * len(lat) / max(got, 1):.2f}; "
          f"added latency p50 {np.percentile(lat_ms, 50):.2f} ms, p99 {np.percentile(lat_ms, 99):.2f} ms")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--frames", type=int, default=150)
    args = ap.parse_args()
    print(f"machine: {cpu_model()}")
    bench_bags(args.frames)
    bench_live(args.frames * 2)


if __name__ == "__main__":
    main()
