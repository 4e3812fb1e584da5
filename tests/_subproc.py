"""Background ``tudorvision`` processes for the tests (a joint-layer server on loopback, mostly)."""
from __future__ import annotations

import select
import subprocess
import sys

import pytest


def start_cli(args, *, expect, timeout_s: float = 20.0):
    """Start ``python -m tudorvision.cli ARGS`` and wait for its first stdout line.

    Returns ``(proc, line)``; the test fails (with the process's stderr) unless the line contains every
    string of ``expect`` within ``timeout_s``.
    """
    proc = subprocess.Popen([sys.executable, "-m", "tudorvision.cli", *map(str, args)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    ready, _, _ = select.select([proc.stdout], [], [], timeout_s)
    line = proc.stdout.readline() if ready else ""
    if not all(s in line for s in expect):
        proc.kill()
        _, err = proc.communicate(timeout=5)
        pytest.fail(f"tudorvision {' '.join(map(str, args))} did not start: {line!r} {err[-2000:]!r}")
    return proc, line


def stop(proc) -> None:
    """Terminate ``proc`` (kill it if it does not stop within 5 s) and reap it."""
    proc.terminate()
    try:
        proc.wait(timeout=5)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait(timeout=5)
