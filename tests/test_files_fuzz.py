"""Issue 14, fuzzing: the sequence index parser and the calibration readers never crash.

Arbitrary text or bytes give a parsed result or the project's one-line error
(:class:`TudorVisionError`, a ``ValueError``), never another exception.
``benchmarks/fuzz_files.py`` runs the same targets for >= 1e5 cases.
"""
from __future__ import annotations

import sys
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
from fuzz_files import SEEDS, TARGETS, run_target  # noqa: E402

FAST = settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])

_index_lines = st.lists(st.one_of(
    st.text(max_size=40),
    st.builds(lambda t, p: f"{t} {p}", st.one_of(st.floats(allow_nan=True), st.integers(), st.text(max_size=8)),
              st.one_of(st.sampled_from(["image/000000.png", "../x.png", "/etc/hosts", "a b.png", ""]),
                        st.text(max_size=20))),
), max_size=12).map("\n".join)


def _mutations(seed: str):
    return st.builds(lambda cut, junk, pos: (seed[:pos] + junk + seed[pos + cut:]),
                     st.integers(0, 40), st.text(max_size=30), st.integers(0, len(seed)))


@FAST
@given(text=_index_lines)
def test_index_parser_never_crashes(tmp_path, text):
    run_target("index", text.encode("utf-8", "surrogatepass"), tmp_path)


@FAST
@given(data=st.binary(max_size=300))
def test_index_parser_on_bytes(tmp_path, data):
    run_target("index", data, tmp_path)


def _calibration_test(target):
    @FAST
    @given(text=st.one_of(_mutations(SEEDS[target]), st.text(max_size=200)))
    def test(tmp_path, text):
        run_target(target, text.encode("utf-8", "surrogatepass"), tmp_path)
    return test


test_own_calibration_yaml_never_crashes = _calibration_test("calibration")
test_ros_camera_info_never_crashes = _calibration_test("ros")
test_opencv_yaml_never_crashes = _calibration_test("opencv")


@FAST
@given(data=st.binary(max_size=300), target=st.sampled_from(sorted(TARGETS)))
def test_every_reader_on_bytes(tmp_path, data, target):
    run_target(target, data, tmp_path)
