"""Which code made a result: the package version and, in a git checkout, the commit.

Stamped on every record the experiment runner writes (:func:`tudorvision.lab.runner.run_tasks`) and on
the sections of ``tudorvision reproduce``, so a resumed run can say which of its results came from
other code.
"""
from __future__ import annotations

import subprocess
from pathlib import Path

__all__ = ["code_version"]


def code_version() -> str:
    """The package version and, in a git checkout, the commit (``+dirty`` with uncommitted changes).

    Returns
    -------
    str
        E.g. ``"0.1.0 (git 7442782+dirty)"``; the version alone outside a checkout.
    """
    from .. import __version__
    root = Path(__file__).resolve().parents[2]
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, timeout=5)
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5)
    except (OSError, subprocess.SubprocessError):
        return __version__
    if head.returncode != 0:
        return __version__
    return f"{__version__} (git {head.stdout.strip()}{'+dirty' if dirty.stdout.strip() else ''})"
