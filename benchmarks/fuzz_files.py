"""Fuzz the sequence index parser and the calibration readers and report crashes (issue 14).

A *crash* is any exception other than the project's one-line errors
(:class:`~tudorvision._checks.TudorVisionError`, ``ValueError``) from

* ``index``       - :func:`tudorvision.io._index.parse_index` (TUM-style ``timestamp path`` lines);
* ``calibration`` - :func:`tudorvision.io.load_calibration` (the project's YAML);
* ``ros``         - :func:`tudorvision.io.load_ros_camera_info`;
* ``opencv``      - :func:`tudorvision.io.load_opencv_stereo` (``intrinsics.yml``, OpenCV FileStorage);
* ``pattern``     - :func:`tudorvision.rgbd.depth_pattern.read_depth_pattern` (a depth pattern, OpenCV YAML);
* ``header``      - :func:`tudorvision.io._imageheader.image_size_from_header` and the pixel
  limit check (the part of :func:`~tudorvision.io._index.read_image` before
  OpenCV decodes; decoding itself is not fuzzed here: mutated PNG/JPEG
  files have aborted the process inside OpenCV's decoders with
  ``malloc(): invalid size``, which no Python code can catch).

Cases, drawn from a seeded ``random.Random``: random bytes, random printable
text, and valid files of each format with 1-4 mutations (byte flips,
deletions, insertions of YAML-significant tokens, truncation).

Run: ``.venv/bin/python benchmarks/fuzz_files.py [--cases 100000] [--seed 0]``;
exit status 1 when any crash was found (the first few are printed).
"""
from __future__ import annotations

import argparse
import os
import random
import sys
import tempfile
import time
import traceback
from pathlib import Path

import numpy as np

from tudorvision._checks import TudorVisionError
from tudorvision.rgbd.depth_pattern import DepthPatternCorrection, read_depth_pattern, write_depth_pattern
from tudorvision.io import (Calibration, CameraModel, StereoExtrinsics, load_calibration, load_opencv_stereo,
                            load_ros_camera_info, save_calibration, save_opencv_stereo, save_ros_camera_info)
from tudorvision.io._imageheader import check_pixel_limit, image_size_from_header
from tudorvision.io._index import parse_index

__all__ = ["SEEDS", "TARGETS", "run_target", "main"]

ALLOWED = (TudorVisionError, ValueError)


def _seeds() -> dict[str, str]:
    K = np.array([[500.0, 0, 320], [0, 500.0, 240], [0, 0, 1]])
    cam = CameraModel(K=K, dist=np.array([0.1, -0.05, 0.001, 0.0, 0.01]), width=640, height=480)
    cal = Calibration(cameras={"left": cam, "right": cam},
                      stereo=StereoExtrinsics(left="left", right="right", R=np.eye(3), T=np.array([-0.2, 0, 0])))
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        save_calibration(cal, d / "cal.yaml")
        save_ros_camera_info(d / "ros.yaml", cam, name="left")
        save_opencv_stereo(cal, d / "intrinsics.yml", d / "extrinsics.yml")
        write_depth_pattern(d / "pattern.yaml", DepthPatternCorrection(np.full((3, 4), 1e-3), 8, (32, 24), 3))
        return {"pattern": (d / "pattern.yaml").read_text(),"calibration": (d / "cal.yaml").read_text(), "ros": (d / "ros.yaml").read_text(),
                "opencv": (d / "intrinsics.yml").read_text(),
                "index": "# timestamp filename\n0.000000 image/000000.png\n0.100000 image/000001.png\n"
                         "0.2 ../x.png\n0.3 /abs/y.png\n",
                "header": ""}


SEEDS = _seeds()


def _index(path: Path):
    (path.parent / "image").mkdir(exist_ok=True)
    return parse_index(path)


def _header(path: Path):
    size = image_size_from_header(path.read_bytes())
    if size is not None and not (isinstance(size, tuple) and len(size) == 2 and all(v >= 0 for v in size)):
        raise AssertionError(f"bad size {size!r}")
    return check_pixel_limit(size, 1_000_000)


TARGETS = {
    "index": ("left.txt", _index),
    "calibration": ("calibration.yaml", load_calibration),
    "ros": ("camera_info.yaml", load_ros_camera_info),
    "opencv": ("intrinsics.yml", lambda p: load_opencv_stereo(p, size=(640, 480))),
    "pattern": ("pattern.yaml", read_depth_pattern),
    "header": ("frame.png", _header),
}


