"""The README's command table, run as written on ``sample_data/`` (issue 16: what the README shows is what runs).

Every backticked span in the table's ``commands`` column that starts with ``tudorvision `` is a
command. They run in the README's order in one scratch folder that links ``sample_data`` (later rows
use what earlier rows wrote), each with ``python -m tudorvision.cli`` and its own timeout; a command
ending in `` &`` runs in the background (``joint serve``) and the next one starts once it says it
listens. Each command must exit 0, and the files it names with ``--out``/``--plot`` must exist.
"""
from __future__ import annotations

import re
import select
import shlex
import subprocess
import sys
from pathlib import Path

import pytest
from _subproc import stop

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
TIMEOUT_S = 60.0

# Rows that fail today for a reason outside this test: {command prefix: reason}. strict: a fix shows up as
# XPASS and fails the test, so the entry is removed with the fix.
KNOWN_FAILING: dict[str, str] = {}


def readme_commands(text: str) -> list[str]:
    """The commands of the README's command table (``| task | commands |``), in order.

    Parameters
    ----------
    text : str
        README.md.

    Returns
    -------
    list of str
        Each backticked ``tudorvision ...`` span of the table's second column.
    """
    lines = text.splitlines()
    start = next(i for i, line in enumerate(lines) if re.match(r"^\|\s*task\s*\|\s*commands\s*\|", line))
    out = []
    for line in lines[start + 2:]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        out += [span for span in re.findall(r"`([^`]+)`", cells[1]) if span.startswith("tudorvision ")]
    return out


COMMANDS = readme_commands(README.read_text())


def test_the_table_is_found_and_covers_every_command_group():
    groups = {c.split()[1] for c in COMMANDS}
    assert {"sim", "seq", "calib", "colormodel", "track", "rgbd", "detect", "servo", "catch", "joint"} <= groups
    assert len(COMMANDS) >= 20
    assert all("sample_data/" in c for c in COMMANDS if c.split()[1] in ("seq", "detect", "rgbd"))


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    d = tmp_path_factory.mktemp("readme")
    (d / "sample_data").symlink_to(ROOT / "sample_data", target_is_directory=True)
    background = []
    yield d, background
    for proc in background:
        stop(proc)


def _marks(cmd):
    return [pytest.mark.xfail(strict=True, reason=why) for prefix, why in KNOWN_FAILING.items()
            if cmd.startswith(prefix)]


def _outputs(argv):
    """Files a command says it writes (``--out``, ``--plot``), as given."""
    return [argv[i + 1] for i, a in enumerate(argv[:-1]) if a in ("--out", "--plot")]


@pytest.mark.parametrize("cmd", [pytest.param(c, marks=_marks(c), id=f"{k:02d} {c[12:60]}")
                                 for k, c in enumerate(COMMANDS)])
def test_readme_command_runs_as_written(cmd, workdir):
    d, background = workdir
    argv = shlex.split(cmd)
    bg = argv[-1] == "&"
    if bg:
        argv = argv[:-1]
    full = [sys.executable, "-m", "tudorvision.cli", *argv[1:]]
    if bg:
        proc = subprocess.Popen(full, cwd=d, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        background.append(proc)
        ready, _, _ = select.select([proc.stdout], [], [], 30.0)
        line = proc.stdout.readline() if ready else ""
        assert "listening on" in line, f"{cmd}: {line!r} {proc.poll()}"
        return
    res = subprocess.run(full, cwd=d, capture_output=True, text=True, timeout=TIMEOUT_S)
    assert res.returncode == 0, f"{cmd}\nexit {res.returncode}\n{res.stderr[-1500:]}\n{res.stdout[-500:]}"
    for path in _outputs(argv):
        assert (d / path).exists(), f"{cmd}: {path} not written"
