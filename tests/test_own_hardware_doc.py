"""``docs/own_hardware.md`` followed end to end on the sample data, and ``examples/own_joint_core.py``.

Every fenced block tagged ``bash test`` in the guide runs as written with ``bash -e``, in order, in one
scratch folder holding links to ``sample_data/`` and ``examples/`` and the virtual environment first on
the ``PATH`` (as after ``source .venv/bin/activate``). A block's background jobs (``&``) are stopped at
the end of the module. The files the guide says it writes are checked to exist.
"""
from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
GUIDE = ROOT / "docs" / "own_hardware.md"
BLOCK_TIMEOUT_S = 90


def guide_blocks(text: str) -> list[str]:
    """The bodies of the fenced blocks opened with ```` ```bash test ````, in order.

    Parameters
    ----------
    text : str
        A markdown document.

    Returns
    -------
    list of str
        Each block's lines, joined.
    """
    return re.findall(r"^```bash test\n(.*?)^```$", text, flags=re.S | re.M)


BLOCKS = guide_blocks(GUIDE.read_text())


def test_the_guide_has_tested_blocks_for_every_step():
    body = "\n".join(BLOCKS)
    for step in ("examples/sequence_to_bag.py", "seq import", "calib stereo", "colormodel", "calib base-stereo", "track stereo",
                 "examples/own_joint_core.py", "joint move", "servo --sim", "catch sample_data"):
        assert step in body, step


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    d = tmp_path_factory.mktemp("own_hardware")
    for name in ("sample_data", "examples"):
        (d / name).symlink_to(ROOT / name, target_is_directory=True)
    groups = []
    yield d, groups
    for pgid in groups:
        try:
            os.killpg(pgid, signal.SIGTERM)
        except ProcessLookupError:
            pass


@pytest.mark.parametrize("block", BLOCKS, ids=[f"{k:02d}" for k in range(len(BLOCKS))])
def test_guide_block_runs_as_written(block, scratch):
    d, groups = scratch
    env = dict(os.environ, PATH=f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}")
    log = d / "block.log"
    with open(log, "w") as fh:         # a file, not a pipe: background jobs must not hold the test
        proc = subprocess.Popen(["bash", "-e", "-c", block], cwd=d, env=env, stdout=fh, stderr=subprocess.STDOUT,
                                start_new_session=True)
        groups.append(proc.pid)
        try:
            code = proc.wait(timeout=BLOCK_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            pytest.fail(f"block timed out after {BLOCK_TIMEOUT_S} s:\n{block}\n{log.read_text()[-2000:]}")
    assert code == 0, f"{block}\nexit {code}\n{log.read_text()[-2500:]}"
    for path in re.findall(r"--(?:out|plot|save-frame) (out/own/\S+)", block):
        assert (d / path).exists(), f"{path} not written"


def test_example_core_runs_and_drives_the_layer():
    res = subprocess.run([sys.executable, str(ROOT / "examples" / "own_joint_core.py")], capture_output=True,
                         text=True, timeout=60)
    assert res.returncode == 0, res.stderr[-2000:]
    lines = res.stdout.splitlines()
    reached = [float(x) for x in lines[0].removeprefix("setpoint reached, theta_deg ").split()]
    assert max(abs(a - b) for a, b in zip(reached, (20.0, 70.0, -15.0))) < 0.1, lines
    m = re.search(r"theta_deg (\S+) (\S+) (\S+), speed (\S+) deg/s", lines[1])
    assert m, lines
    assert abs(float(m.group(2)) - reached[1]) < 0.02 and abs(float(m.group(3)) - reached[2]) < 0.02
    # 0.5 s of 10 deg/s on joint 1, then the watchdog ramp-down: about 5-7 deg further, at rest
    assert 24.0 < float(m.group(1)) < 28.0 and float(m.group(4)) < 0.05