def run_target(target: str, data: bytes, folder) -> bool:
    """Feed ``data`` as a file to ``target``; True when it parsed, False on a one-line error.

    Any other exception propagates (that is a crash).
    """
    name, fn = TARGETS[target]
    path = Path(folder) / name
    path.write_bytes(data)
    try:
        fn(path)
        return True
    except ALLOWED:
        return False


_TOKENS = [b":", b"- ", b"\n", b"  ", b"[", b"]", b"{", b"}", b"'", b'"', b"#", b"!!binary ", b"&a ", b"*a",
           b"nan", b"-.inf", b"1e309", b"0x1F", b"~", b"null", b"true", b"\t", b"\x00", b"\xff", b"%YAML:1.0\n",
           b"!!opencv-matrix", b"rows: 3", b"data: [", b"..", b"/", b"\r"]


def _png_header(r: random.Random) -> bytes:
    import struct
    w, h = r.choice([0, 1, 17, 4000, 30000, 2 ** 31 - 1, 2 ** 32 - 1]), r.choice([0, 1, 9, 30000, 2 ** 32 - 1])
    return b"\x89PNG\r\n\x1a\n" + struct.pack(">I4sII", 13, b"IHDR", w, h) + bytes(r.randrange(256)
                                                                                   for _ in range(r.randrange(40)))


def _jpeg(r: random.Random) -> bytes:
    import cv2
    ok, buf = cv2.imencode(r.choice([".jpg", ".png", ".bmp", ".ppm"]),
                           np.full((r.randrange(1, 9), r.randrange(1, 9), 3), r.randrange(256), np.uint8))
    return buf.tobytes()


def _mutate(r: random.Random, data: bytes) -> bytes:
    b = bytearray(data)
    for _ in range(r.randint(1, 4)):
        op = r.randrange(5)
        pos = r.randrange(len(b) + 1)
        if op == 0 and b:
            b[min(pos, len(b) - 1)] = r.randrange(256)
        elif op == 1:
            del b[pos:pos + r.randrange(1, 30)]
        elif op == 2:
            b[pos:pos] = r.choice(_TOKENS)
        elif op == 3:
            b = b[:pos]
        else:
            b[pos:pos] = bytes(r.randrange(32, 127) for _ in range(r.randrange(1, 12)))
    return bytes(b)


def case(r: random.Random, target: str) -> bytes:
    """One fuzz input for ``target``."""
    kind = r.randrange(4)
    if kind == 0:
        return bytes(r.randrange(256) for _ in range(r.randrange(0, 200)))
    if kind == 1:
        return "".join(chr(r.randrange(9, 127)) for _ in range(r.randrange(0, 200))).encode()
    if target == "header":
        return _mutate(r, _png_header(r) if kind == 2 else _jpeg(r))
    return _mutate(r, SEEDS[target].encode())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=100_000, help="total cases over all targets (default 1e5)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from _machine import cpu_model

    r = random.Random(args.seed)
    targets = sorted(TARGETS)
    stats = {t: [0, 0, 0] for t in targets}   # parsed, refused, crashed
    crashes = []
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        for k in range(args.cases):
            target = targets[k % len(targets)]
            data = case(r, target)
            try:
                stats[target][0 if run_target(target, data, d) else 1] += 1
            except Exception:   # noqa: BLE001 - a crash is what this script counts
                stats[target][2] += 1
                if len(crashes) < 5:
                    crashes.append((target, data[:200], traceback.format_exc(limit=3)))
    wall = time.perf_counter() - t0
    print(f"machine: {os.cpu_count()} CPUs (nproc {len(os.sched_getaffinity(0))}), {cpu_model()}")
    print(f"command: .venv/bin/python benchmarks/fuzz_files.py --cases {args.cases} --seed {args.seed}")
    print(f"{'target':<12} {'cases':>7} {'parsed':>7} {'refused':>8} {'crashes':>8}")
    for t in targets:
        p, f, c = stats[t]
        print(f"{t:<12} {p + f + c:>7} {p:>7} {f:>8} {c:>8}")
    total_crashes = sum(s[2] for s in stats.values())
    print(f"total {args.cases} cases in {wall:.1f} s ({args.cases / wall:.0f} cases/s): {total_crashes} crashes")
    for target, data, tb in crashes:
        print(f"--- crash in {target} on {data!r}\n{tb}")
    return 1 if total_crashes else 0


if __name__ == "__main__":
    sys.exit(main())
