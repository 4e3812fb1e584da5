"""The sphere-family benchmark's simulated user who clicks on what is seen of a sphere (``--user sees``)."""
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_sphere_family as bench  # noqa: E402


def _disc(h, w, uv, r):
    vv, uu = np.mgrid[0:h, 0:w]
    return (uu - uv[0]) ** 2 + (vv - uv[1]) ** 2 <= r * r


def test_clicks_on_the_seen_part_stay_and_hidden_ones_move_onto_it():
    uv, r = np.array([40.0, 30.0]), 12.0
    mask = _disc(60, 80, uv, r)
    c, e = np.array([40.0, 30.0]), np.array([49.0, 30.0])
    c2, e2 = bench._on_seen_part(mask, c, e, uv)                 # both seen: unchanged
    assert np.array_equal(c2, c) and np.array_equal(e2, e)
    hidden = mask & ~(np.abs(np.mgrid[0:60, 0:80][1] - 40) <= 3)  # a vertical bar in front of the centre
    c3, e3 = bench._on_seen_part(hidden, c, np.array([40.0, 39.0]), uv)
    assert hidden[int(c3[1]), int(c3[0])] and hidden[int(e3[1]), int(e3[0])]
    assert np.hypot(*(c3 - c)) <= 6.0                               # the nearest seen pixel 1 px inside
    assert abs(np.hypot(*(e3 - uv)) - 9.0) <= 1.0                    # the edge turned, still at 80 % of r
    assert bench._on_seen_part(np.zeros_like(mask), c, e, uv) is None   # hidden whole: no click
