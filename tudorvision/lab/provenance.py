"""Which code made a result: the package version and, in a git checkout, the commit; and the numerical packages.

Stamped on every record the experiment runner writes (:func:`tudorvision.lab.runner.run_tasks`) and on
the sections of ``tudorvision reproduce``, so a resumed run can say which of its results came from
other code. The versions of the numerical packages go into ``tudorvision reproduce``'s report: the lab's
results move slightly between builds of NumPy, SciPy and OpenCV (an ill-conditioned identification, a throw
decided by a hair), so two reports are comparable throw by throw only on the same versions.
"""
from __future__ import annotations

import subprocess
from pathlib import Path

__all__ = ["code_version", "package_versions", "NUMERICAL_PACKAGES"]

#: The distributions whose builds change the lab's numbers (the installed name, as pip knows it).
NUMERICAL_PACKAGES = ("numpy", "scipy", "opencv-python-headless", "open3d", "filterpy", "dask")


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


def package_versions(names=NUMERICAL_PACKAGES) -> dict:
    """The installed version of each named distribution.

    Parameters
    ----------
    names : sequence of str
        Distribution names (as pip knows them).

    Returns
    -------
    dict
        ``{name: version}``; ``"not installed"`` for a distribution that is not.

    Examples
    --------
    >>> package_versions(["numpy", "no-such-distribution-here"])["no-such-distribution-here"]
    'not installed'
    >>> import numpy
    >>> package_versions(["numpy"])["numpy"] == numpy.__version__
    True
    """
    from importlib import metadata
    out = {}
    for name in names:
        try:
            out[str(name)] = metadata.version(str(name))
        except metadata.PackageNotFoundError:
            out[str(name)] = "not installed"
    return out
