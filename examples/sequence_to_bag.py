"""Write a stereo recording as a ROS 2 bag (mcap storage), to try ``tudorvision seq import`` on a bag.

Stands in for ``ros2 bag record /left/image_raw/compressed /right/image_raw/compressed`` on a real
rig (docs/own_hardware.md, step 1). The images go in as ``sensor_msgs/CompressedImage`` with the
recording's own JPEG/PNG bytes (so an import gives back the same pixels), stamped with the
recording's timestamps from 1.7e9 s on.

Run: ``.venv/bin/python examples/sequence_to_bag.py SEQ OUT_FOLDER``
(e.g. ``sample_data/stereo-step out/own/step_bag``).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

EPOCH_S = 1_700_000_000


def read_index(seq: Path, stream: str) -> list[tuple[float, Path]]:
    """``(t_s, image path)`` rows of a sequence's ``<stream>.txt`` index (comments skipped)."""
    rows = []
    for line in (seq / f"{stream}.txt").read_text().splitlines():
        if line.strip() and not line.startswith("#"):
            t, name = line.split()[:2]
            rows.append((float(t), seq / name))
    return rows


def write_bag(seq: Path, out: Path) -> int:
    """Write the ``left`` and ``right`` streams of ``seq`` to the ROS 2 bag folder ``out``; returns messages."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    Time = store.types["builtin_interfaces/msg/Time"]
    Header = store.types["std_msgs/msg/Header"]
    Compressed = store.types["sensor_msgs/msg/CompressedImage"]
    n = 0
    with Writer(out, version=9, storage_plugin=StoragePlugin.MCAP) as bag:
        for stream in ("left", "right"):
            topic = f"/{stream}/image_raw/compressed"
            conn = bag.add_connection(topic, "sensor_msgs/msg/CompressedImage", typestore=store)
            for t_s, path in read_index(seq, stream):
                t_ns = EPOCH_S * 10**9 + int(round(t_s * 1e9))
                fmt = "png" if path.suffix.lower() == ".png" else "jpeg"
                msg = Compressed(header=Header(stamp=Time(sec=t_ns // 10**9, nanosec=t_ns % 10**9),
                                               frame_id=f"{stream}_camera"),
                                 format=fmt, data=np.frombuffer(path.read_bytes(), np.uint8))
                bag.write(conn, t_ns, store.serialize_cdr(msg, "sensor_msgs/msg/CompressedImage"))
                n += 1
    return n


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__.strip().splitlines()[-2].strip())
    count = write_bag(Path(sys.argv[1]), Path(sys.argv[2]))
    print(f"wrote {count} messages to {sys.argv[2]}")
