"""A short hash of package sources: names the code that computed a shipped artifact.

The catch demo ships results that take minutes to compute (the wall camera's calibration, the strain model
identified on the demo's plant). Each names the code that computed it by a hash of the files whose code runs
in that computation; a test compares the shipped name with today's, and a maintainer script computes the
artifact afresh when they differ (``benchmarks/check_shipped_calibration.py``).
"""
from __future__ import annotations

import functools
import hashlib
from pathlib import Path

__all__ = ["source_hash", "files_run", "PACKAGE_ROOT"]

#: The package folder; the files are named relative to it.
PACKAGE_ROOT = Path(__file__).resolve().parents[1]


@functools.lru_cache(maxsize=8)
def source_hash(files: tuple) -> str:
    """Hash of the files' names and contents (line endings normalised), read once per list.

    Parameters
    ----------
    files : tuple of str
        Paths relative to the package folder, e.g. ``"sim/arm.py"``; the order counts.

    Returns
    -------
    str
        16 hex digits.

    Examples
    --------
    >>> h = source_hash(("geometry.py", "sensors.py"))
    >>> len(h), h == source_hash(("sensors.py", "geometry.py"))
    (16, False)
    """
    h = hashlib.sha1()
    for rel in files:
        h.update(rel.encode())
        h.update((PACKAGE_ROOT / rel).read_bytes().replace(b"\r\n", b"\n"))
    return h.hexdigest()[:16]


def files_run(profile) -> set:
    """The package files whose code ran under a profile, named as in a hashed file list.

    What a test compares with such a list: a file that ran and is not in it would change the artifact
    without changing its hash.

    Parameters
    ----------
    profile : cProfile.Profile
        A profile that was enabled around the computation.

    Returns
    -------
    set of str
        Paths relative to the package folder, e.g. ``"sim/arm.py"``.

    Examples
    --------
    >>> import cProfile
    >>> prof = cProfile.Profile()
    >>> _ = prof.runcall(source_hash.__wrapped__, ("geometry.py",))   # uncached: its body runs
    >>> sorted(files_run(prof))
    ['lab/code_hash.py']
    """
    import pstats

    ran = set()
    for filename, _line, _name in pstats.Stats(profile).stats:
        path = Path(filename).resolve()
        if path.is_relative_to(PACKAGE_ROOT):
            ran.add(path.relative_to(PACKAGE_ROOT).as_posix())
    return ran
